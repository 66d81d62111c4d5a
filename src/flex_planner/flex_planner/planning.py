"""The planning chain of thesis Ch. IV-V.1: tip waypoints -> joint trajectory + nominal torque.

1. static-flexible inversion of every waypoint (Ch. IV, :mod:`.inverse_statics`);
2. cubic splines through the inverted joint angles at the waypoint times (V.3, Fig. 40);
3. admissible nominal input along them (V.1, Fig. 41, :mod:`.nominal_input`).

:func:`plan_tip_path` is the interface the controller relies on: it returns a
``flex_model.trajectory.JointTrajectoryData`` (the plan reaches the controller as data).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.statics import TipLoad
from flex_model.trajectory import JointTrajectoryData

from .inverse_statics import StaticInverse, StaticInverter, invert_waypoints
from .nominal_input import NominalInput, NominalInputSolver
from .rigid_kinematics import check_elbow
from .trajectories import check_times, joint_spline, sample_spline, sample_times

#: VALIDATION.md section F / thesis V.3: tip waypoints P1..P4 (m) at 0, 5, 10, 15 s
SECTION_F_WAYPOINTS = np.array([[-1.0, -1.0], [-2.0, -1.0], [-2.0, -2.0], [-1.0, -2.0]])
SECTION_F_TIMES = np.array([0.0, 5.0, 10.0, 15.0])
SECTION_F_WAYPOINTS.setflags(write=False)
SECTION_F_TIMES.setflags(write=False)

#: largest integration step of the nominal input (s): samples are refined down to it
INTEGRATION_STEP = 1e-3


@dataclass
class Plan:
    """Everything the chain computed: the inverted poses, the nominal input at the
    integration steps and the trajectory at the sample period."""

    poses: list
    nominal: NominalInput
    trajectory: JointTrajectoryData


def check_waypoints(waypoints) -> np.ndarray:
    """(N, 2) finite tip positions (m), N >= 2; errors name the first bad entry."""
    pts = np.asarray(waypoints, float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
        raise ValueError(f"waypoints: got shape {pts.shape}; expected (N, 2) tip positions "
                         "(m, base frame) with N >= 2")
    bad = np.flatnonzero(~np.all(np.isfinite(pts), axis=1))
    if len(bad):
        k = int(bad[0])
        raise ValueError(f"waypoints[{k}]: got {pts[k].tolist()}; expected finite x, y (m)")
    return pts


def refine(t: np.ndarray, factor: int) -> np.ndarray:
    """Every interval of ``t`` cut into ``factor`` equal steps (t itself at every
    ``factor``-th entry)."""
    if factor == 1:
        return t.copy()
    frac = np.arange(factor) / factor
    fine = (t[:-1, None] + np.diff(t)[:, None] * frac[None, :]).ravel()
    return np.append(fine, t[-1])


def plan(model: FlexArmModel, waypoints, times, *, sample_period: float = 1e-3,
         elbow: str = "up", orientations=None, tip_load: TipLoad | None = None,
         integration_step: float = INTEGRATION_STEP) -> Plan:
    """The whole chain; see :func:`plan_tip_path` for the arguments."""
    pts = check_waypoints(waypoints)
    times = check_times(times, len(pts))
    check_elbow(elbow)
    if not (np.isfinite(integration_step) and integration_step > 0):
        raise ValueError(f"integration_step: got {integration_step!r}; expected a time > 0 s")
    t_samples = sample_times(times[0], times[-1], sample_period)
    inverter = StaticInverter(model, tip_load)
    poses: list[StaticInverse] = invert_waypoints(model, pts, orientations, elbow=elbow,
                                                  inverter=inverter)
    spline = joint_spline(times, [p.joint_angles for p in poses])
    factor = max(1, int(np.ceil(sample_period / integration_step - 1e-9)))
    fine = sample_spline(spline, refine(t_samples, factor))
    solver = NominalInputSolver(model, tip_load)
    flex0 = np.linalg.solve(solver.T, poses[0].q)[solver.free]
    nominal = solver.solve(fine, flex0=flex0)
    pick = slice(None, None, factor)
    traj = JointTrajectoryData(
        joint_names=list(model.arm.joint_names), t=nominal.t[pick],
        positions=nominal.theta[pick], velocities=nominal.theta_dot[pick],
        accelerations=nominal.theta_ddot[pick], efforts=nominal.tau[pick],
        q_nominal=nominal.q[pick], tip=nominal.tip[pick])
    return Plan(poses=poses, nominal=nominal, trajectory=traj)


def plan_tip_path(model: FlexArmModel, waypoints, times, *, sample_period: float = 1e-3,
                  elbow: str = "up", orientations=None,
                  tip_load: TipLoad | None = None) -> JointTrajectoryData:
    """Joint trajectory and admissible nominal torque through tip waypoints (Ch. IV-V.1).

    Parameters
    ----------
    model : FlexArmModel
        The arm (gravity, payload included).
    waypoints : (N, 2) array
        Tip positions (m, base frame), N >= 2.
    times : (N,) array
        Their times (s), strictly increasing.
    sample_period : float
        Output sample period (s); the nominal input is integrated with steps of at most
        1 ms whatever the period.
    elbow : {"up", "down"}
        Branch at the first waypoint, kept along the path (:mod:`.rigid_kinematics`).
    orientations : (N,) array, optional
        Tip orientations (rad), required for arms with three or more links.
    tip_load : flex_model.statics.TipLoad, optional
        A known constant load at the tip, in the inversion and the nominal input.

    Returns
    -------
    JointTrajectoryData
        ``t``; joint ``positions``/``velocities``/``accelerations`` (rad, rad/s, rad/s^2);
        ``efforts`` the nominal torques (N m); ``q_nominal`` (N, nq) with the nominal
        deflections; ``tip`` the nominal tip path (m).

    Raises
    ------
    UnreachableError
        A waypoint the static arm cannot reach (``index``, ``reason``).
    ValueError
        Malformed waypoints, times, elbow or orientations (the message names the field).
    """
    return plan(model, waypoints, times, sample_period=sample_period, elbow=elbow,
                orientations=orientations, tip_load=tip_load).trajectory
