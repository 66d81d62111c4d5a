"""A measured experiment from a rosbag2 (MCAP) bag of the suite's topics (needs rclpy).

- ``/joint_states`` (sensor_msgs/JointState): q, v, tau per joint (the time base);
- ``/flex_planner/trajectory`` (trajectory_msgs/JointTrajectory): the reference qset,
  interpolated linearly between its points (header stamp + time_from_start); without it
  the commanded set-points are unknown and the bag is refused;
- optional ``/flex/deflections`` (sensor_msgs/JointState, ``link<i>/tip_deflection``): w<i>;
- optional ``/flex/tip_pose`` (geometry_msgs/PoseStamped): tip_x, tip_y.

Times are the header stamps (the log time where a stamp is zero); every channel is
interpolated onto the /joint_states samples, which must be uniform.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .recording import RecordingError, validate

TOPICS = ("/joint_states", "/flex_planner/trajectory", "/flex/deflections", "/flex/tip_pose")


def _stamp(msg, t_ns) -> float:
    s = msg.header.stamp
    t = s.sec + 1e-9 * s.nanosec
    return t if t > 0 else 1e-9 * t_ns


def load_bag(path, n_joints: int):
    """Read the bag into a :class:`~flex_twin.diagnosis.recording.Recording`."""
    from ..bags import BagError, read_bag, topic_types
    path = Path(path)
    try:
        types = topic_types(path)
    except (BagError, OSError, ValueError) as exc:
        raise RecordingError(f"{path}: not a readable rosbag2/MCAP bag ({exc})") from None
    missing = [t for t in TOPICS[:2] if t not in types]
    if missing:
        raise RecordingError(f"{path}: missing topic(s) {', '.join(missing)} (needs "
                             "/joint_states and the reference /flex_planner/trajectory)")
    js, traj, defl, tip = [], [], [], []
    try:
        for topic, _, t_ns, msg in read_bag(path, [t for t in TOPICS if t in types]):
            if topic == "/joint_states":
                js.append((_stamp(msg, t_ns), list(msg.position), list(msg.velocity),
                           list(msg.effort)))
            elif topic == "/flex_planner/trajectory":
                traj.append((_stamp(msg, t_ns), msg))
            elif topic == "/flex/deflections":
                d = dict(zip(msg.name, msg.position))
                defl.append((_stamp(msg, t_ns), [d.get(f"link{i + 1}/tip_deflection", np.nan)
                                                 for i in range(n_joints)]))
            else:
                tip.append((_stamp(msg, t_ns), msg.pose.position.x, msg.pose.position.y))
    except (BagError, OSError, ValueError, RuntimeError) as exc:
        raise RecordingError(f"{path}: corrupt or truncated bag ({exc})") from None
    if len(js) < 2:
        raise RecordingError(f"{path}: {len(js)} /joint_states messages")
    for k, (_, q, v, e) in enumerate(js):
        if min(len(q), len(v), len(e)) < n_joints:
            raise RecordingError(f"{path}: /joint_states message {k} has fewer than "
                                 f"{n_joints} positions, velocities or efforts")
    t = np.array([m[0] for m in js])
    ch = {}
    for kind, col in (("q", 1), ("v", 2), ("tau", 3)):
        arr = np.array([m[col][:n_joints] for m in js], float)
        for i in range(n_joints):
            ch[f"{kind}{i + 1}"] = arr[:, i]
    ref_t, ref_q = [], []
    for t0, msg in traj:
        for p in msg.points:
            ref_t.append(t0 + p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec)
            ref_q.append(list(p.positions)[:n_joints])
    if not ref_t:
        raise RecordingError(f"{path}: /flex_planner/trajectory has no points")
    order = np.argsort(ref_t)
    ref_t, ref_q = np.array(ref_t)[order], np.array(ref_q, float)[order]
    for i in range(n_joints):
        ch[f"qset{i + 1}"] = np.interp(t, ref_t, ref_q[:, i])
    if defl:
        td = np.array([d[0] for d in defl])
        w = np.array([d[1] for d in defl], float)
        for i in range(n_joints):
            if np.all(np.isfinite(w[:, i])):
                ch[f"w{i + 1}"] = np.interp(t, td, w[:, i])
    if tip:
        tt = np.array([p[0] for p in tip])
        ch["tip_x"] = np.interp(t, tt, [p[1] for p in tip])
        ch["tip_y"] = np.interp(t, tt, [p[2] for p in tip])
    return validate(t, ch, n_joints, str(path))
