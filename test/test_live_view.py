"""Live view (issue 46): the Foxglove WebSocket server of flex_model.live_view, read by a
client written here from the protocol spec (serverInfo, advertise, subscribe, binary
message data), its protobuf messages decoded with the schema the server advertises and
the JointState CDR with rclpy. Servers bind to 127.0.0.1 only."""
import asyncio
import base64
import json
import re
import socket
import struct
import subprocess
import sys
import threading
import uuid

import numpy as np
import pytest
import websockets

from flex_model import urdf
from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.live_view import LiveView, joint_state_cdr, tip_in_base
from flex_model.statics import static_equilibrium

#: what a current Foxglove app offers; foxglove-sdk 0.30 accepts the first only
SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
MESSAGE_DATA = 0x01  # binary opcode of a message on a subscription
TOPICS = {"/joint_states": ("sensor_msgs/msg/JointState", "cdr", "ros2msg"),
          "/flex/tip_pose": ("foxglove.PoseInFrame", "protobuf", "protobuf"),
          "/flex/shape": ("foxglove.SceneUpdate", "protobuf", "protobuf"),
          "/tf": ("foxglove.FrameTransforms", "protobuf", "protobuf")}


# ------------------------------------------------------------ the protocol client
async def _session(port, topics, per_topic=None, timeout=20.0):
    """Connect, read serverInfo and the advertisements of ``topics``, subscribe to them and
    collect their binary messages: ``per_topic`` each, or (None) until the server closes.
    Returns (subprotocol, serverInfo, {topic: channel}, {topic: [(log_time, payload)]})."""
    async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS,
                                  open_timeout=timeout, max_size=None) as ws:
        info = json.loads(await asyncio.wait_for(ws.recv(), timeout))
        channels = {}
        while not set(topics) <= channels.keys():
            op = json.loads(await asyncio.wait_for(ws.recv(), timeout))
            if op["op"] == "advertise":
                channels.update({c["topic"]: c for c in op["channels"]})
        by_subscription = dict(enumerate(topics))
        await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": k, "channelId": channels[t]["id"]} for k, t in by_subscription.items()]}))
        got = {t: [] for t in topics}
        try:
            while per_topic is None or min(len(v) for v in got.values()) < per_topic:
                frame = await asyncio.wait_for(ws.recv(), timeout)
                if isinstance(frame, str):
                    continue  # e.g. status or more advertisements
                opcode, subscription, log_time = struct.unpack_from("<BIQ", frame)
                assert opcode == MESSAGE_DATA
                got[by_subscription[subscription]].append((log_time, frame[13:]))
        except websockets.ConnectionClosed:
            assert per_topic is None, "the server closed early"
        return ws.subprotocol, info, channels, got


def collect(port, topics=tuple(TOPICS), per_topic=None, timeout=20.0):
    return asyncio.run(_session(port, list(topics), per_topic, timeout))


# ------------------------------------------------------------ protobuf, by the schema
def _varint(data, i):
    value = shift = 0
    while True:
        b = data[i]
        i += 1
        value |= (b & 0x7F) << shift
        shift += 7
        if b < 0x80:
            return value, i


def _fields(data):
    """(field number, wire type, raw value) of a protobuf message, in order."""
    i = 0
    while i < len(data):
        key, i = _varint(data, i)
        number, wire = key >> 3, key & 7
        if wire == 0:
            value, i = _varint(data, i)
        elif wire == 1:
            value, i = data[i:i + 8], i + 8
        elif wire == 2:
            size, i = _varint(data, i)
            value, i = data[i:i + size], i + size
        elif wire == 5:
            value, i = data[i:i + 4], i + 4
        else:
            raise ValueError(f"wire type {wire}")
        yield number, wire, value


def message_types(schema_b64):
    """{'.package.Message': {number: (name, type, type_name, repeated)}} of a base64
    google.protobuf.FileDescriptorSet (the protobuf schema a channel advertises)."""
    types = {}

    def message(data, scope):
        name, fields = None, {}
        nested = []
        for number, _, value in _fields(data):
            if number == 1:
                name = value.decode()
            elif number == 2:  # FieldDescriptorProto
                f = {n: v for n, _, v in _fields(value)}
                fields[f[3]] = (f[1].decode(), f[5], f.get(6, b"").decode(), f.get(4) == 3)
            elif number == 3:
                nested.append(value)
        full = f"{scope}.{name}"
        types[full] = fields
        for n in nested:
            message(n, full)

    for number, _, file in _fields(base64.b64decode(schema_b64)):
        assert number == 1
        parts = {n: v for n, _, v in _fields(file) if n == 2}
        package = parts.get(2, b"").decode()
        for n, _, value in _fields(file):
            if n == 4:
                message(value, f".{package}" if package else "")
    return types


