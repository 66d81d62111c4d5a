"""ModelNode: any flexible arm as a ROS 2 node (issue 43, "one model node").

One node class hosts a planar arm (:class:`PlanarArm`, around flex_model.stepper.Stepper)
and a spatial one (flex_model.ros.spatial_node.SpatialArm, around the compiled loop of
spatial/integrate.py); the arm kind is read from ``arm`` at configure. Parameters, topics,
services, lifecycle, lockstep and realtime loops, command timeout, plausibility limits and
divergence handling are this class's, the same for both (the adapter only steps and
measures). ``flex-spatial-model-node`` is this node with :data:`SPATIAL_DEFAULTS`.
Parameters: :data:`PARAMETERS` (:data:`RANGES` in the descriptors). Topics, services,
parameters that may change at run time, lifecycle, bad inputs, divergence and the loops:
docs/ros.md ("Nodes", "Spatial arms", "Lifecycle").
"""
from __future__ import annotations

import os
import sys
import time
from collections import deque
from contextlib import ExitStack
from dataclasses import replace

import numpy as np
from rcl_interfaces.msg import SetParametersResult
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import LifecycleNode
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import Imu
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from . import conversions as conv
from .. import urdf
from ..control_loop import ControlLoop
from ..controller_interface import load_controller
from ..dynamics import FlexArmModel
from .main import (FLOAT_MAX, INT_MAX, MODEL_PARAMETERS, ModelPlumbing, Param, ParameterError,
                   ReasonLog, fmt, lean_node, planar_arm_parameter, positive,
                   read_parameters, run_node)
from ..stepper import Stepper
from .trajectory_action import action_server
from ..trajectory_action import INVALID_GOAL


#: lockstep with an in-loop controller: wall time (s) of one tick's run of control periods
LOCKSTEP_SLICE = 0.02
#: realtime with realtime_priority, the node alone in its executor: wall time (s) of the
#: periods one timer callback runs on a wait set of its own (ModelNode._realtime_slice)
#: before it returns to the executor (0: one period a callback)
REALTIME_SLICE = 0.05
#: commands remembered for the divergence diagnostic (it names the largest of them)
COMMAND_MEMORY = 4096
#: QoS of robot_description and /tf_static (as robot_state_publisher: latched, depth 1)
LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)


def tf_message_type():
    """(tf2_msgs/TFMessage, None), or (None, why not): the pip ROS wheels have no tf2_msgs
    (a ROS install and the docker image do)."""
    try:
        from tf2_msgs.msg import TFMessage
    except ImportError as exc:
        return None, str(exc)
    return TFMessage, None


def _non_negative(v):
    return None if v >= 0 else "a number >= 0 (0: automatic)"


def _gains(v):
    return None if v and all(x >= 0 for x in v) else "one or more gains >= 0"


def _payload_check(v):
    from ..spatial.payload import payload_inertia
    try:
        payload_inertia(v)
    except ValueError as exc:
        return f"a payload vector ({exc})"
    return None


def plausibility_limits(model: FlexArmModel) -> dict:
    """Automatic plausibility limits of an arm (the ``0`` of max_torque, max_payload_mass,
    max_payload_inertia): from its mass, its inertia about joint 1 and the joint torques
    that hold it against gravity, stretched out along x (the largest)."""
    q = model.q_from_joint_angles(np.zeros(model.n_links))
    rates = np.eye(model.n_links)
    dirs = [model.v_from_joint_rates(r) for r in rates]
    inertia = float(dirs[0] @ model.mass_matrix(q) @ dirs[0])
    gravity = max(abs(float(d @ model.gravity_force(q))) for d in dirs)
    return {"max_torque": max(100.0, 10.0 * gravity, 100.0 * inertia),
            "max_payload_mass": 10.0 * float(model.total_mass),
            "max_payload_inertia": 10.0 * inertia}


def _refuse_controller_params(changes, configured: bool = True) -> SetParametersResult:
    """controller_params.* are read when the in-loop controller is built (configure): a
    change while configured is refused with the reason (it would be accepted and do
    nothing)."""
    for p in changes if configured else ():
        if p.name.startswith("controller_params."):
            return SetParametersResult(successful=False, reason=(
                f"parameter {p.name} is read-only at run time (the in-loop controller is "
                f"built from it); restart the node with -p {p.name}:=..."))
    return SetParametersResult(successful=True)


def _choice(*options):
    return lambda v: None if v in options else "one of " + ", ".join(options)


