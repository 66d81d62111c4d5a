"""The rclpy adapter of :mod:`flex_model.trajectory_action` (issue 46): the model node's
control_msgs/FollowJointTrajectory ActionServer on its executor; the node calls
:meth:`FollowJointTrajectoryServer.check` after each step."""
from __future__ import annotations

import math

from ..trajectory_action import (CODE_NAMES, INVALID_GOAL, PATH_TOLERANCE_VIOLATED, SUCCESSFUL,
                                 GoalMonitor, GoalPoints, Tolerances, check_goal,
                                 goal_tolerances, hold, trajectory_data)

#: the action's name, relative: JTC's <controller name>/follow_joint_trajectory
ACTION_NAME = "joint_trajectory_controller/follow_joint_trajectory"
#: simulation time (s) between feedback messages (JTC's action_monitor_rate: 20 Hz)
FEEDBACK_PERIOD = 0.05
CANCELED = "canceled"


def _seconds(d) -> float:
    return d.sec + 1e-9 * d.nanosec


def goal_points(goal) -> GoalPoints:
    """A FollowJointTrajectory goal's trajectory as :class:`GoalPoints`."""
    tr, pts = goal.trajectory, goal.trajectory.points
    return GoalPoints(list(tr.joint_names), [_seconds(p.time_from_start) for p in pts],
                      [list(p.positions) for p in pts], [list(p.velocities) for p in pts],
                      [list(p.accelerations) for p in pts], [list(p.effort) for p in pts],
                      _seconds(tr.header.stamp), len(goal.multi_dof_trajectory.joint_names))


def _entries(tolerances):
    return [(t.name, t.position, t.velocity, t.acceleration) for t in tolerances]


