"""A measured experiment from a rosbag2 (MCAP) bag of the suite's topics (needs rclpy).

- ``/joint_states`` (sensor_msgs/JointState): q, v, tau per joint (the time base);
- ``/flex_planner/trajectory`` (trajectory_msgs/JointTrajectory): the reference qset,
  interpolated linearly between its points (header stamp + time_from_start); without it
  the commanded set-points are unknown and the bag is refused;
- optional ``/flex/deflections`` (sensor_msgs/JointState, ``link<i>/tip_deflection``): w<i>;
- optional ``/flex/tip_pose`` (geometry_msgs/PoseStamped): tip_x, tip_y, the arm's plane
  coordinates (a pose in ``arm_plane`` or without a frame as it is; one in the base
  frame, as the model node publishes it, turned back into the plane of ``gravity``);
- optional link-side encoders of elastic joints, topic :data:`LINK_TOPIC` by default
  (``flex-twin diagnose --link-topic``): a sensor_msgs/JointState whose ``name`` lists the
  joints (names of ``/joint_states``) that have one, ``position`` their link-side angles and
  ``velocity`` their rates, one entry per name: ql<i>, vl<i> as in the CSV
  (:mod:`.recording`; the replay's restarts put the link side there).

The settings a CSV states in comment lines (``start_window``, :mod:`.recording`) are read
from the ``custom_data`` map of the bag's metadata.yaml (rosbag2's key -> string map; e.g.
``start_window: '0.0008'``).

Times are the header stamps (the log time where a stamp is zero); every channel is
interpolated onto the /joint_states samples, which must be uniform.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .recording import DIRECTIVES, RecordingError, directive_value, validate

TOPICS = ("/joint_states", "/flex_planner/trajectory", "/flex/deflections", "/flex/tip_pose")
#: default topic of the link-side encoders (sensor_msgs/JointState); ``--link-topic``
LINK_TOPIC = "/flex/link_encoders"


def _stamp(msg, t_ns) -> float:
    s = msg.header.stamp
    t = s.sec + 1e-9 * s.nanosec
    return t if t > 0 else 1e-9 * t_ns


def load_bag(path, n_joints: int, link_topic: str | None = None, gravity=None):
    """Read the bag into a :class:`~flex_twin.diagnosis.recording.Recording`; the link-side
    encoders from ``link_topic`` (default :data:`LINK_TOPIC`) when the bag has it;
    ``gravity``: the arm's (m/s^2, in its plane), needed for a tip pose in the base frame
    (refused without it: the arm's plane in the base frame depends on it)."""
    from flex_model.urdf import base_to_plane, plane_rotation
    from ..bags import BagError, read_bag, topic_types
    path = Path(path)
    link_topic = LINK_TOPIC if link_topic is None else link_topic
    try:
        types = topic_types(path)
    except (BagError, OSError, ValueError) as exc:
        raise RecordingError(f"{path}: not a readable rosbag2/MCAP bag ({exc})") from None
    missing = [t for t in TOPICS[:2] if t not in types]
    if missing:
        raise RecordingError(f"{path}: missing topic(s) {', '.join(missing)} (needs "
                             "/joint_states and the reference /flex_planner/trajectory)")
    if link_topic in types and not types[link_topic].endswith("JointState"):
        raise RecordingError(f"{path}: {link_topic}: type {types[link_topic]}; the link-side "
                             "encoders need sensor_msgs/msg/JointState")
    js, traj, defl, tip, link = [], [], [], [], []
    names = None
    wanted = [t for t in TOPICS if t in types] + ([link_topic] if link_topic in types else [])
    try:
        for topic, _, t_ns, msg in read_bag(path, wanted):
            if topic == "/joint_states":
                names = names or list(msg.name)
                js.append((_stamp(msg, t_ns), list(msg.position), list(msg.velocity),
                           list(msg.effort)))
            elif topic == link_topic:
                link.append((_stamp(msg, t_ns), list(msg.name), list(msg.position),
                             list(msg.velocity)))
            elif topic == "/flex_planner/trajectory":
                traj.append((_stamp(msg, t_ns), msg))
            elif topic == "/flex/deflections":
                d = dict(zip(msg.name, msg.position))
                defl.append((_stamp(msg, t_ns), [d.get(f"link{i + 1}/tip_deflection", np.nan)
                                                 for i in range(n_joints)]))
            else:
                p, frame = msg.pose.position, msg.header.frame_id
                in_plane = not frame or frame.endswith("arm_plane")
                if not in_plane and gravity is None:
                    raise RecordingError(f"{path}: /flex/tip_pose is in {frame!r}; turning it "
                                         "into the arm's plane needs the arm's gravity")
                x, y = (p.x, p.y) if in_plane else \
                    base_to_plane(plane_rotation(gravity), [p.x, p.y, p.z])[0]
                tip.append((_stamp(msg, t_ns), x, y))
    except RecordingError:
        raise
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
    if link:
        ch.update(_link_channels(path, link_topic, link, names or [], n_joints, t))
    rec = validate(t, ch, n_joints, str(path))
    rec.meta.update(_settings(path))
    return rec


def _settings(path) -> dict:
    """:data:`~.recording.DIRECTIVES` from the ``custom_data`` of metadata.yaml, checked."""
    from ..bags import BagError
    from ..bags.reader import bag_metadata
    try:
        meta = bag_metadata(path if path.is_dir() else path.parent) or {}
    except BagError:
        return {}      # read_bag has warned; the .mcap alone carries no settings
    custom = meta.get("custom_data") or {}
    if not isinstance(custom, dict):
        return {}
    return {k: directive_value(k, custom[k], f"{path}: metadata.yaml custom_data")
            for k in DIRECTIVES if k in custom}


def _link_channels(path, topic, msgs, joint_names, n_joints, t) -> dict:
    """ql<i>, vl<i> from the link-side JointState messages, interpolated onto ``t``; every
    message must give each of its named joints a position and a velocity."""
    names = msgs[0][1]
    if not names:
        raise RecordingError(f"{path}: {topic}: message 0 names no joint (the link-side "
                             f"encoders are named like /joint_states: {joint_names})")
    index = []
    for n in names:
        if n not in joint_names[:n_joints]:
            raise RecordingError(f"{path}: {topic}: joint {n!r} is not among the arm's "
                                 f"/joint_states joints {joint_names[:n_joints]}")
        index.append(joint_names.index(n))
    for k, (_, nm, q, v) in enumerate(msgs):
        if nm != names:
            raise RecordingError(f"{path}: {topic}: message {k} names {nm}, message 0 "
                                 f"{names} (one set of joints for the whole bag)")
        if len(q) != len(nm) or len(v) != len(nm):
            raise RecordingError(f"{path}: {topic}: message {k} has {len(q)} positions and "
                                 f"{len(v)} velocities for {len(nm)} joints (a link-side "
                                 "encoder needs both its angle and its rate)")
    if len(msgs) < 2:
        raise RecordingError(f"{path}: {topic}: {len(msgs)} message; need at least 2")
    tl = np.array([m[0] for m in msgs])
    order = np.argsort(tl, kind="stable")
    q = np.array([m[2] for m in msgs], float)[order]
    v = np.array([m[3] for m in msgs], float)[order]
    tl = tl[order]
    out = {}
    for c, i in enumerate(index):
        for kind, arr in (("ql", q), ("vl", v)):
            bad = ~np.isfinite(arr[:, c])
            if bad.any():   # np.interp would spread it; name the message instead
                k = int(np.flatnonzero(bad)[0])
                raise RecordingError(f"{path}: {topic}: channel {kind}{i + 1}: non-finite "
                                     f"value at message {k} (t = {tl[k]:.6g} s)")
            out[f"{kind}{i + 1}"] = np.interp(t, tl, arr[:, c])
    return out