#: the node's parameters (name, default, description, changeable at run time, check)
PARAMETERS = (
    Param("arm", "thesis_example1_motors", "arm preset name or arm YAML path: planar, or "
          "spatial (DH table or URDF; flex-spatial-model-node's default seed003_like_arm); "
          "the planar default has geared motors: a sampled joint controller is stable on "
          "it, the hub-less thesis_example1 needs its own control design",
          check=lambda v: None if v else "a preset name or a YAML path"),
    Param("from_planar", False, "embed the planar arm ``arm`` in 3D (spatial.from_planar) "
          "and run it as a spatial arm"),
    MODEL_PARAMETERS["vars_per_link"], MODEL_PARAMETERS["kinematics"],
    Param("mode", "realtime", "realtime | lockstep (observer: flex_model.ros.observer_node, "
          "which the entry point starts for -p mode:=observer)",
          check=lambda v: None if v in ("realtime", "lockstep") else
          "realtime or lockstep (mode observer is flex_model.ros.observer_node: started by "
          "the entry point with -p mode:=observer, flex-twin observe, or flex-twin up)"),
    Param("rate", 1000.0, "model loop rate (Hz); lockstep: a command advances 1/rate",
          check=positive),
    Param("publish_rate", 250.0, "rate of the state topics (Hz; at or above rate: every "
          "model period)", True, positive),
    Param("shape_rate", 50.0, "rate of flex/shape (Hz), at most publish_rate", True,
          positive),
    Param("max_step", 1e-3, "integration step (s); a spatial arm splits 1/rate into "
          "ceil((1/rate)/max_step) equal steps",
          check=lambda v: None if 0 < v <= 0.1 else "a step in (0, 0.1] s"),
    Param("step", 1e-3, "the integration step under its spatial node name (= max_step)",
          check=lambda v: None if 0 < v <= 0.1 else "a step in (0, 0.1] s"),
    Param("rho_inf", 0.9, "generalized-alpha spectral radius",
          check=lambda v: None if 0 <= v <= 1 else "a number in [0, 1]"),
    Param("newton_tol", 1e-10, "spatial: Newton tolerance",
          check=lambda v: None if 0 < v <= 1e-4 else "a number in (0, 1e-4]"),
    Param("initial_joint_angles_deg", [0.0], "initial joint angles (deg): one per joint, "
          "or one value for every joint"),
    Param("initial_joint_values", [0.0], "initial joint values (rad or m): one per joint "
          "or one for all (instead of initial_joint_angles_deg)"),
    Param("payload", [0.0], "initial payload: planar [mass] | [mass, inertia]; spatial "
          "at the last link's end frame origin [m] | [m, J_z] | [m, Ixx, Iyy, Izz] | "
          "[m, Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (kg, kg m^2)", check=_payload_check),
    Param("command_timeout", 0.5, "s (simulation time) without a valid command before "
          "timeout_action (0: never); lockstep: a step of the lockstep_timeout watchdog (the "
          "loop stalled) applies it at once; not used with an in-loop controller plugin",
          True, lambda v: None if v >= 0 else "a time >= 0 s (0: never)"),
    Param("timeout_action", "zero", "hold | zero (the command after command_timeout; with "
          "the continuous PD the feed-forward)", True, _choice("hold", "zero")),
    Param("lockstep_timeout", 1.0, "lockstep: wall s without a command before the model "
          "steps with the held one", True, positive),
    MODEL_PARAMETERS["frame_id"], MODEL_PARAMETERS["frame_prefix"],
    Param("publish_tf", True, "publish /tf, /tf_static (needs the tf2_msgs package; without "
          "it TF is off, logged once at start); robot_description is always published"),
    Param("clock_topic", "/clock", "topic of the simulation clock (lockstep, or "
          "publish_clock): a relative name (clock) puts it in the node's namespace, so two "
          "lockstep twins do not share one /clock",
          check=lambda v: None if v else "a topic name (/clock, or clock: the namespace's)"),
    Param("shape_points", 15, "points per link of flex/shape",
          check=lambda v: None if 2 <= v <= 10000 else "an integer in [2, 10000]"),
    Param("publish_clock", False, "publish /clock in realtime mode too"),
    Param("foxglove_port", 0, "planar: port of a Foxglove WebSocket live view on 127.0.0.1 "
          "(flex_model.live_view, at shape_rate); 0: off",
          check=lambda v: None if 0 <= v <= 65535 else "0 (off) or a port 1-65535"),
    Param("start_static", False, "start at rest, deflected under gravity (joints held; "
          "with the continuous PD its equilibrium; with the initial payload)"),
    Param("start_paused", False, "start paused (until ~/pause false)"),
    Param("hold_until_command", True, "hold the arm at its initial state (brakes on: time "
          "runs, joints and links stay) from the start and after ~/reset until the first "
          "valid command (an in-loop controller: from ~/reset until the next trajectory); "
          "false: the arm moves under zero torque (falls under gravity) until then"),
    Param("realtime_priority", 0, "SCHED_FIFO priority of the node's thread (0: off)",
          check=lambda v: None if 0 <= v <= 99 else "0 (off) or 1-99"),
    Param("max_torque", 0.0, "plausibility limit of a joint command (N m, N, or V for "
          "DC-motor joints): a command beyond it is dropped; 0: automatic, the largest of "
          "100 N m, 10 x the static gravity torque of the stretched arm and 100 s^-2 x its "
          "inertia about joint 1", True, _non_negative),
    Param("max_payload_mass", 0.0, "plausibility limit of a payload mass (kg); 0: "
          "automatic, 10 x the arm's mass", True, _non_negative),
    Param("max_payload_inertia", 0.0, "plausibility limit of a payload inertia (kg m^2; "
          "spatial: its largest principal one); 0: automatic, 10 x the stretched arm's "
          "inertia about joint 1", True, _non_negative),
    Param("controller", "", "in-loop controller: planar, a plugin run every control period "
          "inside the model's loop (flex_model.controller_interface: eq95, eq45, "
          "state_feedback or module:factory; its parameters controller_params.<name>); "
          "spatial, eq95 | eq45: the continuous PD in the compiled loop (kp, kd | kpp, "
          "kpv); empty or none: commands come over effort_controller/commands"),
    Param("controller_rate", 500.0, "planar: rate of the in-loop controller plugin (Hz); "
          "its period is split into steps of at most max_step", check=positive),
    Param("kpp", [0.0], "spatial eq45: K_pp (1/s), one per joint or one for all",
          check=_gains),
    Param("kpv", [0.0], "spatial eq45: K_pv (N m s/rad, motor side), one per joint or one "
          "for all", check=_gains),
    Param("kp", [0.0], "spatial eq95: N m/rad (N/m), one per joint or one for all",
          check=_gains),
    Param("kd", [0.0], "spatial eq95: N m s/rad (N s/m), one per joint or one for all",
          check=_gains),
    Param("setpoints", [0.0], "spatial eq95/eq45: initial set-points (rad or m), one per "
          "joint or one for all"),
    Param("restart_on_change", True, "spatial: restart the integrator (consistent "
          "acceleration) when the command or a set-point changes, as the planar Stepper; "
          "false: continue"),
    MODEL_PARAMETERS["parameter_services"], MODEL_PARAMETERS["qos_event_warnings"],
)

#: ranges of the numeric parameters in their descriptors (ros_main.descriptor): the bounds
#: of their checks (an open "> 0" is [0, max] there, the check refuses the 0)
RANGES = {"vars_per_link": (0, INT_MAX, 2), "rate": (0.0, FLOAT_MAX),
          "publish_rate": (0.0, FLOAT_MAX), "shape_rate": (0.0, FLOAT_MAX),
          "max_step": (0.0, 0.1), "step": (0.0, 0.1), "rho_inf": (0.0, 1.0),
          "command_timeout": (0.0, FLOAT_MAX),
          "lockstep_timeout": (0.0, FLOAT_MAX), "shape_points": (2, 10000),
          "realtime_priority": (0, 99), "max_torque": (0.0, FLOAT_MAX),
          "max_payload_mass": (0.0, FLOAT_MAX), "max_payload_inertia": (0.0, FLOAT_MAX),
          "controller_rate": (0.0, FLOAT_MAX)}

