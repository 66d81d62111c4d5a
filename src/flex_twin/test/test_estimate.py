"""Issue 45: ``flex-twin estimate`` on a recording of the independent (Exudyn) suite, and
the Quanser tip estimated from hub encoder and voltage against the lab's gauge (skips
with a reason when ../shared is absent)."""
import json
from pathlib import Path

import numpy as np
import pytest

from flex_model.dynamics import FlexArmModel
from flex_twin.cli import main
from flex_twin.estimate import channel_kind, coverage_95
from flex_twin.estimate_cli import parse_stds
from flex_twin.real_arms import quanser_data as qd
from flex_twin.real_arms.quanser_estimate import estimate_run
from flex_twin.real_arms.quanser_twin import stored_calibrated_arm

SUITE = Path(__file__).resolve().parents[3] / "test" / "data" / "independent_suite"


def _run(root, name):
    return qd.read_cuboulder_file(next(p for p in qd.cuboulder_files(root) if p.name == name))


def test_channel_names_and_coverage():
    assert channel_kind("w2") == ("w", 1) and channel_kind("tip_y") == ("tip_y", 1)
    with pytest.raises(ValueError, match="q<i>"):
        channel_kind("w0")
    with pytest.raises(ValueError, match="CHANNEL=STD"):
        parse_stds(["q1=-1"])
    # 1.96 sigma: a normal error of std 1 lies inside on 95 % of its samples
    e = np.random.default_rng(0).standard_normal(200000)
    assert coverage_95(e, 0.6, 0.8) == pytest.approx(0.95, abs=0.003)


