"""flex_control's controller node closing the loop over ROS on a spatial arm (issue 43,
one model node): the model node in lockstep with the seed003-like arm (three joints, a
flexible forearm), the controller node on the model's clock at the model's rate (one
command per period, as ros2_ws/params/suite.yaml), its Eq. 95 PD with the holding torques as
feed-forward takes the arm to a target and holds it there; the same law sampled on the
plain-Python core (the compiled spatial loop, one call per period) ends at the same
place."""
import os
import time
import uuid

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flex_control.controller_node import ControllerNode
from flex_control.laws import DecentralizedPD
from flex_control.ros_conversions import trajectory_from_msg
from flex_model.ros.model_node import SpatialModelNode
from flex_model.spatial import SpatialArmModel, load_spatial_arm
from flex_model.spatial.integrate import simulate_fixed_compiled
from flex_model.spatial.scenario import holding_torques as hold_torques

ARM = "seed003_like_arm"
TARGET = [0.3, -0.2, 0.4]
GAINS = {"h": [2.0, 2.4, 0.6], "a": [10.0], "torque_limits": [250.0]}
#: 500 Hz: at 200 Hz the one period of latency of the ROS loop (the controller's timer
#: fires on the new clock before the new joint_states arrive) destabilizes the forearm's
#: bending mode under these gains (the core with that delay: 0.72 rad off after 2 s; 1.5e-6
#: rad at 500 Hz)
RATE, STEP = 500.0, 2e-3


def holding_torques(arm, joints):
    return hold_torques(np.array(joints), SpatialArmModel(arm))


def target_msg(names, effort):
    msg = JointTrajectory(joint_names=list(names))
    msg.points = [JointTrajectoryPoint(positions=list(map(float, TARGET)),
                                       velocities=[0.0] * 3, effort=list(map(float, effort)))]
    return msg


def core_run(arm, law, seconds, delay=1):
    """The law sampled every period on the compiled loop (restarted at each command, as
    the node with restart_on_change), on the state ``delay`` periods old (the ROS loop's
    latency)."""
    model = SpatialArmModel(arm)
    q, v = np.zeros(model.nq), np.zeros(model.nq)
    per = int(round(1.0 / RATE / STEP))
    states = [(q, v)] * (delay + 1)
    for k in range(int(round(seconds * RATE))):
        qs, vs = states[-1 - delay]
        tau = law.torque(k / RATE, qs[model.off], vs[model.off])
        run = simulate_fixed_compiled(model, q, v, STEP, per, joint_torques=tau)
        q, v = run.q[-1], run.v[-1]
        states.append((q, v))
    return q[model.off], v[model.off]


def test_the_controller_node_holds_a_spatial_arm_at_its_target():
    arm = load_spatial_arm(ARM)
    effort = holding_torques(arm, TARGET)
    assert np.abs(effort).max() > 1.0          # N m: gravity to hold, not a zero test
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    ns = f"/sp{os.getpid()}_{uuid.uuid4().hex[:6]}"
    ex = SingleThreadedExecutor(context=ctx)
    nodes = []
    try:
        model = SpatialModelNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter("arm", value=ARM), Parameter("mode", value="lockstep"),
            Parameter("rate", value=RATE), Parameter("step", value=STEP),
            Parameter("lockstep_timeout", value=0.5), Parameter("clock_topic", value="clock")])
        # on the model's clock (ros2_ws/params/suite.yaml): one command per model period
        ctrl = ControllerNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter(k, value=v) for k, v in {
                **GAINS, "state_timeout": 5.0, "rate_hz": RATE, "use_sim_time": True,
                "clock_topic": "clock"}.items()])
        probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:6]}", context=ctx,
                                  namespace=ns)
        nodes = [model, ctrl, probe]
        for n in nodes:
            ex.add_node(n)
        pub = probe.create_publisher(JointTrajectory, "flex_planner/trajectory", 1)

        def spin_until(pred, what, timeout=120.0):
            end = time.monotonic() + timeout
            while not pred():
                assert time.monotonic() < end, f"timed out waiting for {what}"
                ex.spin_once(timeout_sec=0.005)
        spin_until(lambda: ctrl.names is not None and pub.get_subscription_count() > 0,
                   "the controller learning the joints")
        assert ctrl.names == ("joint1", "joint2", "joint3")
        msg = target_msg(ctrl.names, effort)
        pub.publish(msg)
        spin_until(lambda: ctrl.t_start is not None, "the trajectory")
        t0 = model.t
        spin_until(lambda: model.t >= t0 + 2.0 or model.diverged is not None,
                   "2 s of model time")
        assert model.diverged is None and model.dropped == 0, list(model.drops.last)[:5]
        js = model.joint_values()
        pos, vel = js[:3], js[3:6]
        law = DecentralizedPD(trajectory_from_msg(msg, list(ctrl.names)), h=GAINS["h"],
                              a=GAINS["a"], torque_limits=GAINS["torque_limits"])
        core_pos, core_vel = core_run(arm, law, 2.0)
        print(f"ROS loop: joints - target {pos - TARGET} rad, rates {vel} rad/s; core: "
              f"{core_pos - TARGET} rad")
        np.testing.assert_allclose(pos, TARGET, rtol=0, atol=1e-4)
        np.testing.assert_allclose(core_pos, TARGET, rtol=0, atol=1e-4)
        np.testing.assert_allclose(pos, core_pos, rtol=0, atol=1e-4)
        assert np.abs(vel).max() < 2e-2
    finally:
        ex.shutdown()
        for n in nodes:
            n.destroy_node()
        rclpy.try_shutdown(context=ctx)
