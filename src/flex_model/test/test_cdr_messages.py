"""Messages serialized from a CDR template (flex_model.ros.cdr_messages): byte for byte what
rclpy's ``serialize_message`` makes of the same message object (except the CDR padding,
which rclpy leaves as it was in memory and the template sets to zero), decoded to the
same message by rclpy and by the independent ``rosbags`` CDR reader (what a bag reader
sees), for the model node's messages (ros_conversions: the object path it replaced) and
values a float64 must keep: -0.0, a subnormal, inf, nan, large times."""
import math

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_typestore
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray, Header
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from flex_model.ros import conversions as conv
from flex_model.ros.cdr_messages import CdrTemplate, encode, padding_mask

ODD = [-0.0, 5e-324, 1e-310, math.inf, -math.inf, math.nan, 1.0e300, -123.456]
TIMES = [0.0, 1e-9, 0.0015, 12.345678901, 86399.999999999, 1.7e9 + 0.123456789]
STORE = get_typestore(Stores.ROS2_JAZZY)


def assert_same_bytes(raw: bytes, msg) -> None:
    """raw is serialize_message(msg) at every non-padding byte; its padding is zero.
    (serialize_message may end with 4 bytes more per empty float64[], which the wire
    does not carry: its size estimate aligns an empty float64[] as if it had items.)"""
    ref = np.frombuffer(serialize_message(msg), np.uint8)
    got = np.frombuffer(raw, np.uint8)
    assert got.size <= ref.size < got.size + 16 and (ref.size - got.size) % 4 == 0
    pad = padding_mask(msg)
    assert np.array_equal(got[~pad], ref[:got.size][~pad])
    assert not got[pad].any()
    assert raw == encode(msg)


def float_bits(values) -> list[int]:
    return np.asarray(values, np.float64).view(np.uint64).tolist()


def values_of(rng, count):
    v = rng.normal(size=count) * 10.0 ** rng.integers(-8, 8, size=count)
    v[: min(count, len(ODD))] = ODD[:count]
    rng.shuffle(v)
    return v


@pytest.mark.parametrize("joints", [1, 2, 3])
def test_joint_states_and_deflections(joints):
    rng = np.random.default_rng(joints)
    names = [f"joint{i + 1}" for i in range(joints)]
    links = [f"link{i + 1}" for i in range(joints)]
    js = conv.joint_state_cdr(names, joints)
    defl = conv.joint_state_cdr(conv.deflection_names(links), 2 * joints, effort=False)
    msg_js, msg_defl = JointState(name=names), JointState(name=conv.deflection_names(links))
    for t in TIMES:
        pos, vel, eff = (values_of(rng, joints) for _ in range(3))
        raw = js.fill(t, np.concatenate([pos, vel, eff]))
        obj = conv.fill_joint_state(msg_js, t, pos, vel, eff)
        assert_same_bytes(raw, obj)
        got = deserialize_message(raw, JointState)
        assert float_bits(got.position) == float_bits(pos)
        assert float_bits(got.effort) == float_bits(eff)
        assert (got.header.stamp.sec, got.header.stamp.nanosec) == \
            divmod(int(round(t * 1e9)), 10**9)
        d, r, dd, dr = (values_of(rng, joints) for _ in range(4))
        values = np.concatenate([np.column_stack([d, r]).ravel(),
                                 np.column_stack([dd, dr]).ravel()])
        raw = defl.fill(t, values)
        assert_same_bytes(raw, conv.fill_deflection_state(msg_defl, t, d, r, dd, dr))
        other = STORE.deserialize_cdr(raw, "sensor_msgs/msg/JointState")  # a bag reader
        assert list(other.name) == conv.deflection_names(links)
        assert float_bits(other.velocity) == float_bits(values[2 * joints:])
        assert list(other.effort) == []


def test_tip_pose_clock_and_imu():
    rng = np.random.default_rng(7)
    tip, clock, imu = conv.tip_pose_cdr("robot1/arm_plane"), conv.clock_cdr(), \
        conv.imu_cdr("link2_tip")
    msg_tip = PoseStamped(header=Header(frame_id="robot1/arm_plane"))
    msg_clock = Clock()
    for t in TIMES:
        x, y, phi = values_of(rng, 2).tolist() + [float(rng.uniform(-7.0, 7.0))]
        raw = tip.fill(t, conv.tip_pose_values(x, y, phi))
        assert_same_bytes(raw, conv.fill_tip_pose(msg_tip, t, x, y, phi))
        pose = STORE.deserialize_cdr(raw, "geometry_msgs/msg/PoseStamped").pose
        assert (pose.orientation.z, pose.orientation.w) == (math.sin(phi / 2),
                                                            math.cos(phi / 2))
        conv.set_time(msg_clock.clock, t)
        assert_same_bytes(clock.fill(t), msg_clock)
        force, rate = values_of(rng, 2), float(rng.normal())
        quat = rng.normal(size=4)
        raw = imu.fill(t, conv.imu_values(force, rate, quat))
        ref = conv.imu(t, force, rate, phi, "link2_tip", quat)
        assert_same_bytes(raw, ref)
        assert deserialize_message(raw, Imu) == ref


