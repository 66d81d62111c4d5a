"""Issue 22: one servo for the rigid-bar and the flexible-link runs (studies.servo_split),
checked on the stored twins and with stand-in fits (no lab data needed)."""
import numpy as np
import pytest

from flex_model.dynamics import FlexArmModel
from flex_twin.real_arms.calibration import CUBOULDER_SPLIT
from flex_twin.real_arms.quanser_twin import calibrated_arm_for

pytest.importorskip("flex_control.state_feedback")   # the studies replay with the lab's law

def test_the_joint_servo_fit_shares_the_servo_and_frees_the_bar():
    """``python -m studies.servo_split``: the unknowns start from the stored twins (rotor inertia
    3.1666e-6, the rigid runs' friction, EI 0.33651 N m^2, lag 37.41 ms; K_t from the
    handout's, within the tolerance); the two twins share rotor inertia and K_t; moving
    inertia from the rotor (x Kg^2) to the bar leaves the rigid twin's mass matrix as it is,
    so only the flexible runs can tell the two apart."""
    from studies.servo_split import joint_arms, joint_parameters
    rigid, flexible = (calibrated_arm_for("cuboulder", k) for k in ("rigid", "flexible"))
    p = {x.name: x for x in joint_parameters(rigid, flexible, 0.3)}
    assert (p["rotor_inertia"].start, p["rotor_inertia"].lower) == pytest.approx(
        (3.1666e-6, 0.3 * 8.5377e-7))
    kt = p["torque_constant"]
    assert kt.start is None and (kt.nominal, kt.lower, kt.upper) == pytest.approx(
        (0.0107, 0.7 * 0.0107, 1.3 * 0.0107))
    fr = rigid.effect("joint_friction", "joint1")
    assert p["rigid_coulomb"].start == pytest.approx(fr["coulomb"])
    assert (p["bar_inertia"].start, p["bar_inertia"].upper) == pytest.approx((0.0015, 0.012))
    assert p["EI"].start is None and p["EI"].nominal == pytest.approx(0.33651)
    assert p["gauge_delay"].start == pytest.approx(0.03741)
    values = {"rotor_inertia": 2e-6, "torque_constant": 0.0112, "bar_inertia": 0.003,
              "rigid_coulomb": 0.02, "coulomb": 0.05, "EI": 0.36}
    r, f = joint_arms(rigid, flexible, values)
    for arm in (r, f):
        assert arm.effect("gear", "joint1")["rotor_inertia"] == 2e-6
        assert arm.effect("dc_motor", "joint1")["torque_constant"] == 0.0112
    assert r.links[0].J_minus == 0.003 and f.links[0].J_minus == flexible.links[0].J_minus
    assert r.effect("joint_friction", "joint1")["coulomb"] == 0.02
    assert f.effect("joint_friction", "joint1")["coulomb"] == 0.05
    assert r.links[0].segments[0].dims["EI"][0] == 100.0
    n2 = 48.4 ** 2
    moved = joint_arms(rigid, flexible, {**values, "rotor_inertia": 2e-6 - 1e-3 / n2,
                                         "bar_inertia": 0.004})[0]
    heavier = joint_arms(rigid, flexible, {**values, "bar_inertia": 0.004})[0]
    q = np.zeros(FlexArmModel(r).nq)
    m0, m1, m2 = (FlexArmModel(a).mass_matrix(q) for a in (r, moved, heavier))
    np.testing.assert_allclose(m1, m0, rtol=1e-12, atol=1e-15)
    assert m2[0, 0] - m0[0, 0] == pytest.approx(1e-3, rel=1e-9)


def test_servo_split_flags_reach_the_study(monkeypatch, tmp_path):
    """``python -m studies.servo_split --kt-tolerance 0.3 --max-evaluations 4``: the study
    gets both and the output folder; the command prints its markdown."""
    from flex_twin.real_arms import quanser_data
    from studies import servo_split
    got = {}

    def fake(runs, make_policy, out, kt_tolerance, max_nfev, progress):
        got.update(kt=kt_tolerance, nfev=max_nfev, out=out)
        (out / "servo_split.md").parent.mkdir(parents=True, exist_ok=True)
        (out / "servo_split.md").write_text("# stub\n")
        return {}
    monkeypatch.setattr(servo_split, "study", fake)
    monkeypatch.setattr(quanser_data, "read_cuboulder", lambda root: {})
    (tmp_path / quanser_data.CUBOULDER).mkdir(parents=True)
    assert servo_split.main(["--data", str(tmp_path), "--out", str(tmp_path / "o"),
                             "--kt-tolerance", "0.3", "--max-evaluations", "4"]) == 0
    assert got == {"kt": 0.3, "nfev": 4, "out": tmp_path / "o"}


