"""Replay test 2 of the suite: the controller node fed a golden bag's reference and joint
states reproduces the bag's commands (thesis Eq. 95) to 1e-12 N m.

Golden bag test/data/bags/controller_hold, written only by
``python test/tools/make_golden_bags.py --force``; read with the independent ``rosbags``.
The node computes on its own timer from the latest state, so each recorded state is sent
and the node's commands are watched until one equals the recorded command for it.
"""
import time
import uuid
from pathlib import Path

import numpy as np
import rclpy
import yaml
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flex_control.controller_node import ControllerNode

BAG = Path(__file__).resolve().parent / "data" / "bags" / "controller_hold"


def test_controller_node_replays_the_golden_bag():
    params = yaml.safe_load((BAG / "provenance.yaml").read_text())["parameters"]
    store = get_typestore(Stores.ROS2_JAZZY)
    rec = {"/flex_planner/trajectory": [], "/joint_states": [],
           "/effort_controller/commands": []}
    with Reader(BAG) as reader:
        for conn, _, raw in reader.messages():
            rec[conn.topic].append(store.deserialize_cdr(raw, conn.msgtype))
    assert len(rec["/joint_states"]) == len(rec["/effort_controller/commands"]) == 101
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        ns = f"/c{uuid.uuid4().hex[:8]}"
        node = ControllerNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter("h", value=params["h"]), Parameter("a", value=params["a"]),
            Parameter("torque_limits", value=params["torque_limits"]),
            Parameter("state_timeout", value=30.0)])
        probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=ctx, namespace=ns)
        qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
        commands = []
        probe.create_subscription(Float64MultiArray, "effort_controller/commands",
                                  lambda m: commands.append(np.array(m.data)), qos)
        js = probe.create_publisher(JointState, "joint_states", qos)
        traj = probe.create_publisher(JointTrajectory, "flex_planner/trajectory", qos)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(probe)

        def spin_until(pred, what, timeout=10.0):
            end = time.monotonic() + timeout
            while not pred():
                assert time.monotonic() < end, f"timed out waiting for {what}"
                ex.spin_once(timeout_sec=0.002)
        spin_until(lambda: js.get_subscription_count() and traj.get_subscription_count(),
                   "discovery")
        t = rec["/flex_planner/trajectory"][0]
        traj.publish(JointTrajectory(joint_names=list(t.joint_names), points=[
            JointTrajectoryPoint(positions=list(p.positions), velocities=list(p.velocities),
                                 effort=list(p.effort)) for p in t.points]))
        for k, (s, want) in enumerate(zip(rec["/joint_states"],
                                          rec["/effort_controller/commands"])):
            js.publish(JointState(name=list(s.name), position=list(s.position),
                                  velocity=list(s.velocity)))
            spin_until(lambda: commands and np.allclose(commands[-1], want.data, rtol=0,
                                                        atol=1e-12), f"command {k}")
        ex.shutdown()
        node.destroy_node()
        probe.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
