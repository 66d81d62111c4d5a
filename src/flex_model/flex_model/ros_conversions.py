"""Messages of the model node built from core outputs (standard message types only)."""
from __future__ import annotations

import math

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray


def stamp(t: float) -> Time:
    """builtin_interfaces/Time of a simulation time t (s), rounded to the nanosecond."""
    sec, nanosec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return Time(sec=sec, nanosec=nanosec)


def joint_state(t, names, position, velocity, effort) -> JointState:
    return JointState(header=Header(stamp=stamp(t)), name=list(names),
                      position=[float(x) for x in position],
                      velocity=[float(x) for x in velocity],
                      effort=[float(x) for x in effort])


def deflection_state(t, link_names, deflection, rotation, d_rate, r_rate) -> JointState:
    """link<i>/tip_deflection (m) and link<i>/tip_rotation (rad) with their rates."""
    names, pos, vel = [], [], []
    for n, d, r, dd, rr in zip(link_names, deflection, rotation, d_rate, r_rate):
        names += [f"{n}/tip_deflection", f"{n}/tip_rotation"]
        pos += [float(d), float(r)]
        vel += [float(dd), float(rr)]
    return JointState(header=Header(stamp=stamp(t)), name=names, position=pos, velocity=vel)


def tip_pose(t, x, y, phi, frame="base_link") -> PoseStamped:
    msg = PoseStamped(header=Header(stamp=stamp(t), frame_id=frame))
    msg.pose.position.x, msg.pose.position.y = float(x), float(y)
    msg.pose.orientation.z, msg.pose.orientation.w = math.sin(phi / 2), math.cos(phi / 2)
    return msg


def shape_markers(t, shapes, chords, frame="base_link", ns="flex") -> MarkerArray:
    """Deflected centre line of every link (LINE_STRIP) and its rigid chord (thin)."""
    out = MarkerArray()
    for i, (line, chord) in enumerate(zip(shapes, chords)):
        for k, (pts, width, color) in enumerate(
                ((line, 0.02, ColorRGBA(r=0.1, g=0.4, b=0.9, a=1.0)),
                 (chord, 0.005, ColorRGBA(r=0.6, g=0.6, b=0.6, a=0.8)))):
            m = Marker(header=Header(stamp=stamp(t), frame_id=frame), ns=f"{ns}/link{i + 1}",
                       id=2 * i + k, type=Marker.LINE_STRIP, action=Marker.ADD, color=color)
            m.scale.x = width
            m.pose.orientation.w = 1.0
            m.points = [Point(x=float(p[0]), y=float(p[1]), z=0.0) for p in pts]
            out.markers.append(m)
    return out


def imu(t, specific_force, angular_rate, phi, frame="tip") -> Imu:
    """Tip accelerometer: linear_acceleration = specific force in the tip frame (m/s^2)."""
    msg = Imu(header=Header(stamp=stamp(t), frame_id=frame))
    msg.linear_acceleration.x, msg.linear_acceleration.y = (float(v) for v in specific_force)
    msg.angular_velocity.z = float(angular_rate)
    msg.orientation.z, msg.orientation.w = math.sin(phi / 2), math.cos(phi / 2)
    return msg


def finite_array(values, length: int, what: str) -> np.ndarray:
    """Checked copy of a received array: raises ValueError naming the problem."""
    arr = np.asarray(values, dtype=float)
    if arr.shape != (length,):
        raise ValueError(f"{what}: got {arr.size} values; expected {length}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{what}: got non-finite values {arr.tolist()}")
    return arr