_SCALARS = {1: "<d", 2: "<f", 6: "<Q", 7: "<I", 15: "<i", 16: "<q"}


def decode(data, name, types):
    """A protobuf message as a dict (every field present: proto3 leaves defaults out)."""
    spec = types[name]
    out = {fname: [] if rep else (None if kind == 11 else 0)
           for fname, kind, _, rep in spec.values()}
    for number, wire, raw in _fields(data):
        fname, kind, tname, rep = spec[number]
        if kind == 11:
            values = [decode(raw, tname, types)]
        elif kind in (9, 12):
            values = [raw.decode() if kind == 9 else raw]
        elif kind in _SCALARS:
            code = _SCALARS[kind]
            values = list(struct.unpack(f"<{len(raw) // struct.calcsize(code)}{code[1]}",
                                        raw))
        else:  # varint kinds, packed (wire 2) or one
            values, i = [], 0
            if wire == 2:
                while i < len(raw):
                    v, i = _varint(raw, i)
                    values.append(v)
            else:
                values = [raw]
        if rep:
            out[fname].extend(values)
        else:
            out[fname] = values[0]
    return out


def decoded(channels, got, topic):
    """The messages on a protobuf topic, decoded by the schema of its advertisement."""
    ch = channels[topic]
    types = message_types(ch["schema"])
    return [(t, decode(payload, "." + ch["schemaName"], types)) for t, payload in got[topic]]


def point(p):
    return np.array([p["x"], p["y"], p["z"]])


def joint_state(payload):
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    return deserialize_message(payload, JointState)


# ------------------------------------------------------------ the tests
def deflected_state(model):
    """The arm at rest under gravity with the joints held at 30 and -45 deg."""
    return static_equilibrium(model, np.radians([30.0, -45.0]), joints="clamped").q


def test_joint_state_cdr_is_what_rclpy_reads():
    names = ["joint1", "joint2", "j3"]
    msg = joint_state(joint_state_cdr(1_796_000_000_123_456_789, "base_link", names,
                                      [0.1, -0.2, 0.3], [1.5, 2.5, -3.5], [10.0, 0.0, -7.25]))
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1_796_000_000, 123_456_789)
    assert msg.header.frame_id == "base_link" and list(msg.name) == names
    assert list(msg.position) == [0.1, -0.2, 0.3]
    assert list(msg.velocity) == [1.5, 2.5, -3.5]
    assert list(msg.effort) == [10.0, 0.0, -7.25]


