"""control_msgs/FollowJointTrajectory for the model node's in-loop controller (issue 46).

Clients written for ros2_control's joint_trajectory_controller (JTC, Jazzy) drive the twin
unchanged: the same action name (``joint_trajectory_controller/follow_joint_trajectory``,
relative: a namespace moves it), goal tolerances read as JTC reads them, the same result
codes and feedback, cancel and preemption as JTC handles them.

Pure part (no ROS; SI units, radians): :func:`check_goal`, :func:`goal_tolerances` and
:class:`GoalMonitor` judge a goal from sampled joint states by JTC's rules:

- tolerances: 0 = not checked; in a goal, > 0 replaces the default, 0 keeps it, -1 erases
  it (0), any other negative value or an unknown joint name: the whole goal falls back to
  the defaults (logged), as JTC. Defaults as JTC's parameters: no path or goal position
  tolerance, stopped_velocity_tolerance 0.01 rad/s as the goal velocity tolerance,
  goal_time 0 (wait until within the goal tolerance, however long).
- while before the last point (and at the first check): |desired - actual| beyond a path
  tolerance -> PATH_TOLERANCE_VIOLATED. From the last point's time on: within every goal
  tolerance -> SUCCESSFUL; else, once more than goal_time_tolerance (> 0) past it ->
  GOAL_TOLERANCE_VIOLATED. Accelerations are not sensed: acceleration tolerances are
  accepted and not checked.
- a goal is checked when accepted. JTC rejects a bad goal without a result; here it is
  accepted and aborted at once, so the client also gets the code and the reason:
  INVALID_JOINTS (joint names not exactly the controller's, any order; a multi-DOF part),
  INVALID_GOAL (no points, times not strictly increasing from >= 0, a point with the wrong
  number of values, non-finite values, a non-zero velocity at the end),
  OLD_HEADER_TIMESTAMP (a non-zero stamp with the trajectory's end before now).
- the trajectory starts at the header stamp (simulation time) or, if 0, on acceptance; a
  first point later than 0 s is reached from the current state (JTC's interpolation from
  the state at acceptance). Efforts, if given, are the in-loop law's feed-forward.
- cancel, and an abort for a tolerance, hold the joints where they are; a new goal
  preempts the active one (aborted with INVALID_GOAL, "preempted", as JTC).

ROS part: :class:`FollowJointTrajectoryServer` (rclpy ActionServer on the node's executor;
the model node calls :meth:`FollowJointTrajectoryServer.check` after each step).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .trajectory import JointTrajectoryData

SUCCESSFUL, INVALID_GOAL, INVALID_JOINTS = 0, -1, -2
OLD_HEADER_TIMESTAMP, PATH_TOLERANCE_VIOLATED, GOAL_TOLERANCE_VIOLATED = -3, -4, -5
CODE_NAMES = {SUCCESSFUL: "SUCCESSFUL", INVALID_GOAL: "INVALID_GOAL",
              INVALID_JOINTS: "INVALID_JOINTS", OLD_HEADER_TIMESTAMP: "OLD_HEADER_TIMESTAMP",
              PATH_TOLERANCE_VIOLATED: "PATH_TOLERANCE_VIOLATED",
              GOAL_TOLERANCE_VIOLATED: "GOAL_TOLERANCE_VIOLATED"}
#: JTC's constraints.stopped_velocity_tolerance default (rad/s): the goal velocity tolerance
STOPPED_VELOCITY = 0.01
#: the value that erases a tolerance in a goal (compared as JTC, to float precision)
ERASE = -1.0
FIELDS = ("position", "velocity", "acceleration")


@dataclass
class Tolerances:
    """Per joint (rows) position, velocity, acceleration tolerances (0: not checked)."""

    path: np.ndarray
    goal: np.ndarray
    goal_time: float = 0.0

    @classmethod
    def defaults(cls, n: int, path_position=0.0, goal_position=0.0,
                 stopped_velocity=STOPPED_VELOCITY, goal_time=0.0) -> "Tolerances":
        """JTC's defaults from its constraints parameters (scalars or one per joint)."""
        path, goal = np.zeros((n, 3)), np.zeros((n, 3))
        path[:, 0] = path_position
        goal[:, 0], goal[:, 1] = goal_position, stopped_velocity
        return cls(path, goal, float(goal_time))


