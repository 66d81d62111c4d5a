"""The model node publishes its state topics as bytes from CDR templates
(flex_model.ros.cdr_messages): every publication is the message the object path built before
(ros_conversions.fill_joint_state, fill_deflection_state, fill_tip_pose, imu, from the
stepper's joint_state, deflections, tip_pose, tip_specific_force), byte for byte, and a
subscriber decodes it to that message. Lockstep with Eq. 95 in the loop, an arm with a
tip accelerometer, publishing at 250 Hz, /flex/shape at 50 Hz; /flex/shape and
/flex/tip_imu (costly to compute) are skipped while nobody subscribes."""
import time
import uuid

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Header
from visualization_msgs.msg import MarkerArray

from flex_model.ros import conversions as conv
from flex_model import urdf
from flex_model.arm import resolve_preset
from flex_model.ros.cdr_messages import encode


def reference(node, topic):
    """The message the node published on ``topic`` before the templates (object path)."""
    st, t = node.stepper, node.stepper.t
    if topic == "joint_states":
        return conv.fill_joint_state(JointState(name=list(node.names)), t, *st.joint_state())
    if topic == "clock":
        return Clock(clock=conv.stamp(t))
    if topic == "flex/deflections":
        return conv.fill_deflection_state(
            JointState(name=conv.deflection_names(node.links)), t, *st.deflections())
    x, y, phi = st.tip_pose()
    if topic == "flex/tip_pose":
        return conv.fill_tip_pose(PoseStamped(header=Header(frame_id=node.frames.base)),
                                  t, x, y, phi, node.plane)
    rate = float(node.model.tip_torque_vector() @ st.v)
    orientation = urdf.quaternion_from_matrix(
        node.plane @ urdf.matrix_from_quaternion(urdf.yaw_quaternion(phi)))
    return conv.imu(t, st.tip_specific_force(), rate, phi, node.frames.tips[-1], orientation)


def test_published_bytes_are_the_object_path_messages(tmp_path):
    arm = tmp_path / "imu_arm.yaml"
    arm.write_text(resolve_preset("thesis_example1_motors").read_text()
                   + "sensors:\n  - {kind: tip_accelerometer}\n")
    from flex_model.ros.model_node import ModelNode
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        ns = f"/b{uuid.uuid4().hex[:8]}"
        node = ModelNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter("arm", value=str(arm)), Parameter("mode", value="lockstep"),
            Parameter("controller", value="eq95"), Parameter("start_paused", value=True),
            Parameter("controller_params.h", value=[25.0]),
            Parameter("controller_params.a", value=[5.0]),
            Parameter("initial_joint_angles_deg", value=[40.0, -30.0]),
            Parameter("clock_topic", value="clock")])
        pubs = {"joint_states": node.pub_js, "clock": node.pub_clock,
                "flex/deflections": node.pub_defl, "flex/tip_pose": node.pub_tip,
                "flex/tip_imu": node.pub_imu}
        sent = {k: [] for k in pubs}
        for topic, pub in pubs.items():
            def capture(raw, topic=topic, publish=pub.publish):
                assert isinstance(raw, bytes)
                ref = reference(node, topic)
                assert raw == encode(ref), topic  # byte for byte (padding zero)
                sent[topic].append(ref)
                publish(raw)
            pub.publish = capture
        shapes = []
        shape_publish = node.pub_shape.publish
        node.pub_shape.publish = lambda raw: (shapes.append(node.stepper.t),
                                              shape_publish(raw))
        period = node.loop.period
        node.step(2 * period)  # nobody listens: /flex/shape and /flex/tip_imu are skipped
        assert shapes == [] and sent["flex/tip_imu"] == [] and len(sent["clock"]) == 1
        for v in sent.values():
            v.clear()
        probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=ctx, namespace=ns)
        got = {k: [] for k in pubs}
        for topic, kind in (("joint_states", JointState), ("clock", Clock),
                            ("flex/deflections", JointState), ("flex/tip_pose", PoseStamped),
                            ("flex/tip_imu", Imu)):
            probe.create_subscription(kind, topic, got[topic].append, 100)
        probe.create_subscription(MarkerArray, "flex/shape", lambda m: None, 10)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(probe)
        end = time.monotonic() + 20.0
        while not all(p.get_subscription_count() for p in (*pubs.values(), node.pub_shape)):
            assert time.monotonic() < end, "discovery"
            ex.spin_once(timeout_sec=0.01)
        for _ in range(12):  # 250 Hz: one publication every other 500 Hz period
            node.step(2 * period)
        while min(len(v) for v in got.values()) < 12:
            assert time.monotonic() < end, {k: len(v) for k, v in got.items()}
            ex.spin_once(timeout_sec=0.01)
        assert np.allclose(shapes, [0.024, 0.044])  # 50 Hz of 250 (0.004 skipped)
        for topic in pubs:
            assert len(sent[topic]) == 12
            for mine, ref in zip(got[topic], sent[topic]):
                assert encode(mine) == encode(ref), topic  # decoded to the same message
        js = got["joint_states"][-1]
        assert js.header.stamp.nanosec == 52_000_000 and len(js.effort) == 2
        assert abs(js.position[0] - np.radians(40.0)) < 0.05
    finally:
        rclpy.try_shutdown(context=ctx)
