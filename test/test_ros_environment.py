"""The venv's rclpy works in-process, on this host only, with a private context and topic."""
import os
import time
import uuid

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

TIMEOUT_S = 5.0


def test_discovery_is_localhost_only():
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert 0 < int(os.environ["ROS_DOMAIN_ID"]) <= 232


def test_joint_state_round_trip():
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    sent_names = ["joint_1", "joint_2", "joint_3"]
    sent_positions = [0.1, -1.2345678901234567, 3.0e-9]
    topic = f"/flex_twin_test/joint_states_{os.getpid()}_{uuid.uuid4().hex[:8]}"
    qos = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE)

    context = rclpy.Context()
    rclpy.init(context=context)
    executor = node = None
    try:
        assert context.get_domain_id() == int(os.environ["ROS_DOMAIN_ID"])
        node = rclpy.create_node(f"flex_twin_env_probe_{os.getpid()}", context=context)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        received = []
        node.create_subscription(JointState, topic, received.append, qos)
        publisher = node.create_publisher(JointState, topic, qos)

        msg = JointState()
        msg.header.stamp = node.get_clock().now().to_msg()
        msg.name = list(sent_names)
        msg.position = list(sent_positions)

        deadline = time.monotonic() + TIMEOUT_S
        while not received and time.monotonic() < deadline:
            if publisher.get_subscription_count() > 0:
                publisher.publish(msg)
            executor.spin_once(timeout_sec=0.05)

        assert received, f"no JointState on {topic} within {TIMEOUT_S} s"
        assert list(received[0].name) == sent_names
        assert list(received[0].position) == sent_positions  # exact, no tolerance
    finally:
        if executor is not None:
            executor.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=context)