def test_the_joint_fits_start_grid_keeps_the_rigid_runs_torque_per_inertia():
    """Every start of the grid gives the rigid twin the stored one's K_t / (Kg^2 J_r +
    J_bar) where the bar's bounds allow: at the stored K_t (-5 %) and rotor, the handout's
    bar 0.0015 kg m^2."""
    from flex_twin.real_arms.quanser_twin import hub_inertia
    from studies.servo_split import grid_starts, joint_arms, joint_parameters
    rigid, flexible = (calibrated_arm_for("cuboulder", k) for k in ("rigid", "flexible"))
    ratio = rigid.effect("dc_motor", "joint1")["torque_constant"] / hub_inertia(rigid)
    grid = grid_starts(rigid, joint_parameters(rigid, flexible, 0.05), 0.05)
    assert len(grid) == 15
    for g in grid:
        r = joint_arms(rigid, flexible, g)[0]
        assert g["torque_constant"] / hub_inertia(r) == pytest.approx(ratio, rel=1e-9)
    low = next(g for g in grid if g["torque_constant"] < 0.0107 and g["rotor_inertia"]
               == pytest.approx(3.1666e-6))
    assert low["bar_inertia"] == pytest.approx(0.0015, rel=2e-3)   # K_t stored to 5 digits


def test_the_joint_fit_starts_from_its_grids_best_point(monkeypatch):
    """servo_split.joint_fit with a stand-in replay: the rigid runs see only K_t / hub
    inertia, the flexible ones want a rotor of 1.5e-6 and K_t 0.0112: of the 15 grid
    points the fit starts at K_t +5 % and 0.45x the stored rotor; the stored twins' cost
    and every evaluation are reported."""
    from types import SimpleNamespace
    from flex_twin.real_arms.quanser_twin import hub_inertia
    from studies import servo_split
    rigid = calibrated_arm_for("cuboulder", "rigid")
    ratio = rigid.effect("dc_motor", "joint1")["torque_constant"] / hub_inertia(rigid)

    def fake_replay(arm, runs, make_policy, t_final=None):
        kt = arm.effect("dc_motor", "joint1")["torque_constant"]
        if arm.links[0].length < 0.2:   # the rigid bar
            return np.array([1e3 * (kt / hub_inertia(arm) / ratio - 1.0)])
        jr = arm.effect("gear", "joint1")["rotor_inertia"]
        return np.array([(jr - 1.5e-6) / 1e-7, (kt - 0.0112) / 1e-4])
    got = {}

    def fake_fit(params, residual, max_nfev, progress):
        got.update({p.name: p.start for p in params})
        return {"rotor_inertia": 1.0}, 0.5, 7
    monkeypatch.setattr(servo_split, "replay_residual", fake_replay)
    monkeypatch.setattr(servo_split, "fit_values", fake_fit)
    names = CUBOULDER_SPLIT["servo_fit"] + CUBOULDER_SPLIT["link_fit"]
    fit = servo_split.joint_fit({n: SimpleNamespace(name=n) for n in names}, None, 0.05)
    assert len(fit["grid"]) == 15 and fit["evaluations"] == 7 + 15 + 1
    assert got["torque_constant"] == pytest.approx(1.05 * 0.0107)
    assert got["rotor_inertia"] == pytest.approx(0.45 * 3.1666e-6)
    assert fit["cost_grid"] == min(g["cost"] for g in fit["grid"])
    stored = np.array([1e3 * (0.010167 / hub_inertia(rigid) / ratio - 1.0),
                       (3.1666e-6 - 1.5e-6) / 1e-7, (0.010167 - 0.0112) / 1e-4])
    assert fit["cost_stored"] == pytest.approx(np.sqrt(np.mean(stored ** 2)), rel=1e-9)
    assert (fit["values"], fit["cost_fitted"]) == ({"rotor_inertia": 1.0}, 0.5)
