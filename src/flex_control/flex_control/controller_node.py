"""ControllerNode: the joint controller of flex-twin (seed 000 Eq. 45 or thesis Eq. 95)."""
from __future__ import annotations

import sys
from dataclasses import fields, replace

import numpy as np
from rclpy.duration import Duration
from rclpy.lifecycle import LifecycleNode
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.time import Time
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory

from flex_model.ros.main import (Managed, Param, ParameterError, ReasonLog, clock_topic_param, fmt,
                                 follow_clock, lean_node, read_parameters, run_node)

from .laws import hold_reference
from .params import ControllerParams, build_controller
from .ros_conversions import (commands_msg, deflection_array, joint_state_arrays,
                              stamp_seconds, trajectory_from_msg)

THROTTLE_S = 1.0
NODE_PARAMETERS = (("parameter_services", True), ("qos_event_warnings", True))
#: fixed for the node's life (the controller's structure and timer are built from them)
READ_ONLY = ("joint_names", "law", "rate_hz", "use_deflections")
#: the node's defaults where they differ from ControllerParams' (the thesis's h = 25 is a
#: continuous-time design: sampled, with the few ms of latency of a realtime loop, it
#: drives the default model arm, joint inertias ~1-5 kg m^2, into a limit cycle at the
#: torque limits; h = 5, a = 5 holds it with up to 15 ms of loop latency, sagging ~7 deg
#: at joint 1 stretched out under gravity)
NODE_DEFAULTS = {"h": [5.0], "a": [5.0]}


def parameter_specs() -> tuple:
    """The node's parameters: the fields of ControllerParams (``joint_names`` default
    empty: the joints of the model's joint_states) and the node parameters."""
    specs = []
    for f in fields(ControllerParams):
        rng = f.metadata.get("range")
        doc = f.metadata["doc"] + (f" [{rng[0]:g}, {rng[1]:g}]" if rng else "")
        if f.name == "joint_names":
            specs.append(Param(f.name, [], doc + "; empty (default): the joints of the first "
                               "joint_states message, in its order (the model's)", item=str))
            continue
        default = list(f.default) if isinstance(f.default, tuple) else f.default
        default = NODE_DEFAULTS.get(f.name, default)
        specs.append(Param(f.name, default, doc, runtime=f.name not in READ_ONLY,
                           item=float if isinstance(default, list) else None))
    specs += [Param(name, default, "false: see flex_model.ros.main.lean_node")
              for name, default in NODE_PARAMETERS]
    specs.append(Param("hold_joint_angles_deg", [], "joint angles (deg) held until a "
                       "trajectory arrives, one per joint or one for all, e.g. the model's "
                       "initial_joint_angles_deg: a restarted controller holds the same pose; "
                       "empty (default): the first measured pose (a restart re-anchors to "
                       "where the arm sagged)", item=float))
    specs.append(clock_topic_param("the timer and the trajectory time run on it"))
    return tuple(specs)


def stand_in_joints(values: dict) -> tuple:
    """Joint names to check the parameters with until joint_states names the joints: as
    many as the longest of h, a, torque_limits."""
    k = max(len(values[f]) for f in ("h", "a", "torque_limits"))
    return tuple(f"joint{i + 1}" for i in range(k))