def test_live_view_serves_the_deflected_arm():
    model = FlexArmModel(load_arm("thesis_example1"))
    q = deflected_state(model)
    plane = urdf.plane_rotation(model.gravity)
    rigid_tip, _ = tip_in_base(model, model.q_from_joint_angles(np.radians([30.0, -45.0])),
                               plane)
    tip, orientation = tip_in_base(model, q, plane)
    assert np.linalg.norm(tip - rigid_tip) > 1e-3  # deflected: the check below can fail
    view = LiveView(model, port=0, points_per_link=9)
    try:
        assert view.url == f"ws://localhost:{view.port}"
        theta = model.joint_angles(q)

        def publish():
            view.publish(1.25, q, theta, [0.0, 0.0], [3.0, -4.0])

        publish()  # before anyone listens: dropped, harmless
        stop = threading.Event()

        def keep_publishing():
            while not stop.wait(0.02):
                publish()
        th = threading.Thread(target=keep_publishing, daemon=True)
        th.start()
        try:
            sub, info, channels, got = collect(view.port, per_topic=2)
        finally:
            stop.set()
            th.join()
    finally:
        view.close()
    assert sub == "foxglove.sdk.v1"
    assert info["op"] == "serverInfo" and info["name"] == "flex-twin"
    for topic, (schema, encoding, schema_encoding) in TOPICS.items():
        ch = channels[topic]
        assert (ch["schemaName"], ch["encoding"], ch["schemaEncoding"]) == \
            (schema, encoding, schema_encoding)
    stamp = view.stamp_ns(1.25)
    assert {t for v in got.values() for t, _ in v} == {stamp}
    # the shape: one strip of 9 points per link, in base_link; the last point is the tip
    (_, update), *_ = decoded(channels, got, "/flex/shape")
    (entity,) = update["entities"]
    assert (entity["id"], entity["frame_id"]) == ("arm", "base_link")
    assert (entity["timestamp"]["seconds"], entity["timestamp"]["nanos"]) == \
        divmod(stamp, 10**9)
    lines = [np.array([point(p) for p in line["points"]]) for line in entity["lines"]]
    assert [len(line) for line in lines] == [9, 9]
    expected = [urdf.plane_to_base(plane, line) for line in model.shape(q, 9)]
    for line, want in zip(lines, expected):
        np.testing.assert_allclose(line, want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lines[-1][-1], tip, rtol=0, atol=1e-9)
    x, y = model.link_origins(q)[-1]
    np.testing.assert_allclose(lines[-1][-1], plane @ [x, y, 0.0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(lines[1][0], lines[0][-1], rtol=0, atol=1e-12)  # joint 2
    # the tip pose
    (_, pose), *_ = decoded(channels, got, "/flex/tip_pose")
    assert pose["frame_id"] == "base_link"
    np.testing.assert_allclose(point(pose["pose"]["position"]), tip, rtol=0, atol=1e-9)
    o = pose["pose"]["orientation"]
    np.testing.assert_allclose([o["x"], o["y"], o["z"], o["w"]], orientation, atol=1e-12)
    # the frames: base -> ... -> the last link's deflected tip lands on the same point
    (_, tfs), *_ = decoded(channels, got, "/tf")
    transforms = [urdf.Transform(f["parent_frame_id"], f["child_frame_id"],
                                 tuple(point(f["translation"])),
                                 tuple(f["rotation"][k] for k in "xyzw"))
                  for f in tfs["transforms"]]
    assert [t.child for t in transforms] == ["arm_plane", "link1", "link1_tip", "link2",
                                             "link2_tip"]
    _, tip_from_tf = urdf.compose(transforms, transforms[-1].child, "base_link")
    np.testing.assert_allclose(tip_from_tf, tip, rtol=0, atol=1e-9)
    # the joint states (CDR, read by rclpy)
    msg = joint_state(got["/joint_states"][0][1])
    assert list(msg.name) == model.arm.joint_names
    np.testing.assert_array_equal(msg.position, theta)
    assert list(msg.effort) == [3.0, -4.0]
    assert msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec == stamp


def start_view(*args):
    """``flex-twin view ... --port 0 --wait`` and the port it reports on stderr."""
    proc = subprocess.Popen([sys.executable, "-m", "flex_twin.cli", "view", *args,
                             "--port", "0", "--wait"], stderr=subprocess.PIPE, text=True)
    lines = []
    for line in proc.stderr:
        lines.append(line)
        found = re.search(r"serving ws://localhost:(\d+)", line)
        if found:
            return proc, int(found.group(1))
    proc.wait()
    raise AssertionError("no server line: " + "".join(lines))


def test_view_command_streams_the_swinging_arm():
    duration = 0.5
    proc, port = start_view("thesis_example1", "--duration", str(duration),
                            "--joint-angles-deg", "30", "-45", "--publish-rate", "20")
    try:
        sub, _, channels, got = collect(port, timeout=60.0)
        rest = proc.stderr.read()
        assert proc.wait(timeout=30) == 0, rest
    finally:
        proc.kill()
    assert f"streamed {duration:g} s simulated" in rest
    for topic, (schema, _, _) in TOPICS.items():
        assert channels[topic]["schemaName"] == schema
    times = sorted(t for t, _ in got["/flex/shape"])
    assert len(times) >= 5
    for topic in TOPICS:  # every frame on every channel
        assert sorted(t for t, _ in got[topic]) == times, topic
    assert times[-1] - times[0] == pytest.approx(duration * 1e9, abs=2)  # ns
    shapes = dict(decoded(channels, got, "/flex/shape"))
    poses = dict(decoded(channels, got, "/flex/tip_pose"))
    states = {t: joint_state(p) for t, p in got["/joint_states"]}
    model = FlexArmModel(load_arm("thesis_example1"))
    plane = urdf.plane_rotation(model.gravity)
    theta0 = np.radians([30.0, -45.0])
    q0 = model.q_from_joint_angles(theta0)
    # the first frame: the arm at rest, as released
    first = [np.array([point(p) for p in line["points"]])
             for line in shapes[times[0]]["entities"][0]["lines"]]
    for line, want in zip(first, shape_lines(model, q0, plane)):
        np.testing.assert_allclose(line, want, rtol=0, atol=1e-9)
    np.testing.assert_allclose(states[times[0]].position, theta0, rtol=0, atol=1e-12)
    # every frame: the tip pose is the last point of the shape
    for t in times:
        last = point(shapes[t]["entities"][0]["lines"][-1]["points"][-1])
        np.testing.assert_allclose(point(poses[t]["pose"]["position"]), last, rtol=0,
                                   atol=1e-9)
    # the last frame: where the core's stepper has the arm after the same time (frames
    # every 0.05 s: whole 1 ms steps, the same as one advance over 0.5 s)
    from flex_model.stepper import Stepper
    st = Stepper(model, q0)
    st.advance(duration)
    tip, _ = tip_in_base(model, st.q, plane)
    end = point(poses[times[-1]]["pose"]["position"])
    start = point(poses[times[0]]["pose"]["position"])
    assert np.linalg.norm(end - start) > 0.01  # it swung
    np.testing.assert_allclose(end, tip, rtol=0, atol=1e-9)  # the same 1 ms steps


def shape_lines(model, q, plane):
    return [urdf.plane_to_base(plane, line) for line in model.shape(q, 15)]


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Warnings:
    def __init__(self):
        self.lines = []

    def warning(self, text):
        self.lines.append(text)

    info = warning


def test_node_view_in_a_port_in_use_is_a_warning():
    from flex_model.live_view import node_live_view
    model = FlexArmModel(load_arm("thesis_example1"))
    taken = LiveView(model, port=0)
    try:
        log = Warnings()
        assert node_live_view(model, taken.port, "", "base_link", 15, log) is None
        assert log.lines and f"foxglove_port {taken.port}: no live view" in log.lines[0]
        assert node_live_view(model, 0, "", "base_link", 15, log) is None  # 0: off
    finally:
        taken.close()


def ns_of(stamp):
    return stamp.sec * 10**9 + stamp.nanosec


def test_model_node_streams_what_it_publishes_over_ros():
    """foxglove_port: the node's Foxglove frames (at shape_rate) carry the state of its ROS
    publications at the same simulation time: the tip, and the joint states."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    from flex_model.ros.model_node import ModelNode
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    ns = f"/lv{uuid.uuid4().hex[:8]}"
    params = {"arm": "thesis_example1", "foxglove_port": free_port(), "shape_rate": 20.0,
              "publish_rate": 100.0, "initial_joint_angles_deg": [30.0, -45.0],
              "hold_until_command": False}  # the arm falls: frames that differ
    node = ModelNode(context=ctx, namespace=ns, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()])
    probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=ctx, namespace=ns)
    ros_tips, ros_states = {}, {}
    probe.create_subscription(PoseStamped, "flex/tip_pose",
                              lambda m: ros_tips.__setitem__(ns_of(m.header.stamp), m), 100)
    probe.create_subscription(JointState, "joint_states",
                              lambda m: ros_states.__setitem__(ns_of(m.header.stamp), m), 100)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(node)
    ex.add_node(probe)
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            ex.spin_once(timeout_sec=0.005)
    spinner = threading.Thread(target=spin, daemon=True)
    spinner.start()
    try:
        assert node.live_view is not None and node.live_view.port == params["foxglove_port"]
        _, info, channels, got = collect(node.live_view.port, per_topic=20, timeout=30.0)
        epoch = node.live_view.epoch_ns
    finally:
        stop.set()
        spinner.join()
        if node.live_view is not None:
            node.live_view.close()
        ex.shutdown()
        node.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=ctx)
    assert info["name"] == "flex_model"
    poses = decoded(channels, got, "/flex/tip_pose")
    shapes = dict(decoded(channels, got, "/flex/shape"))
    states = dict(got["/joint_states"])
    matched = matched_states = 0
    for log_time, pose in poses:
        t_ns = log_time - epoch  # the node's simulation time
        ros = [m for s, m in ros_tips.items() if abs(s - t_ns) <= 1000]
        if not ros:
            continue  # before the probe was discovered
        matched += 1
        p = ros[0].pose.position  # in base_link, as the live view's
        tip = point(pose["pose"]["position"])
        np.testing.assert_allclose(tip, [p.x, p.y, p.z], rtol=0, atol=1e-9)
        last = point(shapes[log_time]["entities"][0]["lines"][-1]["points"][-1])
        np.testing.assert_allclose(last, tip, rtol=0, atol=1e-9)
        for ros_state in [m for s, m in ros_states.items() if abs(s - t_ns) <= 1000]:
            matched_states += 1
            ours = joint_state(states[log_time])
            np.testing.assert_array_equal(ours.position, ros_state.position)
            np.testing.assert_array_equal(ours.effort, ros_state.effort)
    assert matched >= 5 and matched_states >= 5
    tips = [point(pose["pose"]["position"]) for _, pose in poses]
    assert np.linalg.norm(tips[-1] - tips[0]) > 1e-3  # the arm moved: not one state


class FakeView:
    def __init__(self):
        self.frames = []

    def publish(self, t, q, angles, rates, torques):
        self.frames.append(t)


class FakeClock:
    def __init__(self, step_cost):
        self.now, self.step_cost, self.sleeps = 100.0, step_cost, []

    def clock(self):
        self.now += self.step_cost  # every look at the clock: some work done
        return self.now

    def sleep(self, s):
        self.sleeps.append(s)
        self.now += s


class Source:
    def at(self, t):
        return t, None, None, None, None


@pytest.mark.parametrize("cost", [0.001, 0.2])  # on time; slower than the frame period
def test_stream_frames_on_the_simulation_grid(cost):
    """Frame k at simulation time k F / HZ (F = 2, HZ = 10: every 0.2 s), the last at the
    duration; on time, frame k leaves at wall k / HZ; behind, none is skipped."""
    from flex_twin.view_cli import stream
    view, clk, seen = FakeView(), FakeClock(cost), []
    simulated, wall = stream(view, Source(), 1.3, 2.0, 10.0, seen.append, clk.clock,
                             clk.sleep)
    np.testing.assert_allclose(view.frames, [0, 0.2, 0.4, 0.6, 0.8, 1.0, 1.2, 1.3],
                               rtol=0, atol=1e-12)
    assert seen == view.frames and simulated == 1.3
    if cost < 0.01:
        assert wall == pytest.approx(0.7 + cost, abs=1e-9)  # 7 periods + the last look
    else:  # one look a frame at 0.2 s: longer than the 0.1 s period, never a sleep
        assert max(clk.sleeps) == 0.0 and wall == pytest.approx(8 * 0.2, abs=1e-9)


def test_view_refuses_bad_input(capsys):
    from flex_twin.cli import main
    for argv, what in ((["view", "thesis_three_link_pd", "--joint-angles-deg", "10"],
                        "--joint-angles-deg"),
                       (["view", "thesis_example1", "--rate-factor", "0"], "--rate-factor"),
                       (["view", "seed000_real_arm_3d"], "spatial")):
        assert main(argv) == 2
        assert what in capsys.readouterr().err


def test_playback_holds_the_last_sample():
    """A scenario plays back sample by sample: at t the last sample at or before t, with
    the joint angles and rates of that sample's q and v."""
    from flex_model.simulate import SimulationResult
    from flex_twin.view_cli import PlaybackSource
    model = FlexArmModel(load_arm("thesis_example1"))
    t = np.array([0.0, 0.01, 0.02, 0.03])
    q = np.array([model.q_from_joint_angles([0.1 * k, -0.2 * k]) for k in range(4)])
    v = np.array([model.v_from_joint_rates([k, 2.0 * k]) for k in range(4)])
    tau = np.arange(8.0).reshape(4, 2)
    source = PlaybackSource(SimulationResult(model, t, q, v, tau))
    assert source.duration == 0.03
    for when, k in ((0.0, 0), (0.0149, 1), (0.02, 2), (0.5, 3)):
        t_k, q_k, angles, rates, torques = source.at(when)
        assert t_k == t[k] and np.array_equal(q_k, q[k])
        np.testing.assert_allclose(angles, [0.1 * k, -0.2 * k], rtol=0, atol=1e-15)
        np.testing.assert_allclose(rates, [k, 2.0 * k], rtol=0, atol=1e-12)
        assert list(torques) == [2.0 * k, 2.0 * k + 1]
