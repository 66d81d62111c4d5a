"""In-loop controllers (issue 24): flex_control's laws loaded by name into the model's
update loop reproduce flex_model.simulate with the same law as a sampled policy."""
import numpy as np
import pytest

from flex_control.laws import DecentralizedPD, PDLikeCascade, as_policy, hold_reference
from flex_model.arm import load_arm
from flex_model.control_loop import ControlLoop
from flex_model.controller_interface import available_controllers, load_controller
from flex_model.dynamics import FlexArmModel
from flex_model.simulate import simulate
from flex_model.stepper import Stepper

NAMES = ["joint1", "joint2"]
PERIOD = 2e-3


@pytest.fixture(scope="module")
def model():
    return FlexArmModel(load_arm("thesis_example1_motors"))


def _loop_vs_simulate(model, controller, policy, t_final=0.6):
    q0 = model.q_from_joint_angles(np.radians([10.0, -20.0]))
    loop = ControlLoop(Stepper(model, q0), controller, PERIOD)
    loop.advance(int(round(t_final / PERIOD)))
    res = simulate(model, q0, np.zeros(model.nq), t_final=t_final, sample_period=PERIOD,
                   policy=policy, method="fixed", dt=1e-3)
    return loop, res


def test_the_laws_are_registered():
    assert {"eq95", "eq45", "state_feedback"} <= set(available_controllers())


def test_eq95_in_the_loop_equals_the_sampled_simulation(model):
    ref = hold_reference(NAMES, np.radians([30.0, 0.0]))
    # limits above the torques: a command held unchanged over two periods (at a limit) does
    # not restart the stepper's method, while simulate restarts at every policy instant
    ctl = load_controller("eq95", NAMES, {"h": [25.0], "a": [5.0], "torque_limits": [1e3]})
    ctl.set_trajectory(ref)
    pd = DecentralizedPD(ref, h=[25.0], a=[5.0], torque_limits=[1e3])
    loop, res = _loop_vs_simulate(model, ctl, as_policy(pd, model))
    assert loop.stepper.t == pytest.approx(0.6, abs=1e-12)
    # the same law, the same zero-order hold, the same generalized-alpha restarts
    np.testing.assert_allclose(loop.stepper.x[:2 * model.nq], res.q[-1].tolist()
                               + res.v[-1].tolist(), rtol=0, atol=1e-12)
    assert np.degrees(model.joint_angles(loop.stepper.q)[0]) > 12.0  # it moved to 30 deg
    assert loop.n_updates == 300


def test_eq45_in_the_loop_equals_the_sampled_simulation(model):
    ref = hold_reference(NAMES, np.radians([15.0, -10.0]))
    params = {"kpp": 20.0, "kpv": 0.02, "gear_ratio": 10.0, "torque_limits": [1e3]}
    ctl = load_controller("eq45", NAMES, params)
    ctl.set_trajectory(ref)
    law = PDLikeCascade(ref, kpp=20.0, kpv=0.02, gear_ratio=10.0, torque_limits=[1e3])
    loop, res = _loop_vs_simulate(model, ctl, as_policy(law, model))
    np.testing.assert_allclose(loop.stepper.q, res.q[-1], rtol=0, atol=1e-12)


def test_state_feedback_in_the_loop_equals_the_law_written_out(model):
    K = [40.0, 100.0, 8.0, 1.0, 20.0, 50.0, 4.0, 0.5]
    ctl = load_controller("state_feedback", NAMES, {"gains": K, "limit": 80.0})
    r = np.radians([5.0, 5.0])
    ctl.set_trajectory(hold_reference(NAMES, r))
    G = model.G
    idx = [model.tip_deflection_index(i) for i in range(2)]
    k = np.reshape(K, (2, 4))

    def policy(t, x):  # the law by hand, from the state vector
        q, v = x[:model.nq], x[model.nq:2 * model.nq]
        u = k[:, 0] * (r - G @ q) - k[:, 1] * q[idx] - k[:, 2] * (G @ v) - k[:, 3] * v[idx]
        return np.clip(u, -80.0, 80.0)

    loop, res = _loop_vs_simulate(model, ctl, policy)
    np.testing.assert_allclose(loop.stepper.q, res.q[-1], rtol=0, atol=1e-12)


class _Own:
    """A user's own controller: hold a torque."""

    def __init__(self, joint_names, parameters):
        self.joint_names = joint_names
        self.tau = np.asarray(parameters.get("tau", [0.0, 0.0]), float)

    def set_trajectory(self, trajectory):
        pass

    def update(self, time, period, state):
        return self.tau


def test_own_controllers_and_refusals(model):
    own = load_controller(f"{__name__}:_Own", NAMES, {"tau": [1.0, 2.0]})
    loop = ControlLoop(Stepper(model), own, PERIOD)
    loop.advance(1)
    np.testing.assert_array_equal(loop.stepper.u, [1.0, 2.0])
    with pytest.raises(ValueError, match="expected one of eq45, eq95, state_feedback"):
        load_controller("eq96", NAMES)
    with pytest.raises(ValueError, match="h: got"):
        load_controller("eq95", NAMES, {"h": [-1.0]})
    with pytest.raises(ValueError, match="rate_hz: got a parameter of the controller node"):
        load_controller("eq95", NAMES, {"rate_hz": 500.0})
    with pytest.raises(ValueError, match="gains: got 3 values; expected 8"):
        load_controller("state_feedback", NAMES, {"gains": [1, 2, 3]})
    bad = load_controller(f"{__name__}:_Own", NAMES, {"tau": [np.nan, 0.0]})
    with pytest.raises(ValueError, match="expected 2 finite values"):
        ControlLoop(Stepper(model), bad, PERIOD).advance(1)
    with pytest.raises(ValueError, match="trajectory joint_names"):
        load_controller("eq95", NAMES).set_trajectory(hold_reference(["a", "b"], [0, 0]))
