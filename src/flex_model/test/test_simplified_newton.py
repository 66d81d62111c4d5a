"""Simplified Newton in the fixed-step mode (solvers.loop.simplified_newton):
the same solution as full Newton to the step tolerance, at a fraction of the cost."""
import numpy as np

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.simulate import JointPD, Pulse, simulate


def _run(model, newton):
    th0 = np.radians([-20.0, 20.0, -20.0])
    return simulate(model, model.q_from_joint_angles(th0), t_final=0.3, sample_period=0.005,
                    method="fixed", dt=1e-3, newton=newton,
                    pd=JointPD(np.full(3, 5e3), np.full(3, 250.0), th0),
                    pulses=[Pulse(0.1, 0.2, (1000.0, 0.0, 0.0))])


def test_simplified_newton_matches_full_newton_on_section_E():
    """Section E (second order, 4 variables per link, the 1 kN m pulse, 0.3 s): the tips
    agree to 1e-9 m (the Newton tolerance is 1e-10 m per step; the discretization error
    at 1 ms is 35 um), and the simplified iterations, each one inverse-dynamics pass,
    number at most 3.5 per step through the pulse (3.1 measured; over the 10 s run 2.2)."""
    model = FlexArmModel(load_arm("thesis_three_link", 4).with_kinematics("second_order"))
    full, simp = _run(model, "full"), _run(model, "simplified")
    diff = np.max(np.abs(np.array(simp.link_tips()) - np.array(full.link_tips())))
    assert diff < 1e-9, diff
    assert np.max(np.abs(simp.v - full.v)) < 1e-7
    assert simp.stats["newton_iterations"] <= 3.5 * simp.stats["steps"]


def test_default_newton_follows_the_kinematics():
    """Default: simplified for second order, full Newton (results as before) for the
    thesis kinematics; a bad value is refused with what is allowed."""
    arm = load_arm("thesis_three_link", 2)
    small = FlexArmModel(arm)
    r0, r1 = _run(small, None), _run(small, "full")
    np.testing.assert_array_equal(r0.q, r1.q)
    second = FlexArmModel(arm.with_kinematics("second_order"))
    np.testing.assert_array_equal(_run(second, None).q, _run(second, "simplified").q)
    try:
        _run(small, "quasi")
    except ValueError as e:
        assert "'full', 'simplified'" in str(e)
    else:
        raise AssertionError("newton='quasi' accepted")
