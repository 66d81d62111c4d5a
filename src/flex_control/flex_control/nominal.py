"""Nominal trajectories for design and checks: a quasi-static one, and NPZ files.

The admissible nominal input of thesis V.1 is the planner's job (flex_planner); the
controller only consumes it as :class:`flex_model.trajectory.JointTrajectoryData`. For
design studies without the planner, :func:`quasi_static_trajectory` holds static poses
along a smooth joint path: joint angles by a clamped cubic spline through waypoints (thesis
V.3, Fig. 40), at each sample the static equilibrium of the arm with the joints held
(``q_nominal``), and as nominal torques the least-squares joint torques of
``B a + c + K q + D v`` along it. For slow paths this is close to the admissible input; it
is not exactly admissible (the deformation equations hold only statically).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from flex_model.dynamics import FlexArmModel
from flex_model.statics import static_equilibrium
from flex_model.trajectory import JointTrajectoryData

NPZ_FIELDS = ("t", "positions", "velocities", "accelerations", "efforts", "q_nominal", "tip")


def quasi_static_trajectory(model: FlexArmModel, times, joint_angles,
                            sample_period: float = 0.02) -> JointTrajectoryData:
    """Quasi-static nominal trajectory through joint waypoints ``joint_angles`` (rad,
    shape (len(times), n_joints)) at ``times`` (s, increasing), at rest at both ends."""
    times = np.asarray(times, float).reshape(-1)
    wp = np.asarray(joint_angles, float)
    nj = model.n_links
    if len(times) < 2 or np.any(np.diff(times) <= 0) or not np.all(np.isfinite(times)):
        raise ValueError(f"times: got {times.tolist()}; expected at least 2 increasing "
                         "finite times (s)")
    if wp.shape != (len(times), nj) or not np.all(np.isfinite(wp)):
        raise ValueError(f"joint_angles: got shape {wp.shape}; expected ({len(times)}, {nj}) "
                         "finite angles (rad), one row per time")
    if not sample_period > 0:
        raise ValueError(f"sample_period: got {sample_period!r}; expected a time > 0 s")
    spline = CubicSpline(times, wp, bc_type="clamped")
    n = int(np.floor((times[-1] - times[0]) / sample_period + 1e-9)) + 1
    t = times[0] + sample_period * np.arange(n)
    if t[-1] < times[-1] - 1e-12:
        t = np.append(t, times[-1])
    th, dth, ddth = spline(t), spline(t, 1), spline(t, 2)
    q = np.empty((len(t), model.nq))
    guess = None
    for k, angles in enumerate(th):
        q[k] = static_equilibrium(model, angles, joints="clamped", q_guess=guess).q
        guess = q[k]
    v = np.gradient(q, t, axis=0, edge_order=2) if len(t) > 2 else np.zeros_like(q)
    a = np.gradient(v, t, axis=0, edge_order=2) if len(t) > 2 else np.zeros_like(q)
    Ginv = np.linalg.pinv(model.G.T)
    tau = np.array([Ginv @ (model.inverse_dynamics(qk, vk, ak) + model.K @ qk + model.D @ vk)
                    for qk, vk, ak in zip(q, v, a)])
    tip = np.array([model.link_origins(qk)[-1] for qk in q])
    return JointTrajectoryData(joint_names=list(model.arm.joint_names), t=t, positions=th,
                               velocities=dth, accelerations=ddth, efforts=tau, q_nominal=q,
                               tip=tip)


def save_trajectory(path, data: JointTrajectoryData) -> Path:
    """Write a trajectory to an ``.npz`` file (arrays of :data:`NPZ_FIELDS`, joint names)."""
    path = Path(path)
    arrays = {k: np.asarray(getattr(data, k)) for k in NPZ_FIELDS
              if getattr(data, k) is not None}
    with path.open("wb") as fh:
        np.savez(fh, joint_names=np.array(list(data.joint_names)), **arrays)
    return path


def load_trajectory(path) -> JointTrajectoryData:
    """Read an ``.npz`` trajectory written by :func:`save_trajectory` (or any producer
    of the same arrays); errors name the file and the field."""
    path = Path(path)
    try:
        npz = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: got an unreadable file; expected an .npz trajectory "
                         f"({exc})") from None
    with npz:
        missing = [k for k in ("joint_names", "t", "positions", "velocities", "accelerations")
                   if k not in npz.files]
        if missing:
            raise ValueError(f"{path}: {missing[0]}: got <missing>; expected arrays "
                             "joint_names, t, positions, velocities, accelerations "
                             "(efforts, q_nominal, tip optional)")
        fields = {k: npz[k] for k in NPZ_FIELDS if k in npz.files}
        names = [str(n) for n in npz["joint_names"].tolist()]
    try:
        return JointTrajectoryData(joint_names=names, **fields)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
