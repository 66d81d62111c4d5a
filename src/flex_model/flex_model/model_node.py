"""ModelNode: the flexible arm as a ROS 2 node (a thin adapter around flex_model.stepper).

Topic names are relative, so a namespace (``--ros-args -r __ns:=/robot1``) moves the whole
model-controller loop; in the root namespace they are the absolute names below.
/diagnostics, /tf and /tf_static stay global (ROS tools expect them there; frame_prefix
keeps two TF trees apart); the clock is ``clock_topic`` (default /clock; ``clock`` puts it
in the namespace, for two lockstep twins).

Publications (simulation time in every header; frames: flex_model.urdf, REP 103 z up):
    joint_states        sensor_msgs/JointState   joint angles (encoder), rates, applied torques
    flex/deflections    sensor_msgs/JointState   link<i>/tip_deflection (m), tip_rotation (rad)
    flex/tip_pose       geometry_msgs/PoseStamped  tip of the arm in ``frame_id`` (the
                        base, z up, as flex/shape: its last point; the plane's (x, y, phi)
                        turned by urdf.plane_rotation)
    flex/shape          visualization_msgs/MarkerArray  deflected centre lines and chords, in
                        ``frame_id`` (the base, z up)
    flex/tip_imu        sensor_msgs/Imu          when the arm has a tip_accelerometer sensor,
                        in the last link's tip frame
    robot_description   std_msgs/String          the URDF (transient local, depth 1)
    /tf, /tf_static     tf2_msgs/TFMessage       joints, link roots, deflected tips (/tf
                        while someone subscribes); base -> arm_plane (where tf2_msgs
                        imports: scripts/bootstrap.sh builds it)
    /clock              rosgraph_msgs/Clock      in lockstep mode (or publish_clock), on
                        ``clock_topic``
    /diagnostics        diagnostic_msgs/DiagnosticArray  OK (running or paused, mode,
                        simulation time) every second of wall time in every mode; ERROR
                        after a divergence (every second until ~/reset), OK after it
Subscriptions:
    effort_controller/commands  std_msgs/Float64MultiArray  joint torques, joint order
    flex/payload                std_msgs/Float64MultiArray  [mass kg, inertia kg m^2]
Services: ~/reset (std_srvs/Trigger: initial state and payload, zero command, t = 0; an
in-loop controller's trajectory is dropped: zero until the next one; after a divergence it
restarts the loop), ~/pause (std_srvs/SetBool).
Action (with an in-loop controller, where control_msgs imports): joint_trajectory_controller/
follow_joint_trajectory (control_msgs/FollowJointTrajectory, flex_model.ros_trajectory_action).

Parameters (:data:`PARAMETERS`: defaults, descriptions, checks): arm (default
thesis_example1_motors: with its geared motors the default controller node, a sampled
Eq. 95 PD with h = 25, a = 5 at 500 Hz, holds it; on the hub-less thesis_example1 any
sampled rate feedback acts on the tiny root inertia of a flexible link and diverges within
0.1 s), vars_per_link, kinematics, mode (realtime | lockstep), rate (Hz, model loop),
publish_rate (Hz), shape_rate (Hz, /flex/shape, at most publish_rate), max_step (s),
initial_joint_angles_deg (one per joint, or one for all), start_static (start deflected at
rest under gravity), start_paused (until ~/pause false), hold_until_command (default true:
from the start and after ~/reset the initial state is held, time running, until the first
valid command, or with an in-loop controller after ~/reset the next trajectory: the arm
does not fall before its controller connects), command_timeout (s of simulation
time, default 0.5, 0 = never; lockstep: a watchdog step applies it at once; not with an
in-loop controller), timeout_action (zero, the default, | hold), lockstep_timeout (s,
wall), frame_id (the base frame, root of the URDF and TF), frame_prefix, publish_tf,
clock_topic, shape_points, publish_clock, the plausibility limits max_torque (N m),
max_payload_mass (kg) and max_payload_inertia (kg m^2) (a command or payload beyond them
is dropped with a logged reason; 0, the default: automatic from the arm,
:func:`plausibility_limits`, logged at start: 100 N m or 10 x the static gravity torque
of the stretched arm or 100 s^-2 x its inertia about joint 1, whichever is largest, 10 x
the arm's mass, 10 x that inertia; thesis_example1_motors: 490 N m, 8.2 kg, 49 kg m^2),
realtime_priority (0 = off; 1-99:
SCHED_FIFO priority of the thread that creates and spins the node, realtime mode, as
ros2_control's thread_priority; needs CAP_SYS_NICE), parameter_services and
qos_event_warnings (default true; false: the node has no parameter services, resp. no
QoS-event handlers, which only log incompatible QoS or types: fewer entities in every wait
of the SingleThreadedExecutor, a faster lockstep loop, see flex_model.ros_main). A float
parameter takes an integer (``rate:=500``); a bad value at start is one line naming the
parameter, the value and what is allowed (exit status 2). At run time publish_rate,
shape_rate, command_timeout, timeout_action, lockstep_timeout and the plausibility limits
may be set (checked); the others are read_only in their descriptors (rclpy refuses them),
and the bounded numbers carry ranges (:data:`RANGES`).

Lifecycle (issue 46, flex_model.ros_main.Managed, docs/ros.md "Lifecycle"): a managed
node; ``autostart`` (default true) configures and activates it at start; false: it starts
unconfigured for a lifecycle manager. configure loads the arm, activate runs the loop,
deactivate holds the state (time stands still, inputs refused), cleanup releases the arm.

Bad inputs are dropped with a reason logged at most once a second per reason (not per
call site: a wrong length does not hide a NaN). A failed integration step (Newton fails,
the state runs away) under external commands is done again in steps 4, then 16 x
shorter (Stepper.advance_refining; a warning line). If that fails too, the model diverged:
one error names the command applied then, the largest command before (of the last
COMMAND_MEMORY) and the payload, publishes the ERROR diagnostic, sets the command to zero
and stops stepping; the node stays up (commands are answered with a reason), publishes the
last good state with zero effort (at publish_rate, at most the timer's rate) and ~/reset
restarts it.

realtime: a timer at ``rate`` integrates the wall time elapsed since the last tick in steps
of exactly ``max_step`` (rcl timers skip missed periods: a late tick catches up with several
steps; simulation time stays on the step grid, within a step of the wall clock). With
realtime_priority in effect (SCHED_FIFO) and the node alone in its executor, one timer
callback runs the periods of up to REALTIME_SLICE s on a wait set of its own and returns
at once on any input (the executor's wait-set rebuild per period cost more than the
period's work).
joint_states, flex/deflections, flex/tip_pose, flex/tip_imu go out at publish_rate,
flex/shape at shape_rate. lockstep: deterministic; each command advances the model by
1/rate and publishes the new joint_states (and /clock) at once, the other topics at their
rates, so simulation time moves only as the model-controller loop completes; without a
command for ``lockstep_timeout`` (wall) the model steps with the held one (a warning once
the loop ran; before the first command this is the start: a controller timed by /clock
needs that first step). The state messages are serialized once (CDR templates,
flex_model.cdr_messages) and published as bytes, only their stamps and numbers written
per publication (the same bytes a subscriber got from the message objects; /tf too,
from flex_model.urdf.ArmTransforms); flex/shape, flex/tip_imu and /tf only while someone
subscribes.
"""
from __future__ import annotations

