"""rosbag2 (MCAP) bags: write/read round trip checked by the independent ``rosbags`` reader,
metadata.yaml v9, a recorder stopped with SIGINT, bag_info figures, player order and timing.

In-process ROS uses a private rclpy context per test (conftest.py sets the environment).
"""
import argparse
import array
import json
import os
import signal
import subprocess
import sys
import time
import uuid

import numpy as np
import pytest
import rclpy
import yaml
from geometry_msgs.msg import PoseStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, MultiArrayDimension
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
from visualization_msgs.msg import Marker, MarkerArray

from flex_twin.bag_cli import add_bag_parsers, cmd_record
from flex_twin.bags import (BagDamageWarning, BagError, BagWriter, Player, Recorder, bag_info,
                            read_bag)

T0_NS = 1_700_000_000_123_456_789
RELIABLE = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)
TIMEOUT_S = 10.0


def joint_state(i):
    m = JointState(name=["joint1", "joint2"], position=[0.1 * i, -2.5e-3 * i],
                   velocity=[1.0 + i, 2.0], effort=[])
    m.header.stamp.sec, m.header.stamp.nanosec, m.header.frame_id = 1000 + i, 999_999_999, "b"
    return m


def samples():
    """(topic, message) pairs of the five types under test."""
    arr = Float64MultiArray(data=[1.5, -2.25, 1e-300, 7.0])
    arr.layout.dim = [MultiArrayDimension(label="x", size=2, stride=4),
                      MultiArrayDimension(label="y", size=2, stride=2)]
    pose = PoseStamped()
    pose.header.frame_id = "world"
    pose.header.stamp.sec, pose.header.stamp.nanosec = 12, 345
    pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = 0.1, 0.2, 0.3
    pose.pose.orientation.z, pose.pose.orientation.w = 0.6, 0.8
    marker = Marker(ns="arm", id=7, type=Marker.LINE_STRIP, action=Marker.ADD, text="tip")
    marker.points = [PoseStamped().pose.position for _ in range(3)]
    marker.points[1].x, marker.points[2].y = 1.25, -0.5
    marker.scale.x, marker.color.r, marker.color.a = 0.01, 1.0, 0.5
    traj = JointTrajectory(joint_names=["joint1", "joint2"])
    traj.header.frame_id = "base"
    for k in range(4):
        p = JointTrajectoryPoint(positions=[0.1 * k, 0.2 * k], velocities=[1.0, -1.0],
                                 accelerations=[], effort=[])
        p.time_from_start.sec, p.time_from_start.nanosec = k, 250_000_000 * k
        traj.points.append(p)
    return [("/joint_states", joint_state(0)), ("/flex/deflections", arr),
            ("/tip_pose", pose), ("/markers", MarkerArray(markers=[marker, Marker(id=8)])),
            ("/trajectory", traj), ("/joint_states", joint_state(1)),
            ("/joint_states", joint_state(2))]


def assert_same(rc, rb, where="msg"):
    """Field-by-field exact equality of an rclpy message and a rosbags message."""
    if hasattr(rc, "get_fields_and_field_types"):
        for field in rc.get_fields_and_field_types():
            assert_same(getattr(rc, field), getattr(rb, field), f"{where}.{field}")
    elif isinstance(rc, list) and rc and hasattr(rc[0], "get_fields_and_field_types"):
        assert len(rc) == len(rb), where
        for k, (a, b) in enumerate(zip(rc, rb)):
            assert_same(a, b, f"{where}[{k}]")
    elif isinstance(rc, (list, array.array, np.ndarray)):
        assert np.array_equal(np.asarray(rc), np.asarray(rb)), f"{where}: {rc} != {rb}"
    else:
        assert rc == rb, f"{where}: {rc!r} != {rb!r}"


def write_samples(path):
    written = [(topic, msg, T0_NS + 1_000_003 * k) for k, (topic, msg) in enumerate(samples())]
    with BagWriter(path) as writer:
        for topic, msg, t_ns in written:
            writer.write(topic, msg, t_ns)
    return written


