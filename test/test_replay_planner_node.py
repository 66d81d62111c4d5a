"""Replay test 3 of the suite: the planner node fed a golden bag's waypoints reproduces the
bag's joint trajectory (positions, velocities, accelerations, nominal torques, times).

Golden bag test/data/bags/planner_short, written only by
``python test/tools/make_golden_bags.py --force``; read with the independent ``rosbags``.
Tolerance 1e-9 (rad, rad/s, rad/s^2, N m, s).
"""
import time
import uuid
from pathlib import Path

import numpy as np
import rclpy
import yaml
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from trajectory_msgs.msg import JointTrajectory

from flex_planner.planner_node import PlannerNode

BAG = Path(__file__).resolve().parent / "data" / "bags" / "planner_short"


def arrays(points, field):
    return np.array([list(getattr(p, field)) for p in points])


def test_planner_node_replays_the_golden_bag():
    params = yaml.safe_load((BAG / "provenance.yaml").read_text())["parameters"]
    store = get_typestore(Stores.ROS2_JAZZY)
    rec = {}
    with Reader(BAG) as reader:
        for conn, _, raw in reader.messages():
            rec[conn.topic] = store.deserialize_cdr(raw, conn.msgtype)
    want = rec["/flex_planner/trajectory"]
    assert len(want.points) == 101
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        ns = f"/p{uuid.uuid4().hex[:8]}"
        node = PlannerNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter("arm", value=params["arm"]),
            Parameter("sample_period", value=params["sample_period"])])
        probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=ctx, namespace=ns)
        qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
        got = []
        probe.create_subscription(JointTrajectory, "flex_planner/trajectory", got.append, qos)
        pub = probe.create_publisher(PathMsg, "flex_planner/waypoints", qos)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(probe)

        def spin_until(pred, what, timeout=60.0):
            end = time.monotonic() + timeout
            while not pred():
                assert time.monotonic() < end, f"timed out waiting for {what}"
                ex.spin_once(timeout_sec=0.01)
        spin_until(lambda: pub.get_subscription_count() and node.count_publishers(
            f"{ns}/flex_planner/trajectory") and probe.count_subscribers(
            f"{ns}/flex_planner/trajectory"), "discovery")
        w = rec["/flex_planner/waypoints"]
        msg = PathMsg()
        msg.header.frame_id = w.header.frame_id
        for p in w.poses:
            pose = PoseStamped()
            pose.header.frame_id = p.header.frame_id
            pose.header.stamp.sec, pose.header.stamp.nanosec = p.header.stamp.sec, \
                p.header.stamp.nanosec
            pose.pose.position.x, pose.pose.position.y = p.pose.position.x, p.pose.position.y
            pose.pose.orientation.w = p.pose.orientation.w
            msg.poses.append(pose)
        pub.publish(msg)
        spin_until(lambda: got, "the trajectory")
        out = got[-1]
        assert list(out.joint_names) == list(want.joint_names)
        for field in ("positions", "velocities", "accelerations", "effort"):
            np.testing.assert_allclose(arrays(out.points, field), arrays(want.points, field),
                                       rtol=0, atol=1e-9)
        t_out = [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in out.points]
        t_want = [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
                  for p in want.points]
        np.testing.assert_allclose(t_out, t_want, rtol=0, atol=1e-9)
        ex.shutdown()
        node.destroy_node()
        probe.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