def _resolve(default: float, value: float) -> float:
    """A goal's tolerance value against the default (JTC): > 0 wins, -1 erases, 0 keeps."""
    if value > 0.0:
        return float(value)
    if abs(value - ERASE) < np.finfo(np.float32).eps:
        return 0.0
    if value < 0.0 or not math.isfinite(value):
        raise ValueError(f"{value!r} is not a tolerance (> 0, 0: default, -1: none)")
    return default


def goal_tolerances(defaults: Tolerances, joint_names, path=(), goal=(), goal_time=0.0):
    """(tolerances, problem): a goal's tolerances resolved against ``defaults``.

    ``path``/``goal``: (joint name, position, velocity, acceleration) per entry. An unknown
    joint or an illegal value returns (defaults, the reason), as JTC (which logs it)."""
    out = Tolerances(defaults.path.copy(), defaults.goal.copy(), defaults.goal_time)
    names = list(joint_names)
    try:
        out.goal_time = _resolve(defaults.goal_time, float(goal_time))
    except ValueError as exc:
        return defaults, f"goal_time_tolerance: {exc}; using the default tolerances"
    for label, entries, table, base in (("path_tolerance", path, out.path, defaults.path),
                                        ("goal_tolerance", goal, out.goal, defaults.goal)):
        for name, *values in entries:
            if name not in names:
                return defaults, (f"{label}: joint {name!r} is not one of {names}; using "
                                  "the default tolerances")
            i = names.index(name)
            for k, value in enumerate(values):
                try:
                    table[i, k] = _resolve(base[i, k], float(value))
                except ValueError as exc:
                    return defaults, (f"{label} {name}.{FIELDS[k]}: {exc}; using the "
                                      "default tolerances")
    return out, None


@dataclass
class GoalPoints:
    """A goal's trajectory as plain data (the message's joint order)."""

    joint_names: list
    times: list          # time_from_start of each point (s)
    positions: list      # per point, a list (one per joint)
    velocities: list     # per point, a list: empty or one per joint
    accelerations: list
    efforts: list
    start: float = 0.0   # header stamp (s), 0: on acceptance
    multi_dof_joints: int = 0


def check_goal(points: GoalPoints, controller_joints, now: float):
    """(code, reason) of a goal that cannot run, or None."""
    names, want = list(points.joint_names), list(controller_joints)
    if points.multi_dof_joints:
        return INVALID_JOINTS, "multi_dof_trajectory: this arm has no multi-DOF joints"
    if sorted(names) != sorted(want) or len(set(names)) != len(names):
        return INVALID_JOINTS, f"joint_names: got {names}; expected {want} (any order)"
    n, t = len(names), np.asarray(points.times, float)
    if len(t) == 0:
        return INVALID_GOAL, "trajectory.points: empty"
    if not np.all(np.isfinite(t)) or t[0] < 0 or np.any(np.diff(t) <= 0):
        return INVALID_GOAL, (f"time_from_start: got {t.tolist()} s; expected strictly "
                              "increasing times from >= 0")
    for field in ("positions", "velocities", "accelerations", "efforts"):
        for k, values in enumerate(getattr(points, field)):
            if len(values) != n and (field == "positions" or len(values)):
                return INVALID_GOAL, (f"points[{k}].{field}: got {len(values)} values; "
                                      f"expected {n}" + ("" if field == "positions" else
                                                         " or none"))
            if not np.all(np.isfinite(values)):
                return INVALID_GOAL, f"points[{k}].{field}: not finite: {list(values)}"
    last = points.velocities[-1]
    if len(last) and np.max(np.abs(last)) > np.finfo(np.float32).eps:
        return INVALID_GOAL, (f"points[-1].velocities: got {list(last)}; expected zero at "
                              "the end (JTC's allow_nonzero_velocity_at_trajectory_end false)")
    if points.start > 0 and points.start + t[-1] < now:
        return OLD_HEADER_TIMESTAMP, (f"header.stamp {points.start:.6f} s + "
                                      f"{t[-1]:.6f} s ends before now ({now:.6f} s)")
    return None