import os
import sys
import time
from collections import deque
from contextlib import ExitStack

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as SteadyClock, ClockType
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.lifecycle import LifecycleNode
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import Imu, JointState
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from . import ros_conversions as conv
from . import urdf
from .control_loop import ControlLoop
from .controller_interface import load_controller
from .dynamics import FlexArmModel
from .ros_main import (FLOAT_MAX, INT_MAX, Managed, Param, ParameterError, ReasonLog, fmt,
                       lean_node, planar_arm_parameter, read_parameters, run_node)
from .stepper import Stepper
from .ros_trajectory_action import action_server
from .trajectory_action import INVALID_GOAL


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


def _positive(v):
    return None if v > 0 else "a number > 0"


def _non_negative(v):
    return None if v >= 0 else "a number >= 0 (0: automatic)"


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
    Param("arm", "thesis_example1_motors", "arm preset name or arm YAML path (the default "
          "has geared motors: a sampled joint controller is stable on it; the hub-less "
          "thesis_example1 needs its own control design)",
          check=lambda v: None if v else "a preset name or a YAML path"),
    Param("vars_per_link", 0, "deformation variables per link (0: as in the arm file)",
          check=lambda v: None if v >= 0 and v % 2 == 0 else "0 or an even integer >= 2"),
    Param("kinematics", "", "joint-to-link kinematics override (empty: the arm's)"),
    Param("mode", "realtime", "realtime | lockstep (observer: flex_model.observer_node, "
          "which the entry point starts for -p mode:=observer)",
          check=lambda v: None if v in ("realtime", "lockstep") else
          "realtime or lockstep (mode observer is flex_model.observer_node: started by "
          "the entry point with -p mode:=observer, flex-twin observe, or flex-twin up)"),
    Param("rate", 1000.0, "model loop rate (Hz); lockstep: a command advances 1/rate",
          check=_positive),
    Param("publish_rate", 250.0, "rate of the state topics (Hz)", True, _positive),
    Param("shape_rate", 50.0, "rate of flex/shape (Hz), at most publish_rate", True,
          _positive),
    Param("max_step", 1e-3, "integration step (s)",
          check=lambda v: None if 0 < v <= 0.1 else "a step in (0, 0.1] s"),
    Param("initial_joint_angles_deg", [0.0], "initial joint angles (deg): one per joint, "
          "or one value for every joint"),
    Param("command_timeout", 0.5, "s (simulation time) without a valid command before "
          "timeout_action (0: never); lockstep: a step of the lockstep_timeout watchdog (the "
          "loop stalled) applies it at once; not used with an in-loop controller", True,
          lambda v: None if v >= 0 else "a time >= 0 s (0: never)"),
    Param("timeout_action", "zero", "hold | zero (the command after command_timeout)", True,
          _choice("hold", "zero")),
    Param("lockstep_timeout", 1.0, "lockstep: wall s without a command before the model "
          "steps with the held one", True, _positive),
    Param("frame_id", "base_link", "the robot's base frame (REP 105): root of "
          "robot_description and of the TF tree; flex/shape is drawn in it, z up (REP 103)",
          check=lambda v: None if v else "a non-empty frame name"),
    Param("frame_prefix", "", "prefix of every frame name (frame_id too), e.g. robot1/ for "
          "two arms in one TF tree"),
    Param("publish_tf", True, "publish /tf, /tf_static (needs the tf2_msgs package; without "
          "it TF is off, logged once at start); robot_description is always published"),
    Param("clock_topic", "/clock", "topic of the simulation clock (lockstep, or "
          "publish_clock): a relative name (clock) puts it in the node's namespace, so two "
          "lockstep twins do not share one /clock",
          check=lambda v: None if v else "a topic name (/clock, or clock: the namespace's)"),
    Param("shape_points", 15, "points per link of flex/shape",
          check=lambda v: None if 2 <= v <= 10000 else "an integer in [2, 10000]"),
    Param("publish_clock", False, "publish /clock in realtime mode too"),
    Param("foxglove_port", 0, "port of a Foxglove WebSocket live view on 127.0.0.1 "
          "(flex_model.live_view, at shape_rate); 0: off",
          check=lambda v: None if 0 <= v <= 65535 else "0 (off) or a port 1-65535"),
    Param("start_static", False, "start at rest, deflected under gravity"),
    Param("start_paused", False, "start paused (until ~/pause false)"),
    Param("hold_until_command", True, "hold the arm at its initial state (brakes on: time "
          "runs, joints and links stay) from the start and after ~/reset until the first "
          "valid command (an in-loop controller: from ~/reset until the next trajectory); "
          "false: the arm moves under zero torque (falls under gravity) until then"),
    Param("realtime_priority", 0, "SCHED_FIFO priority of the node's thread (0: off)",
          check=lambda v: None if 0 <= v <= 99 else "0 (off) or 1-99"),
    Param("max_torque", 0.0, "plausibility limit of a joint command (N m, or V for "
          "DC-motor joints): a command beyond it is dropped; 0: automatic, the largest of "
          "100 N m, 10 x the static gravity torque of the stretched arm and 100 s^-2 x its "
          "inertia about joint 1", True, _non_negative),
    Param("max_payload_mass", 0.0, "plausibility limit of a payload mass (kg); 0: "
          "automatic, 10 x the arm's mass", True, _non_negative),
    Param("max_payload_inertia", 0.0, "plausibility limit of a payload inertia (kg m^2); "
          "0: automatic, 10 x the stretched arm's inertia about joint 1", True,
          _non_negative),
    Param("controller", "", "in-loop controller run every control period inside the model's "
          "loop (flex_model.controller_interface: eq95, eq45, state_feedback or "
          "module:factory); its parameters are controller_params.<name>; empty: commands "
          "come over effort_controller/commands"),
    Param("controller_rate", 500.0, "rate of the in-loop controller (Hz); its period is "
          "split into steps of at most max_step", check=_positive),
    Param("parameter_services", True, "false: no parameter services (flex_model.ros_main)"),
    Param("qos_event_warnings", True, "false: no QoS-event handlers (flex_model.ros_main)"),
)

