"""Issue 9 step 3: a Quanser lab run exported as the inputs of ``flex-twin diagnose``.

One diagnosis takes 1-2 minutes, so most tests check the exporter's exactness (recording =
lab data, controller = the lab's law, arm = the handout twin); one runs the whole diagnosis
on the issue-22 run (its other results are in docs/real-arms.md). Skips without ../shared.
"""
import argparse

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_twin.cli import run_command
from flex_twin.diagnosis.controller import load_controller
from flex_twin.diagnosis.sources import load_recording
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from flex_twin.real_arms.cli import add_real_arm_parsers
from flex_twin.real_arms.quanser_diagnosis import export_run, run_path

state_feedback = pytest.importorskip("flex_control.state_feedback")


@pytest.fixture(scope="module")
def real(cuboulder_root):
    return cuboulder_root.parent


def _engine_law(exported):
    """The exported controller's voltage on the measured channels, through the diagnosis
    engine's own policy (a model state whose channels are the measured ones)."""
    p, run = exported["paths"], exported["case"]["run"]
    rec = load_recording(p["data"], 1)
    ctl = load_controller(p["controller"])
    model = FlexArmModel(load_arm(p["arm"]))
    pinv = np.linalg.pinv(ctl.channel_matrix(model))
    law = ctl.policy(model, rec.t, rec.stack("qset"), rec.stack("tau_ff"))
    sign = run.gauge_sign()
    y = np.column_stack([rec.channels["q1"], rec.channels["w1"]])
    yd = np.column_stack([run.theta_rate, sign * run.deflection_rate])
    return np.array([law(t, np.concatenate([pinv @ y[k], pinv @ yd[k]]))[0]
                     for k, t in enumerate(rec.t)])


def test_recording_csv_is_the_lab_data(real, tmp_path):
    """flexibleArm_test_3 (gauge wired the other way, +30.7 mm bias): every column equals
    the lab's to 1e-12; w1 = -(d - bias); tau_ff1 = -K2 bias."""
    e = export_run(run_path("flexibleArm_test_3", real), tmp_path)
    run = e["case"]["run"]
    rec = load_recording(e["paths"]["data"], 1)
    assert run.gauge_sign() == -1.0 and run.gauge_bias() == pytest.approx(0.0307, abs=2e-4)
    for name, lab in (("q1", run.theta), ("v1", run.theta_rate), ("tau1", run.voltage),
                      ("qset1", run.reference), ("w1", -(run.deflection - run.gauge_bias()))):
        assert np.max(np.abs(rec.channels[name] - lab)) < 1e-12, name
    np.testing.assert_allclose(rec.t, np.arange(10000) * 1e-3, atol=1e-12)
    assert rec.channels["tau_ff1"] == pytest.approx(-run.gains[1] * run.gauge_bias(), abs=1e-12)


def test_run_name_is_not_taken_for_a_same_named_directory(real, tmp_path, monkeypatch):
    """A folder called like the run in the working directory (an earlier --out, say) does
    not shadow the run name; a lab file given by path is taken as it is."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "flexarm_K1_6").mkdir()
    hit = run_path("flexarm_K1_6", real)
    assert hit.is_file() and hit.name == "flexarm_K1_6" and tmp_path not in hit.parents
    assert run_path(str(hit), None) == hit


def test_controller_is_the_lab_law(real, tmp_path):
    """Through the engine's policy the exported law equals flex_control's lab law to 1e-9 V
    (sign and bias of the gauge included), and reproduces the logged voltage to 0.056 V RMS
    on a run with all four gains (< 0.1 V asked)."""
    for name, rms_max in (("flexibleArm_test_3", None), ("flexarm_K1K2K3k4_6_-3_213_4", 0.06)):
        e = export_run(run_path(name, real), tmp_path / name)
        run = e["case"]["run"]
        u = _engine_law(e)
        lab = state_feedback.lab_controller(run)
        ref = [lab.voltage(t, th, th_d, w, w_d) for t, th, th_d, w, w_d in zip(
            run.t, run.theta, run.theta_rate, run.gauge_sign() * (run.deflection
                                                                  - run.gauge_bias()),
            run.gauge_sign() * run.deflection_rate)]
        assert np.max(np.abs(u - ref)) < 1e-9, name
        if rms_max:
            assert np.sqrt(np.mean((u - run.voltage) ** 2)) < rms_max


def test_nominal_arm_is_the_handout_twin(real, tmp_path):
    """The exported arm has the preset's EI and m (1e-12) and its 1.8 Hz clamped mode, and
    declares the run's tip gauge (exact: gain 1, no lag) for the diagnosis to fit."""
    from flex_model.sensors import tip_gauge
    e = export_run(run_path("flexarm_K1_6", real), tmp_path)
    arm, preset = load_arm(e["paths"]["arm"]), load_arm("quanser_cuboulder_flexible")
    assert [(s.kind, s.target, s.gain, s.delay) for s in arm.sensors
            if s.kind == "tip_deflection"] == [("tip_deflection", "link1", 1.0, 0.0)]
    assert tip_gauge(arm).name == "tip_gauge"
    z = np.linspace(0.0, 1.0, 5)
    for a, b in zip(arm.links[0].segments[0].properties(z)[:2],
                    preset.links[0].segments[0].properties(z)[:2]):
        np.testing.assert_allclose(a, b, rtol=1e-12)
    f1 = natural_modes(FlexArmModel(arm), joints="clamped").frequencies_hz[0]
    assert f1 == pytest.approx(1.8, abs=1e-4)


