"""Joint limits of a spatial arm (URDF ``<limit>``): arrays, effort clipping, violations.

Effort limits are honoured by the compiled fixed-step loop (compiled.SpatialModel clips the
joint torques inline, and with an in-loop PD its whole torque: integrate's ``pd_clip``;
:func:`clip_efforts` is the same clip for Python callers); position limits become end
stops with the arm file's ``joint_stops`` (description.JointStops), else they are, like
the velocity limits, reported by :func:`limit_violations`. The spatial model node
(spatial_node.py) clips so (joint_states' effort is the clipped torque, eq95 included)
and logs position and velocity violations after every period (at most once a second per
joint).
"""
from __future__ import annotations

import numpy as np


def joint_limits(arm) -> dict:
    """Arrays (n_joints) ``lower``, ``upper`` (rad or m), ``effort`` (N m or N),
    ``velocity`` (rad/s or m/s); infinite where the description has none."""
    return {k: np.array([float(getattr(lk.joint, k)) for lk in arm.links])
            for k in ("lower", "upper", "effort", "velocity")}


def clip_efforts(arm, tau) -> np.ndarray:
    """Joint torques/forces clipped to +- the effort limits (last axis: joints)."""
    e = joint_limits(arm)["effort"]
    return np.clip(np.asarray(tau, float), -e, e)


def limit_violations(model, q, v=None) -> list[str]:
    """Human-readable position (and velocity) limit violations at (q, v)."""
    lim = joint_limits(model.arm)
    qj = np.asarray(q, float)[model.off]
    out = []
    for i, lk in enumerate(model.arm.links):
        if qj[i] < lim["lower"][i] or qj[i] > lim["upper"][i]:
            out.append(f"{lk.joint.name}: position {qj[i]:.6g} outside "
                       f"[{lim['lower'][i]:.6g}, {lim['upper'][i]:.6g}]")
        if v is not None:
            vj = float(np.asarray(v, float)[model.off[i]])
            if abs(vj) > lim["velocity"][i]:
                out.append(f"{lk.joint.name}: velocity {vj:.6g} beyond "
                           f"+-{lim['velocity'][i]:.6g}")
    return out
