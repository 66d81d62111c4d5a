"""Live view: a planar arm's state and deflected shape served to Foxglove (issue 46).

A WebSocket server of the ``foxglove-sdk`` package (default ws://127.0.0.1:8765) whose
channels use schemas Foxglove shows without any of our packages:

    /joint_states   sensor_msgs/msg/JointState  ros2msg schema, CDR: rad, rad/s, N m
    /flex/tip_pose  foxglove.PoseInFrame        protobuf: the arm's end in the base frame
    /flex/shape     foxglove.SceneUpdate        protobuf: entity ``arm``, one line strip
                                                per link (its deflected centre line)
    /tf             foxglove.FrameTransforms    protobuf: base -> arm_plane -> link roots
                                                -> deflected link tips (flex_model.urdf)

Everything is in the base frame (``base_link``, REP 103 z up), as /flex/shape of the model
node. Stamps (and log times) are ``epoch + t``: the wall clock when the view started plus
the simulation time t, so all channels share one clock. No ROS imports; foxglove is
imported when a view starts. The functions that build messages are pure (tests decode
them against the model).
"""
from __future__ import annotations

import struct
import threading
import time

import numpy as np

from . import urdf
from .dynamics import FlexArmModel

DEFAULT_PORT = 8765
DEFAULT_HOST = "127.0.0.1"  # this machine only; another address must be asked for
SHAPE_ENTITY = "arm"
LINE_THICKNESS_PX = 4.0

#: sensor_msgs/msg/JointState with its dependencies, in the ros2msg concatenation
JOINT_STATE_SCHEMA = "\n".join([
    "std_msgs/Header header", "string[] name", "float64[] position", "float64[] velocity",
    "float64[] effort", "=" * 80, "MSG: std_msgs/Header", "builtin_interfaces/Time stamp",
    "string frame_id", "=" * 80, "MSG: builtin_interfaces/Time", "int32 sec",
    "uint32 nanosec", ""])

#: one colour per link (RGBA, 0..1), repeated for longer arms
LINK_COLORS = ((0.12, 0.47, 0.71, 1.0), (1.0, 0.5, 0.05, 1.0), (0.17, 0.63, 0.17, 1.0),
               (0.84, 0.15, 0.16, 1.0))


# ---------------------------------------------------------------- pure: geometry
def shape_in_base(model: FlexArmModel, q, plane, points_per_link: int) -> list[np.ndarray]:
    """Deflected centre line of every link, (points, 3) in the base frame (m)."""
    return [urdf.plane_to_base(plane, line) for line in model.shape(q, points_per_link)]


def tip_in_base(model: FlexArmModel, q, plane) -> tuple[np.ndarray, tuple]:
    """(position (3,) m, orientation quaternion (x, y, z, w)) of the arm's end in the base
    frame: the tip point and its tangent (x axis) rotated by the plane's rotation."""
    x, y, phi = model.tip_pose(q)
    position = urdf.plane_to_base(plane, [[x, y]])[0]
    rotation = plane @ urdf.matrix_from_quaternion(urdf.yaw_quaternion(phi))
    return position, urdf.quaternion_from_matrix(rotation)


def stamp_parts(stamp_ns: int) -> tuple[int, int]:
    """(seconds, nanoseconds) of a time in integer nanoseconds."""
    return divmod(int(stamp_ns), 1_000_000_000)


# ---------------------------------------------------------------- pure: encodings
def joint_state_cdr(stamp_ns: int, frame_id: str, names, position, velocity,
                    effort) -> bytes:
    """sensor_msgs/msg/JointState as plain little-endian CDR (what rmw_fastrtps sends):
    encapsulation header, then the fields in order, each aligned to its size counted from
    the end of the header."""
    out = bytearray(b"\x00\x01\x00\x00")

    def align(size):
        out.extend(b"\x00" * ((-(len(out) - 4)) % size))

    def uint32(value):
        align(4)
        out.extend(struct.pack("<I", value))

    def string(text):
        data = text.encode("utf-8") + b"\x00"
        uint32(len(data))
        out.extend(data)

    sec, nanosec = stamp_parts(stamp_ns)
    align(4)
    out.extend(struct.pack("<iI", sec, nanosec))
    string(frame_id)
    uint32(len(names))
    for name in names:
        string(name)
    for values in (position, velocity, effort):
        values = np.asarray(values, "<f8").ravel()
        uint32(len(values))
        if len(values):
            align(8)
            out.extend(values.tobytes())
    return bytes(out)


