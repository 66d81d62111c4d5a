"""The compiled control loop (issue 24): flex_control's built-in laws run in one compiled
call per ControlLoop.advance and give the trajectory of the Python path (controller
called every period) on the twin demo's arm and task, to 1e-12."""
import numpy as np
import pytest

from flex_control.laws import hold_reference
from flex_model.arm import load_arm
from flex_model.control_loop import ControlLoop
from flex_model.controller_interface import load_controller
from flex_model.dynamics import FlexArmModel
from flex_model.statics import static_equilibrium
from flex_model.stepper import Stepper
from flex_planner.planning import SECTION_F_TIMES, SECTION_F_WAYPOINTS
from flex_planner.planning import plan

NAMES = ["joint1", "joint2"]
PERIOD = 2e-3
WAYPOINTS, TIMES = SECTION_F_WAYPOINTS, SECTION_F_TIMES   # thesis Ch. V task


@pytest.fixture(scope="module")
def demo():
    model = FlexArmModel(load_arm("thesis_example1_motors"))
    traj = plan(model, WAYPOINTS, TIMES, sample_period=PERIOD).trajectory
    q0 = static_equilibrium(model, traj.positions[0], joints="clamped").q
    return model, traj, q0


def _both(model, q0, make, trajectory, periods, start=0.0, chunks=(1,)):
    """(Python path, compiled path) after ``periods`` periods; the compiled loop is
    advanced in pieces of the sizes ``chunks`` (cycled), as the model node calls it."""
    out = []
    for compiled in (False, True):
        ctl = make()
        if trajectory is not None:
            ctl.set_trajectory(trajectory)
        loop = ControlLoop(Stepper(model, q0), ctl, PERIOD, compiled=compiled)
        loop.t0 = start
        done, k = 0, 0
        while done < periods:
            n = min(chunks[k % len(chunks)] if compiled else 1, periods - done)
            loop.advance(n)
            done, k = done + n, k + 1
        out.append(loop)
    return out


def test_eq95_compiled_equals_python_on_the_demo_task(demo):
    model, traj, q0 = demo
    make = lambda: load_controller("eq95", NAMES, {"h": [25.0], "a": [5.0]})  # noqa: E731
    # 1 s from t = 4.5 s of the task: the corner at the second waypoint (5 s) inside
    py, cc = _both(model, q0, make, traj, 500, start=-4.5, chunks=(1, 2, 497))
    assert cc.controller.compiled_law() is not None
    assert cc.stepper.t == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(cc.stepper.x, py.stepper.x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cc.stepper.a, py.stepper.a, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(cc.stepper.u, py.stepper.u)  # the same held command
    assert cc.n_updates == py.n_updates == 500
    # it tracked: the joints moved by more than a degree in that second
    moved = np.degrees(np.abs(model.joint_angles(cc.stepper.q) - model.joint_angles(q0)))
    assert moved.max() > 1.0


def test_state_feedback_and_eq45_compiled_equal_python(demo):
    model, traj, q0 = demo
    K = [40.0, 100.0, 8.0, 1.0, 20.0, 50.0, 4.0, 0.5]
    make = lambda: load_controller("state_feedback", NAMES,  # noqa: E731
                                   {"gains": K, "limit": 30.0})
    py, cc = _both(model, q0, make, traj, 500, start=-4.5, chunks=(500,))
    np.testing.assert_allclose(cc.stepper.x, py.stepper.x, rtol=0, atol=1e-12)
    assert np.abs(py.stepper.u).max() > 1.0  # a real command, not a hold at zero
    # no trajectory: both hold the angles sensed at the first update (from the Python path)
    make = lambda: load_controller("eq45", NAMES, {  # noqa: E731
        "kpp": 20.0, "kpv": 0.02, "gear_ratio": 10.0, "torque_limits": [5.0]})
    q1 = model.q_from_joint_angles(np.radians([10.0, -20.0]))
    py, cc = _both(model, q1, make, None, 250, chunks=(250,))
    np.testing.assert_allclose(cc.stepper.x, py.stepper.x, rtol=0, atol=1e-12)


def test_compiled_loop_reports_what_the_python_path_reports(demo):
    model, traj, q0 = demo
    ctl = load_controller("state_feedback", NAMES, {"gains": [40.0] + [0.0] * 7})
    ctl.set_trajectory(hold_reference(NAMES, [1e308, 0.0]))  # 40 x 1e308 overflows
    loop = ControlLoop(Stepper(model, q0), ctl, PERIOD)
    assert loop.compiled_law() is not None
    with pytest.raises(ValueError, match="expected 2 finite values"):
        loop.advance(3)
    assert loop.stepper.t == 0.0 and loop.n_updates == 0
