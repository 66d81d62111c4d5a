"""Message <-> array conversions of the planner node, with the request checks.

A request is a ``nav_msgs/Path`` of tip waypoints: positions in the planner's frame,
``poses[k].header.stamp`` the time of waypoint k from the start of the motion (s) and,
for arms with three or more links, the tip orientation as the yaw of the pose's
quaternion. Every check raises ``ValueError`` naming the field, the value and what is
allowed, so the node can log it and publish nothing for that request.
"""
from __future__ import annotations

import struct

import numpy as np
from builtin_interfaces.msg import Duration
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flex_model.trajectory import JointTrajectoryData


def stamp_seconds(stamp) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


def duration_msg(seconds: float) -> Duration:
    ns = int(round(seconds * 1e9))
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def yaw(quaternion) -> float:
    """Rotation about z (rad) of a quaternion (planar tip orientation)."""
    q = quaternion
    return float(np.arctan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z)))


def serialized_path_size(data: bytes) -> int | None:
    """The number of poses of a serialized nav_msgs/Path (plain CDR, as the ROS 2 RMWs
    write it), read from its first bytes without deserializing the poses (rclpy builds
    every pose as Python objects: minutes for 10^6); None if the encapsulation is not
    plain CDR."""
    if len(data) < 20 or data[0] != 0 or data[1] not in (0, 1):
        return None
    order = "<" if data[1] == 1 else ">"
    # after the 4-byte encapsulation (CDR aligns from there): header.stamp (8 bytes),
    # header.frame_id (uint32 length with the NUL, the bytes), then the poses' count
    (n_frame,) = struct.unpack_from(order + "I", data, 4 + 8)
    count_at = 4 + (8 + 4 + n_frame + 3) // 4 * 4
    if count_at + 4 > len(data):
        return None
    return struct.unpack_from(order + "I", data, count_at)[0]


def waypoints_msg(points, frame_id: str = "arm_plane") -> Path:
    """Tip waypoints ``(x, y, t)`` (m, m, s from the start) as the planner node takes them
    (the inverse of :func:`path_request`): a nav_msgs/Path in ``frame_id`` (the poses'
    own frame_id left empty: the Path's applies), each pose stamped with its time."""
    msg = Path()
    msg.header.frame_id = frame_id
    for x, y, t in points:
        pose = PoseStamped()
        pose.header.stamp.sec = int(t)
        pose.header.stamp.nanosec = int(round((t - int(t)) * 1e9))
        pose.pose.position.x, pose.pose.position.y = float(x), float(y)
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg


def path_request(msg: Path, frame_id: str, with_orientation: bool):
    """(waypoints (N, 2) m, times (N,) s, orientations (N,) rad or None) of a request."""
    if msg.header.frame_id != frame_id:
        raise ValueError(f"Path.header.frame_id: got {msg.header.frame_id!r}; expected "
                         f"{frame_id!r} (the planner's frame_id parameter)")
    if len(msg.poses) < 2:
        raise ValueError(f"Path.poses: got {len(msg.poses)} poses; expected at least 2 "
                         "waypoints")
    pts, times, phis = [], [], []
    for k, pose in enumerate(msg.poses):
        if pose.header.frame_id not in ("", frame_id):
            raise ValueError(f"Path.poses[{k}].header.frame_id: got "
                             f"{pose.header.frame_id!r}; expected {frame_id!r} or empty")
        p = pose.pose.position
        if not np.all(np.isfinite([p.x, p.y])):
            raise ValueError(f"Path.poses[{k}].pose.position: got ({p.x}, {p.y}); expected "
                             "finite x, y (m)")
        t = stamp_seconds(pose.header.stamp)
        if times and t <= times[-1]:
            raise ValueError(f"Path.poses[{k}].header.stamp: got {t:.9g} s after "
                             f"{times[-1]:.9g} s; expected strictly increasing times from "
                             "the start")
        pts.append([p.x, p.y])
        times.append(t)
        phis.append(yaw(pose.pose.orientation))
    orientations = np.array(phis) if with_orientation else None
    return np.array(pts, float), np.array(times, float), orientations


def trajectory_msg(traj: JointTrajectoryData, frame_id: str) -> JointTrajectory:
    """Positions, velocities, accelerations and ``effort`` = nominal torque per sample;
    ``time_from_start`` = the sample time; header stamp zero (start on arrival)."""
    msg = JointTrajectory()
    msg.header.frame_id = frame_id
    msg.joint_names = list(traj.joint_names)
    pos, vel, acc, eff = (a.tolist() for a in (traj.positions, traj.velocities,
                                                traj.accelerations, traj.efforts))
    msg.points = [JointTrajectoryPoint(positions=pos[k], velocities=vel[k],
                                       accelerations=acc[k], effort=eff[k],
                                       time_from_start=duration_msg(t))
                  for k, t in enumerate(traj.t.tolist())]
    return msg


def nominal_path_msg(traj: JointTrajectoryData, frame_id: str, stamp) -> Path:
    """The nominal tip path; each pose's stamp is its time from the start (as requests)."""
    msg = Path()
    msg.header.frame_id = frame_id
    msg.header.stamp = stamp
    poses = []
    for t, (x, y) in zip(traj.t.tolist(), traj.tip.tolist()):
        ps = PoseStamped()
        ps.header.frame_id = frame_id
        d = duration_msg(t)
        ps.header.stamp.sec, ps.header.stamp.nanosec = d.sec, d.nanosec
        ps.pose.position.x, ps.pose.position.y = x, y
        ps.pose.orientation.w = 1.0
        poses.append(ps)
    msg.poses = poses
    return msg


def deflections_msg(traj: JointTrajectoryData, names, indices, frame_id: str) -> JointTrajectory:
    """The nominal deformation variables (m, rad) as a JointTrajectory whose "joints" are
    the model's deformation coordinates (``link1/delta1``, ``link1/gamma1``, ...)."""
    msg = JointTrajectory()
    msg.header.frame_id = frame_id
    msg.joint_names = [names[i] for i in indices]
    values = traj.q_nominal[:, indices].tolist()
    msg.points = [JointTrajectoryPoint(positions=values[k], time_from_start=duration_msg(t))
                  for k, t in enumerate(traj.t.tolist())]
    return msg
