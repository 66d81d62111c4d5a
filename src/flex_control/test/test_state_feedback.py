"""The Quanser lab's state feedback (issue 9): the law, the held reference, the gauge sign,
and a closed loop on the handout twin that settles where the law says it must."""
import numpy as np
import pytest

from flex_control.state_feedback import TipStateFeedback
from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.simulate import simulate


def test_law_and_held_reference():
    """V = K1 (r - theta) + K2 (0 - d) - K3 theta_dot - K4 d_dot with the lab's sign of d
    (sign s and bias b: d_lab = s d + b), the reference held between its samples."""
    law = TipStateFeedback([6.0, -3.0, 0.2, 0.1], [0.0, 1.0], [0.1, -0.1], gauge_sign=-1.0,
                           gauge_bias=0.002)
    d_lab, dd_lab = -0.01 + 0.002, -0.5
    expect = 6.0 * (0.1 - 0.05) + 3.0 * d_lab - 0.2 * 0.4 - 0.1 * dd_lab
    assert law.voltage(0.999, 0.05, 0.4, 0.01, 0.5) == pytest.approx(expect, rel=1e-14)
    assert law.reference_at(1.0) == -0.1 and law.reference_at(0.5) == 0.1
    with pytest.raises(ValueError, match="gains"):
        TipStateFeedback([1.0, 2.0], [0.0], [0.0])
    # a voltage offset V_0 is added before the clipping (0.246 - 0.15 V clipped to 0.05)
    off = TipStateFeedback([6.0, -3.0, 0.2, 0.1], [0.0, 1.0], [0.1, -0.1], gauge_sign=-1.0,
                           gauge_bias=0.002, voltage_limit=0.05, voltage_offset=-0.15)
    assert off.voltage(0.999, 0.05, 0.4, 0.01, 0.5) == pytest.approx(
        min(expect - 0.15, 0.05), rel=1e-14)
    with pytest.raises(ValueError, match="voltage_offset"):
        TipStateFeedback([1.0, 2.0, 0.0, 0.0], [0.0], [0.0], voltage_offset=np.nan)
    # a gauge reading g times the deflection: the deflection terms see g d (g = 0.5)
    half = TipStateFeedback([6.0, -3.0, 0.2, 0.1], [0.0, 1.0], [0.1, -0.1], gauge_sign=-1.0,
                            gauge_bias=0.002, gauge_gain=0.5)
    d_half, dd_half = -0.005 + 0.002, -0.25
    assert half.voltage(0.999, 0.05, 0.4, 0.01, 0.5) == pytest.approx(
        6.0 * 0.05 + 3.0 * d_half - 0.2 * 0.4 - 0.1 * dd_half, rel=1e-14)
    with pytest.raises(ValueError, match="gauge_gain"):
        TipStateFeedback([1.0, 2.0, 0.0, 0.0], [0.0], [0.0], gauge_gain=0.0)


def test_a_lagging_gauge_feeds_the_law_the_tip_of_a_while_ago():
    """gauge_delay 25 ms: along a tip deflection d = 0.003 + sin(3 t) / 100 and its rate,
    called at uneven times, the law's K2 and K4 terms read d and d_dot at t - 0.025,
    linearly interpolated between the calls (np.interp), the first call's values held
    before t = 25 ms; a call at an earlier time starts a new run (the replay's retry at a
    halved step)."""
    model = FlexArmModel(load_arm("quanser_cuboulder_flexible"))
    law = TipStateFeedback([0.0, 2.0, 0.0, 0.5], [0.0], [0.0], gauge_delay=0.025)
    policy = law.policy(model)
    i = model.tip_deflection_index(0)
    times = np.cumsum(np.r_[0.0, np.random.default_rng(1).uniform(0.002, 0.012, 30)])

    def tip(t):
        return 0.003 + np.sin(3 * t) / 100, 0.03 * np.cos(3 * t)

    for rerun in range(2):
        for k, t in enumerate(times):
            x = np.zeros(2 * model.nq)
            x[i], x[model.nq + i] = tip(t)
            d, dd = (np.interp(t - 0.025, times[:k + 1], tip(times[:k + 1])[j])
                     for j in (0, 1))
            assert policy(t, x)[0] == pytest.approx(-2.0 * d - 0.5 * dd, rel=1e-12)
    with pytest.raises(ValueError, match="gauge_delay"):
        TipStateFeedback([1.0, 2.0, 0.0, 0.0], [0.0], [0.0], gauge_delay=-0.01)


def test_closed_loop_settles_on_the_reference_without_friction():
    """The frictionless handout twin under the law (K1 = 6, K3 = 0.2) settles on the
    reference (an integrating plant: zero steady-state error) with the link at rest."""
    model = FlexArmModel(load_arm("quanser_cuboulder_flexible"))
    law = TipStateFeedback([6.0, 0.0, 0.2, 0.0], [0.0], [0.1])
    res = simulate(model, model.q_from_joint_angles([0.0]), t_final=6.0,
                   sample_period=1e-3, policy=law.policy(model), method="fixed", dt=1e-3)
    assert res.joint_angles[-1, 0] == pytest.approx(0.1, abs=2e-4)
    assert abs(res.tip_deflections[-1, 0]) < 1e-4
    assert np.max(np.abs(res.u[:, 0])) == pytest.approx(0.6, rel=1e-9)  # K1 * 0.1 at t = 0
