"""ControllerNode: the joint controller of flex-twin (seed 000 Eq. 45 or thesis Eq. 95)."""
from __future__ import annotations

import sys
from dataclasses import fields, replace

import numpy as np
from rcl_interfaces.msg import (FloatingPointRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from flex_model.ros_main import lean_node, run_node

from .laws import hold_reference
from .params import ControllerParams, build_controller
from .ros_conversions import (commands_msg, deflection_array, joint_state_arrays,
                              trajectory_from_msg)

THROTTLE_S = 1.0
NODE_PARAMETERS = (("parameter_services", True), ("qos_event_warnings", True))


class ControllerNode(Node):
    """Joint torque controller.

    Subscriptions: ``joint_states`` (sensor_msgs/JointState), ``flex_planner/trajectory``
    (trajectory_msgs/JointTrajectory; its start is ``header.stamp``, or the arrival time if
    zero), ``flex/deflections`` (sensor_msgs/JointState as the model node publishes it: the
    positions named ``link<i>/tip_deflection``, m; only with ``use_deflections``).
    Publication: ``effort_controller/commands`` (std_msgs/Float64MultiArray, torques in
    N m in ``joint_names`` order). Names are relative,
    so a namespace moves them all. Parameters: the fields of
    :class:`flex_control.params.ControllerParams` (law, gains or schedule file, torque
    limits, rate, timeout, stale action); gains and limits may be set at run time and are
    validated before they are swapped in (with the parameter services, default). Node
    parameters ``parameter_services`` and ``qos_event_warnings`` (default true): false
    leaves out rclpy's parameter services (no run-time changes then), resp. its QoS-event
    handlers, for a faster lockstep loop (flex_model.ros_main).

    Safety: until a trajectory arrives the controller holds the first measured pose; joint
    states older than ``state_timeout`` (by arrival time) give zero torques (or the last
    command, ``stale_action: hold``), logged once per episode; malformed or non-finite
    inputs and trajectories with other joint names are logged and dropped; every command is
    clamped to ``torque_limits``; :func:`main` publishes zeros on SIGINT/SIGTERM.
    """

    def __init__(self, **kwargs):
        super().__init__("flex_controller", **kwargs)
        values = {}
        for f in fields(ControllerParams):
            rng = f.metadata.get("range")
            desc = ParameterDescriptor(description=f.metadata["doc"])
            if rng is not None:
                desc.floating_point_range = [FloatingPointRange(from_value=float(rng[0]),
                                                                to_value=float(rng[1]))]
            default = list(f.default) if isinstance(f.default, tuple) else f.default
            values[f.name] = self.declare_parameter(f.name, default, desc).value
        self.params = ControllerParams.from_mapping(values)
        self.controller = build_controller(self.params)
        self.n = len(self.params.joint_names)
        self.t_start = None          # rclpy Time of the trajectory's start, None: holding
        self.state = None            # (positions, velocities, arrival Time)
        self.deflections = None      # (array, arrival Time)
        self.last_command = np.zeros(self.n)
        self.stale_logged = False
        self.pub = self.create_publisher(Float64MultiArray, "effort_controller/commands", 10)
        self.msg = Float64MultiArray()  # reused for every command
        self.create_subscription(JointState, "joint_states", self.on_joint_state,
                                 qos_profile_sensor_data)
        self.create_subscription(JointTrajectory, "flex_planner/trajectory",
                                 self.on_trajectory,
                                 QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        if self.params.use_deflections:
            self.create_subscription(JointState, "flex/deflections", self.on_deflections,
                                     qos_profile_sensor_data)
        lean = [self.declare_parameter(name, default).value for name, default in NODE_PARAMETERS]
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.timer = self.create_timer(1.0 / self.params.rate_hz, self.on_timer)
        lean_node(self, *lean)
        self.get_logger().info(f"law {self.params.law} on {list(self.params.joint_names)} at "
                               f"{self.params.rate_hz:g} Hz")

    def on_joint_state(self, msg: JointState) -> None:
        try:
            pos, vel = joint_state_arrays(msg, self.params.joint_names)
        except ValueError as exc:
            self.get_logger().warn(f"joint state rejected: {exc}",
                                   throttle_duration_sec=THROTTLE_S)
            return
        if self.state is None and self.t_start is None:
            self.controller.set_reference(hold_reference(self.params.joint_names, pos))
        self.state = (pos, vel, self.get_clock().now())

    def on_deflections(self, msg: JointState) -> None:
        try:
            self.deflections = (deflection_array(msg, self.n), self.get_clock().now())
        except ValueError as exc:
            self.get_logger().warn(f"deflections rejected: {exc}",
                                   throttle_duration_sec=THROTTLE_S)

    def on_trajectory(self, msg: JointTrajectory) -> None:
        try:
            data = trajectory_from_msg(msg, self.params.joint_names)
            self.controller.set_reference(data)
        except ValueError as exc:
            self.get_logger().error(f"trajectory rejected: {exc}")
            return
        stamp = Time.from_msg(msg.header.stamp, clock_type=self.get_clock().clock_type)
        self.t_start = stamp if stamp.nanoseconds > 0 else self.get_clock().now()
        self.get_logger().info(f"trajectory accepted: {len(data.t)} points, "
                               f"{data.duration:.3f} s")

    def on_timer(self) -> None:
        now = self.get_clock().now()

        def since(stamp) -> float:  # s from stamp to now
            return (now - stamp).nanoseconds * 1e-9
        if self.state is None or since(self.state[2]) > self.params.state_timeout:
            if not self.stale_logged:
                self.get_logger().warn(f"joint states missing or older than "
                                       f"{self.params.state_timeout:g} s: commanding "
                                       f"{self.params.stale_action}")
                self.stale_logged = True
            self.publish(self.last_command if self.params.stale_action == "hold"
                         else np.zeros(self.n))
            return
        if self.stale_logged:
            self.get_logger().info("joint states fresh again: control resumed")
            self.stale_logged = False
        pos, vel, _ = self.state
        defl = None
        if self.deflections is not None and \
                since(self.deflections[1]) <= self.params.state_timeout:
            defl = self.deflections[0]
        t = 0.0 if self.t_start is None else since(self.t_start)
        try:
            tau = self.controller.torque(t, pos, vel, defl)
        except ValueError as exc:
            self.get_logger().error(f"controller failed: {exc}; commanding zero",
                                    throttle_duration_sec=THROTTLE_S)
            tau = np.zeros(self.n)
        self.publish(tau)

    def publish(self, tau) -> None:
        tau = np.where(np.isfinite(tau), tau, 0.0)
        tau = np.clip(tau, -self.controller.torque_limits, self.controller.torque_limits)
        self.last_command = tau
        self.pub.publish(commands_msg(tau, self.msg))

    def publish_zero(self, wait_s: float = 0.5) -> None:
        """Command zero torques and wait (bounded) until subscribers acknowledge them."""
        self.publish(np.zeros(self.n))
        self.pub.wait_for_all_acked(Duration(seconds=wait_s))

    def stop(self) -> None:
        """The last act of a stopping node (SIGINT/SIGTERM, ``flex-twin up``'s end):
        zero torques."""
        self.publish_zero()
        self.get_logger().info("stopped: zero torques commanded")

    def on_set_parameters(self, changes) -> SetParametersResult:
        values = {p.name: (tuple(p.value) if isinstance(p.value, (list, tuple)) else p.value)
                  for p in changes}
        fixed = {"joint_names", "law", "rate_hz", "use_deflections",
                 *dict(NODE_PARAMETERS)} & set(values)
        if fixed:
            return SetParametersResult(successful=False,
                                       reason=f"{sorted(fixed)}: read-only at run time")
        try:
            params = replace(self.params, **values)
            controller = build_controller(params, reference=self.controller.reference)
        except (ValueError, OSError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        self.params, self.controller = params, controller
        return SetParametersResult(successful=True)


def main(args=None) -> int:
    """Spin the node (SingleThreadedExecutor); on SIGINT/SIGTERM publish zero torques, then
    shut down (flex_model.ros_main.run_node: rclpy's signal handlers replaced by ours, so
    the context is still valid for the last command)."""
    run_node(ControllerNode, args, on_stop=ControllerNode.stop)
    return 0


if __name__ == "__main__":
    sys.exit(main())