#: the arm's objects, None while the node is unconfigured (cleanup released them)
RELEASED = ("model", "stepper", "live_view")

#: the spatial node's defaults (flex-spatial-model-node, flex-model-node -p arm:=<spatial>)
#: (publications every period up to 1 kHz)
SPATIAL_DEFAULTS = {"arm": "seed003_like_arm", "rate": 250.0, "publish_rate": 1000.0,
                    "shape_rate": 1000.0, "shape_points": 21, "hold_until_command": False}

#: parameters that mean something for one arm kind only: what to use on the other
PLANAR_ONLY = {
    "vars_per_link": "a spatial arm's discretization is its arm file's (elements per link)",
    "controller_rate": "on a spatial arm eq95/eq45 is the continuous PD in the compiled "
                       "loop (kp, kd)",
    "foxglove_port": "the Foxglove live view (flex_model.live_view) draws planar arms; "
                     "spatial arms: flex/shape and /tf in RViz or Foxglove over ROS"}
SPATIAL_ONLY = {
    "newton_tol": "the planar Stepper's Newton tolerance is fixed (1e-10)",
    "restart_on_change": "the planar Stepper restarts at every command change",
    **{k: "on a planar arm the in-loop PD is the plugin controller eq95 (or eq45), "
          "sampled at controller_rate, its gains controller_params.kp, kd, ..., its "
          "set-points a trajectory on flex_planner/trajectory"
       for k in ("kp", "kd", "kpp", "kpv", "setpoints")}}


def _aliases(p: dict, specs) -> None:
    """max_step/step and initial_joint_angles_deg/initial_joint_values: one value each
    (the one set), in p["max_step"] and p["initial_joint_values"] (rad or m)."""
    default = {s.name: s.default for s in specs}
    for a, b in (("max_step", "step"), ("initial_joint_angles_deg", "initial_joint_values")):
        if p[a] != default[a] and p[b] != default[b]:
            raise ParameterError(f"parameter {b}: got {fmt(p[b])} and {a} {fmt(p[a])}; "
                                 f"expected one of them (they name one value)")
    if p["step"] != default["step"]:
        p["max_step"] = p["step"]
    if p["initial_joint_values"] == default["initial_joint_values"]:
        p["initial_joint_values"] = list(np.radians(p["initial_joint_angles_deg"]))


def _refuse_other_kind(p: dict, specs, spatial: bool) -> None:
    """A parameter of the other arm kind, set: one line saying why and what instead."""
    default = {s.name: s.default for s in specs}
    for name, why in (PLANAR_ONLY if spatial else SPATIAL_ONLY).items():
        if p[name] != default[name]:
            kind = "spatial" if spatial else "planar"
            raise ParameterError(f"parameter {name}: got {fmt(p[name])} on the {kind} arm "
                                 f"{p['arm']!r}; expected the default {fmt(default[name])}: "
                                 f"{why}")


