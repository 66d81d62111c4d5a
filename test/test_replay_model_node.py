"""Replay test 1 of the suite: the model node in lockstep, fed the effort commands of a
golden bag, reproduces the bag's /joint_states and /flex/deflections to 1e-9.

The golden bag (test/data/bags/model_lockstep) is written only by
``python test/tools/make_golden_bags.py --force``; it is read here with the independent
``rosbags`` library. Tolerances: 1e-9 rad, rad/s, m (the node and the recording run the
same arithmetic; the bound leaves room for message round trips only).
"""
import time
import uuid
from pathlib import Path

import numpy as np
import rclpy
import yaml
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from flex_model.ros.model_node import ModelNode

BAG = Path(__file__).resolve().parent / "data" / "bags" / "model_lockstep"
TOL = 1e-9


def read_golden():
    store = get_typestore(Stores.ROS2_JAZZY)
    out = {"/joint_states": [], "/flex/deflections": [], "/effort_controller/commands": []}
    with Reader(BAG) as reader:
        for conn, t_ns, raw in reader.messages():
            out[conn.topic].append((t_ns, store.deserialize_cdr(raw, conn.msgtype)))
    return out


def test_model_node_replays_the_golden_bag():
    params = yaml.safe_load((BAG / "provenance.yaml").read_text())["parameters"]
    golden = read_golden()
    assert len(golden["/effort_controller/commands"]) == params["steps"]
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        ns = f"/r{uuid.uuid4().hex[:8]}"  # relative topics: the probe shares the namespace
        node = ModelNode(context=ctx, namespace=ns,
                         parameter_overrides=[
                             Parameter("arm", value=params["arm"]),
                             Parameter("mode", value="lockstep"),
                             Parameter("rate", value=params["rate"]),
                             Parameter("publish_rate", value=params["rate"]),
                             Parameter("lockstep_timeout", value=30.0),
                             Parameter("initial_joint_angles_deg",
                                       value=params["initial_joint_angles_deg"])])
        probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=ctx, namespace=ns)
        states, defl = {}, {}

        def keep(store):
            return lambda m: store.setdefault(
                m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, m)
        probe.create_subscription(JointState, "joint_states", keep(states), 200)
        probe.create_subscription(JointState, "flex/deflections", keep(defl), 200)
        cmd = probe.create_publisher(Float64MultiArray, "effort_controller/commands", 200)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(probe)

        def spin_until(pred, what):
            end = time.monotonic() + 20.0
            while not pred():
                assert time.monotonic() < end, f"timed out waiting for {what}"
                ex.spin_once(timeout_sec=0.005)
        spin_until(lambda: cmd.get_subscription_count() > 0, "discovery")
        step_ns = int(round(1e9 / params["rate"]))
        for k, (t_ns, msg) in enumerate(golden["/effort_controller/commands"]):
            cmd.publish(Float64MultiArray(data=[float(x) for x in msg.data]))
            spin_until(lambda: (k + 1) * step_ns in states and (k + 1) * step_ns in defl,
                       f"state {k + 1}")
        for topic, got in (("/joint_states", states), ("/flex/deflections", defl)):
            for t_ns, want in golden[topic][1:]:
                m = got[t_ns]
                assert list(m.name) == list(want.name)
                np.testing.assert_allclose(m.position, want.position, rtol=0, atol=TOL)
                np.testing.assert_allclose(m.velocity, want.velocity, rtol=0, atol=TOL)
                if topic == "/joint_states":
                    np.testing.assert_allclose(m.effort, want.effort, rtol=0, atol=TOL)
        ex.shutdown()
        node.destroy_node()
        probe.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