class ControllerNode(Managed, LifecycleNode):
    """Joint torque controller; a lifecycle node (flex_model.ros.main.Managed).

    Reads ``joint_states``, ``flex_planner/trajectory`` and (``use_deflections``)
    ``flex/deflections``; publishes ``effort_controller/commands`` (N m, ``joint_names``
    order; empty names: taken from the first joint_states). Parameters: the fields of
    :class:`flex_control.params.ControllerParams`, defaults :data:`NODE_DEFAULTS`; gains and
    limits may change at run time (validated before they are swapped in), the structural
    ones (joint_names, law, rate_hz, use_deflections, hold_joint_angles_deg) are refused
    with a reason. Holding, stale states, clamping, lean nodes, simulation time:
    docs/ros.md ("Nodes", "Lean nodes", "Simulation time").
    """

    def __init__(self, **kwargs):
        super().__init__("flex_controller", **kwargs)
        self.specs = parameter_specs()
        self._start_lifecycle(self.specs, self.apply_parameters)

    def _configure(self) -> None:
        """Read and check the parameters, build the controller, its topics."""
        values = read_parameters(self, self.specs)
        lean = [values.pop(name) for name, _ in NODE_PARAMETERS]
        clock_topic = values.pop("clock_topic")
        self.hold_deg = values.pop("hold_joint_angles_deg")
        names = tuple(values["joint_names"])
        if names and len(self.hold_deg) not in (0, 1, len(names)):
            raise ParameterError(f"parameter hold_joint_angles_deg: got {fmt(self.hold_deg)}; "
                                 f"expected {len(names)} angles (deg) or one for all")
        if not names:  # checked with stand-in joints now, with the model's when they come
            values["joint_names"] = stand_in_joints(values)
        try:
            self.params = ControllerParams.from_mapping(values)
            self.controller = build_controller(self.params)
        except (ValueError, OSError) as exc:
            raise ParameterError(f"parameter {exc}") from None
        self.names = names or None   # None: learn them from joint_states
        self.n = len(names)
        self.t_start = None          # rclpy Time of the trajectory's start, None: holding
        self.state = None            # (positions, velocities, arrival Time)
        self.deflections = None      # (array, arrival Time)
        self.pending = {}            # trajectory/deflections that came before the joints
        self.last_command = np.zeros(self.n)
        self.stale_logged = False
        self.checked = {}            # joint_states name tuple -> usable (checked once)
        self.previous = None         # (positions, stamp s): rates when joint_states has none
        self.logged = set()
        self.drops = ReasonLog(self, THROTTLE_S)
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
        follow_clock(self, clock_topic)
        self.timer = None  # while active
        lean_node(self, *lean)
        joints = list(names) if names else "the joints of joint_states"
        self.get_logger().info(f"law {self.params.law} on {joints} at "
                               f"{self.params.rate_hz:g} Hz")

    def _activate(self) -> None:
        """Start the control timer (the held reference and the joints stay)."""
        self.timer = self.create_timer(1.0 / self.params.rate_hz, self.on_timer)

    def _deactivate(self) -> None:
        """Stop the timer and command zero torques once (as on SIGINT)."""
        self.destroy_timer(self.timer)
        self.timer = None
        self.publish_zero()
        self.get_logger().info("inactive: no commands; zero torques commanded once")

    def _once(self, key, text, level="warning") -> None:
        """Log ``text`` once per ``key`` (each severity from its own call site)."""
        if key in self.logged:
            return
        self.logged.add(key)
        if level == "error":
            self.get_logger().error(text)
        elif level == "info":
            self.get_logger().info(text)
        else:
            self.get_logger().warning(text)

    # ------------------------------------------------------------- joints
    def learn_joints(self, names) -> bool:
        """Take the controller's joints from the model's joint_states (joint_names empty)."""
        try:
            params = replace(self.params, joint_names=tuple(names))
            controller = build_controller(params)
        except (ValueError, OSError) as exc:
            self._once(("learn", tuple(names)), f"joints {list(names)} from joint_states "
                       f"do not fit the parameters: {exc}; no control", "error")
            return False
        self.params, self.controller = params, controller
        self.names, self.n = tuple(names), len(names)
        self.last_command = np.zeros(self.n)
        self.get_logger().info(f"joints from joint_states: {list(names)} (the command order)")
        pending = self.pending
        self.pending = {}
        if "trajectory" in pending:
            self.on_trajectory(*pending["trajectory"])
        if "deflections" in pending:
            self.on_deflections(*pending["deflections"])
        return True

    def joints_usable(self, names: tuple) -> bool:
        """Check a set of joint_states names against the controller's joints once; a
        mismatch is one line, then its messages are dropped silently."""
        ok = self.checked.get(names)
        if ok is not None:
            return ok
        mine = list(self.names)
        missing = [j for j in mine if j not in names]
        extra = [j for j in names if j not in mine]
        ok = not missing and len(set(names)) == len(names)
        if not ok:
            self.get_logger().error(
                f"joint mismatch: joint_states names {list(names)} lack the controller's "
                f"joints {missing} (joint_names {mine}); these messages are dropped, no "
                "control from them (leave joint_names empty to take the model's joints)")
        elif extra:
            self.get_logger().warning(
                f"joint mismatch: joint_states has joints {extra} that this controller "
                f"does not command (joint_names {mine}); a model node with them drops "
                f"commands of {len(mine)} values")
        self.checked[names] = ok
        return ok

    # ------------------------------------------------------------- inputs
    def on_joint_state(self, msg: JointState) -> None:
        names = tuple(msg.name)
        if self.names is None:
            if not names or len(set(names)) != len(names) or not all(names):
                self.drops.warning(f"joint state rejected: JointState.name: got "
                                   f"{list(names)}; expected unique, non-empty joint names")
                return
            if not self.learn_joints(names):
                return
        if not self.joints_usable(names):
            return
        try:
            pos, vel = joint_state_arrays(msg, self.names)
        except ValueError as exc:
            self.drops.warning(f"joint state rejected: {exc}")
            return
        now = self.get_clock().now()
        if vel is None:
            vel = self.differentiate(pos, msg, now)
        if self.state is None and self.t_start is None:
            self.controller.set_reference(hold_reference(self.params.joint_names,
                                                         self.hold_positions(pos)))
        self.state = (pos, vel, now)

    def hold_positions(self, measured) -> np.ndarray:
        """The pose held until a trajectory arrives (rad): hold_joint_angles_deg, else the
        first measured one (logged once, with what a restart does)."""
        if not self.hold_deg:
            self._once("hold", f"holding the first measured pose {fmt(np.degrees(measured))} "
                       "deg until a trajectory arrives (hold_joint_angles_deg empty: a "
                       "restarted controller holds where the arm has sagged to)", "info")
            return measured
        if len(self.hold_deg) not in (1, self.n):
            self._once("hold-length", f"parameter hold_joint_angles_deg: got "
                       f"{fmt(self.hold_deg)}; expected {self.n} angles (deg, one per joint "
                       f"{list(self.names)}) or one for all; holding the measured pose",
                       "error")
            return measured
        return np.radians(np.broadcast_to(np.asarray(self.hold_deg, float), (self.n,)))

    def differentiate(self, pos, msg, now) -> np.ndarray:
        """Joint rates from the positions of successive messages (their header stamps, or
        arrival times if unstamped): joint_states without velocities."""
        self._once("no-velocity", "joint_states without velocities: the rates are the "
                   "differentiated positions", "info")
        t = stamp_seconds(msg.header.stamp) or now.nanoseconds * 1e-9
        vel = np.zeros(self.n)
        if self.previous is not None and t > self.previous[1]:
            vel = (pos - self.previous[0]) / (t - self.previous[1])
        elif self.previous is not None and self.state is not None:
            vel = self.state[1]  # same stamp again: keep the last estimate
        self.previous = (pos, t)
        return vel

    def on_deflections(self, msg: JointState, arrival=None) -> None:
        arrival = self.get_clock().now() if arrival is None else arrival
        if self.names is None:
            self.pending["deflections"] = (msg, arrival)
            return
        try:
            self.deflections = (deflection_array(msg, self.n), arrival)
        except ValueError as exc:
            self.drops.warning(f"deflections rejected: {exc}")

    def on_trajectory(self, msg: JointTrajectory, arrival=None) -> None:
        arrival = self.get_clock().now() if arrival is None else arrival
        if self.names is None:
            self.pending["trajectory"] = (msg, arrival)
            self.get_logger().info("trajectory kept until joint_states names the joints")
            return
        try:
            data = trajectory_from_msg(msg, self.params.joint_names)
            self.controller.set_reference(data)
        except ValueError as exc:
            self.get_logger().error(f"trajectory rejected: {exc}")
            return
        stamp = Time.from_msg(msg.header.stamp, clock_type=self.get_clock().clock_type)
        self.t_start = stamp if stamp.nanoseconds > 0 else arrival
        self.get_logger().info(f"trajectory accepted: {len(data.t)} points, "
                               f"{data.duration:.3f} s")

    def on_timer(self) -> None:
        if self.names is None:
            self._once("waiting", "waiting for joint_states to name the joints (joint_names "
                       "empty): nothing commanded until then", "info")
            return
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
            self.drops.error(f"controller failed: {exc}; commanding zero")
            tau = np.zeros(self.n)
        self.publish(tau)

    def publish(self, tau) -> None:
        tau = np.where(np.isfinite(tau), tau, 0.0)
        tau = np.clip(tau, -self.controller.torque_limits, self.controller.torque_limits)
        self.last_command = tau
        self.pub.publish(commands_msg(tau, self.msg))

    def publish_zero(self, wait_s: float = 0.5) -> None:
        """Command zero torques and wait (bounded) until subscribers acknowledge them."""
        if self.names is None:  # no joints known: nothing was ever commanded
            return
        self.publish(np.zeros(self.n))
        self.pub.wait_for_all_acked(Duration(seconds=wait_s))

    def stop(self) -> None:
        """The last act of a stopping node (SIGINT/SIGTERM, ``flex-twin up``'s end):
        zero torques (inactive or unconfigured: nothing, deactivate commanded them)."""
        if not self.active:
            return
        if self.names is None:
            self.get_logger().info("stopped: no joints known, nothing was commanded")
            return
        self.publish_zero()
        self.get_logger().info("stopped: zero torques commanded")

    def apply_parameters(self, values: dict) -> None:
        """Run-time gains, limits, timeouts (checked types): validated by building the
        controller before it is swapped in (raises ValueError with the reason)."""
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items()
                  if k not in dict(NODE_PARAMETERS)}
        reference = self.controller.reference
        if self.names is None:  # no joints yet: as many stand-ins as the longest list
            values["joint_names"] = stand_in_joints({**vars(self.params), **values})
            reference = None
        params = replace(self.params, **values)
        try:
            controller = build_controller(params, reference=reference)
        except OSError as exc:
            raise ValueError(f"schedule_file: {exc}") from None
        self.params, self.controller = params, controller


def main(args=None) -> int:
    """Spin the node (SingleThreadedExecutor); on SIGINT/SIGTERM publish zero torques, then
    shut down (flex_model.ros.main.run_node: rclpy's signal handlers replaced by ours, so
    the context is still valid for the last command)."""
    run_node(ControllerNode, args, on_stop=ControllerNode.stop)
    return 0


if __name__ == "__main__":
    sys.exit(main())