def trajectory_data(points: GoalPoints, controller_joints, positions, velocities):
    """The goal (checked by :func:`check_goal`) as JointTrajectoryData in the controller's
    joint order; a first point after 0 s is reached from the current state at 0 s."""
    want = list(controller_joints)
    idx = [list(points.joint_names).index(j) for j in want]
    m, n = len(points.times), len(want)

    def table(rows):
        out = np.zeros((m, n))
        for k, row in enumerate(rows):
            if len(row):
                out[k] = np.asarray(row, float)[idx]
        return out
    t = np.asarray(points.times, float)
    arrays = [table(points.positions), table(points.velocities),
              table(points.accelerations), table(points.efforts)]
    if t[0] > 0:
        t = np.concatenate([[0.0], t])
        now = [np.asarray(positions, float), np.asarray(velocities, float), np.zeros(n),
               arrays[3][0]]
        arrays = [np.vstack([row, arr]) for row, arr in zip(now, arrays)]
    return JointTrajectoryData(want, t, *arrays)


def hold(joint_names, positions) -> JointTrajectoryData:
    """Stay at ``positions`` (rad), at rest."""
    p = np.asarray(positions, float)
    z = np.zeros((2, len(p)))
    return JointTrajectoryData(list(joint_names), np.array([0.0, 1.0]), np.vstack([p, p]),
                               z, z.copy(), z.copy())


class GoalMonitor:
    """JTC's verdict on one running goal from the sampled joint state."""

    def __init__(self, data: JointTrajectoryData, start: float, tolerances: Tolerances):
        self.data, self.start, self.tol = data, float(start), tolerances
        self.checks = 0

    def sample(self, t: float):
        """(time along the trajectory, desired positions, velocities, accelerations)."""
        tau = t - self.start
        p, v, a, _ = self.data.sample(tau)
        return tau, p, v, a

    def check(self, t: float, positions, velocities):
        """(code, reason) once the goal is over, else None; ``t`` simulation time (s)."""
        tau, p, v, _ = self.sample(t)
        err = np.column_stack([p - np.asarray(positions, float),
                               v - np.asarray(velocities, float)])
        end = float(self.data.t[-1])
        first, self.checks = self.checks == 0, self.checks + 1
        if tau < end or first:
            bad = _beyond(err, self.tol.path, self.data.joint_names)
            if bad:
                return PATH_TOLERANCE_VIOLATED, f"at {tau:.4f} s of the trajectory: {bad}"
        if tau < end:
            return None
        bad = _beyond(err, self.tol.goal, self.data.joint_names)
        if not bad:
            return SUCCESSFUL, ""
        late = tau - end
        if self.tol.goal_time > 0 and late > self.tol.goal_time:
            return GOAL_TOLERANCE_VIOLATED, (f"{late:.4f} s after the end (goal_time_tolerance"
                                             f" {self.tol.goal_time:g} s): {bad}")
        return None


def _beyond(err, tol, names) -> str:
    """The first (position or velocity) error beyond its tolerance (> 0), as text, or ''."""
    for i, name in enumerate(names):
        for k in range(2):
            if tol[i, k] > 0 and abs(err[i, k]) > tol[i, k]:
                unit = ("rad", "rad/s")[k]
                return (f"{name} {FIELDS[k]} error {err[i, k]:+.6g} {unit} beyond the "
                        f"tolerance {tol[i, k]:g} {unit}")
    return ""


# ------------------------------------------------------------------ ROS adapter
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
