"""Link-side encoders ql<i>, vl<i> of an elastic joint in a recording (issue 22): the
replay's restarts (multiple shooting) put the link side there and the motor side at
q<i>, v<i>, the coupling twisted as measured; without them, or on a rigid twin, the
start is unchanged (motor and link together)."""
import numpy as np
import pytest

from flex_model.arm import arm_from_dict, load_arm
from flex_model.dynamics import FlexArmModel
from flex_twin.diagnosis.baseline import baseline_parameters
from flex_twin.diagnosis.controller import controller_from_dict
from flex_twin.diagnosis.evaluation import Context, predict_channels
from flex_twin.diagnosis.recording import RecordingError, load_csv, save_csv, validate
from flex_twin.diagnosis.replay import initial_state, measured_start, simulate_closed_loop
from flex_twin.real_arms.two_mass_twin import arm_dict, parameters_from_arm

P = 1e-3
CTL = controller_from_dict({"controller": {"law": "pd", "kp": [20.0], "kd": [0.5],
                                           "period": P, "feedforward": "recorded"}})
ARM = load_arm("two_mass_bench")   # drive motor - coupling (joint_elasticity) - load


@pytest.fixture(scope="module")
def run():
    """A noiseless closed-loop run of the elastic two-mass twin (PD on the motor encoder
    plus a two-tone feed-forward at 23 and 60 Hz, near the 54/76 Hz coupling modes)."""
    m = FlexArmModel(ARM)
    T = 0.6
    t = np.arange(int(round(T / P)) + 1) * P
    qset = (0.2 * np.sin(2 * np.pi * t))[:, None]
    ff = (0.5 * np.sin(2 * np.pi * 60 * t) + 0.3 * np.sin(2 * np.pi * 23 * t + 1))[:, None]
    X, tau = simulate_closed_loop(m, CTL, initial_state(m, [0.0]), T, qset, ff,
                                  sample_period=P, dt=2.5e-4)
    q, v = X[:, :m.nq], X[:, m.nq:2 * m.nq]
    return t, {"q1": q @ m.Ga[0], "v1": v @ m.Ga[0], "tau1": tau[:, 0], "qset1": qset[:, 0],
               "tau_ff1": ff[:, 0], "ql1": q @ m.G[0], "vl1": v @ m.G[0]}


def _worst(rec, arm, window):
    ctx = Context.build(arm, CTL, rec, baseline_parameters(arm), dt=2.5e-4, segment=0.1)
    ctx.start_window = window
    pred = predict_channels(ctx, arm)
    return {c: float(np.max(np.abs(pred.channels[c] - rec.channels[c])))
            for c in pred.channels}


def test_restarts_from_the_link_encoder_reproduce_the_run(run):
    """Six 0.1-s segments: restarted from the first sample (window 0) with the link side
    at ql, vl the replay reproduces the run (q1 to 1e-9 rad; the rest is the stiff load
    bar's bending, restarted in static equilibrium: measured 1.7e-10 rad, 2.4e-8 rad/s,
    1.3e-8 N m); restarted with zero twist (no ql column) it misses by 2.7 mrad (twist
    RMS 0.86 mrad), and with the default 50-ms fit by 4.1 mrad."""
    t, ch = run
    assert np.std(ch["q1"] - ch["ql1"]) > 5e-4            # the coupling does twist
    rec = validate(t, ch, 1, "twin run")
    exact = _worst(rec, ARM, 0.0)
    assert exact["q1"] < 1e-9 and exact["v1"] < 1e-6 and exact["tau1"] < 1e-6
    no_link = validate(t, {k: v for k, v in ch.items() if k[:2] not in ("ql", "vl")}, 1, "x")
    zero_twist = _worst(no_link, ARM, 0.0)
    assert zero_twist["q1"] > 1e-3 and zero_twist["v1"] > 0.1
    assert _worst(rec, ARM, 0.05)["q1"] > 1e-3             # 50 ms = 3.8 periods at 76 Hz


def test_without_an_elastic_joint_the_link_encoder_is_ignored(run):
    """The rigid nominal (coupling locked): ql1/vl1 change nothing, bit for bit."""
    t, ch = run
    rigid = arm_from_dict(arm_dict(parameters_from_arm(ARM), elastic=False))
    rec = validate(t, ch, 1, "a")
    bare = validate(t, {k: v for k, v in ch.items() if k[:2] not in ("ql", "vl")}, 1, "b")
    a = Context.build(rigid, CTL, rec, baseline_parameters(rigid), dt=2.5e-4, segment=0.2)
    b = Context.build(rigid, CTL, bare, baseline_parameters(rigid), dt=2.5e-4, segment=0.2)
    pa, pb = predict_channels(a, rigid), predict_channels(b, rigid)
    assert all(np.array_equal(pa.channels[c], pb.channels[c]) for c in pb.channels)
    # initial_state: no link angles, or an elastic joint's NaN, is the old start
    m = FlexArmModel(ARM)
    old = initial_state(m, [0.3], [1.0])
    assert np.array_equal(initial_state(m, [0.3], [1.0], [np.nan], [np.nan]), old)
    tw = initial_state(m, [0.3], [1.0], [0.29], [0.5])
    assert m.actuator_angles(tw[:m.nq])[0] == 0.3 and m.joint_angles(tw[:m.nq])[0] == \
        pytest.approx(0.29, abs=1e-12)
    assert (tw[m.nq:2 * m.nq] @ m.Ga[0], tw[m.nq:2 * m.nq] @ m.G[0]) == (1.0, 0.5)


def test_link_channels_and_start_window_are_validated(run, tmp_path):
    t, ch = run
    with pytest.raises(RecordingError, match="ql1 without vl1"):
        validate(t, {k: v for k, v in ch.items() if k != "vl1"}, 1, "f.csv")
    with pytest.raises(RecordingError, match="ql2: no joint 2"):
        validate(t, {**ch, "ql2": ch["ql1"], "vl2": ch["vl1"]}, 1, "f.csv")
    rec = validate(t, ch, 1, "f.csv")
    rec.meta["start_window"] = 0.0008
    save_csv(rec, tmp_path / "r.csv")
    back = load_csv(tmp_path / "r.csv", 1)
    assert back.meta["start_window"] == 0.0008 and back.link_encoders() == [0]
    # a window of 2 samples: the first sample itself
    assert measured_start(back, 2 * P)[0][0] == pytest.approx(ch["q1"][0], abs=1e-15)
    text = (tmp_path / "r.csv").read_text().replace("start_window: 0.0008",
                                                     "start_window: -1")
    (tmp_path / "bad.csv").write_text(text)
    with pytest.raises(RecordingError, match="start_window: '-1' is not a number of seconds"):
        load_csv(tmp_path / "bad.csv", 1)
