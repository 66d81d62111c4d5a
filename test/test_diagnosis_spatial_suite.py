"""Issue 44, item 4: spatial arms diagnosed in closed loop by the planar engine, on data
the twin did not make (test/data/spatial_suite: Exudyn's geometrically exact 3D beams,
the L arm of bench/independent_suite/generate_spatial.py under a continuous PD, and one
healthy run under a PD sampled at 500 Hz).

Cheap tests: the nominal twin's closed-loop replay of a healthy run within the gate at the
spatial replay's step (spatial_loop.MAX_STEP; at the engine's default 2 ms it is not), and
the hidden plane's stiffness found by its hypothesis (the other plane's cannot explain
it). The full diagnoses (a minute or more each) are in the acceptance tier."""
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.optimize import minimize_scalar

from flex_model.spatial.loader import load_spatial_arm
from flex_twin.diagnosis import spatial_loop
from flex_twin.diagnosis.baseline import baseline_parameters
from flex_twin.diagnosis.controller import load_controller
from flex_twin.diagnosis.engine import DEFAULT_GATE
from flex_twin.diagnosis.evaluation import Context, cost, residual_vector
from flex_twin.diagnosis.hypotheses import FRICTION_WIDTH, library_hypotheses
from flex_twin.diagnosis.recording import load_csv

DATA = Path(__file__).resolve().parent / "data" / "spatial_suite"
HEALTHY = DATA / "S-cont-healthy-s1"
BENDING = DATA / "S-cont-bending-link1-y-0.8-s1"
SAMPLED = DATA / "S-samp500-healthy-s1"
FRICTION = DATA / "S-cont-joint_friction-joint2-s1"


def _context(case, dt=2e-3):
    arm = load_spatial_arm(case / "arm.yaml")
    ctl = load_controller(case / "controller.yaml")
    rec = load_csv(case / "recording.csv", arm.n_links)
    return arm, Context.build(arm, ctl, rec, baseline_parameters(arm), dt=dt)


def test_a_healthy_spatial_run_replays_within_the_gate(monkeypatch):
    arm, ctx = _context(HEALTHY)
    J = cost(residual_vector(ctx, arm))
    assert J - 1.0 < DEFAULT_GATE, J        # 1.35 measured (1 ms)
    monkeypatch.setattr(spatial_loop, "MAX_STEP", 2e-3)   # the engine's default step
    assert cost(residual_vector(ctx, arm)) - 1.0 > 2 * DEFAULT_GATE   # 3.4 measured


def test_a_healthy_sampled_run_replays_within_the_gate():
    """A PD sampled at 500 Hz (zero-order hold): each control period restarts from the
    command jump's acceleration (spatial_loop._sampled); carrying the generalized-alpha
    acceleration history across the jumps smears them (J 1.73 at 1 ms: v2 8.4, tau2 3.9
    noise units, above the gate on its own)."""
    arm, ctx = _context(SAMPLED)
    assert not ctx.controller.continuous and ctx.controller.period == 2e-3
    J = cost(residual_vector(ctx, arm))
    assert J - 1.0 < DEFAULT_GATE, J        # 1.11 measured (1 ms)


def _fit(ctx, arm, hyp):
    def J(x):
        return cost(residual_vector(ctx, hyp.apply(arm, [x])[0]))
    res = minimize_scalar(J, bounds=(-4.0, 4.0), method="bounded", options={"xatol": 1e-3})
    return res.x, res.fun


def test_the_hidden_planes_stiffness_is_found_by_its_hypothesis():
    """Link 1's EI_y 20 % low (600 -> 480 N m^2) in Exudyn: the out-of-plane hypothesis
    of link 1 fits it within 5 % and explains the run; the in-plane one does not."""
    arm, ctx = _context(BENDING)
    truth = yaml.safe_load((BENDING / "truth.yaml").read_text())["hidden"][0]
    assert truth["parameters"] == {"plane": "y", "scale": 0.8}
    hyps = {h.label: h for h in library_hypotheses(arm, ctx.rec, ctx.controller)}
    J0 = cost(residual_vector(ctx, arm))
    x, J_y = _fit(ctx, arm, hyps["bending_stiffness_y@link1"])
    _, J_z = _fit(ctx, arm, hyps["bending_stiffness_z@link1"])
    twin = hyps["bending_stiffness_y@link1"].apply(arm, [x])[0]
    names, values, _ = hyps["bending_stiffness_y@link1"].physical([0.1 * x], [0.0], twin)
    assert names == ("EI_y",)
    assert values[0] == pytest.approx(480.0, rel=0.05)
    assert J_y - 1.0 < DEFAULT_GATE < J0 - 1.0
    assert J_z - 1.0 > 0.5 * (J0 - 1.0)


def test_the_friction_hypothesis_carries_the_width_of_its_coulomb_transition():
    """Joint 2's friction in Exudyn builds its Coulomb torque up over tanh(w / 0.02 rad/s)
    (viscous 0.2 N m s/rad, Coulomb 0.08 N m). At those levels the friction hypothesis
    with the planar law's fixed width (1 mrad/s, x = 0) leaves the run above the gate
    (J 1.66 measured), with the width fitted at 0.02 rad/s within it (1.17): the width is
    the joint's, a parameter of the hypothesis (hypotheses.joint_friction), reported."""
    arm, ctx = _context(FRICTION, dt=spatial_loop.MAX_STEP)
    truth = yaml.safe_load((FRICTION / "truth.yaml").read_text())["hidden"][0]["parameters"]
    hyp = {h.label: h for h in library_hypotheses(arm, ctx.rec, ctx.controller)}[
        "joint_friction@joint2"]
    assert hyp.names[-1] == "regularization"

    def J(eps):
        x = [truth["viscous"] / hyp.scale[0], truth["coulomb"] / hyp.scale[1], 0.0,
             (eps - 1e-3) / FRICTION_WIDTH]
        twin = hyp.apply(arm, x)[0]
        names, values, _ = hyp.physical(hyp.values(x), [0.0] * 4, twin)
        assert dict(zip(names, values))["regularization"] == pytest.approx(eps)
        return cost(residual_vector(ctx, twin))

    assert J(truth["regularization"]) - 1.0 < DEFAULT_GATE < J(1e-3) - 1.0


def _diagnose(case, tmp_path):
    from flex_twin.diagnosis.batch import RunSpec, diagnose_run
    from flex_twin.diagnosis.evaluation import default_executor
    pool = default_executor()
    try:
        return diagnose_run(RunSpec.from_case_dir(case), str(tmp_path), plots=False,
                            executor=pool)
    finally:
        if hasattr(pool, "shutdown"):
            pool.shutdown()


@pytest.mark.acceptance
def test_a_spatial_closed_loop_run_is_diagnosed_with_the_right_plane(tmp_path):
    s = _diagnose(BENDING, tmp_path)
    assert s["verdict"] == "named", s["stop"]
    assert [n["label"] for n in s["named"]] == ["bending_stiffness_y@link1"]
    assert s["named"][0]["parameters"]["EI_y"] == pytest.approx(480.0, rel=0.05)


@pytest.mark.acceptance
def test_a_healthy_spatial_closed_loop_run_is_clean(tmp_path):
    s = _diagnose(HEALTHY, tmp_path)
    assert s["verdict"] == "no material discrepancy", s["named"]


if not DATA.is_dir():  # pragma: no cover - the cases are committed with the tests
    raise RuntimeError(f"{DATA} missing: python bench/independent_suite/generate_spatial.py "
                       "--out test/data/spatial_suite --subset ci")
assert np  # noqa (numpy for the reader's checks)