class ModelNode(ModelPlumbing, LifecycleNode):
    """Any arm simulated at ``rate`` and published at ``publish_rate``; a lifecycle node
    (ros_main.Managed): configure loads the arm, activate runs the loop, deactivate holds
    the state (time stands still), cleanup releases the arm. ``defaults``: other default
    values of :data:`PARAMETERS` (:data:`SPATIAL_DEFAULTS`). The arm adapter's state
    (``stepper``, ``model``, ``q``, ``t``, ...) reads through the node (``node.stepper``)."""

    def __init__(self, defaults: dict | None = None, **kwargs):
        super().__init__("flex_model", **kwargs)
        self.specs = tuple(replace(s, default=(defaults or {}).get(s.name, s.default))
                           for s in PARAMETERS)
        self.add_on_set_parameters_callback(
            lambda changes: _refuse_controller_params(changes, self.configured))
        self._start_lifecycle(self.specs, lambda d: self.p.update(d))

    def __getattr__(self, name):
        arm = self.__dict__.get("arm_io")
        if arm is None and name in RELEASED:  # (unconfigured: no arm)
            return None
        if arm is None or name.startswith("__"):
            raise AttributeError(name)
        return getattr(arm, name)

    def _configure(self) -> None:
        """Read and check the parameters, load the arm, make the publishers,
        subscriptions, services and the in-loop controller."""
        p = read_parameters(self, self.specs, RANGES)
        _aliases(p, self.specs)
        self.p = p
        from ..spatial.description import is_spatial_arm
        spatial = bool(p["from_planar"]) or is_spatial_arm(p["arm"])
        _refuse_other_kind(p, self.specs, spatial)
        if spatial:
            from .spatial_node import SpatialArm
            self.arm_io = SpatialArm(self, p)
        else:
            self.arm_io = PlanarArm(self, p)
        arm = self.arm_io
        self.names = arm.names
        self.paused = bool(p["start_paused"])
        # hold_until_command: the initial state held until a command (an in-loop controller
        # commands from the start)
        self.braked = bool(p["hold_until_command"]) and not arm.in_loop
        self.command_time = 0.0
        self.commanded = False  # a valid command has arrived (lockstep: the loop runs)
        self.next_publish = self.next_shape = 0.0
        self.behind = 0.0  # realtime: wall time not yet integrated (s)
        self.diverged = None  # after a divergence: its DiagnosticStatus (stepping stops)
        self.diverged_at = 0.0  # simulation time of the divergence (s)
        self.next_diagnostic = 0.0  # wall time of the next repeat of that status
        self.next_held_state = 0.0  # diverged: wall time of the next held-state publication
        self.recent_commands = deque(maxlen=COMMAND_MEMORY)  # (t, command): the diagnostic
        self.warned = set()
        self.dropped = 0
        self.drops = ReasonLog(self)
        self._make_entities(p)
        self.loop = self._in_loop_controller(p) if arm.plugin else None
        # control_msgs/FollowJointTrajectory for the in-loop controller (trajectory_action)
        self.fjt = action_server(self) if self.loop is not None else None
        self.timer = None  # the model loop's, while active
        if p["mode"] == "realtime" and p["realtime_priority"]:
            self._set_realtime_priority(int(p["realtime_priority"]))
        lean_node(self, p["parameter_services"], p["qos_event_warnings"])
        self.pub_description.publish(String(data=arm.robot_description()))
        self.get_logger().info(f"{arm.summary()}, {p['mode']} at {p['rate']:g} Hz, "
                               f"publishing at {p['publish_rate']:g} Hz; "
                               f"plausibility limits {self.limit('max_torque'):.4g} N m, "
                               f"payload {self.limit('max_payload_mass'):.4g} kg, "
                               f"{self.limit('max_payload_inertia'):.4g} kg m^2"
                               + ("; the initial state is held until the first command "
                                  "(hold_until_command)" if self.braked else ""))

    def _make_entities(self, p) -> None:
        """Publishers (state messages as CDR templates, flex_model.ros.cdr_messages: published
        as bytes), subscriptions and services."""
        arm, qos = self.arm_io, 10
        self.cdr_tip = conv.tip_pose_cdr(arm.base_frame)
        self.cdr_clock = conv.clock_cdr()
        self.msg_shape = conv.ShapeMarkers(len(arm.shape_labels), int(p["shape_points"]),
                                           arm.base_frame, labels=arm.shape_labels,
                                           widths=arm.shape_widths)
        # relative names: a namespace (__ns:=/robot1) moves the whole loop; /diagnostics
        # stays global, as ROS tools (the aggregator) expect; the clock is clock_topic
        self._state_publishers("joint_states", arm.deflection_names, qos)
        self.pub_tip = self.create_publisher(PoseStamped, "flex/tip_pose", qos)
        self.pub_shape = self.create_publisher(MarkerArray, "flex/shape", qos)
        self.pub_imu = self.create_publisher(Imu, "flex/tip_imu", qos) if arm.has_imu \
            else None
        self.pub_clock = self.create_publisher(Clock, p["clock_topic"], qos) \
            if p["mode"] == "lockstep" or p["publish_clock"] else None
        self.pub_description = self.create_publisher(String, "robot_description", LATCHED)
        self.pub_tf = None
        self._tf_setup(p)
        self._diagnostics()
        self.create_subscription(Float64MultiArray, "effort_controller/commands",
                                 self.on_command, qos)
        if arm.has_setpoints:
            self.create_subscription(Float64MultiArray, "flex/setpoints", self.on_setpoints,
                                     qos)
        self.create_subscription(Float64MultiArray, "flex/payload", self.on_payload, qos)
        self.create_service(Trigger, "~/reset", self.on_reset)
        self.create_service(SetBool, "~/pause", self.on_pause)

    def _activate(self) -> None:
        """Start the model loop from the held state (the wall time spent inactive is not
        integrated) and publish that state."""
        p = self.p
        # realtime: the model loop; lockstep: steps happen on commands, this is the watchdog;
        # lockstep with an in-loop controller: each tick runs the loop for LOCKSTEP_SLICE s
        period = 1.0 / p["rate"] if p["mode"] == "realtime" else 0.05
        if self.loop is not None and p["mode"] == "lockstep":
            period = 1e-4
        self._start_loop(period)
        self.publish_state(full=True)

    def _deactivate(self) -> None:
        """Stop the loop: time and state stand still, nothing stepping-related is
        published, inputs are refused. The command becomes the safe one of a command
        timeout (timeout_action zero: zero torque) and, with hold_until_command, the arm is
        held after activate until the next command; an in-loop controller's trajectory
        (and goal) ends, as on ~/reset."""
        self._stop_loop(self.arm_io.t)
        if self.fjt is not None:
            self.fjt.finish(INVALID_GOAL, "ended by deactivate (lifecycle)")
        if self.loop is not None:  # as ~/reset: zero (held) until the next trajectory
            self.loop.drop_trajectory()
        else:
            if self.p["timeout_action"] == "zero":
                self.arm_io.zero_command()
            self.braked = bool(self.p["hold_until_command"])

    def _cleanup(self) -> None:
        """Release the arm, the in-loop controller and the live view's server (the
        entities go in ros_main.Managed)."""
        if getattr(self, "fjt", None) is not None:  # (a failed configure: partly built)
            self.fjt.finish(INVALID_GOAL, "ended by cleanup (lifecycle)")
        arm = self.__dict__.get("arm_io")
        if arm is not None:
            arm.close()
        self.loop = self.fjt = self.arm_io = None

    def _tf_setup(self, p) -> None:
        """/tf_static (latched, once) and /tf publishers, if tf2_msgs can be imported and
        publish_tf; else one line saying TF is off and why."""
        if not p["publish_tf"]:
            return
        tf_type, why = tf_message_type()
        if tf_type is None:
            self.get_logger().info(f"TF off: tf2_msgs cannot be imported ({why}; the pip "
                                   "ROS wheels have none, a ROS install has it); "
                                   "robot_description is published, /tf and /tf_static not")
            return
        static = self.arm_io.tf_setup(tf_type)
        if static:
            self.create_publisher(tf_type, "/tf_static", LATCHED).publish(
                tf_type(transforms=conv.Transforms(static).msgs))
        self.pub_tf = self.create_publisher(tf_type, "/tf", 100)

    def _in_loop_controller(self, p) -> ControlLoop:
        """The controller named by the parameter ``controller`` in the model's loop (the
        ros2_control pattern: no DDS round trip per control period); it takes trajectories
        on flex_planner/trajectory (times from the header stamp, in simulation time, or
        from arrival)."""
        prefix = "controller_params."
        params = {}
        for name, override in getattr(self, "_parameter_overrides", {}).items():
            if name.startswith(prefix):  # (declared at the first configure)
                params[name[len(prefix):]] = (self.get_parameter(name) if self.has_parameter(
                    name) else self.declare_parameter(name, override.value)).value
        try:
            ctl = load_controller(p["controller"], self.names, params)
        except ValueError as exc:
            raise ParameterError(f"parameter {exc}") from None
        self.create_subscription(JointTrajectory, "flex_planner/trajectory",
                                 self.on_trajectory, 1)
        self.get_logger().info(f"in-loop controller {p['controller']} at "
                               f"{p['controller_rate']:g} Hz, parameters {params or 'default'}")
        return ControlLoop(self.arm_io.stepper, ctl, 1.0 / p["controller_rate"])

    def on_trajectory(self, msg: JointTrajectory) -> None:
        try:
            if not self.active:
                raise ValueError(self._inactive())
            data = conv.trajectory_from_msg(msg, self.names)
            start = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            self.loop.set_trajectory(data, start if start > 0 else self.arm_io.t)
        except ValueError as exc:
            self.drops.warning(f"dropped flex_planner/trajectory: {exc}")
            return
        self.get_logger().info(f"trajectory: {len(data.t)} points, {data.duration:.3f} s")

    def _set_realtime_priority(self, priority: int) -> None:
        """SCHED_FIFO for this thread (Linux: the other threads, DDS's, keep theirs)."""
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        except (OSError, AttributeError) as exc:
            self.get_logger().warning(f"realtime_priority {priority}: {exc}; running with "
                                      "the normal scheduler")

    def limit(self, name: str) -> float:
        """A plausibility limit: the parameter, or the arm's automatic one if 0."""
        return self.p[name] or self.arm_io.auto_limits[name]

    # ------------------------------------------------------------- inputs
    def _warn_once(self, key, text, level="warning"):
        """Log ``text`` once per ``key``. rclpy binds one severity to each call site (a
        second severity from the same line raises ValueError), so each level has its own."""
        if key in self.warned:
            return
        self.warned.add(key)
        if level == "info":
            self.get_logger().info(text)
        else:
            self.get_logger().warning(text)

    def _drop(self, topic: str, why: str, held: str = "value") -> None:
        self.dropped += 1
        self.drops.warning(f"dropped {topic}: {why}; holding the last valid {held}")

    def _refuse_input(self) -> None:
        """Raise why an input is refused: inactive (lifecycle), or diverged."""
        if not self.active:
            raise ValueError(self._inactive())
        if self.diverged is not None:
            raise ValueError(f"the model diverged at t = {fmt(self.diverged_at)} s and is "
                             "stopped; call ~/reset")

    def on_command(self, msg: Float64MultiArray) -> None:
        arm = self.arm_io
        try:
            u = conv.finite_array(msg.data, len(self.names), "command",
                                  f"one per joint: {', '.join(self.names)}")
            conv.within_limit(u, self.limit("max_torque"), "command", self.names,
                              "max_torque", arm.torque_unit)
            self._refuse_input()
            if self.loop is not None:
                raise ValueError(f"the in-loop controller {self.p['controller']} drives "
                                 "the arm (parameter controller)")
        except ValueError as exc:
            self._drop("effort_controller/commands", str(exc), "command")
            return
        arm.set_command(u)
        self.command_time, self.commanded, self.braked = arm.t, True, False
        self.recent_commands.append((self.command_time, u))
        if self.p["mode"] == "lockstep" and not self.paused:
            self.last_wall = time.monotonic()
            self.step(1.0 / self.p["rate"])

    def on_setpoints(self, msg: Float64MultiArray) -> None:
        try:
            self.arm_io.set_setpoints(msg.data)
            if not self.active:
                raise ValueError(self._inactive())
        except ValueError as exc:
            self._drop("flex/setpoints", str(exc))

    def on_payload(self, msg: Float64MultiArray) -> None:
        try:
            payload = self.arm_io.payload_from(msg.data, self.limit)
            self._refuse_input()
            self.arm_io.set_payload(payload)
        except ValueError as exc:
            self._drop("flex/payload", str(exc))
            return
        self.get_logger().info(f"payload now {self.arm_io.payload_text()}")

    def on_reset(self, request, response):
        """Back to the initial state, payload and a zero command at t = 0; after a
        divergence this restarts the loop (the diagnostic goes back to OK)."""
        if not self.active:
            response.success, response.message = False, self._inactive()
            return response
        was_diverged = self.diverged is not None
        self.arm_io.reset()
        self.recent_commands.clear()
        if self.fjt is not None:  # a running FollowJointTrajectory goal ends here
            self.fjt.finish(INVALID_GOAL, "ended by ~/reset")
        if self.loop is not None:  # the old task must not replay: zero until a trajectory
            self.loop.drop_trajectory()
        self.braked = bool(self.p["hold_until_command"]) and self.loop is None
        self.command_time = self.next_publish = self.next_shape = self.behind = 0.0
        self.last_wall = time.monotonic()
        self.diverged = None
        if self.timer.is_canceled():
            self.timer.reset()
        if was_diverged:
            self.publish_diagnostic(conv.diagnostic_status(
                self.get_fully_qualified_name(), self.arm_io.name, "ok",
                "reset after a divergence: running"))
            self.get_logger().info("reset after the divergence: the model runs again")
        self.publish_state(full=True)
        response.success, response.message = True, "reset to the initial state at t = 0"
        return response

    def on_status(self) -> None:
        """The node's OK status on /diagnostics every second of wall time, in every mode
        (a diagnostic aggregator marks a node stale without one); after a divergence
        on_tick repeats the ERROR instead."""
        if self.diverged is None:
            self.publish_diagnostic(conv.diagnostic_status(
                self.get_fully_qualified_name(), self.arm_io.name, "ok",
                f"{self._activity(self.paused)} ({self.p['mode']})",
                t=fmt(self.arm_io.t)))

    def on_pause(self, request, response):
        if not self.active:
            response.success, response.message = False, self._inactive()
            return response
        was_paused, self.paused = self.paused, bool(request.data)
        if self.p["mode"] == "lockstep":  # realtime: paused ticks keep last_wall on the grid
            self.last_wall = time.monotonic()
            if was_paused and not self.paused:
                self.step(1.0 / self.p["rate"])  # restart the model-controller loop
        response.success, response.message = True, "paused" if self.paused else "running"
        return response

    # ------------------------------------------------------------- loop
    def on_tick(self) -> None:
        now = time.monotonic()
        elapsed, self.last_wall = now - self.last_wall, now
        if self.diverged is not None:  # stopped until ~/reset: the diagnostic every second
            if now >= self.next_diagnostic:
                self.next_diagnostic = now + 1.0
                self.publish_diagnostic(self.diverged)
            if now >= self.next_held_state:  # the last good state, its effort zero
                self.next_held_state = now + 1.0 / self.p["publish_rate"]
                self.publish_state(full=True, shape=False)
            return
        if self.paused:
            return
        if self.loop is not None and self.p["mode"] == "lockstep":
            # as fast as the arm computes: control periods for LOCKSTEP_SLICE s of wall time,
            # then back to the executor (trajectories, payload, services)
            end = now + LOCKSTEP_SLICE
            while self.diverged is None and time.monotonic() < end:
                # one compiled call up to the next publication (flex_model.control_kernel)
                k = max(1, int(round((self.next_publish - self.arm_io.t) / self.loop.period)))
                self.step(k * self.loop.period)
            return
        if self.p["mode"] == "lockstep":  # watchdog: no command for lockstep_timeout
            if elapsed < self.p["lockstep_timeout"]:
                self.last_wall -= elapsed  # keep measuring from the last step
                return
            if self.commanded:  # the loop stalled
                self._warn_once("lockstep", "lockstep: no command within lockstep_timeout; "
                                "stepping with the held command (timeout_action after "
                                "command_timeout)")
                self.apply_command_timeout(stalled=True)
            else:  # the start: a time-triggered controller waits for this first step
                self._warn_once("start", "lockstep: no command yet; stepping with the held "
                                "command every lockstep_timeout until one arrives", "info")
            self.step(1.0 / self.p["rate"])
            return
        self.realtime_period(elapsed)
        if self.p["realtime_priority"] and self._alone_in_executor() \
                and os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR):
            self._realtime_slice()  # (not when SCHED_FIFO was refused: no CAP_SYS_NICE)

    def realtime_period(self, elapsed: float) -> None:
        """One period of the realtime loop: integrate the owed wall time (``elapsed`` since
        the last period, s) in whole steps, with a quarter step of slack: timer jitter about
        the step grid must not alternate ticks of 0 and 2 steps (the state may then run up
        to h/4 ahead of the wall clock); a stalled process owes at most 0.1 s."""
        h = self.arm_io.period if self.loop is None else self.loop.period
        self.behind = min(self.behind + elapsed, 0.1)
        n = int(self.behind / h + 0.25)
        if n:
            self.behind -= n * h
            self.step(n * h)

    def _alone_in_executor(self) -> bool:
        ex = self.executor
        return REALTIME_SLICE > 0 and ex is not None and len(ex.get_nodes()) == 1

    def _realtime_slice(self) -> None:
        """Run the next realtime periods inside this timer callback, for up to
        REALTIME_SLICE s of wall time, waiting on a wait set of this node's own timer,
        subscriptions and services: rclpy's executor rebuilds its wait set in Python from
        every entity on each wake-up (0.3-0.7 ms per 1 ms period on the dev machine,
        more than the period's step and publication), this one costs tens of us. The
        timer is called as the executor would (its grid and period stay); a ready message
        or service request ends the slice at once, so the executor handles every input as
        before. Only with realtime_priority (SCHED_FIFO: the thread that now sleeps most of
        the period gets its core back at once; with normal scheduling CPU-bound neighbours
        take it: 17-27 % missed periods at load 1.1-1.8, against 0.3-39 % without) and
        when this node is alone in its executor (other nodes' callbacks would wait for the
        slice)."""
        subs, srvs, timer = list(self.subscriptions), list(self.services), self.timer
        end = time.monotonic() + REALTIME_SLICE
        with ExitStack() as stack:
            for entity in (*subs, *srvs, timer):
                stack.enter_context(entity.handle)
            stack.enter_context(self.context.handle)
            ws = _rclpy.WaitSet(len(subs), 0, 1, 0, len(srvs), 0, self.context.handle)
            # back to the executor right after a period that left most of the period idle
            # (not after a publication), so that its wake-up does not delay the next one
            # (an overloaded loop, never idle, returns after twice the slice: the executor's
            # guard conditions, Ctrl-C and QoS events wait at most that long)
            idle = 0.7e9 / self.p["rate"]  # ns
            while not self.paused and self.diverged is None and not timer.is_canceled():
                now = time.monotonic()
                if now >= end + REALTIME_SLICE or (now >= end and
                                                   timer.time_until_next_call() >= idle):
                    return
                ws.clear_entities()
                for sub in subs:
                    ws.add_subscription(sub.handle)
                for srv in srvs:
                    ws.add_service(srv.handle)
                ws.add_timer(timer.handle)
                ws.wait(int(4e9 / self.p["rate"]))  # (a timer is due within a period)
                if ws.get_ready_entities("subscription") or \
                        ws.get_ready_entities("service"):
                    return  # an input: back to the executor, which takes it
                if not ws.get_ready_entities("timer") or not timer.handle.is_timer_ready():
                    continue
                timer.handle.call_timer()
                now = time.monotonic()
                elapsed, self.last_wall = now - self.last_wall, now
                self.realtime_period(elapsed)

    def advance(self) -> None:
        """One model period (1/rate): the command timeout, the step, the publications."""
        self.step(1.0 / self.p["rate"])

    def step(self, dt: float) -> None:
        """Advance the model by dt (s), apply the command timeout, publish."""
        if self.diverged is not None:
            return
        self.apply_command_timeout()
        arm = self.arm_io
        try:
            if self.braked or (self.loop is not None and self.loop.idle and
                               self.p["hold_until_command"]):  # until a command/trajectory
                arm.hold(dt)
            elif self.loop is None:
                refined = arm.advance_refining(dt)
                if refined > 1:
                    self.drops.warning(f"integration failed at t = {fmt(arm.t - dt)}"
                                       f" s with the step {fmt(arm.max_step)} s; "
                                       f"integrated again in steps {refined} x shorter")
            else:
                self.loop.advance(max(1, int(round(dt / self.loop.period))))
        except Exception as exc:  # a diverged model stops stepping, loudly, and stays up
            self.on_divergence(exc)
            return
        t = arm.t
        full = t >= self.next_publish - 1e-12
        if full:
            self.next_publish = t + 1.0 / self.p["publish_rate"]
        shape = full and t >= self.next_shape - 1e-12
        if shape:
            self.next_shape = t + 1.0 / self.p["shape_rate"]
        if full or (self.p["mode"] == "lockstep" and self.loop is None):
            self.publish_state(full=full, shape=shape)
        if self.fjt is not None:  # the running FollowJointTrajectory goal's verdict
            self.fjt.check()

    def apply_command_timeout(self, stalled: bool = False) -> None:
        """After command_timeout s (simulation time) without a valid command, or at once on
        a lockstep watchdog step (``stalled``: no command for lockstep_timeout of wall
        time), timeout_action: zero torque (with the continuous PD: zero feed-forward), or
        hold. Not with an in-loop controller plugin."""
        timeout = self.p["command_timeout"]
        if self.loop is not None or timeout <= 0:
            return
        if stalled or self.arm_io.t - self.command_time > timeout + 1e-12:
            if self.p["timeout_action"] == "zero" and np.any(self.arm_io.u):
                self.arm_io.zero_command()
                self._warn_once("timeout", f"no valid command for command_timeout = "
                                f"{timeout:g} s (or a stalled lockstep loop): zero torque")
            elif self.p["timeout_action"] == "hold":
                self._warn_once("timeout-hold", f"no valid command for command_timeout = "
                                f"{timeout:g} s: holding the last command")

    def on_divergence(self, exc: Exception) -> None:
        """The integration failed: name the likely cause (the inputs held), command zero
        torque, stop stepping (the timer keeps running: commands are answered with a
        reason, the diagnostic repeats every second) until ~/reset."""
        arm = self.arm_io
        u = arm.u.copy()
        k = int(np.argmax(np.abs(u))) if u.size else 0
        peak = self._largest_recent_command(u)
        cause = (f"the arm's state ran away under the joint command {fmt(u)} applied when it "
                 f"failed (largest {fmt(abs(u[k]))} at {self.names[k]}){peak} with the "
                 f"payload {arm.payload_text()}: likely a command or payload beyond what "
                 "this arm can follow, or an unstable control loop (a sampled joint "
                 "controller too stiff for the arm)")
        self.diverged_at = arm.t
        self.diverged = conv.diagnostic_status(
            self.get_fully_qualified_name(), arm.name, "error",
            f"model diverged at t = {fmt(arm.t)} s: {cause}; zero torque commanded, stepping "
            "stopped; call ~/reset to restart",
            t=fmt(arm.t), command=fmt(u), payload=arm.payload_text(), integrator=str(exc))
        arm.stop()  # zero torque (no restart of the method on a run-away state)
        self.get_logger().error(self.diverged.message + f" ({exc})")
        self.publish_diagnostic(self.diverged)
        self.next_diagnostic = time.monotonic() + 1.0
        self.next_held_state = 0.0  # the held state from the next tick on, effort zero
        if self.fjt is not None:
            self.fjt.check()

    def _largest_recent_command(self, applied) -> str:
        """'; the largest command before: [..] at t = .. s' (of the last COMMAND_MEMORY
        since the start or ~/reset) if it exceeds the applied one (a pulse that left the
        arm running away, a command timed out to zero), else ''."""
        if not self.recent_commands:
            return ""
        tc, u = max(self.recent_commands, key=lambda item: float(np.max(np.abs(item[1]))))
        if np.max(np.abs(u)) <= np.max(np.abs(applied)):
            return ""
        return f"; the largest command before: {fmt(u)} at t = {fmt(tc)} s"

    def publish_state(self, full: bool = True, shape: bool = True) -> None:
        """/joint_states, then /clock (a sim-time controller, woken by the clock, then has
        the new state also across processes); with ``full`` the other topics (/flex/shape
        only with ``shape`` too). The costly ones (shape, IMU, /tf) only while someone
        listens (get_subscription_count costs about 1 us)."""
        arm, t = self.arm_io, self.arm_io.t
        self.pub_js.publish(self.cdr_js.fill(t, arm.joint_values()))
        if self.pub_clock is not None:
            self.pub_clock.publish(self.cdr_clock.fill(t))
        if not full:
            return
        self.pub_defl.publish(self.cdr_defl.fill(t, arm.deflection_values()))
        self.pub_tip.publish(self.cdr_tip.fill(t, arm.tip_values()))
        if shape and self.pub_shape.get_subscription_count():  # base frame, z up (REP 103)
            # serialized in place: the same message, 0.03 instead of 0.4 ms (conversions)
            self.pub_shape.publish(self.msg_shape.serialized(
                t, arm.shape_lines(int(self.p["shape_points"]))))
        if shape:
            arm.live(t)
        if self.pub_imu is not None and self.pub_imu.get_subscription_count():
            self.pub_imu.publish(arm.imu_message(t))
        if self.pub_tf is not None and self.pub_tf.get_subscription_count():
            self.pub_tf.publish(arm.tf_message(t))


