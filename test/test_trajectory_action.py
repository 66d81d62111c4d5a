"""control_msgs/FollowJointTrajectory served by the model node's in-loop controller
(issue 46, flex_model.trajectory_action).

Pure (no ROS): tolerances resolved as joint_trajectory_controller (JTC) resolves them, the
goal checks and their codes, the verdicts of a running goal. Live, with a real rclpy
ActionClient against a model node in lockstep (thesis_example1_motors, eq95 in the loop):
success, a path tolerance violation, a goal tolerance violation, cancel, preemption,
refused goals; after an abort or a cancel the joints hold where they were.
"""
import math
import sys
import time
import uuid

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory as FJT  # built by scripts/bootstrap.sh
from control_msgs.msg import JointTolerance
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter as P
from trajectory_msgs.msg import JointTrajectoryPoint

from flex_model.ros import trajectory_action as rta
from flex_model import trajectory_action as ta

NAMES = ["joint1", "joint2"]


# ------------------------------------------------------------------ pure
def test_goal_tolerances_resolve_as_jtc():
    d = ta.Tolerances.defaults(2, path_position=0.3, goal_position=0.02, goal_time=0.5)
    tol, why = ta.goal_tolerances(d, NAMES, path=[("joint1", 0.1, 0.0, -1.0)],
                                  goal=[("joint2", 0.0, 0.2, 0.0)], goal_time=1.5)
    assert why is None
    np.testing.assert_array_equal(tol.path, [[0.1, 0.0, 0.0], [0.3, 0.0, 0.0]])
    np.testing.assert_array_equal(tol.goal, [[0.02, 0.01, 0.0], [0.02, 0.2, 0.0]])
    assert tol.goal_time == 1.5
    tol, _ = ta.goal_tolerances(d, NAMES, path=[("joint2", -1.0, 0.0, 0.0)], goal_time=-1.0)
    assert tol.path[1, 0] == 0.0 and tol.goal_time == 0.0  # -1 erases
    for kwargs, word in (({"path": [("elbow", 0.1, 0, 0)]}, "elbow"),
                         ({"goal": [("joint1", -2.0, 0, 0)]}, "joint1.position"),
                         ({"goal_time": -0.5}, "goal_time_tolerance")):
        tol, why = ta.goal_tolerances(d, NAMES, **kwargs)
        assert tol is d and word in why  # the whole goal falls back to the defaults
    np.testing.assert_array_equal(d.path[:, 0], [0.3, 0.3])  # defaults untouched


def points(times, positions, names=NAMES, velocities=None, start=0.0):
    return ta.GoalPoints(list(names), list(times), [list(p) for p in positions],
                         velocities or [[] for _ in times], [[] for _ in times],
                         [[] for _ in times], start)


def test_bad_goals_get_jtcs_codes():
    ok = points([0.5, 1.0], [[0.1, 0.2], [0.3, 0.4]])
    assert ta.check_goal(ok, NAMES, now=0.0) is None
    assert ta.check_goal(points([1.0], [[0.0, 0.0]], names=NAMES[::-1]), NAMES, 0.0) is None
    cases = [
        (points([1.0], [[0.0, 0.0]], names=["joint1", "elbow"]), ta.INVALID_JOINTS),
        (points([1.0], [[0.0, 0.0]], names=["joint1", "joint1"]), ta.INVALID_JOINTS),
        (points([1.0], [[0.0]], names=["joint1"]), ta.INVALID_JOINTS),
        (points([], []), ta.INVALID_GOAL),
        (points([1.0, 1.0], [[0, 0], [0, 0]]), ta.INVALID_GOAL),
        (points([1.0, 0.5], [[0, 0], [0, 0]]), ta.INVALID_GOAL),
        (points([1.0], [[0.0]]), ta.INVALID_GOAL),
        (points([1.0], [[0.0, math.nan]]), ta.INVALID_GOAL),
        (points([1.0], [[0.0, 0.0]], velocities=[[0.0, 0.1]]), ta.INVALID_GOAL),
        (points([1.0], [[0.0, 0.0]], start=3.0), ta.OLD_HEADER_TIMESTAMP),
    ]
    for goal, code in cases:
        got = ta.check_goal(goal, NAMES, now=5.0)
        assert got is not None and got[0] == code, (goal, got)
    assert ta.check_goal(points([1.0], [[0.0, 0.0]], start=4.5), NAMES, now=5.0) is None