def _timestamp(stamp_ns: int):
    from foxglove.messages import Timestamp
    sec, nsec = stamp_parts(stamp_ns)
    return Timestamp(sec=sec, nsec=nsec)


def scene_update(lines, frame_id: str, stamp_ns: int):
    """foxglove.SceneUpdate: entity ``arm`` in ``frame_id`` with one line strip per link."""
    from foxglove import messages as fm
    strips = [fm.LinePrimitive(
        type=fm.LinePrimitiveLineType.LineStrip, thickness=LINE_THICKNESS_PX,
        scale_invariant=True, color=fm.Color(**_rgba(i)),
        points=[fm.Point3(x=float(x), y=float(y), z=float(z)) for x, y, z in line])
        for i, line in enumerate(lines)]
    entity = fm.SceneEntity(timestamp=_timestamp(stamp_ns), frame_id=frame_id,
                            id=SHAPE_ENTITY, lines=strips)
    return fm.SceneUpdate(entities=[entity])


def _rgba(link: int) -> dict:
    r, g, b, a = LINK_COLORS[link % len(LINK_COLORS)]
    return {"r": r, "g": g, "b": b, "a": a}


def pose_in_frame(position, quaternion, frame_id: str, stamp_ns: int):
    """foxglove.PoseInFrame of a position (m) and a quaternion (x, y, z, w)."""
    from foxglove import messages as fm
    x, y, z, w = (float(c) for c in quaternion)
    pose = fm.Pose(position=fm.Vector3(x=float(position[0]), y=float(position[1]),
                                       z=float(position[2])),
                   orientation=fm.Quaternion(x=x, y=y, z=z, w=w))
    return fm.PoseInFrame(timestamp=_timestamp(stamp_ns), frame_id=frame_id, pose=pose)


def frame_transforms(transforms, stamp_ns: int):
    """foxglove.FrameTransforms of :class:`flex_model.urdf.Transform` s."""
    from foxglove import messages as fm
    stamp = _timestamp(stamp_ns)
    return fm.FrameTransforms(transforms=[fm.FrameTransform(
        timestamp=stamp, parent_frame_id=tf.parent, child_frame_id=tf.child,
        translation=fm.Vector3(x=float(tf.translation[0]), y=float(tf.translation[1]),
                               z=float(tf.translation[2])),
        rotation=fm.Quaternion(**dict(zip("xyzw", (float(c) for c in tf.rotation)))))
        for tf in transforms])


# ---------------------------------------------------------------- the server
def _subscription_listener():
    """A foxglove ServerListener (its other callbacks: the protocol's no-ops) whose
    ``subscribed`` Event is set at the first subscription."""
    from foxglove.websocket import ServerListener

    class SubscriptionListener(ServerListener):
        def __init__(self):
            self.subscribed = threading.Event()

        def on_subscribe(self, client, channel) -> None:
            self.subscribed.set()

    return SubscriptionListener()