class FollowJointTrajectoryServer:
    """The FollowJointTrajectory action of a model node's in-loop controller.

    ``node`` has ``names`` (joints), ``stepper``, ``loop`` (ControlLoop) and ``diverged``;
    it calls :meth:`check` after each step. One goal runs at a time."""

    def __init__(self, node, defaults: Tolerances | None = None, name: str = ACTION_NAME):
        from control_msgs.action import FollowJointTrajectory
        from rclpy.action import ActionServer, CancelResponse, GoalResponse
        self.node, self.Action = node, FollowJointTrajectory
        self.defaults = defaults or Tolerances.defaults(len(node.names))
        self.active = None  # (goal handle, GoalMonitor, future) of the running goal
        self.futures = {}   # goal id -> future of its (code, reason)
        self.t0 = None      # the loop's trajectory start set by the running goal
        self.next_feedback = 0.0
        self.server = ActionServer(
            node, FollowJointTrajectory, name, execute_callback=self._execute,
            goal_callback=lambda goal: GoalResponse.ACCEPT,
            handle_accepted_callback=self._accepted,
            cancel_callback=lambda handle: self._cancel(handle) or CancelResponse.ACCEPT)

    def _accepted(self, handle) -> None:
        """Check the goal; run it (preempting the active one) or abort it at once."""
        from rclpy.task import Future
        node, st = self.node, self.node.stepper
        future = self.futures[bytes(handle.goal_id.uuid)] = Future()
        points = goal_points(handle.request)
        problem = check_goal(points, node.names, st.t)
        if problem is None and node.diverged is not None:
            problem = INVALID_GOAL, "the model diverged and is stopped; call ~/reset"
        if problem is not None:
            node.get_logger().warning(f"FollowJointTrajectory goal refused: "
                                      f"{CODE_NAMES[problem[0]]}: {problem[1]}")
            future.set_result(problem)
            handle.execute()
            return
        req = handle.request
        tol, why = goal_tolerances(self.defaults, node.names, _entries(req.path_tolerance),
                                   _entries(req.goal_tolerance),
                                   _seconds(req.goal_time_tolerance))
        if why:
            node.get_logger().error(f"FollowJointTrajectory goal: {why}")
        self.finish(INVALID_GOAL, "preempted by a new goal")
        position, velocity = self.joints()
        data = trajectory_data(points, node.names, position, velocity)
        start = points.start if points.start > 0 else st.t
        node.loop.set_trajectory(data, start)
        self.t0, self.next_feedback = node.loop.t0, st.t
        self.active = (handle, GoalMonitor(data, start, tol), future)
        node.get_logger().info(f"FollowJointTrajectory goal: {len(points.times)} points, "
                               f"{data.duration:.3f} s from t = {start:.3f} s")
        handle.execute()

    def joints(self):
        """Joint angles (rad) and rates (rad/s) now (Stepper.joint_state without torques)."""
        st = self.node.stepper
        return st.model.joint_angles(st.q), st.model.G @ st.v

    def _cancel(self, handle) -> None:
        """A cancel of the running goal holds the joints where they are."""
        if self.active is not None and \
                bytes(self.active[0].goal_id.uuid) == bytes(handle.goal_id.uuid):
            self.finish(CANCELED, "canceled")

    def finish(self, code, reason: str) -> None:
        """End the running goal (if any) with ``code``; hold the joints unless it succeeded
        or a new goal takes over."""
        if self.active is None:
            return
        handle, _, future = self.active
        self.active = None
        if code not in (SUCCESSFUL, INVALID_GOAL):
            st = self.node.stepper
            self.node.loop.set_trajectory(hold(self.node.names, self.joints()[0]), st.t)
        future.set_result((code, reason))
        text = f"FollowJointTrajectory goal: {CODE_NAMES.get(code, code)} {reason}".rstrip()
        if code in (SUCCESSFUL, CANCELED):  # (rclpy: one severity per call site)
            self.node.get_logger().info(text)
        else:
            self.node.get_logger().warning(text)

    def check(self) -> None:
        """After a step: the running goal's verdict, feedback every FEEDBACK_PERIOD s."""
        if self.active is None:
            return
        node, st = self.node, self.node.stepper
        if node.diverged is not None:
            return self.finish(PATH_TOLERANCE_VIOLATED, "the model diverged")
        if node.loop.t0 != self.t0:  # a JointTrajectory on flex_planner/trajectory
            return self.finish(INVALID_GOAL, "replaced by a trajectory on "
                               "flex_planner/trajectory")
        position, velocity = self.joints()
        handle, monitor, _ = self.active
        verdict = monitor.check(st.t, position, velocity)
        if st.t >= self.next_feedback - 1e-12 or verdict is not None:
            self.next_feedback = st.t + FEEDBACK_PERIOD
            handle.publish_feedback(self._feedback(monitor, st.t, position, velocity))
        if verdict is not None:
            self.finish(*verdict)

    def _feedback(self, monitor, t, position, velocity):
        from builtin_interfaces.msg import Duration
        from trajectory_msgs.msg import JointTrajectoryPoint
        fb = self.Action.Feedback(joint_names=list(self.node.names))
        fb.header.stamp.sec, fb.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9)) % 10**9
        tau, p, v, a = monitor.sample(t)
        since = Duration(sec=int(math.floor(tau)), nanosec=int((tau % 1) * 1e9) % 10**9)
        fb.desired = JointTrajectoryPoint(positions=p.tolist(), velocities=v.tolist(),
                                          accelerations=a.tolist(), time_from_start=since)
        fb.actual = JointTrajectoryPoint(positions=list(map(float, position)),
                                         velocities=list(map(float, velocity)),
                                         time_from_start=since)
        fb.error = JointTrajectoryPoint(positions=(p - position).tolist(),
                                        velocities=(v - velocity).tolist(),
                                        time_from_start=since)
        return fb

    async def _execute(self, handle):
        """The goal's result, once :meth:`finish` has its verdict."""
        code, reason = await self.futures.pop(bytes(handle.goal_id.uuid))
        if code == CANCELED:
            handle.canceled()
            code = SUCCESSFUL
        elif code == SUCCESSFUL:
            handle.succeed()
        else:
            handle.abort()
        return self.Action.Result(error_code=code, error_string=reason)


def action_server(node):
    """The node's FollowJointTrajectory server, or None (logged) without control_msgs."""
    try:
        import control_msgs.action  # noqa: F401
    except ImportError as exc:
        node.get_logger().info(f"FollowJointTrajectory off: control_msgs cannot be imported "
                               f"({exc}; scripts/bootstrap.sh builds it into .venv)")
        return None
    return FollowJointTrajectoryServer(node)
