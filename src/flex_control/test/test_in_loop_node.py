"""The model node with an in-loop controller (issue 24): Eq. (95) runs inside the model's
update loop (no DDS round trip per period), takes its trajectory over ROS, and the arm it
publishes is the core ControlLoop's, bit for bit."""
import time
import uuid

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Duration
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flex_control.laws import hold_reference
from flex_model.arm import load_arm
from flex_model.control_loop import ControlLoop
from flex_model.controller_interface import load_controller
from flex_model.dynamics import FlexArmModel
from flex_model.ros.model_node import ModelNode
from flex_model.ros.main import ParameterError
from flex_model.stepper import Stepper

ARM = "thesis_example1_motors"
GOAL = [20.0, -10.0]


def _node(ctx, ns, **params):
    return ModelNode(context=ctx, namespace=ns, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()])


def test_lockstep_in_loop_eq95_follows_a_trajectory_and_equals_the_core_loop():
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    ns = f"/l{uuid.uuid4().hex[:8]}"
    try:
        node = _node(ctx, ns, arm=ARM, mode="lockstep", controller="eq95",
                     controller_rate=500.0, publish_rate=50.0, start_paused=True,
                     **{"controller_params.h": [25.0], "controller_params.a": [5.0]})
        probe = rclpy.create_node(f"p{uuid.uuid4().hex[:8]}", context=ctx, namespace=ns)
        states = []
        probe.create_subscription(JointState, "joint_states", states.append, 1000)
        traj_pub = probe.create_publisher(JointTrajectory, "flex_planner/trajectory", 1)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(probe)

        def spin_until(pred, what, timeout=60.0):
            end = time.monotonic() + timeout
            while not pred():
                assert time.monotonic() < end, f"timed out waiting for {what}"
                ex.spin_once(timeout_sec=0.01)
        spin_until(lambda: traj_pub.get_subscription_count() > 0, "discovery")
        msg = JointTrajectory(joint_names=["joint1", "joint2"])
        msg.points = [JointTrajectoryPoint(positions=list(np.radians(GOAL)),
                                           time_from_start=Duration(sec=0))]
        traj_pub.publish(msg)
        spin_until(lambda: node.loop.controller.pending is not None, "the trajectory")
        node.paused = False  # start the loop now that the reference is set
        spin_until(lambda: node.stepper.t >= 2.0, "2 s of simulation", timeout=120.0)
        node.paused = True
        t_node = node.stepper.t
        # an external command is refused while the in-loop controller drives the arm
        u = node.stepper.u.copy()
        node.on_command(Float64MultiArray(data=[1.0, 1.0]))
        np.testing.assert_array_equal(node.stepper.u, u)
        # published at publish_rate (every 20 ms of simulation), not every period
        stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in states]
        assert np.allclose(np.diff(stamps[1:]), 0.02, atol=1e-9)
        # the same arm, controller and periods in the core loop
        model = FlexArmModel(load_arm(ARM))
        ctl = load_controller("eq95", ["joint1", "joint2"], {"h": [25.0], "a": [5.0]})
        ctl.set_trajectory(hold_reference(["joint1", "joint2"], np.radians(GOAL)))
        loop = ControlLoop(Stepper(model), ctl, 2e-3)
        loop.advance(int(round(t_node / 2e-3)))
        np.testing.assert_array_equal(node.stepper.x, loop.stepper.x)
        # and it followed the trajectory from 0 deg: joint 1 within 2 deg of its goal after
        # 2 s (the PD without gravity feed-forward sags 1.6 deg)
        assert abs(np.degrees(model.joint_angles(node.stepper.q)[0]) - GOAL[0]) < 2.0
    finally:
        rclpy.try_shutdown(context=ctx)


def test_a_bad_in_loop_controller_is_one_line():
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        with pytest.raises(ParameterError, match="controller: got 'eq96'; expected one of"):
            _node(ctx, "/bad1", arm=ARM, controller="eq96")
        with pytest.raises(ParameterError, match="h: got"):
            _node(ctx, "/bad2", arm=ARM, controller="eq95", **{"controller_params.h": [-1.0]})
    finally:
        rclpy.try_shutdown(context=ctx)