class LiveView:
    """A Foxglove WebSocket server streaming one planar arm (see the module docstring)."""

    def __init__(self, model: FlexArmModel, *, port: int = DEFAULT_PORT,
                 host: str = DEFAULT_HOST, points_per_link: int = 15, frame_prefix: str = "",
                 frame_id: str = "base_link", name: str = "flex-twin"):
        import foxglove
        from foxglove import channels

        self.model, self.points_per_link, self.host = model, int(points_per_link), host
        self.frames = urdf.Frames.of(model, frame_prefix, frame_id)
        self.plane = urdf.plane_rotation(model.gravity)
        self.static_tf = urdf.static_transforms(model, self.frames)
        self.epoch_ns = time.time_ns()
        self.context = foxglove.Context()  # channels of this view only (no global state)
        ctx = self.context
        self.joint_states = foxglove.Channel(
            "/joint_states", message_encoding="cdr", context=ctx,
            schema=foxglove.Schema(name="sensor_msgs/msg/JointState", encoding="ros2msg",
                                   data=JOINT_STATE_SCHEMA.encode()))
        self.tip_pose = channels.PoseInFrameChannel("/flex/tip_pose", context=ctx)
        self.shape = channels.SceneUpdateChannel("/flex/shape", context=ctx)
        self.tf = channels.FrameTransformsChannel("/tf", context=ctx)
        self.listener = _subscription_listener()
        self.server = foxglove.start_server(name=name, host=host, port=port, context=ctx,
                                            server_listener=self.listener)

    @property
    def port(self) -> int:
        """The port served (the one chosen by the system when asked for 0)."""
        return self.server.port

    @property
    def url(self) -> str:
        """What to enter in Foxglove's Open connection dialog."""
        host = "localhost" if self.host == DEFAULT_HOST else self.host
        return f"ws://{host}:{self.port}"

    def stamp_ns(self, t: float) -> int:
        return self.epoch_ns + int(round(t * 1e9))

    def publish(self, t: float, q, position, velocity, effort) -> None:
        """Every channel a client subscribes to, at simulation time ``t`` (s): state q,
        joint angles (rad), rates (rad/s) and torques (N m). Without a subscriber nothing
        is computed (a publication costs about 0.4 ms on two links, 0.55 on three)."""
        stamp = self.stamp_ns(t)
        if self.joint_states.has_sinks():
            self.joint_states.log(joint_state_cdr(stamp, "", self.model.arm.joint_names,
                                                  position, velocity, effort),
                                  log_time=stamp)
        if self.tip_pose.has_sinks():
            tip, orientation = tip_in_base(self.model, q, self.plane)
            self.tip_pose.log(pose_in_frame(tip, orientation, self.frames.base, stamp),
                              log_time=stamp)
        if self.shape.has_sinks():
            lines = shape_in_base(self.model, q, self.plane, self.points_per_link)
            self.shape.log(scene_update(lines, self.frames.base, stamp), log_time=stamp)
        if self.tf.has_sinks():
            moving = urdf.arm_transforms(self.model, q, self.frames)
            self.tf.log(frame_transforms(self.static_tf + moving, stamp), log_time=stamp)

    def wait_for_subscriber(self, timeout: float | None = None,
                            settle: float = 0.2) -> bool:
        """Block until a client subscribes to a channel (True) or ``timeout`` s pass; then
        ``settle`` s more, for the rest of the client's burst of subscriptions."""
        subscribed = self.listener.subscribed.wait(timeout)
        if subscribed:
            time.sleep(settle)
        return subscribed

    def close(self, linger: float = 0.0) -> None:
        """Stop the server after ``linger`` s (the last messages still in flight reach the
        clients); clients see the connection close."""
        time.sleep(linger)
        self.server.stop()


def node_live_view(model: FlexArmModel, port: int, frame_prefix: str, frame_id: str,
                   points_per_link: int, logger) -> LiveView | None:
    """The model node's view (its parameter ``foxglove_port``; 0: none) on 127.0.0.1. A
    port in use or foxglove-sdk missing is one warning on ``logger`` (``info``,
    ``warning``): the node runs on without the view."""
    if not port:
        return None
    try:
        view = LiveView(model, port=port, points_per_link=points_per_link,
                        frame_prefix=frame_prefix, frame_id=frame_id, name="flex_model")
    except (RuntimeError, ImportError) as exc:
        logger.warning(f"foxglove_port {port}: no live view ({exc})")
        return None
    logger.info(f"live view: {view.url} (Foxglove: Open connection > Foxglove WebSocket)")
    return view