#: ranges of the numeric parameters in their descriptors (ros_main.descriptor): the bounds
#: of their checks (an open "> 0" is [0, max] there, the check refuses the 0)
RANGES = {"vars_per_link": (0, INT_MAX, 2), "rate": (0.0, FLOAT_MAX),
          "publish_rate": (0.0, FLOAT_MAX), "shape_rate": (0.0, FLOAT_MAX),
          "max_step": (0.0, 0.1), "command_timeout": (0.0, FLOAT_MAX),
          "lockstep_timeout": (0.0, FLOAT_MAX), "shape_points": (2, 10000),
          "realtime_priority": (0, 99), "max_torque": (0.0, FLOAT_MAX),
          "max_payload_mass": (0.0, FLOAT_MAX), "max_payload_inertia": (0.0, FLOAT_MAX),
          "controller_rate": (0.0, FLOAT_MAX)}


class ModelNode(Managed, LifecycleNode):
    """The arm simulated at ``rate`` and published at ``publish_rate``; a lifecycle node
    (ros_main.Managed): configure loads the arm, activate runs the loop, deactivate holds
    the state (time stands still), cleanup releases the arm."""

    def __init__(self, **kwargs):
        super().__init__("flex_model", **kwargs)
        self.add_on_set_parameters_callback(
            lambda changes: _refuse_controller_params(changes, self.configured))
        self._start_lifecycle(PARAMETERS, lambda d: self.p.update(d))

    def _configure(self) -> None:
        """Read and check the parameters, load the arm, make the publishers,
        subscriptions, services and the in-loop controller."""
        p = read_parameters(self, PARAMETERS, RANGES)
        arm = planar_arm_parameter(p)
        self.model = FlexArmModel(arm)
        n = self.model.n_links
        angles = p["initial_joint_angles_deg"]
        if len(angles) not in (1, n):
            raise ParameterError(f"parameter initial_joint_angles_deg: got {fmt(angles)}; "
                                 f"expected {n} angles (deg, one per joint of {arm.name}) "
                                 "or one for every joint")
        theta0 = np.radians(np.broadcast_to(np.asarray(angles, float), (n,)))
        q0 = self.model.q_from_joint_angles(theta0)
        if p["start_static"]:  # at rest, deflected under gravity with the joints held
            from .statics import static_equilibrium
            q0 = static_equilibrium(self.model, theta0, joints="clamped").q
        self.stepper = Stepper(self.model, q0, max_step=p["max_step"])
        self.auto_limits = plausibility_limits(self.model)
        self.payload0 = tuple(self.stepper.model.payload)
        self.p = p
        self.names = arm.joint_names
        self.links = [lk.name for lk in arm.links]
        self.has_imu = any(s.kind == "tip_accelerometer" for s in arm.sensors)
        self.paused = bool(p["start_paused"])
        # hold_until_command: the initial state held until a command (an in-loop controller
        # commands from the start)
        self.braked = bool(p["hold_until_command"]) and not p["controller"]
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
        self.drops = ReasonLog(self)
        # REP 103/105 frames (flex_model.urdf): the plane's coordinates in the base frame
        self.frames = urdf.Frames.of(self.model, p["frame_prefix"], p["frame_id"])
        self.plane = urdf.plane_rotation(self.model.gravity)
        # the messages of every publication, serialized once and refilled in place
        # (flex_model.cdr_messages: published as bytes, the same messages)
        self.cdr_js = conv.joint_state_cdr(self.names, n)
        self.cdr_defl = conv.joint_state_cdr(conv.deflection_names(self.links), 2 * n,
                                             effort=False)
        self.cdr_tip = conv.tip_pose_cdr(self.frames.base)  # the base, as flex/shape
        self.cdr_clock = conv.clock_cdr()
        self.cdr_imu = conv.imu_cdr(self.frames.tips[-1]) if self.has_imu else None
        self.msg_shape = conv.ShapeMarkers(n, int(p["shape_points"]), self.frames.base)
        from .live_view import node_live_view  # Foxglove WebSocket (issue 46); 0: None
        self.live_view = node_live_view(self.model, p["foxglove_port"], p["frame_prefix"],
                                        p["frame_id"], p["shape_points"],
                                        self.get_logger())
        self._values = np.empty(4 * n)  # the float64 fields of one message
        # what Stepper.deflections and FlexArmModel.tip_pose compute, with their index and
        # selection matrices built once (the same arithmetic: test_ros_model_node_bytes.py)
        self._tip_index = np.array([self.model.tip_deflection_index(i) for i in range(n)])
        self._tip_rotation = self.model.tip_rotation_matrix()
        self._last_alpha = self.model.alpha_index(n - 1)
        qos = 10
        # relative names: a namespace (__ns:=/robot1) moves the whole loop; /diagnostics
        # stays global, as ROS tools (the aggregator) expect; the clock is clock_topic
        self.pub_js = self.create_publisher(JointState, "joint_states", qos)
        self.pub_defl = self.create_publisher(JointState, "flex/deflections", qos)
        self.pub_tip = self.create_publisher(PoseStamped, "flex/tip_pose", qos)
        self.pub_shape = self.create_publisher(MarkerArray, "flex/shape", qos)
        self.pub_imu = self.create_publisher(Imu, "flex/tip_imu", qos) if self.has_imu \
            else None
        self.pub_clock = self.create_publisher(Clock, p["clock_topic"], qos) \
            if p["mode"] == "lockstep" or p["publish_clock"] else None
        self.pub_description = self.create_publisher(String, "robot_description", LATCHED)
        self.pub_tf = self.cdr_tf = None
        self._tf_setup(p)
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", qos)
        self.create_subscription(Float64MultiArray, "effort_controller/commands",
                                 self.on_command, qos)
        self.create_subscription(Float64MultiArray, "flex/payload", self.on_payload, qos)
        self.create_service(Trigger, "~/reset", self.on_reset)
        self.create_service(SetBool, "~/pause", self.on_pause)
        self.loop = self._in_loop_controller(p) if p["controller"] else None
        # control_msgs/FollowJointTrajectory for the in-loop controller (trajectory_action)
        self.fjt = action_server(self) if self.loop is not None else None
        self.timer = None  # the model loop's, while active
        self.create_timer(1.0, self.on_status,  # wall time: sim time may stand still
                          clock=SteadyClock(clock_type=ClockType.STEADY_TIME))
        if p["mode"] == "realtime" and p["realtime_priority"]:
            self._set_realtime_priority(int(p["realtime_priority"]))
        lean_node(self, p["parameter_services"], p["qos_event_warnings"])
        self.pub_description.publish(String(data=urdf.robot_description(
            self.model, p["frame_prefix"], p["frame_id"],
            effort_limits=[self.limit("max_torque")] * n)))
        self.get_logger().info(f"arm {arm.name} ({self.model.nq} coordinates, joints "
                               f"{', '.join(self.names)}), {p['mode']} at {p['rate']:g} Hz, "
                               f"publishing at {p['publish_rate']:g} Hz; plausibility "
                               f"limits {self.limit('max_torque'):.4g} N m, payload "
                               f"{self.limit('max_payload_mass'):.4g} kg, "
                               f"{self.limit('max_payload_inertia'):.4g} kg m^2"
                               + ("; the initial state is held until the first command "
                                  "(hold_until_command)" if self.braked else ""))

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
        self._stop_loop(self.stepper.t)
        if self.fjt is not None:
            self.fjt.finish(INVALID_GOAL, "ended by deactivate (lifecycle)")
        if self.loop is not None:  # as ~/reset: zero (held) until the next trajectory
            self.loop.drop_trajectory()
        else:
            if self.p["timeout_action"] == "zero":
                self.stepper.set_command(np.zeros(self.model.n_links))
            self.braked = bool(self.p["hold_until_command"])

    def _cleanup(self) -> None:
        """Release the arm, the in-loop controller and the live view's server (the
        entities go in ros_main.Managed)."""
        if getattr(self, "fjt", None) is not None:  # (a failed configure: partly built)
            self.fjt.finish(INVALID_GOAL, "ended by cleanup (lifecycle)")
        if getattr(self, "live_view", None) is not None:
            self.live_view.close()
        self.loop = self.fjt = self.live_view = self.stepper = self.model = None

    def _tf_setup(self, p) -> None:
        """/tf_static (base -> arm_plane, latched) once and /tf publishers, if tf2_msgs can
        be imported and publish_tf; else one line saying TF is off and why."""
        if not p["publish_tf"]:
            return
        tf_type, why = tf_message_type()
        if tf_type is None:
            self.get_logger().info(f"TF off: tf2_msgs cannot be imported ({why}; the pip "
                                   "ROS wheels have none, a ROS install has it); "
                                   "robot_description is published, /tf and /tf_static not")
            return
        static = urdf.static_transforms(self.model, self.frames)
        self.create_publisher(tf_type, "/tf_static", LATCHED).publish(
            tf_type(transforms=conv.Transforms(static).msgs))
        self.pub_tf = self.create_publisher(tf_type, "/tf", 100)
        # the moving transforms as numbers into a CDR template (flex_model.cdr_messages)
        self.tf_values = urdf.ArmTransforms(self.model, self.frames)
        self.cdr_tf = conv.transforms_cdr(tf_type, self.tf_values.pairs)

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
        return ControlLoop(self.stepper, ctl, 1.0 / p["controller_rate"])

    def on_trajectory(self, msg: JointTrajectory) -> None:
        try:
            if not self.active:
                raise ValueError(self._inactive())
            data = conv.trajectory_from_msg(msg, self.names)
            start = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            self.loop.set_trajectory(data, start if start > 0 else self.stepper.t)
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
        return self.p[name] or self.auto_limits[name]

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

    def on_command(self, msg: Float64MultiArray) -> None:
        try:
            u = conv.finite_array(msg.data, self.model.n_links, "command",
                                  f"one per joint: {', '.join(self.names)}")
            conv.within_limit(u, self.limit("max_torque"), "command", self.names,
                              "max_torque", "N m")
            if not self.active:
                raise ValueError(self._inactive())
            if self.diverged is not None:
                raise ValueError(f"the model diverged at t = "
                                 f"{fmt(self.diverged_at)} s and is stopped; call ~/reset")
            if self.loop is not None:
                raise ValueError(f"the in-loop controller {self.p['controller']} drives "
                                 "the arm (parameter controller)")
        except ValueError as exc:
            self.drops.warning(f"dropped effort_controller/commands: {exc}; holding the last "
                               "valid command")
            return
        self.stepper.set_command(u)
        self.command_time, self.commanded, self.braked = self.stepper.t, True, False
        self.recent_commands.append((self.command_time, u))
        if self.p["mode"] == "lockstep" and not self.paused:
            self.last_wall = time.monotonic()
            self.step(1.0 / self.p["rate"])

    def on_payload(self, msg: Float64MultiArray) -> None:
        try:
            m, j = (float(v) for v in conv.finite_array(
                msg.data, 2, "payload [mass, inertia]"))
            for value, name, limit, unit in (
                    (m, "mass", "max_payload_mass", "kg"),
                    (j, "inertia", "max_payload_inertia", "kg m^2")):
                if value < 0:
                    raise ValueError(f"payload {name}: got {fmt(value)} {unit}; expected "
                                     ">= 0")
                if value > self.limit(limit):
                    raise ValueError(f"payload {name}: got {fmt(value)} {unit}; expected at "
                                     f"most {limit} = {fmt(self.limit(limit))} {unit} (a "
                                     f"plausibility limit; raise {limit} if intended)")
            if self.diverged is not None:
                raise ValueError("the model diverged and is stopped; call ~/reset")
            if not self.active:
                raise ValueError(self._inactive())
            self.stepper.set_payload(m, j)
        except ValueError as exc:
            self.drops.warning(f"dropped flex/payload: {exc}")
            return
        self.get_logger().info(f"payload now {fmt(m)} kg, {fmt(j)} kg m^2")

    def on_reset(self, request, response):
        """Back to the initial state, payload and a zero command at t = 0; after a
        divergence this restarts the loop (the diagnostic goes back to OK)."""
        if not self.active:
            response.success, response.message = False, self._inactive()
            return response
        was_diverged = self.diverged is not None
        self.stepper.model.set_payload(*self.payload0)
        self.stepper.reset()
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
                self.get_fully_qualified_name(), self.model.arm.name, "ok",
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
                self.get_fully_qualified_name(), self.model.arm.name, "ok",
                f"{self._activity(self.paused)} ({self.p['mode']})",
                t=fmt(self.stepper.t)))

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
                k = max(1, int(round((self.next_publish - self.stepper.t) / self.loop.period)))
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
        h = self.p["max_step"] if self.loop is None else self.loop.period
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

    def step(self, dt: float) -> None:
        """Advance the model by dt (s), apply the command timeout, publish."""
        if self.diverged is not None:
            return
        self.apply_command_timeout()
        try:
            if self.braked or (self.loop is not None and self.loop.idle and
                               self.p["hold_until_command"]):  # until a command/trajectory
                self.stepper.hold(dt)
            elif self.loop is None:
                refined = self.stepper.advance_refining(dt)
                if refined > 1:
                    self.drops.warning(f"integration failed at t = {fmt(self.stepper.t - dt)}"
                                       f" s with the step {fmt(self.stepper.max_step)} s; "
                                       f"integrated again in steps {refined} x shorter")
            else:
                self.loop.advance(max(1, int(round(dt / self.loop.period))))
        except Exception as exc:  # a diverged model stops stepping, loudly, and stays up
            self.on_divergence(exc)
            return
        t = self.stepper.t
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
        time), timeout_action: zero torque, or hold. Not with an in-loop controller."""
        timeout = self.p["command_timeout"]
        if self.loop is not None or timeout <= 0:
            return
        if stalled or self.stepper.t - self.command_time > timeout:
            if self.p["timeout_action"] == "zero" and np.any(self.stepper.u):
                self.stepper.set_command(np.zeros(self.model.n_links))
                self._warn_once("timeout", f"no valid command for command_timeout = "
                                f"{timeout:g} s (or a stalled lockstep loop): zero torque")
            elif self.p["timeout_action"] == "hold":
                self._warn_once("timeout-hold", f"no valid command for command_timeout = "
                                f"{timeout:g} s: holding the last command")

    def on_divergence(self, exc: Exception) -> None:
        """The integration failed: name the likely cause (the inputs held), command zero
        torque, stop stepping (the timer keeps running: commands are answered with a
        reason, the diagnostic repeats every second) until ~/reset."""
        st = self.stepper
        u = st.u.copy()
        k = int(np.argmax(np.abs(u))) if u.size else 0
        mass, inertia = st.model.payload
        peak = self._largest_recent_command(u)
        cause = (f"the arm's state ran away under the joint command {fmt(u)} applied when it "
                 f"failed (largest {fmt(abs(u[k]))} at {self.names[k]}){peak} with the "
                 f"payload {fmt(mass)} kg, {fmt(inertia)} kg m^2: likely a command or payload "
                 "beyond what this arm can follow, or an unstable control loop (a sampled "
                 "joint controller too stiff for the arm)")
        self.diverged_at = st.t
        self.diverged = conv.diagnostic_status(
            self.get_fully_qualified_name(), self.model.arm.name, "error",
            f"model diverged at t = {fmt(st.t)} s: {cause}; zero torque commanded, stepping "
            "stopped; call ~/reset to restart",
            t=fmt(st.t), command=fmt(u), payload_mass_kg=fmt(mass),
            payload_inertia_kg_m2=fmt(inertia), integrator=str(exc))
        st.u[:] = 0.0  # zero torque (no restart of the method on a run-away state)
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

    def publish_diagnostic(self, status) -> None:
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.pub_diag.publish(msg)

    def publish_state(self, full: bool = True, shape: bool = True) -> None:
        """/joint_states, then /clock (a sim-time controller, woken by the clock, then has
        the new state also across processes); with ``full`` the other topics (/flex/shape
        only with ``shape`` too)."""
        st, t = self.stepper, self.stepper.t
        values = self._values
        n = self.model.n_links
        position, velocity, effort = st.joint_state()
        values[:n], values[n:2 * n], values[2 * n:3 * n] = position, velocity, effort
        self.pub_js.publish(self.cdr_js.fill(t, values[:3 * n]))
        if self.pub_clock is not None:
            self.pub_clock.publish(self.cdr_clock.fill(t))
        if not full:
            return
        # per link (deflection, rotation), then their rates (conv.fill_deflection_state)
        q, v, r = st.q, st.v, self._tip_rotation
        values[0:2 * n:2], values[1:2 * n:2] = q[self._tip_index], r @ q
        values[2 * n::2], values[2 * n + 1::2] = v[self._tip_index], r @ v
        self.pub_defl.publish(self.cdr_defl.fill(t, values))
        origins = self.model.link_origins(q)
        x, y = origins[-1]  # st.tip_pose()
        phi = float(q[self._last_alpha] + r[-1] @ q)
        self.pub_tip.publish(self.cdr_tip.fill(t, conv.tip_pose_values(x, y, phi,
                                                                       self.plane)))
        # the costly two only when someone listens (volatile topics: a subscriber that is
        # not there gets nothing either way; get_subscription_count costs about 1 us)
        if shape and self.pub_shape.get_subscription_count():  # base frame, z up (REP 103)
            shapes = [urdf.plane_to_base(self.plane, line)
                      for line in self.model.shape(st.q, int(self.p["shape_points"]))]
            # serialized in place: the same message, 0.03 instead of 0.4 ms (conversions)
            self.pub_shape.publish(self.msg_shape.serialized(t, shapes))
        if shape and self.live_view is not None:
            self.live_view.publish(t, st.q, position, velocity, effort)
        if self.pub_imu is not None and self.pub_imu.get_subscription_count():
            # in the last link's tip frame
            rate = float(self.model.tip_torque_vector() @ st.v)  # tip frame rotation rate
            orientation = urdf.quaternion_from_matrix(
                self.plane @ urdf.matrix_from_quaternion(urdf.yaw_quaternion(phi)))
            self.pub_imu.publish(self.cdr_imu.fill(t, conv.imu_values(
                st.tip_specific_force(), rate, orientation)))
        # /tf while someone subscribes (volatile: a later subscriber gets the next ones,
        # as it would), as bytes: the TFMessage of urdf.arm_transforms
        if self.pub_tf is not None and self.pub_tf.get_subscription_count():
            rows = self.tf_values.values(q, origins)
            self.pub_tf.publish(self.cdr_tf.fill(t, rows.ravel()))


def _arm_argument(argv, name: str = "arm") -> str | None:
    """The value of ``-p <name>:=...`` (default the arm) among the ROS arguments (the last
    one wins)."""
    value, prefix = None, name + ":="
    for a, b in zip(argv, list(argv[1:]) + [""]):
        if a in ("-p", "--param") and b.startswith(prefix):
            value = b[len(prefix):]
    return value


def main(args=None) -> None:
    """A spatial arm (issue 25) goes to :mod:`flex_model.spatial_node`, ``mode:=observer``
    (issue 45) to :mod:`flex_model.observer_node`."""
    argv = sys.argv if args is None else args
    if _arm_argument(argv, "mode") == "observer":
        from .observer_node import main as observer_main
        return observer_main(args)
    arm = _arm_argument(argv)
    if arm:
        from .spatial.description import is_spatial_arm
        if is_spatial_arm(arm):
            from .spatial_node import main as spatial_main
            return spatial_main(args)
    run_node(ModelNode, args)


if __name__ == "__main__":
    main()
