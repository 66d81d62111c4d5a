"""Continuous-time controller laws in the diagnosis replay (issue 21, step 1).

The hub-less arm is thesis Example 1 (two aluminium links of 2 m, no hub inertia, vertical
plane) under the issue's PD (Kp = 625, Kd = 176.8 on the relative joint angles, no gravity
compensation) with set-point steps."""
import numpy as np
import pytest
import yaml

from flex_model.arm import PRESET_DIR, load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.simulate import SimulationDivergedError, simulate
from flex_twin.cli import main
from flex_twin.diagnosis.controller import (controller_from_dict, controller_to_dict,
                                             load_controller)
from flex_twin.diagnosis.recording import validate
from flex_twin.diagnosis.replay import initial_state, replay, residuals

ARM = load_arm("thesis_example1")
GAINS = {"law": "pd", "kp": [625.0, 625.0], "kd": [176.8, 176.8], "feedforward": "none"}
CONTINUOUS = controller_from_dict({"controller": dict(GAINS, timing="continuous")})
T, DT = 1.2, 0.002


def _reference(t):
    return np.column_stack([np.where(t < 0.3, -1.2, -1.0), np.where(t < 0.7, 0.3, 0.5)])


@pytest.fixture(scope="module")
def exact_run():
    """The continuous law through simulate() (Dormand-Prince, rtol 1e-10) and its
    recording (q, v, the law's command tau at the samples, qset)."""
    m = FlexArmModel(ARM)
    t = np.arange(int(round(T / DT)) + 1) * DT
    qset = _reference(t)
    ff = CONTINUOUS.feedforward(m, qset)
    x0 = initial_state(m, qset[0])
    r = simulate(m, x0[:m.nq], x0[m.nq:], t_final=T, sample_period=DT, method="variable",
                 rtol=1e-10, **CONTINUOUS.simulate_inputs(m, t, qset, ff))
    tau = CONTINUOUS.command(m, np.column_stack([r.q, r.v]), CONTINUOUS.reference(qset), ff)
    ch = {}
    for i in range(2):
        ch[f"q{i + 1}"], ch[f"v{i + 1}"] = r.q @ m.Ga[i], r.v @ m.Ga[i]
        ch[f"tau{i + 1}"], ch[f"qset{i + 1}"] = tau[:, i], qset[:, i]
    return m, x0, validate(t, ch, 2, "exact"), r


def test_continuous_pd_replay_equals_the_variable_step_simulation(exact_run):
    m, x0, rec, _ = exact_run
    err = {}
    for h in (1e-3, 2.5e-4):
        res = residuals(rec, replay(m, CONTINUOUS, rec, dt=h, x0=x0))
        err[h] = {k: float(np.sqrt(np.mean(v * v))) for k, v in res.items()}
    fine = err[2.5e-4]
    # generalized-alpha at 0.25 ms against the exact solution: micro-radians
    assert fine["q1"] < 2e-6 and fine["q2"] < 4e-6
    assert fine["v1"] < 5e-3 and fine["v2"] < 2e-2
    # second order: 4 times the step, about 16 times the error (15 measured)
    assert err[1e-3]["q2"] / fine["q2"] > 10 and err[1e-3]["q1"] / fine["q1"] > 10


def test_continuous_pd_is_stable_at_2ms_where_the_sampled_pd_diverges(exact_run):
    m, x0, rec, _ = exact_run
    res = residuals(rec, replay(m, CONTINUOUS, rec, dt=2e-3, x0=x0))
    assert all(np.all(np.isfinite(v)) for v in res.values())
    assert np.abs(res["q1"]).max() < 5e-4 and np.abs(res["q2"]).max() < 2e-3  # 0.14, 0.62 mrad
    for period in (2e-3, 5e-4):    # the same law sampled: the D term on a hub-less joint
        sampled = controller_from_dict({"controller": dict(GAINS, period=period)})
        with pytest.raises(SimulationDivergedError):
            replay(m, sampled, rec, dt=period, x0=x0)


def test_continuous_yaml_round_trip_and_one_line_refusals(tmp_path, capsys, exact_run):
    path = tmp_path / "c.yaml"
    path.write_text(yaml.safe_dump(controller_to_dict(CONTINUOUS)))
    assert "timing: continuous" in path.read_text() and "period" not in path.read_text()
    back = load_controller(path)
    assert back.continuous and back.period == 0.0
    assert back.gains.tolist() == CONTINUOUS.gains.tolist()
    assert back.rate_gains.tolist() == CONTINUOUS.rate_gains.tolist()
    sampled = controller_from_dict({"controller": dict(GAINS, period=0.002)})
    assert "timing" not in controller_to_dict(sampled)["controller"]
    with pytest.raises(ValueError, match=r"controller\.period: got 0\.002; expected no period "
                                         "with timing: continuous"):
        controller_from_dict({"controller": dict(GAINS, timing="continuous", period=0.002)})
    with pytest.raises(ValueError, match="one of sampled, continuous"):
        controller_from_dict({"controller": dict(GAINS, timing="analog")})
    with pytest.raises(ValueError, match="gains on w1 for joint 1.*timing: sampled"):
        controller_from_dict({"controller": {
            "law": "state_feedback", "timing": "continuous",
            "gains": [{"q1": 20.0, "w1": -40.0}], "rate_gains": [{"q1": 1.5}]}})
    # a continuous state feedback on each joint's own angle is the joint PD
    sf = controller_from_dict({"controller": {
        "law": "state_feedback", "timing": "continuous", "gains": [{"q1": 20.0}, {"q2": 8.0}],
        "rate_gains": [{"q1": 1.5}, {"q2": 0.5}]}})
    assert [a.tolist() for a in sf.joint_pd()] == [[20.0, 8.0], [1.5, 0.5]]
    # the CLI: one line, exit 2 (a law the replay cannot integrate; a delayed continuous law)
    m, x0, rec, _ = exact_run
    data = tmp_path / "d.csv"
    names = ["t"] + [f"{k}{i}" for i in (1, 2) for k in ("q", "v", "tau", "qset")]
    data.write_text(",".join(names) + "\n" + "\n".join(
        ",".join(repr(float(x)) for x in row) for row in np.column_stack(
            [rec.t] + [rec.channels[n] for n in names[1:]])))
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"controller": {
        "law": "state_feedback", "timing": "continuous", "gains": [{"q2": 1.0}, {"q2": 1.0}],
        "rate_gains": [{"q1": 0.1}, {"q2": 0.1}]}}))
    assert main(["diagnose", str(data), "--arm", "thesis_example1", "--controller", str(bad),
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "gains on q2 for joint 1" in err[0]
    delayed = tmp_path / "delayed.yaml"
    arm_dict = yaml.safe_load((PRESET_DIR / "thesis_example1.yaml").read_text())
    arm_dict["effects"] = [{"type": "actuator_delay", "joint": "joint1", "delay": 0.004}]
    delayed.write_text(yaml.safe_dump(arm_dict))
    assert main(["diagnose", str(data), "--arm", str(delayed), "--controller", str(path),
                 "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "actuator_delay of joint1" in err[0]
    # the delay hypotheses are not screened under a continuous law
    from flex_twin.diagnosis.hypotheses import library_hypotheses
    kinds = {h.kind for h in library_hypotheses(ARM, rec, CONTINUOUS)}
    assert "sensor_delay" not in kinds and "actuator_delay" not in kinds
    assert "sensor_bias" in kinds