class PlanarArm:
    """A planar arm in the model node: its :class:`~flex_model.stepper.Stepper` and what
    the node publishes of it (frames: flex_model.urdf, the plane's (x, y, phi) turned by
    urdf.plane_rotation into the base frame, z up)."""

    torque_unit = "N m"
    has_setpoints = False

    def __init__(self, node: ModelNode, p: dict):
        arm = planar_arm_parameter(p)
        self.node, self.p = node, p
        self.model = model = FlexArmModel(arm)
        self.name, n = arm.name, model.n_links
        if p["payload"] != [0.0]:
            if len(p["payload"]) > 2:
                raise ParameterError(f"parameter payload: got {fmt(p['payload'])}; expected "
                                     "[mass] or [mass, inertia] on the planar arm")
            model.set_payload(*(list(p["payload"]) + [0.0])[:2])
        values = p["initial_joint_values"]
        if len(values) not in (1, n):
            raise ParameterError(f"parameter initial_joint_angles_deg: got "
                                 f"{fmt(np.degrees(values))}; expected {n} angles (deg, one "
                                 f"per joint of {arm.name}) or one for every joint")
        theta0 = np.broadcast_to(np.asarray(values, float), (n,))
        q0 = model.q_from_joint_angles(theta0)
        if p["start_static"]:  # at rest, deflected under gravity with the joints held
            from ..statics import static_equilibrium
            q0 = static_equilibrium(model, theta0, joints="clamped").q
        self.stepper = Stepper(model, q0, max_step=p["max_step"], rho_inf=p["rho_inf"])
        self.auto_limits = plausibility_limits(model)
        self.payload0 = tuple(self.stepper.model.payload)
        self.names = arm.joint_names
        self.links = [lk.name for lk in arm.links]
        self.has_imu = any(s.kind == "tip_accelerometer" for s in arm.sensors)
        self.plugin = p["controller"] not in ("", "none")
        self.in_loop = self.plugin
        # REP 103/105 frames (flex_model.urdf): the plane's coordinates in the base frame
        self.frames = urdf.Frames.of(model, p["frame_prefix"], p["frame_id"])
        self.plane = urdf.plane_rotation(model.gravity)
        self.base_frame = self.frames.base
        self.outputs = conv.PlanarOutputs(model, self.plane)
        self.deflection_names = self.outputs.names
        self.shape_labels = [f"link{i + 1}" for i in range(n)]
        self.shape_widths = (0.02, 0.005)
        self.cdr_imu = conv.imu_cdr(self.frames.tips[-1]) if self.has_imu else None
        from ..live_view import node_live_view  # Foxglove WebSocket (issue 46); 0: None
        self.live_view = node_live_view(model, p["foxglove_port"], p["frame_prefix"],
                                        p["frame_id"], p["shape_points"],
                                        node.get_logger())
        self._values = np.empty(3 * n)  # the float64 fields of joint_states
        self._origins = None

    # the state, the stepping
    t = property(lambda self: self.stepper.t)
    u = property(lambda self: self.stepper.u)
    max_step = property(lambda self: self.stepper.max_step)
    period = property(lambda self: self.stepper.max_step)

    def summary(self) -> str:
        return (f"arm {self.name} ({self.model.nq} coordinates, joints "
                f"{', '.join(self.names)})")

    def robot_description(self) -> str:
        n = self.model.n_links
        return urdf.robot_description(self.model, self.p["frame_prefix"], self.p["frame_id"],
                                      effort_limits=[self.node.limit("max_torque")] * n)

    def set_command(self, u) -> None:
        self.stepper.set_command(u)

    def zero_command(self) -> None:
        self.stepper.set_command(np.zeros(self.model.n_links))

    def stop(self) -> None:
        self.stepper.u[:] = 0.0

    def set_setpoints(self, data) -> None:
        raise ValueError("no set-point controller on a planar arm")

    def payload_from(self, data, limit):
        m, j = (float(v) for v in conv.finite_array(data, 2, "payload [mass, inertia]"))
        conv.check_payload(((m, "mass", "kg"), (j, "inertia", "kg m^2")), limit)
        return m, j

    def set_payload(self, payload) -> None:
        self.stepper.set_payload(*payload)

    def payload_text(self) -> str:
        mass, inertia = self.stepper.model.payload
        return f"{fmt(mass)} kg, {fmt(inertia)} kg m^2"

    def reset(self) -> None:
        self.stepper.model.set_payload(*self.payload0)
        self.stepper.reset()

    def advance_refining(self, dt: float) -> int:
        return self.stepper.advance_refining(dt)

    def hold(self, dt: float) -> None:
        self.stepper.hold(dt)

    def close(self) -> None:
        if self.live_view is not None:
            self.live_view.close()
        self.live_view = None

    # the outputs
    def joint_values(self) -> np.ndarray:
        n, values = self.model.n_links, self._values
        self._joint = position, velocity, effort = self.stepper.joint_state()
        values[:n], values[n:2 * n], values[2 * n:3 * n] = position, velocity, effort
        return values[:3 * n]

    def deflection_values(self) -> np.ndarray:
        """Per link (deflection, rotation), then their rates (conv.PlanarOutputs)."""
        return self.outputs.deflections(self.stepper.q, self.stepper.v)

    def tip_values(self):
        q = self.stepper.q
        self._origins = self.model.link_origins(q)
        x, y = self._origins[-1]  # st.tip_pose()
        self._phi = self.outputs.phi(q)
        return conv.tip_pose_values(x, y, self._phi, self.plane)

    def shape_lines(self, points: int) -> list:
        return [urdf.plane_to_base(self.plane, line)
                for line in self.model.shape(self.stepper.q, points)]

    def live(self, t: float) -> None:
        if self.live_view is not None:
            self.live_view.publish(t, self.stepper.q, *self._joint)

    def imu_message(self, t: float):
        """flex/tip_imu (bytes) in the last link's tip frame."""
        st = self.stepper
        rate = float(self.model.tip_torque_vector() @ st.v)  # tip frame rotation rate
        orientation = urdf.quaternion_from_matrix(
            self.plane @ urdf.matrix_from_quaternion(urdf.yaw_quaternion(self._phi)))
        return self.cdr_imu.fill(t, conv.imu_values(st.tip_specific_force(), rate,
                                                    orientation))

    def tf_setup(self, tf_type) -> list:
        """The static transforms (base -> arm_plane); the moving ones as numbers into a
        CDR template (flex_model.ros.cdr_messages)."""
        self.tf_values = urdf.ArmTransforms(self.model, self.frames)
        self.cdr_tf = conv.transforms_cdr(tf_type, self.tf_values.pairs)
        return urdf.static_transforms(self.model, self.frames)

    def tf_message(self, t: float):
        """The TFMessage of urdf.arm_transforms, as bytes."""
        rows = self.tf_values.values(self.stepper.q, self._origins)
        return self.cdr_tf.fill(t, rows.ravel())