@pytest.mark.parametrize("links, points, dim", [(2, 15, 3), (3, 7, 2), (1, 2, 3)])
def test_shape_markers(links, points, dim):
    rng = np.random.default_rng(links * 100 + points)
    shapes_msg = conv.ShapeMarkers(links, points, "robot1/base_link")
    for t in TIMES[:3]:
        shapes = [rng.normal(size=(points, dim)) for _ in range(links)]
        raw = shapes_msg.serialized(t, shapes)
        assert_same_bytes(raw, shapes_msg.update(t, shapes))
        other = STORE.deserialize_cdr(raw, "visualization_msgs/msg/MarkerArray")
        last = other.markers[-1]  # the last chord: first and last point of the last line
        assert (last.points[1].x, last.points[1].y) == (shapes[-1][-1, 0], shapes[-1][-1, 1])
        assert encode(deserialize_message(raw, MarkerArray)) == raw  # (float32 colours)


def test_long_shapes():
    """2000 points per link (shape_points allows 10,000): the earlier serialized copy,
    found by searching the bytes for marker values, stopped at about 500 points (its
    marker values were no longer unique)."""
    rng = np.random.default_rng(11)
    shapes_msg = conv.ShapeMarkers(2, 2000)
    shapes = [rng.normal(size=(2000, 2)) for _ in range(2)]
    assert_same_bytes(shapes_msg.serialized(12.5, shapes), shapes_msg.update(12.5, shapes))


def test_any_message_encodes_as_rclpy_serializes():
    """The encoder itself on messages with strings of every length (padding after them),
    nested sequences, bytes, a bool at the end (no end padding) and empty float64[] (Fast
    CDR aligns them to 8 even when empty: 4 bytes more after an odd count)."""
    status = conv.diagnostic_status("node", "arm", "error", "x" * 5, a="1", bb="22", ccc="")
    for msg in (DiagnosticArray(status=[status, status]), conv.ShapeMarkers(1, 3).msg,
                Imu(), Clock(), JointState(name=["a", "bc", "def", "ghij"]), JointState(),
                JointState(name=["ab"], position=[1.0]), Marker(), Float64MultiArray(),
                JointTrajectory(points=[JointTrajectoryPoint(positions=[1.0])])):
        assert_same_bytes(encode(msg), msg)
        assert encode(deserialize_message(encode(msg), type(msg))) == encode(msg)


def test_template_refuses_a_missing_field():
    with pytest.raises(ValueError, match="no float64 field at 'pose.nothing'"):
        CdrTemplate(PoseStamped(), ["header.stamp"], ["pose.nothing"])
    with pytest.raises(ValueError, match="no int32 field at 'stamp.sec'"):
        CdrTemplate(PoseStamped(), ["stamp"])


def test_on_the_wire_the_bytes_of_the_published_message_object():
    """A raw subscription (as the bag recorder's) receives byte for byte the same from
    the template as from rclpy publishing the message object (padding included)."""
    import time
    import uuid

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        node = rclpy.create_node(f"cdr_{uuid.uuid4().hex[:8]}", context=ctx)
        topic = f"cdr_{uuid.uuid4().hex[:8]}/defl"
        got = []
        node.create_subscription(JointState, topic, got.append, 100, raw=True)
        pub = node.create_publisher(JointState, topic, 100)
        end = time.monotonic() + 10.0
        while pub.get_subscription_count() == 0:
            assert time.monotonic() < end, "discovery"
            time.sleep(0.01)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        rng = np.random.default_rng(3)
        links = ["link1", "link2"]
        tpl = conv.joint_state_cdr(conv.deflection_names(links), 4, effort=False)
        msg = JointState(name=conv.deflection_names(links))
        for t in TIMES:  # object, template, object, ...: the same message twice each
            values = values_of(rng, 8)
            pub.publish(conv.fill_joint_state(msg, t, values[:4], values[4:]))
            pub.publish(tpl.fill(t, values))
        while len(got) < 2 * len(TIMES):
            assert time.monotonic() < end, f"{len(got)} of {2 * len(TIMES)} received"
            ex.spin_once(timeout_sec=0.05)
        for obj, raw in zip(got[::2], got[1::2]):
            assert obj == raw
    finally:
        rclpy.try_shutdown(context=ctx)
