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

No ROS here: the rclpy adapter is :mod:`flex_model.ros.trajectory_action`.
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