def _arm_argument(argv, name: str = "arm") -> str | None:
    """The value of ``-p <name>:=...`` (default the arm) among the ROS arguments (the last
    one wins)."""
    value, prefix = None, name + ":="
    for a, b in zip(argv, list(argv[1:]) + [""]):
        if a in ("-p", "--param") and b.startswith(prefix):
            value = b[len(prefix):]
    return value


def SpatialModelNode(**kwargs) -> ModelNode:  # noqa: N802 (the former class's name)
    """The model node with the spatial defaults (:data:`SPATIAL_DEFAULTS`)."""
    return ModelNode(defaults=SPATIAL_DEFAULTS, **kwargs)


def spatial_main(args=None) -> None:
    """flex-spatial-model-node: the model node with :data:`SPATIAL_DEFAULTS`."""
    run_node(SpatialModelNode, args)


def main(args=None) -> None:
    """A spatial arm (issue 25) runs with :data:`SPATIAL_DEFAULTS`, ``mode:=observer``
    (issue 45) is :mod:`flex_model.ros.observer_node`."""
    argv = sys.argv if args is None else args
    if _arm_argument(argv, "mode") == "observer":
        from .observer_node import main as observer_main
        return observer_main(args)
    arm = _arm_argument(argv)
    if arm:
        from ..spatial.description import is_spatial_arm
        if is_spatial_arm(arm) or _arm_argument(argv, "from_planar") == "true":
            return run_node(SpatialModelNode, args)
    run_node(ModelNode, args)


if __name__ == "__main__":
    main()