def test_cli_estimates_the_held_out_deflections(tmp_path):
    """Exudyn arm B, PD at 500 Hz: joint angles measured, both links' tip deflections held
    out; the filter starts from the static sag at the first measured angles (its default).
    Over the first 1.2 s, w1 (peak 9.9 mm, the sag) within 0.9 mm RMS and every sample in
    the band."""
    case = SUITE / "B-samp500-healthy-s1"
    out = tmp_path / "est"
    assert main(["estimate", str(case / "recording.csv"), "--arm", str(case / "arm.yaml"),
                 "--measure", "q1,q2", "--std", "q1=5e-5", "--std", "q2=5e-5",
                 "--duration", "1.2", "--out", str(out), "--json"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert (out / "estimate.png").stat().st_size > 10000
    head = (out / "estimate.csv").read_text().splitlines()[0].split(",")
    assert head[:3] == ["t", "q1", "q1_std"] and "w2_std" in head
    w1 = s["held_out"]["w1"]
    assert w1["peak"] == pytest.approx(9.9e-3, abs=0.3e-3)
    assert w1["rms"] < 0.9e-3 and w1["coverage_95"] > 0.99
    assert set(s["held_out"]) == {"v1", "v2", "w1", "w2", "tip_x", "tip_y"}


def test_cli_fits_the_hidden_friction_over_a_horizon(tmp_path, capsys):
    """Exudyn arm B with a hidden joint-1 friction (Coulomb 2 N m, viscous 8 N m s/rad)
    and a 0.3 kg payload from the start, the filter starting from the nominal arm
    (frictions 0): ``--adapt-horizon 1`` fits joint 1's frictions on the last 1 s (the
    payload a random walk). Before the first large move (2 s) the viscous friction is still
    near 0 (0.12 measured); at 3 s 6.99 (-13 %) and Coulomb 2.19 (+10 %), payload 0.315.
    The JSON summary reports the fitted values and the horizon."""
    case = SUITE / "B-samp500-two-joint_friction+payload-s1"
    out = tmp_path / "est"
    args = ["estimate", str(case / "recording.csv"), "--arm", str(case / "arm.yaml"),
            "--measure", "q1,q2", "--std", "q1=5e-5", "--std", "q2=5e-5",
            "--torque-noise", "0.5", "--modal-noise", "1", "--duration", "3",
            "--out", str(out), "--json", "--adapt", "coulomb_friction:joint1",
            "viscous_friction:joint1", "payload_mass"]
    assert main(args + ["--adapt-horizon", "1"]) == 0
    f = json.loads((out / "summary.json").read_text())["filter"]
    assert (f["adapt_horizon"], f["adapt_block"]) == (1.0, 0.05)
    p = f["parameters"]
    assert p["viscous_friction:joint1"] == pytest.approx(8.0, rel=0.15)
    assert p["coulomb_friction:joint1"] == pytest.approx(2.0, rel=0.15)
    assert p["payload_mass"] == pytest.approx(0.3, rel=0.1)
    assert 0 < f["parameter_std"]["viscous_friction:joint1"] < 1.0
    est = np.genfromtxt(out / "estimate.csv", delimiter=",", names=True)
    assert est["viscous_frictionjoint1"][est["t"] < 2.0].max() < 0.5
    capsys.readouterr()
    assert main(args[:-3] + ["--adapt-horizon", "1"]) == 2
    assert "adapt_horizon: got 1.0 with adapt []; expected a coulomb_friction" in \
        capsys.readouterr().err


def test_quanser_gauge_never_enters_the_filter(cuboulder_root):
    """The estimate of a held-out run is the same with the gauge's log scrambled."""
    model = FlexArmModel(stored_calibrated_arm("flexible"))
    run = _run(cuboulder_root, "flexarm_K1K2K3_6_-5_213").head(0.5)
    a = estimate_run(model, run)
    run.deflection = np.random.default_rng(1).permutation(run.deflection)
    b = estimate_run(model, run)
    assert np.array_equal(a.result.tip_deflections, b.result.tip_deflections)


def test_quanser_held_out_run_tip_from_hub_and_voltage(cuboulder_root):
    """A held-out run's first 4.5 s (3.5 s at rest, then a 0.2 rad step): the tip from hub
    encoder and voltage against the gauge (measured: tip 3.48 mm RMS, 83 % of its square
    before the step, where the stuck hub shows nothing; hub 2.6 mrad, NIS mean 2.7; the
    filter's own band holds 16 % of the gauge, with the link model error 98 %). Far from
    the 1 mm aim: docs/estimation.md says why."""
    model = FlexArmModel(stored_calibrated_arm("flexible"))
    run = _run(cuboulder_root, "flexarm_K1K2K3_6_-5_213").head(4.5)
    m = estimate_run(model, run).metrics
    assert m["hub_rms_rad"] < 3e-3 and m["nis_mean"] < 4.0
    assert 3.0 < m["tip_rms_mm"] < 4.0 and m["before_first_step_share"] > 0.75
    assert m["coverage_95_filter"] < 0.25 and 0.95 < m["coverage_95"] < 0.99


def test_quanser_driven_link_pins_the_hub_and_follows_the_gauge(cuboulder_root):
    """The driven link (the link's mode driven by the hub's acceleration, the hub pinned
    by its encoder alone; tuned on Hagenau's fit runs) on a held-out run of that unit:
    hub within 0.3 mrad (the EKF: 2.5), tip 2.55 mm RMS (the EKF on the stored twin: 2.81,
    docs/estimation.md); the gauge never enters it."""
    from flex_twin.real_arms.quanser_estimate import estimate_run_driven, link_unit
    run = _run(cuboulder_root, "flexarm_K1K2K3_6_-5_213")
    assert link_unit(run.name) == "hagenau"
    est = estimate_run_driven(run)
    m = est.metrics
    assert m["hub_rms_rad"] < 3e-4
    assert 2.3 < m["tip_rms_mm"] < 2.8
    assert 0.95 < m["coverage_95"] < 1.0
    run.deflection = np.random.default_rng(1).permutation(run.deflection)
    assert np.array_equal(estimate_run_driven(run).result.deflection, est.result.deflection)