@pytest.fixture
def ros():
    """A private context, an executor and a node factory; shut down at the end."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    nodes = []

    def make_node(prefix):
        node = rclpy.create_node(f"{prefix}_{uuid.uuid4().hex[:8]}", context=ctx)
        executor.add_node(node)
        nodes.append(node)
        return node

    def spin_until(predicate, what, timeout=TIMEOUT_S):
        deadline = time.monotonic() + timeout
        while not predicate():
            assert time.monotonic() < deadline, f"timed out waiting for {what}"
            executor.spin_once(timeout_sec=0.01)
    yield make_node, spin_until
    executor.shutdown(timeout_sec=1.0)
    for node in nodes:
        node.destroy_node()
    rclpy.try_shutdown(context=ctx)


def test_round_trip_own_reader_and_rosbags(tmp_path):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
    bag = tmp_path / "bag"
    written = write_samples(bag)
    read = list(read_bag(bag))
    assert [(t, ts) for t, _, ts, _ in read] == [(t, ts) for t, _, ts in written]
    for (topic, type_str, _, msg), (_, orig, _) in zip(read, written):
        assert msg == orig, topic
        assert type(msg) is type(orig) and type_str.endswith("/" + type(orig).__name__)
    assert [m[3] for m in read_bag(bag, topics=["/joint_states"])] == [
        joint_state(i) for i in range(3)]

    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag) as reader:
        types = {c.topic: (c.msgtype, c.msgcount) for c in reader.connections}
        assert types == {"/joint_states": ("sensor_msgs/msg/JointState", 3),
                         "/flex/deflections": ("std_msgs/msg/Float64MultiArray", 1),
                         "/tip_pose": ("geometry_msgs/msg/PoseStamped", 1),
                         "/markers": ("visualization_msgs/msg/MarkerArray", 1),
                         "/trajectory": ("trajectory_msgs/msg/JointTrajectory", 1)}
        got = [(c.topic, t, store.deserialize_cdr(raw, c.msgtype))
               for c, t, raw in reader.messages()]
    assert [(t, ts) for t, ts, _ in got] == [(t, ts) for t, _, ts in written]
    for (topic, _, rb), (_, rc, _) in zip(got, written):
        assert_same(rc, rb, topic)


def test_metadata_v9_and_mcap_channels(tmp_path):
    from mcap.reader import make_reader
    bag = tmp_path / "bag"
    written = write_samples(bag)
    info = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == 9 and info["storage_identifier"] == "mcap"
    assert info["message_count"] == len(written) == 7
    counts = {t["topic_metadata"]["name"]: t["message_count"]
              for t in info["topics_with_message_count"]}
    assert counts == {"/joint_states": 3, "/flex/deflections": 1, "/tip_pose": 1,
                      "/markers": 1, "/trajectory": 1}
    assert info["starting_time"]["nanoseconds_since_epoch"] == T0_NS
    assert info["duration"]["nanoseconds"] == 6 * 1_000_003
    for t in info["topics_with_message_count"]:
        meta = t["topic_metadata"]
        assert meta["serialization_format"] == "cdr"
        assert meta["type_description_hash"].startswith("RIHS01_")
        assert meta["offered_qos_profiles"][0]["reliability"] == "reliable"
    (mcap_file,) = [bag / f for f in info["relative_file_paths"]]
    with open(mcap_file, "rb") as f:
        reader = make_reader(f)
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
    assert {s.encoding for s in summary.schemas.values()} == {"ros2msg"}
    for channel in summary.channels.values():
        assert channel.message_encoding == "cdr"
        assert yaml.safe_load(channel.metadata["offered_qos_profiles"])[0]["depth"] == 10
    assert sum(summary.statistics.channel_message_counts.values()) == 7


def test_writer_refuses_existing_non_empty_dir_and_bad_input(tmp_path):
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    with pytest.raises(BagError, match="not empty"):
        BagWriter(tmp_path / "full")
    (tmp_path / "empty").mkdir()
    with BagWriter(tmp_path / "empty") as writer:  # an empty directory is accepted
        with pytest.raises(BagError, match="not added"):
            writer.write("/raw", b"\x00\x01\x00\x00", 1)
        with pytest.raises(BagError, match="not one of the standard"):
            writer.add_topic("/x", "rcl_interfaces/msg/Log")
        with pytest.raises(BagError, match="t_ns"):
            writer.write("/js", joint_state(0), -1)
    with pytest.raises(BagError, match="no topic"):
        list(read_bag(tmp_path / "empty", topics=["/nope"]))


def test_bag_info_figures_and_cli_json(tmp_path, capsys):
    bag = tmp_path / "bag"
    rng = np.random.default_rng(1)
    times = {"/js": [T0_NS + 10_000_000 * k + int(rng.integers(-500_000, 500_000))
                     for k in range(201)],
             "/defl": [T0_NS + 300_000_000 + 100_000_000 * k for k in range(10)]}
    with BagWriter(bag) as writer:
        for t_ns in times["/js"]:
            writer.write("/js", joint_state(0), t_ns)
        for t_ns in times["/defl"]:
            writer.write("/defl", Float64MultiArray(data=[1.0]), t_ns)
    info = bag_info(bag)
    start, end = min(times["/js"]), max(times["/js"])
    assert info["duration_s"] == pytest.approx((end - start) * 1e-9, abs=1e-9)
    assert info["duration_s"] == pytest.approx(2.0, abs=2e-3)
    assert info["start_time_s"] == pytest.approx(start * 1e-9, abs=1e-6)
    topics = {t["name"]: t for t in info["topics"]}
    assert topics["/js"]["count"] == 201 and topics["/defl"]["count"] == 10
    assert topics["/js"]["type"] == "sensor_msgs/msg/JointState"
    assert topics["/js"]["frequency_hz"] == pytest.approx(100.0, rel=0.01)
    assert topics["/defl"]["frequency_hz"] == pytest.approx(10.0, rel=1e-9)
    assert info["message_count"] == 211 and info["version"] == 9

    parser = argparse.ArgumentParser()
    add_bag_parsers(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["bag", "info", str(bag), "--json"])
    assert args.func(args) == 0
    assert json.loads(capsys.readouterr().out) == json.loads(json.dumps(info))
    args = parser.parse_args(["bag", "info", str(bag)])
    assert args.func(args) == 0
    assert "/js" in capsys.readouterr().out


def test_recorder_in_process_receive_time_and_header_stamp(tmp_path, ros):
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore
    make_node, spin_until = ros
    pub_node, rec_node = make_node("pub"), make_node("rec")
    ns = f"/t{uuid.uuid4().hex[:8]}"
    js_pub = pub_node.create_publisher(JointState, f"{ns}/js", RELIABLE)
    arr_pub = pub_node.create_publisher(Float64MultiArray, f"{ns}/arr", RELIABLE)
    writer = BagWriter(tmp_path / "bag")
    recorder = Recorder(rec_node, writer, [f"{ns}/js", f"{ns}/arr"],
                        use_header_stamp={f"{ns}/js"})
    spin_until(lambda: js_pub.get_subscription_count() and arr_pub.get_subscription_count(),
               "discovery")
    t_before = rec_node.get_clock().now().nanoseconds
    for i in range(20):
        js_pub.publish(joint_state(i))
        arr_pub.publish(Float64MultiArray(data=[float(i), 2.0 * i]))
    spin_until(lambda: sum(writer.counts.values()) == 40, "40 recorded messages")
    recorder.stop()
    writer.close()
    rows = list(read_bag(tmp_path / "bag"))
    js = [(t, m) for topic, _, t, m in rows if topic.endswith("/js")]
    arr = [(t, m) for topic, _, t, m in rows if topic.endswith("/arr")]
    assert [m for _, m in js] == [joint_state(i) for i in range(20)]
    assert [t for t, _ in js] == [(1000 + i) * 1_000_000_000 + 999_999_999 for i in range(20)]
    assert [list(m.data) for _, m in arr] == [[float(i), 2.0 * i] for i in range(20)]
    assert all(t_before <= t <= t_before + int(TIMEOUT_S * 1e9) for t, _ in arr)
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(tmp_path / "bag") as reader:  # bytes from the wire decode with rosbags too
        decoded = [store.deserialize_cdr(raw, c.msgtype) for c, _, raw in reader.messages()]
    assert len(decoded) == 40
    meta = yaml.safe_load((tmp_path / "bag" / "metadata.yaml").read_text())
    hashes = {t["topic_metadata"]["name"]: t["topic_metadata"]["type_description_hash"]
              for t in meta["rosbag2_bagfile_information"]["topics_with_message_count"]}
    graph = rec_node.get_publishers_info_by_topic(f"{ns}/js")[0].topic_type_hash
    assert hashes[f"{ns}/js"] == str(graph)  # the typestore hash is the one on the wire


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_record_subprocess_stopped_by_signal_leaves_readable_bag(tmp_path, ros, repo_root, sig):
    from rosbags.rosbag2 import Reader
    make_node, spin_until = ros
    node = make_node("src")
    topic = f"/t{uuid.uuid4().hex[:8]}/joint_states"
    pub = node.create_publisher(JointState, topic, RELIABLE)
    bag = tmp_path / "bag"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(repo_root / "src" / "flex_model"), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-m", "flex_twin.bag_cli", "record", topic,
                             "--output", str(bag)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        spin_until(lambda: pub.get_subscription_count() > 0 or proc.poll() is not None,
                   "the recorder's subscription", timeout=20.0)
        assert proc.poll() is None, proc.communicate()
        for i in range(50):
            pub.publish(joint_state(i))
            time.sleep(0.002)
        time.sleep(0.5)  # let the recorder take the 50 messages; it is still recording
        proc.send_signal(sig)
        out, err = proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert "recorded 50 message(s)" in out
    assert [m for _, _, _, m in read_bag(bag)] == [joint_state(i) for i in range(50)]
    with Reader(bag) as reader:
        assert [(c.topic, c.msgcount) for c in reader.connections] == [(topic, 50)]
    assert bag_info(bag)["topics"][0]["count"] == 50


def _record_subprocess(repo_root, *args):
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(repo_root / "src" / "flex_model"), os.environ.get("PYTHONPATH", "")]))
    return subprocess.Popen([sys.executable, "-m", "flex_twin.bag_cli", "record", *args],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def test_record_killed_keeps_all_but_the_last_second(tmp_path, ros, repo_root):
    """SIGKILL of ``record`` after 5 s of a 100 Hz topic: every chunk closed (0.5 s) is on
    disk; the bag (no metadata.yaml, no MCAP summary) is reindexed on reading."""
    make_node, spin_until = ros
    node = make_node("src")
    topic = f"/t{uuid.uuid4().hex[:8]}/joint_states"
    pub = node.create_publisher(JointState, topic, RELIABLE)
    bag = tmp_path / "bag"
    proc = _record_subprocess(repo_root, topic, "-o", str(bag))
    try:
        spin_until(lambda: pub.get_subscription_count() > 0 or proc.poll() is not None,
                   "the recorder's subscription", timeout=20.0)
        assert proc.poll() is None, proc.communicate()
        t0, sent = time.monotonic(), 0
        while time.monotonic() - t0 < 5.0:  # 100 Hz for 5 s
            pub.publish(joint_state(sent))
            sent += 1
            time.sleep(max(0.0, t0 + 0.01 * sent - time.monotonic()))
        proc.kill()
        proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == -signal.SIGKILL
    assert not (bag / "metadata.yaml").exists()  # killed: nothing written at exit
    with pytest.warns(BagDamageWarning, match="no metadata.yaml.*no footer"):
        got = [m for _, _, _, m in read_bag(bag)]
    assert got == [joint_state(i) for i in range(len(got))]  # in order, none missing
    print(f"SIGKILL after 5 s: kept {len(got)} of {sent} messages")
    assert len(got) >= sent - 100, f"kept {len(got)} of {sent}"  # all but the last second
    with pytest.warns(BagDamageWarning):
        info = bag_info(bag)
    assert info["message_count"] == len(got) and info["topics"][0]["name"] == topic
    assert info["duration_s"] >= (len(got) - 1) * 0.01 * 0.9


def test_record_keeps_latched_messages_published_before_and_after_its_start(
        tmp_path, ros, repo_root):
    """Transient-local topics are subscribed transient-local once their publisher is seen,
    so a latched message published before the recorder started (or before it discovered the
    publisher) is recorded; a volatile topic stays volatile."""
    make_node, spin_until = ros
    node = make_node("latch")
    ns = f"/t{uuid.uuid4().hex[:8]}"
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    early = node.create_publisher(JointState, f"{ns}/early", latched)
    early.publish(joint_state(1))
    bag = tmp_path / "bag"
    proc = _record_subprocess(repo_root, f"{ns}/early=sensor_msgs/msg/JointState",
                              f"{ns}/late=sensor_msgs/msg/JointState",
                              f"{ns}/plain=sensor_msgs/msg/JointState", "-o", str(bag))
    try:
        first = proc.stderr.readline()
        assert first.startswith("recording 3 topic(s)"), first
        late = node.create_publisher(JointState, f"{ns}/late", latched)
        late.publish(joint_state(2))  # before the recorder has discovered this publisher
        plain = node.create_publisher(JointState, f"{ns}/plain", RELIABLE)
        spin_until(lambda: all(p.get_subscription_count() for p in (early, late, plain))
                   or proc.poll() is not None, "the recorder's subscriptions", timeout=20.0)
        plain.publish(joint_state(3))
        time.sleep(0.5)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    got = {topic: m for topic, _, _, m in read_bag(bag)}
    assert got == {f"{ns}/early": joint_state(1), f"{ns}/late": joint_state(2),
                   f"{ns}/plain": joint_state(3)}
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    durability = {t["topic_metadata"]["name"]:
                  t["topic_metadata"]["offered_qos_profiles"][0]["durability"]
                  for t in meta["topics_with_message_count"]}
    assert durability == {f"{ns}/early": "transient_local", f"{ns}/late": "transient_local",
                          f"{ns}/plain": "volatile"}


def test_record_all_picks_up_a_topic_published_after_the_start(tmp_path, ros, repo_root):
    make_node, spin_until = ros
    topic = f"/t{uuid.uuid4().hex[:8]}/late"
    bag = tmp_path / "bag"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(repo_root / "src" / "flex_model"), os.environ.get("PYTHONPATH", "")]))
    proc = subprocess.Popen([sys.executable, "-m", "flex_twin.bag_cli", "record", "--all",
                             "--duration", "60", "--discovery-time", "0.2", "-o", str(bag)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # the topic must appear after the recorder's start-up scan (a loaded machine can take
        # longer than any fixed sleep to start Python): wait for its first line
        first = proc.stderr.readline()
        assert first.startswith("recording "), first
        pub = make_node("late").create_publisher(JointState, topic, RELIABLE)
        spin_until(lambda: pub.get_subscription_count() > 0, "the late subscription",
                   timeout=20.0)
        for i in range(10):
            pub.publish(joint_state(i))
        time.sleep(0.5)  # let the recorder take the 10 messages, then stop it (Ctrl-C)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=15)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, err
    assert topic not in first and f"recording new topic {topic}" in err
    assert [m for t, _, _, m in read_bag(bag) if t == topic] == [
        joint_state(i) for i in range(10)]


def test_record_command_stops_after_duration(tmp_path):
    args = argparse.Namespace(topics=["/idle=std_msgs/msg/Float64MultiArray"], all=False,
                              output=str(tmp_path / "bag"), duration=0.4,
                              use_header_stamp=(), discovery_time=1.0,
                              discovery_timeout=1.0)
    t0 = time.monotonic()
    assert cmd_record(args) == 0
    assert 0.4 <= time.monotonic() - t0 < 5.0
    info = bag_info(tmp_path / "bag")
    assert info["topics"] == [{"name": "/idle", "type": "std_msgs/msg/Float64MultiArray",
                               "count": 0, "frequency_hz": None}]


def test_player_republishes_in_order_with_clock_and_loop(tmp_path, ros):
    from rosgraph_msgs.msg import Clock
    make_node, spin_until = ros
    ns = f"/t{uuid.uuid4().hex[:8]}"
    times = [T0_NS + 7_000_000 * k for k in range(30)]
    with BagWriter(tmp_path / "bag") as writer:
        for k, t_ns in enumerate(times):
            if k % 3:
                writer.write(f"{ns}/js", joint_state(k), t_ns)
            else:
                writer.write(f"{ns}/arr", Float64MultiArray(data=[float(k)]), t_ns)
    sub_node, play_node = make_node("sub"), make_node("play")
    got, clocks = [], []
    sub_node.create_subscription(JointState, f"{ns}/js", lambda m: got.append(m), RELIABLE)
    sub_node.create_subscription(Float64MultiArray, f"{ns}/arr", got.append, RELIABLE)
    sub_node.create_subscription(Clock, "/clock", clocks.append, RELIABLE)
    player = Player(play_node, tmp_path / "bag", clock=True, loop=True)
    spin_until(lambda: all(p.get_subscription_count() for p in player.publishers.values()),
               "discovery")
    spin_until(lambda: sub_node.count_publishers("/clock") > 0, "clock discovery")
    for k in range(30):
        assert player.step() == (f"{ns}/arr" if k % 3 == 0 else f"{ns}/js", times[k])
        spin_until(lambda: len(got) == k + 1, f"message {k}")
    assert got == [m for _, _, _, m in read_bag(tmp_path / "bag")]
    spin_until(lambda: len(clocks) == 30, "30 clock messages")
    assert [c.clock.sec * 10**9 + c.clock.nanosec for c in clocks] == times
    assert player.step() == (f"{ns}/arr", times[0])  # loop: back to the first message


@pytest.mark.parametrize("rate", [2.0])
def test_player_rate_scales_wall_duration(tmp_path, ros, rate):
    make_node, _ = ros
    with BagWriter(tmp_path / "bag") as writer:
        for k in range(61):
            writer.write("/js", joint_state(k), T0_NS + 10_000_000 * k)  # a 0.6 s bag
    player = Player(make_node("play"), tmp_path / "bag", rate=rate, topics=["/js"])
    t0 = time.monotonic()
    assert player.play_all(realtime=True) == 61
    wall = time.monotonic() - t0
    assert wall == pytest.approx(0.6 / rate, rel=0.2)
    fast = Player(make_node("fast"), tmp_path / "bag")
    t0 = time.monotonic()
    assert fast.play_all(realtime=False) == 61
    assert time.monotonic() - t0 < 0.3


def test_play_command_with_rate_and_topic_selection(tmp_path, capsys):
    with BagWriter(tmp_path / "bag") as writer:
        for k in range(21):
            writer.write("/js", joint_state(k), T0_NS + 10_000_000 * k)  # 0.2 s
            writer.write("/arr", Float64MultiArray(data=[1.0]), T0_NS + 10_000_000 * k + 1)
    parser = argparse.ArgumentParser()
    add_bag_parsers(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["play", str(tmp_path / "bag"), "--rate", "4", "--topics", "/js",
                              "--clock", "--delay", "0"])
    assert args.func(args) == 0
    out = capsys.readouterr().out
    assert "published 21 message(s)" in out
    assert 0.04 <= float(out.split(" in ")[1].split()[0]) < 0.1  # 0.2 s / 4 = 0.05 s
    with pytest.raises(BagError, match="no topic"):
        args.func(parser.parse_args(["play", str(tmp_path / "bag"), "--topics", "/x"]))


def test_recorder_use_sim_time_stamps_with_the_latest_clock(tmp_path, ros):
    """Sim-time recording (``record --use-sim-time``, the twin demo): log time = the latest
    /clock; /clock itself by its value; a message before the first /clock gets that first
    value; so a lockstep bag spans the simulated time, not the wall clock."""
    from rosgraph_msgs.msg import Clock
    make_node, spin_until = ros
    pub_node, rec_node = make_node("pub"), make_node("rec")
    ns = f"/t{uuid.uuid4().hex[:8]}"
    js_pub = pub_node.create_publisher(JointState, f"{ns}/js", RELIABLE)
    clock_pub = pub_node.create_publisher(Clock, "/clock", RELIABLE)
    writer = BagWriter(tmp_path / "bag")
    recorder = Recorder(rec_node, writer, {f"{ns}/js": "sensor_msgs/msg/JointState",
                                           "/clock": "rosgraph_msgs/msg/Clock"},
                        use_sim_time=True)
    spin_until(lambda: js_pub.get_subscription_count() and clock_pub.get_subscription_count()
               >= 2, "discovery")

    def clock(t_ns):
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = divmod(t_ns, 1_000_000_000)
        clock_pub.publish(msg)
        spin_until(lambda: recorder.sim_time_ns == t_ns, f"clock {t_ns}")
    js_pub.publish(joint_state(0))  # before any /clock: held for the first one
    spin_until(lambda: len(recorder._early) == 1, "the early message")
    sim = [10_000_000_000 + 2_000_000 * k for k in range(5)]
    for k, t_ns in enumerate(sim):
        clock(t_ns)
        js_pub.publish(joint_state(k + 1))
        spin_until(lambda: writer.counts[f"{ns}/js"] == k + 2, f"message {k + 1}")
    spin_until(lambda: writer.counts["/clock"] == 5, "the recorded /clock")
    recorder.stop()
    writer.close()
    rows = [(topic, t) for topic, _, t, _ in read_bag(tmp_path / "bag")]
    assert [t for topic, t in rows if topic == "/clock"] == sim
    assert [t for topic, t in rows if topic.endswith("/js")] == [sim[0]] + sim
    info = bag_info(tmp_path / "bag")
    assert info["duration_s"] == pytest.approx(4 * 0.002) and info["warnings"] == []


def test_player_clock_replaces_a_recorded_clock(tmp_path, ros):
    """``play --clock``: one /clock, the player's (from the log times); the recorded /clock
    is not republished beside it. Without ``--clock`` it is played as any topic."""
    from rosgraph_msgs.msg import Clock
    make_node, spin_until = ros
    ns = f"/t{uuid.uuid4().hex[:8]}"
    times = [2_000_000 * k for k in range(20)]  # sim time from 0
    with BagWriter(tmp_path / "bag") as writer:
        for k, t_ns in enumerate(times):
            msg = Clock()
            msg.clock.nanosec = t_ns
            writer.write("/clock", msg, t_ns)
            writer.write(f"{ns}/js", joint_state(k), t_ns)
    sub_node = make_node("sub")
    got, clocks = [], []
    sub_node.create_subscription(JointState, f"{ns}/js", got.append, RELIABLE)
    sub_node.create_subscription(Clock, "/clock", clocks.append, RELIABLE)
    player = Player(make_node("play"), tmp_path / "bag", clock=True)
    assert set(player.publishers) == {f"{ns}/js"}
    spin_until(lambda: player.publishers[f"{ns}/js"].get_subscription_count()
               and sub_node.count_publishers("/clock") == 1, "discovery")
    while player.step() is not None:
        pass
    spin_until(lambda: len(got) == 20 and len(clocks) == 20, "20 messages and clocks")
    stamps = [c.clock.sec * 10**9 + c.clock.nanosec for c in clocks]
    assert stamps == times  # one clock, in order, no interleaved second clock
    assert "/clock" in Player(make_node("plain"), tmp_path / "bag").publishers


def test_mixed_time_bases_are_warned_and_refused_by_play(tmp_path, ros):
    """A bag whose topics mix sim time (from 0) and wall-clock log times (the old twin-demo
    bag: 1.8e9 s 'duration'): bag_info warns, play refuses unless one base is selected."""
    make_node, _ = ros
    with BagWriter(tmp_path / "bag") as writer:
        for k in range(10):
            writer.write("/sim", joint_state(k), 2_000_000 * k)
            writer.write("/wall", Float64MultiArray(data=[1.0]), T0_NS + 2_000_000 * k)
    info = bag_info(tmp_path / "bag")
    assert [w for w in info["warnings"] if "mixed time bases" in w and "/sim" in w]
    with pytest.raises(BagError, match="mixed time bases"):
        Player(make_node("play"), tmp_path / "bag")
    assert Player(make_node("one"), tmp_path / "bag", topics=["/sim"]).bag_span_ns == 18_000_000


def test_recorder_reads_stamps_from_the_bytes():
    """The recorder's stamp of a serialized message (no deserialization): header.stamp of
    a stamped type, the time of a Clock, as rclpy's deserialization gives it; types that
    do not start with a stamp are not read so."""
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock

    from flex_twin.bags.recorder import leading_stamp_ns, starts_with_stamp
    js = JointState(name=["joint1"], position=[1.5])
    js.header.stamp.sec, js.header.stamp.nanosec = 1234, 567_890_123
    clock = Clock()
    clock.clock.sec, clock.clock.nanosec = -2, 999_999_999
    assert leading_stamp_ns(serialize_message(js)) == 1234_567_890_123
    assert leading_stamp_ns(serialize_message(clock)) == -1_000_000_001
    assert starts_with_stamp(JointState) and starts_with_stamp(Clock)
    assert not starts_with_stamp(Float64MultiArray)