def test_held_out_run_with_another_law_is_refused(real, tmp_path, capsys):
    """One controller replays both recordings: a held-out run with other gains exits 2."""
    parser = argparse.ArgumentParser()
    add_real_arm_parsers(parser.add_subparsers())
    code = run_command(parser.parse_args(
        ["real-arm", "diagnose", "flexarm_K1_6", "--holdout", "flexarm_k1k2_6_-3", "--data",
         str(real), "--out", str(tmp_path)]))
    assert code == 2
    assert "differ from the fit run's" in capsys.readouterr().err


@pytest.mark.acceptance
def test_the_issue_run_names_stick_slip_friction_by_default(real, tmp_path):
    """Issue 22's run (flexarm_k1k2_6_-3, held out: its last 40 %), the default settings
    (restarts every 0.5 s): the stick-slip friction is named, sliding = break-away level
    0.083 N m (the holds' break-away 0.064-0.078 N m held still, above), and it removes
    97.6 % of the held-out error (whole run: the viscous joint_friction the issue reports);
    ~50 s on 2 workers."""
    import json
    parser = argparse.ArgumentParser()
    add_real_arm_parsers(parser.add_subparsers())
    code = run_command(parser.parse_args(
        ["real-arm", "diagnose", "flexarm_k1k2_6_-3", "--data", str(real), "--out",
         str(tmp_path), "--workers", "2", "--no-plots"]))
    assert code == 0
    d = json.loads((tmp_path / "diagnosis.json").read_text())
    assert [n["label"] for n in d["named"]] == ["stick_slip_friction@joint1"]
    values = d["named"][0]["parameters"]
    assert values["coulomb"] == pytest.approx(0.0833, abs=0.005)
    assert values["static"] == pytest.approx(values["coulomb"], rel=1e-3)
    assert d["holdout_error_reduction"] > 0.95


def test_the_gauges_lag_is_fitted_but_not_named_on_the_handout_twin(real, tmp_path):
    """Covington's flexibleArm_test_3 -> test_4 on the handout twin: the diagnosis fits the
    declared gauge's lag to 50 ms (the link's own fit: 57-64 ms on these runs, flex-twin
    real-arm link-response) but it explains 9.7 % of the held-out excess, under the gate:
    nothing is named (the handout link's other errors dominate); ~15 s on 2 workers."""
    import json
    parser = argparse.ArgumentParser()
    add_real_arm_parsers(parser.add_subparsers())
    code = run_command(parser.parse_args(
        ["real-arm", "diagnose", "flexibleArm_test_3", "--holdout", "flexibleArm_test_4",
         "--data", str(real), "--out", str(tmp_path), "--workers", "2", "--no-plots"]))
    assert code == 0
    d = json.loads((tmp_path / "diagnosis.json").read_text())
    assert d["named"] == []
    lag = next(c for c in d["rounds"][0]["candidates"] if c["label"] == "gauge_delay@link1")
    assert lag["parameters"]["delay"] == pytest.approx(0.05, abs=1e-9)
    assert lag["share_explained"] == pytest.approx(0.097, abs=0.02)