def test_goal_in_the_controllers_order_from_the_current_state():
    g = points([0.5, 1.0], [[0.2, 0.1], [0.4, 0.3]], names=["joint2", "joint1"])
    data = ta.trajectory_data(g, NAMES, positions=[-0.1, 0.05], velocities=[0.2, 0.0])
    np.testing.assert_array_equal(data.t, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(data.positions, [[-0.1, 0.05], [0.1, 0.2], [0.3, 0.4]])
    np.testing.assert_array_equal(data.velocities[0], [0.2, 0.0])
    assert data.sample(0.25)[0] == pytest.approx([0.0, 0.125])


def test_monitor_verdicts():
    data = ta.trajectory_data(points([0.0, 1.0], [[0.0, 0.0], [1.0, -1.0]]), NAMES,
                              [0, 0], [0, 0])
    tol = ta.Tolerances.defaults(2, path_position=0.1, goal_position=0.02, goal_time=0.5)
    m = ta.GoalMonitor(data, start=10.0, tolerances=tol)
    assert m.check(10.5, [0.45, -0.45], [1.0, -1.0]) is None  # 0.05 behind: on the path
    code, why = m.check(10.5, [0.5, -0.35], [1.0, -1.0])
    assert code == ta.PATH_TOLERANCE_VIOLATED and "joint2 position error -0.15" in why
    m = ta.GoalMonitor(data, 10.0, tol)
    assert m.check(10.2, [0.2, -0.2], [1.0, -1.0]) is None
    assert m.check(11.0, [0.97, -1.0], [0.0, 0.0]) is None  # 0.03 short: not yet
    assert m.check(11.0, [0.99, -1.0], [0.0, 0.02]) is None  # still moving (0.01 rad/s)
    assert m.check(11.4, [0.99, -1.0], [0.0, 0.005]) == (ta.SUCCESSFUL, "")
    code, why = m.check(11.51, [0.97, -1.0], [0.0, 0.0])
    assert code == ta.GOAL_TOLERANCE_VIOLATED and "joint1 position error +0.03" in why
    tol.goal_time = 0.0  # JTC: wait for the goal tolerance, however long
    assert ta.GoalMonitor(data, 10.0, tol).check(1e6, [0.9, -1.0], [0, 0]) is None
    # the first check also judges the path (JTC: the first sample may be the last point)
    assert ta.GoalMonitor(data, 10.0, tol).check(12.0, [0.5, -1.0], [0, 0])[0] == \
        ta.PATH_TOLERANCE_VIOLATED


def test_no_control_msgs_no_server_and_a_log_line(monkeypatch):
    logged = []

    class Node:
        def get_logger(self):
            return type("L", (), {"info": staticmethod(logged.append)})()
    monkeypatch.setitem(sys.modules, "control_msgs.action", None)
    assert rta.action_server(Node()) is None
    assert "FollowJointTrajectory off: control_msgs cannot be imported" in logged[0]


# ------------------------------------------------------------------ live
SUCCEEDED, CANCELED, ABORTED = 4, 5, 6  # action_msgs/GoalStatus


class Rig:
    """A lockstep model node with eq95 in its loop and an ActionClient, one executor."""

    def __init__(self):
        from flex_model.ros.model_node import ModelNode
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        ns = f"/a{uuid.uuid4().hex[:8]}"
        self.node = ModelNode(context=self.ctx, namespace=ns, parameter_overrides=[
            P("mode", value="lockstep"), P("controller", value="eq95"),
            P("controller_rate", value=500.0), P("controller_params.h", value=[25.0]),
            P("controller_params.a", value=[5.0]), P("publish_rate", value=100.0),
            P("start_static", value=True), P("publish_tf", value=False)])
        self.client_node = rclpy.create_node("fjt_client", context=self.ctx, namespace=ns)
        self.client = ActionClient(self.client_node, FJT,
                                   "joint_trajectory_controller/follow_joint_trajectory")
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.ex.add_node(self.client_node)
        self.spin_until(self.client.server_is_ready, "the action server", 30.0)

    def spin_until(self, pred, what, timeout=180.0):
        end = time.monotonic() + timeout  # a first run compiles the loop (numba)
        while not pred():
            assert time.monotonic() < end, f"timed out waiting for {what}"
            self.ex.spin_once(timeout_sec=0.01)

    def send(self, goal, feedback=None):
        fut = self.client.send_goal_async(goal, feedback_callback=feedback)
        self.spin_until(fut.done, "the goal response")
        handle = fut.result()
        assert handle.accepted
        return handle

    def result(self, handle):
        fut = handle.get_result_async()
        self.spin_until(fut.done, "the result")
        return fut.result()

    def angles(self):
        return np.array(self.node.stepper.joint_state()[0])

    def close(self):
        self.ex.shutdown()
        self.client.destroy()
        self.client_node.destroy_node()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


@pytest.fixture(scope="module")
def rig():
    r = Rig()
    yield r
    r.close()


def ramp(start, target, duration, n=20, names=NAMES, path=None, goal=None, goal_time=0.0):
    """A goal from ``start`` to ``target`` (rad) in ``n`` points over ``duration`` s."""
    g = FJT.Goal()
    g.trajectory.joint_names = list(names)
    for k in range(1, n + 1):
        s = k / n
        t = duration * s
        g.trajectory.points.append(JointTrajectoryPoint(
            positions=list((1 - s) * np.asarray(start) + s * np.asarray(target)),
            time_from_start=Duration(sec=int(t), nanosec=int(round(t % 1 * 1e9)) % 10**9)))
    g.path_tolerance = [JointTolerance(name=j, position=path) for j in names] if path else []
    g.goal_tolerance = [JointTolerance(name=j, position=goal, velocity=0.05) for j in names] \
        if goal else []
    g.goal_time_tolerance = Duration(sec=int(goal_time), nanosec=int(goal_time % 1 * 1e9))
    return g


def test_goal_succeeds_with_feedback(rig):
    """0.3, -0.2 rad in 2 s: success within the goal tolerance (0.05 rad, 0.05 rad/s);
    the feedback's error is desired - actual and desired is the ramp."""
    start, target = rig.angles(), rig.angles() + [0.3, -0.2]
    fbs = []
    handle = rig.send(ramp(start, target, 2.0, path=0.2, goal=0.05, goal_time=2.0),
                      lambda m: fbs.append(m.feedback))
    res = rig.result(handle)
    assert (res.status, res.result.error_code) == (SUCCEEDED, FJT.Result.SUCCESSFUL)
    angles = rig.angles()
    assert np.max(np.abs(angles - target)) < 0.05
    assert np.max(np.abs(angles - start)) > 0.25  # it really moved
    assert len(fbs) >= 3
    for fb in fbs:
        assert list(fb.joint_names) == NAMES
        d, a = np.array(fb.desired.positions), np.array(fb.actual.positions)
        np.testing.assert_allclose(fb.error.positions, d - a, rtol=0, atol=1e-12)
        tau = fb.desired.time_from_start.sec + 1e-9 * fb.desired.time_from_start.nanosec
        s = min(tau / 2.0, 1.0)
        np.testing.assert_allclose(d, start + s * (target - start), rtol=0, atol=1e-6)


def test_path_tolerance_violation_aborts_and_holds(rig):
    """A fast 0.5 rad step in 0.2 s with a 0.01 rad path tolerance: PATH_TOLERANCE_VIOLATED
    naming the joint, then the joints hold (they do not go on to the target)."""
    start = rig.angles()
    target = start + [0.5, 0.0]
    handle = rig.send(ramp(start, target, 0.2, n=4, path=0.01))
    res = rig.result(handle)
    assert (res.status, res.result.error_code) == (ABORTED, FJT.Result.PATH_TOLERANCE_VIOLATED)
    assert "position error" in res.result.error_string
    err = float(res.result.error_string.split("position error ")[1].split()[0])
    assert abs(err) > 0.01
    held = rig.angles()
    t = rig.node.stepper.t
    rig.spin_until(lambda: rig.node.stepper.t > t + 1.0, "1 s more")
    assert np.max(np.abs(rig.angles() - held)) < 0.05
    assert abs(rig.angles()[0] - target[0]) > 0.3


def test_goal_tolerance_violation_after_goal_time(rig):
    """A 1e-4 rad goal tolerance the PD with gravity cannot meet: GOAL_TOLERANCE_VIOLATED
    once goal_time_tolerance (0.3 s) is over, not before."""
    start = rig.angles()
    handle = rig.send(ramp(start, start + [0.1, 0.1], 0.5, goal=1e-4, goal_time=0.3))
    res = rig.result(handle)
    assert (res.status, res.result.error_code) == (ABORTED, FJT.Result.GOAL_TOLERANCE_VIOLATED)
    late = float(res.result.error_string.split(" s after")[0])
    assert 0.3 <= late < 0.35  # (printed to 0.1 ms; checked each 10 ms publication)


def test_cancel_holds_the_joints(rig):
    start = rig.angles()
    target = start + [0.6, 0.3]
    handle = rig.send(ramp(start, target, 4.0))
    t = rig.node.stepper.t
    rig.spin_until(lambda: rig.node.stepper.t > t + 1.0, "1 s of the goal")
    fut = handle.cancel_goal_async()
    rig.spin_until(fut.done, "the cancel response")
    assert len(fut.result().goals_canceling) == 1
    res = rig.result(handle)
    assert res.status == CANCELED
    held, t = rig.angles(), rig.node.stepper.t
    rig.spin_until(lambda: rig.node.stepper.t > t + 1.0, "1 s after the cancel")
    assert np.max(np.abs(rig.angles() - held)) < 0.05  # held, the ramp would add >= 0.15
    assert abs(rig.angles()[0] - target[0]) > 0.2


def test_new_goal_preempts_the_running_one(rig):
    start = rig.angles()
    first = rig.send(ramp(start, start + [0.5, 0.5], 4.0))
    t = rig.node.stepper.t
    rig.spin_until(lambda: rig.node.stepper.t > t + 0.5, "0.5 s of the first goal")
    now = rig.angles()
    target = start - [0.2, 0.1]
    second = rig.send(ramp(now, target, 1.0, goal=0.05, goal_time=2.0))
    res = rig.result(first)
    assert (res.status, res.result.error_code) == (ABORTED, FJT.Result.INVALID_GOAL)
    assert "preempted" in res.result.error_string
    res = rig.result(second)
    assert (res.status, res.result.error_code) == (SUCCEEDED, FJT.Result.SUCCESSFUL)
    assert np.max(np.abs(rig.angles() - target)) < 0.05


def test_bad_goals_are_aborted_with_their_code(rig):
    start = rig.angles()
    for goal, code in (
            (ramp(start[:1], start[:1] + 0.1, 1.0, names=["joint1"]),
             FJT.Result.INVALID_JOINTS),
            (ramp([0, 0], [0.1, 0.1], 1.0, names=["joint1", "shoulder"]),
             FJT.Result.INVALID_JOINTS)):
        res = rig.result(rig.send(goal))
        assert (res.status, res.result.error_code) == (ABORTED, code), res.result.error_string
    bad = ramp(start, start + 0.1, 1.0, n=3)
    bad.trajectory.points[2].time_from_start = Duration(sec=0, nanosec=100_000_000)
    res = rig.result(rig.send(bad))
    assert (res.status, res.result.error_code) == (ABORTED, FJT.Result.INVALID_GOAL)
    assert "strictly increasing" in res.result.error_string
