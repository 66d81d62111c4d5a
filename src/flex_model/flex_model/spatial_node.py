"""SpatialModelNode: a spatial arm (issue 25) as a ROS 2 node, a thin adapter around the
compiled generalized-alpha loop (spatial/integrate.simulate_fixed_compiled) and the
message layout of flex_model.ros_spatial (the same as ``flex-twin simulate --bag``).

Topic names are relative (a namespace moves them), /tf is global.

Publications (simulation time in every header):
    joint_states        sensor_msgs/JointState   joint values (rad or m), rates, applied
                        torques/forces (the command clipped to the URDF effort limits; with
                        the eq95 controller kp (s - theta_a) - kd theta_a' + command)
    flex/deflections    sensor_msgs/JointState   link<i>/tip_deflection_y|z (m), tip_twist
                        (rad), rates as velocities
    flex/tip_pose       geometry_msgs/PoseStamped  the last link's end frame (the deflected
                        tip, or the tool frame of a URDF) in the base frame (frame_id)
    flex/shape          visualization_msgs/MarkerArray  per flexible link the deformed centre
                        line and its chord in the base frame, z up (only while
                        subscribed)
    /tf                 tf2_msgs/TFMessage       link roots, deflected tips, link ends (where
                        tf2_msgs imports: scripts/bootstrap.sh builds it; else one log line)
    robot_description   std_msgs/String          the rigid skeleton's URDF (latched)
    /clock              rosgraph_msgs/Clock      lockstep mode (or publish_clock), on
                        ``clock_topic``
    /diagnostics        diagnostic_msgs/DiagnosticArray  OK every second of wall time in every
                        mode; ERROR after a Newton failure (every second until ~/reset),
                        OK after the reset
Subscriptions:
    effort_controller/commands  std_msgs/Float64MultiArray  joint torques/forces, joint
                                order (with eq95: feed-forward added to the PD)
    flex/setpoints              std_msgs/Float64MultiArray  eq95 set-points (rad or m)
    flex/payload                std_msgs/Float64MultiArray  a payload at the last link's end
                                frame origin, replacing the previous one (spatial/payload.py:
                                [m] | [m, J_z] | [m, Ixx, Iyy, Izz] | [m, Ixx, Iyy, Izz, Ixy,
                                Ixz, Iyz], kg, kg m^2 in the end frame)
Services: ~/reset (std_srvs/Trigger: initial state and payload, zero command, t = 0; after
a Newton failure it restarts the loop), ~/pause (std_srvs/SetBool).

Parameters (:data:`PARAMETERS`): arm (spatial preset or file; with from_planar a planar
preset or file, embedded by spatial.from_planar), mode (realtime | lockstep), rate (Hz:
the model loop and the publications; lockstep: a command advances 1/rate), step (s: the
integration step, 1/rate is split into ceil((1/rate)/step) equal steps), rho_inf,
newton_tol, initial_joint_values (rad or m: one per joint or one for all), start_static
(at rest, deflected under gravity, joints held; with eq95 the PD's equilibrium; with the
initial payload), start_paused (until ~/pause false), payload (the initial payload, a
vector as on flex/payload), controller (none | eq45 | eq95: thesis Eq. 95 with constant
gains; eq45, seed 000's cascade with kpp, kpv, is the same PD with kp = n^2 kpv kpp,
kd = n^2 kpv, n the joint's gear ratio;
tau = kp (s - theta_a) - kd theta_a', inside the compiled loop as spatial/scenario.py runs
it: -kp, -kd as stiffness and damping on the actuator coordinate), kp, kd, setpoints (one
per joint or one for all), command_timeout (s of simulation time without a valid command,
default 0.5, 0 = never; lockstep: a watchdog step applies it at once), timeout_action
(zero, the default, | hold; with eq95 it acts on the feed-forward, the PD keeps holding
the set-points), lockstep_timeout (s, wall: lockstep without a command for this long steps
with the held command), clock_topic, publish_clock (realtime too), frame_id (the base
frame's name, default base_link), frame_prefix (before every frame name: /tf,
robot_description's links, flex/shape, flex/tip_pose; the joint names stay), max_torque,
max_payload_mass, max_payload_inertia (plausibility limits: a command or payload beyond
them is dropped with a reason; 0: automatic, logged at start: the largest of 100 N m,
10 x the largest gravity torque and 100 s^-2 x the inertia about joint 1, 10 x the arm's
mass, 10 x that inertia, all at zero joint values),
shape_points, publish_tf, parameter_services, qos_event_warnings. A bad value at start
is one line naming the parameter, value and what is allowed (exit status 2). At run time
command_timeout, timeout_action, lockstep_timeout and the plausibility limits may be set
(checked); the others are refused with a reason.

Lifecycle (issue 46, flex_model.ros_main.Managed, docs/ros.md "Lifecycle"): a managed
node as the planar one; ``autostart`` (default true) configures and activates it at start;
false: it starts unconfigured for a lifecycle manager. configure loads the arm, activate
runs the loop, deactivate holds the state (time stands still, inputs refused, the command
zero with timeout_action zero), cleanup releases the arm.

Limits of a URDF arm (spatial/limits.py): joint_states' effort and the loop's torques are
the commands clipped to the ``<limit effort>`` (inside the compiled loop; with eq95 the
whole actuator torque, PD and feed-forward, is clipped: simulate_fixed_compiled's
``pd_clip``); the position and velocity limits are checked after every period and a
violation is logged (at most once a second per joint); the arm file's ``joint_stops``
make the position limits end stops (description.JointStops).

Every period (a command in lockstep, a timer tick in realtime) is one call of the
compiled loop, continued from the previous one (its accelerations carried over: periods
under one held input equal one run); a new command, set-point or payload restarts the
method (consistent acceleration) as the planar Stepper does (``restart_on_change``: false
continues through command and set-point changes too, as one compiled run over a torque
array; a payload change always restarts: the mass matrix changes).
Bad messages (wrong length, NaN/inf, a command or payload beyond the plausibility
limits, a negative mass) are dropped with a logged reason (at most once a second per
reason) and counted (``dropped``), the last valid value held; a Newton failure logs an error,
publishes the ERROR diagnostic, stops stepping and keeps the node up (commands are
answered with a reason; ~/reset restarts).
"""
from __future__ import annotations

import math
import time
from types import SimpleNamespace

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rclpy.clock import Clock as SteadyClock, ClockType
from rclpy.lifecycle import LifecycleNode
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import MarkerArray

from . import ros_spatial as sr
from .config import ConfigError
from .ros_conversions import diagnostic_status, within_limit
from .ros_main import (Managed, Param, ParameterError, ReasonLog, fmt, lean_node, read_parameters,
                       run_node)
from .urdf import quaternion_from_matrix

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: realtime: at most this many periods are caught up in one tick (the rest is dropped)
MAX_CATCH_UP = 20
#: lockstep: period (s, wall) of the watchdog timer (lockstep_timeout, the diagnostic)
WATCHDOG_PERIOD = 0.05


def _positive(v):
    return None if v > 0 else "a number > 0"


def _non_negative(v):
    return None if v >= 0 else "a number >= 0 (0: automatic)"


def _choice(*options):
    return lambda v: None if v in options else "one of " + ", ".join(options)


def _gains(v):
    return None if v and all(x >= 0 for x in v) else "one or more gains >= 0"


def _payload_check(v):
    from .spatial.payload import payload_inertia
    try:
        payload_inertia(v)
    except ValueError as exc:
        return f"a payload vector ({exc})"
    return None


PARAMETERS = (
    Param("arm", "seed003_like_arm", "spatial arm preset name or YAML path (from_planar: "
          "a planar preset or file)", check=lambda v: None if v else "a preset or a path"),
    Param("from_planar", False, "embed the planar arm ``arm`` in 3D (spatial.from_planar)"),
    Param("mode", "realtime", "realtime | lockstep", check=_choice("realtime", "lockstep")),
    Param("rate", 250.0, "model loop and publication rate (Hz); lockstep: a command "
          "advances 1/rate", check=_positive),
    Param("step", 1e-3, "integration step (s), at most 1/rate",
          check=lambda v: None if 0 < v <= 0.1 else "a step in (0, 0.1] s"),
    Param("rho_inf", 0.9, "generalized-alpha spectral radius",
          check=lambda v: None if 0 <= v <= 1 else "a number in [0, 1]"),
    Param("newton_tol", 1e-10, "Newton tolerance",
          check=lambda v: None if 0 < v <= 1e-4 else "a number in (0, 1e-4]"),
    Param("initial_joint_values", [0.0], "initial joint values (rad or m): one per joint "
          "or one for all"),
    Param("start_static", False, "start at rest, deflected under gravity (joints held; "
          "with eq95: the PD's equilibrium; with the initial payload)"),
    Param("start_paused", False, "start paused (until ~/pause false)"),
    Param("payload", [0.0], "initial payload at the last link's end frame origin: [m] | "
          "[m, J_z] | [m, Ixx, Iyy, Izz] | [m, Ixx, Iyy, Izz, Ixy, Ixz, Iyz] (kg, kg m^2, "
          "end frame)", check=_payload_check),
    Param("controller", "none", "none | eq95 (in-loop PD, thesis Eq. 95, constant gains) "
          "| eq45 (seed 000's PD-like cascade Eq. 45: the in-loop PD kp = n^2 kpv kpp, "
          "kd = n^2 kpv, n the joint's gear ratio)", check=_choice("none", "eq95", "eq45")),
    Param("kpp", [0.0], "eq45: K_pp (1/s), one per joint or one for all", check=_gains),
    Param("kpv", [0.0], "eq45: K_pv (N m s/rad, motor side), one per joint or one for all",
          check=_gains),
    Param("kp", [0.0], "eq95: N m/rad (N/m), one per joint or one for all", check=_gains),
    Param("kd", [0.0], "eq95: N m s/rad (N s/m), one per joint or one for all",
          check=_gains),
    Param("setpoints", [0.0], "eq95: initial set-points (rad or m), one per joint or one "
          "for all"),
    Param("restart_on_change", True, "restart the integrator (consistent acceleration) when "
          "the command or a set-point changes, as the planar Stepper; false: continue"),
    Param("command_timeout", 0.5, "s (simulation time) without a valid command before "
          "timeout_action (0: never); lockstep: a step of the lockstep_timeout watchdog "
          "applies it at once", True, lambda v: None if v >= 0 else "a time >= 0 s (0: never)"),
    Param("timeout_action", "zero", "hold | zero (the command after command_timeout; with "
          "eq95 the feed-forward)", True, _choice("hold", "zero")),
    Param("lockstep_timeout", 1.0, "lockstep: wall s without a command before the model "
          "steps with the held command", True, _positive),
    Param("frame_id", "base_link", "the robot's base frame (REP 105): root of "
          "robot_description and of the TF tree; flex/shape and flex/tip_pose are in it",
          check=lambda v: None if v else "a non-empty frame name"),
    Param("frame_prefix", "", "prefix of every frame name (frame_id too: /tf, "
          "robot_description's links, flex/shape, flex/tip_pose), e.g. robot1/ for two arms "
          "in one TF tree"),
    Param("publish_clock", False, "publish the clock in realtime mode too"),
    Param("clock_topic", "/clock", "topic of the simulation clock (lockstep): a relative "
          "name (clock) puts it in the node's namespace",
          check=lambda v: None if v else "a topic name (/clock, or clock: the namespace's)"),
    Param("max_torque", 0.0, "plausibility limit of a joint command (N m or N): a command "
          "beyond it is dropped (within it, the URDF effort limits clip); 0: automatic, the "
          "largest of 100, 10 x the largest static gravity torque of the arm at zero joint "
          "values and 100 s^-2 x its inertia about joint 1", True, _non_negative),
    Param("max_payload_mass", 0.0, "plausibility limit of a payload mass (kg); 0: "
          "automatic, 10 x the arm's mass", True, _non_negative),
    Param("max_payload_inertia", 0.0, "plausibility limit of the payload's largest "
          "principal inertia (kg m^2); 0: automatic, 10 x the arm's inertia about joint 1 "
          "at zero joint values", True, _non_negative),
    Param("shape_points", 21, "points per flexible link of flex/shape",
          check=lambda v: None if 2 <= v <= 10000 else "an integer in [2, 10000]"),
    Param("publish_tf", True, "publish /tf (needs tf2_msgs; without it one log line)"),
    Param("parameter_services", True, "false: no parameter services (flex_model.ros_main)"),
    Param("qos_event_warnings", True, "false: no QoS-event handlers (flex_model.ros_main)"),
)


def load_arm_parameter(arm: str, planar: bool):
    """The SpatialArm named by the ``arm`` parameter (ParameterError naming it)."""
    from .spatial.loader import load_spatial_arm
    try:
        if planar:
            from .arm import load_arm
            from .spatial.description import from_planar
            return from_planar(load_arm(arm))
        return load_spatial_arm(arm)
    except (ConfigError, ValueError, OSError) as exc:
        raise ParameterError(f"parameter arm: {exc}") from None


def arm_mass(model) -> float:
    """Total mass of a spatial arm (kg): beams (rhoA ds at the Gauss points) and bodies."""
    m = sum(float(np.sum(b.mass_w)) for b in model.beams if b is not None)
    return m + sum(lk.root_body.mass + lk.end_body.mass for lk in model.arm.links)


def plausibility_limits(model) -> dict:
    """Automatic plausibility limits (the ``0`` of max_torque, max_payload_mass,
    max_payload_inertia), as the planar node's: from the arm's mass, the generalized
    inertia of joint 1 and the joint forces of gravity, all at zero joint values."""
    q = np.zeros(model.nq)
    inertia = float(model.mass_matrix(q)[model.off[0], model.off[0]])
    gravity = float(np.max(np.abs(model.gravity_force(q)[model.off])))
    return {"max_torque": max(100.0, 10.0 * gravity, 100.0 * inertia),
            "max_payload_mass": 10.0 * arm_mass(model),
            "max_payload_inertia": 10.0 * inertia}


class SpatialModelNode(Managed, LifecycleNode):
    """A spatial arm stepped at ``rate`` (realtime) or per command (lockstep); a lifecycle
    node as the planar ModelNode (ros_main.Managed): configure loads the arm, activate
    runs the loop, deactivate holds the state (time stands still), cleanup releases it."""

    def __init__(self, **kwargs):
        super().__init__("flex_model", **kwargs)
        self._start_lifecycle(PARAMETERS, lambda d: self.p.update(d))

    def _configure(self) -> None:
        """Read and check the parameters, load the arm, build the loop's matrices and
        the initial state, make the publishers, subscriptions, services, the status
        timer; robot_description goes out (latched)."""
        from .spatial.dynamics import SpatialArmModel
        from .spatial.limits import joint_limits
        from .spatial.payload import payload_inertia
        p = read_parameters(self, PARAMETERS)
        self.p = p
        self.arm0 = load_arm_parameter(p["arm"], p["from_planar"])   # without payload
        self.payload0 = payload_inertia(p["payload"])
        self.payload = self.payload0
        self.model = self._model_with(self.payload0)
        self.auto_limits = plausibility_limits(  # of the arm without the payload
            self.model if self.model.arm is self.arm0 else SpatialArmModel(self.arm0))
        self.names = list(self.arm.joint_names)
        vec = {k: self._per_joint(k, p[k]) for k in ("initial_joint_values", "kp", "kd",
                                                      "setpoints", "kpp", "kpv")}
        self.period = 1.0 / p["rate"]
        self.per = max(1, int(math.ceil(self.period / p["step"] - 1e-9)))
        self.h = self.period / self.per
        law = p["controller"]
        self.in_loop_pd = law in ("eq95", "eq45")    # Eq. 45 is a joint PD too
        self.motor_joints = [self.names[j] for j, *_ in self.model.motors]
        if self.in_loop_pd and self.motor_joints:
            raise ParameterError(
                f"parameter controller: got {law} on an arm with dc_motor joints "
                f"({', '.join(self.motor_joints)}); expected none: their commands are "
                f"voltages, {law}'s PD gives torques")
        self.kp, self.kd = vec["kp"], vec["kd"]
        if law == "eq45":
            from .spatial.scenario import eq45_joint_gains
            self.kp, self.kd = eq45_joint_gains(self.arm, vec["kpp"], vec["kpv"])
        self.setpoints0 = vec["setpoints"]
        self.act = self.model.actuator_index >= 0
        self.Kp, self.Dp = np.zeros((2, self.model.nq, self.model.nq))
        if self.in_loop_pd:
            for i, a in enumerate(self.model.actuator_index):
                if a >= 0:
                    self.Kp[a, a] += self.kp[i]
                    self.Dp[a, a] += self.kd[i]
        self.limits = joint_limits(self.arm)
        self.effort = self.limits["effort"]
        self.q0, self.v0 = self._initial_state(vec["initial_joint_values"],
                                               p["start_static"])
        self.model0 = self.model
        self.dindex = sr.deflection_index(self.model)
        self.dnames = sr.deflection_names(self.model)
        self.dropped = 0
        self.drops = ReasonLog(self)
        self.warned = set()
        self.paused = bool(p["start_paused"])
        self.reset_state()
        qos = 10
        self.pub_js = self.create_publisher(JointState, "joint_states", qos)
        self.pub_defl = self.create_publisher(JointState, "flex/deflections", qos)
        self.pub_tip = self.create_publisher(PoseStamped, "flex/tip_pose", qos)
        self.pub_shape = self.create_publisher(MarkerArray, "flex/shape", qos)
        self.pub_description = self.create_publisher(String, "robot_description", LATCHED)
        self.pub_clock = self.create_publisher(Clock, p["clock_topic"], qos) \
            if p["mode"] == "lockstep" or p["publish_clock"] else None
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", qos)
        self.pub_tf = self.tf_types = None
        if p["publish_tf"]:
            self._tf_setup()
        self.create_subscription(Float64MultiArray, "effort_controller/commands",
                                 self.on_command, qos)
        self.create_subscription(Float64MultiArray, "flex/setpoints", self.on_setpoints, qos)
        self.create_subscription(Float64MultiArray, "flex/payload", self.on_payload, qos)
        self.create_service(Trigger, "~/reset", self.on_reset)
        self.create_service(SetBool, "~/pause", self.on_pause)
        self.timer = None  # the model loop's, while active
        self.create_timer(1.0, self.on_status,  # wall time: sim time may stand still
                          clock=SteadyClock(clock_type=ClockType.STEADY_TIME))
        lean_node(self, p["parameter_services"], p["qos_event_warnings"])
        self.base = sr.frame_name("base_link", p["frame_prefix"], p["frame_id"])
        self.pub_description.publish(String(data=sr.skeleton_urdf(
            self.model, p["frame_prefix"], p["frame_id"])))
        m, inertia = self.payload0
        self.get_logger().info(
            f"spatial arm {self.arm.name} ({self.model.nq} coordinates, joints "
            f"{', '.join(self.names)}), {p['mode']} at {p['rate']:g} Hz, {self.per} step(s) "
            f"of {self.h:.6g} s a period, controller {p['controller']}, payload {fmt(m)} kg"
            f"{' (paused)' if self.paused else ''}; plausibility limits: command "
            f"{self.limit('max_torque'):.4g} N m (N), payload "
            f"{self.limit('max_payload_mass'):.4g} kg, "
            f"{self.limit('max_payload_inertia'):.4g} kg m^2")
        if self.motor_joints:
            self.get_logger().info(
                f"dc_motor joints {', '.join(self.motor_joints)}: their commands on "
                "effort_controller/commands are voltages (V), through the motor model")

    def _activate(self) -> None:
        """Start the loop from the held state and publish that state: realtime the model
        loop, lockstep the watchdog (steps happen on commands)."""
        self._start_loop(self.period if self.p["mode"] == "realtime" else WATCHDOG_PERIOD)
        self.publish()

    def _deactivate(self) -> None:
        """Stop the loop: time and state stand still, nothing stepping-related is
        published, inputs are refused. The command becomes the command timeout's
        (timeout_action zero: a zero command; with eq95 the PD holds the set-points)."""
        self._stop_loop(self.t)
        if self.p["timeout_action"] == "zero" and np.any(self.u):
            self.u = np.zeros(self.model.n_links)
            self.acc = None if self.p["restart_on_change"] else self.acc

    def _cleanup(self) -> None:
        """Release the arm and its models (the entities go in ros_main.Managed)."""
        self.model = self.model0 = self.arm0 = None

    # ------------------------------------------------------------- set-up
    @property
    def arm(self):
        """The arm as simulated (with the current payload in its last end body)."""
        return self.model.arm

    def _model_with(self, payload):
        from .spatial.dynamics import SpatialArmModel
        from .spatial.payload import with_payload
        return SpatialArmModel(with_payload(self.arm0, *payload))

    def limit(self, name: str) -> float:
        """A plausibility limit: the parameter, or the arm's automatic one if 0."""
        return self.p[name] or self.auto_limits[name]

    def _per_joint(self, name, values) -> np.ndarray:
        n = self.model.n_links
        if len(values) not in (1, n):
            raise ParameterError(f"parameter {name}: got {fmt(values)}; expected {n} values "
                                 f"(one per joint of {self.arm.name}) or one for all")
        return np.array(np.broadcast_to(np.asarray(values, float), (n,)))

    def _initial_state(self, values, static):
        """(q0, v0) as spatial/scenario.py builds them (SpatialScenario.initial_state)."""
        from .spatial.scenario import SpatialPD, SpatialScenario
        sc = SpatialScenario(name=self.arm.name, arm=self.arm, duration=1.0, step=self.h,
                             sample_period=self.period, rho_inf=self.p["rho_inf"],
                             joint_values=values, joint_rates=np.zeros(len(values)),
                             start_static=static,
                             pd=SpatialPD(self.kp, self.kd, self.setpoints0) if self.in_loop_pd
                             else None)
        try:
            q0, v0, _ = sc.initial_state(self.model)
        except (RuntimeError, np.linalg.LinAlgError) as exc:
            raise ParameterError(f"parameter start_static: no static state ({exc})") from None
        return q0, v0

    def _tf_setup(self) -> None:
        try:
            from tf2_msgs.msg import TFMessage
            from builtin_interfaces.msg import Time
            from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
            from std_msgs.msg import Header
        except ImportError as exc:
            self.get_logger().info(f"TF off: tf2_msgs cannot be imported ({exc}; "
                                   "scripts/bootstrap.sh builds it into .venv); "
                                   "robot_description is published, /tf not")
            return
        self.tf_types = SimpleNamespace(TFMessage=TFMessage, Time=Time, Header=Header,
                                        Quaternion=Quaternion, Transform=Transform,
                                        TransformStamped=TransformStamped, Vector3=Vector3)
        self.pub_tf = self.create_publisher(TFMessage, "/tf", 100)

    def reset_state(self) -> None:
        """The initial state, payload and set-points, a zero command, t = 0."""
        self.model = self.model0
        self.payload = self.payload0
        self.q, self.v = self.q0.copy(), self.v0.copy()
        self.t = 0.0
        self.steps = 0
        self.u = np.zeros(self.model.n_links)
        self.setpoints = self.setpoints0.copy()
        self.command_time = 0.0
        self.commanded = False     # a valid command has arrived (lockstep: the loop runs)
        self.diverged = None       # after a Newton failure: its DiagnosticStatus
        self.diverged_at = 0.0
        self.next_diagnostic = 0.0
        self.acc = None   # the method's (a, abar): None restarts it

    # ------------------------------------------------------------- inputs
    def _warn_once(self, key, text, level="warning"):
        """Log ``text`` once per ``key`` (each severity its own call site, as rclpy binds
        one severity to each)."""
        if key in self.warned:
            return
        self.warned.add(key)
        if level == "info":
            self.get_logger().info(text)
        else:
            self.get_logger().warning(text)

    def _vector(self, msg, what, unit) -> np.ndarray:
        n = self.model.n_links
        data = np.asarray(msg.data, float)
        if data.shape != (n,):
            raise ValueError(f"got {len(data)} values; expected {n} ({unit}, one per joint: "
                             f"{', '.join(self.names)})")
        if not np.all(np.isfinite(data)):
            raise ValueError(f"got {fmt(data)}; expected finite values")
        return data

    def _not_diverged(self) -> None:
        """Raise the reason an input is refused: inactive (lifecycle), or diverged."""
        if not self.active:
            raise ValueError(self._inactive())
        if self.diverged is not None:
            raise ValueError(f"the model diverged at t = {fmt(self.diverged_at)} s and is "
                             "stopped; call ~/reset")

    def _drop(self, topic: str, why: str) -> None:
        self.dropped += 1
        self.drops.warning(f"dropped {topic}: {why}; holding the last valid one")

    def on_command(self, msg: Float64MultiArray) -> None:
        try:
            u = self._vector(msg, "command", "N m or N")
            within_limit(u, self.limit("max_torque"), "command", self.names, "max_torque",
                         "N m (N)")
            self._not_diverged()
        except ValueError as exc:
            self._drop("effort_controller/commands", str(exc))
            return
        if self.p["restart_on_change"] and not np.array_equal(u, self.u):
            self.acc = None
        self.u = u
        self.command_time, self.commanded = self.t, True
        if self.p["mode"] == "lockstep" and not self.paused:
            self.last_wall = time.monotonic()
            self.advance()
            self.publish()

    def on_setpoints(self, msg: Float64MultiArray) -> None:
        try:
            if not self.in_loop_pd:
                raise ValueError("no set-point controller (parameter controller is none)")
            s = self._vector(msg, "set-points", "rad or m")
            if not self.active:
                raise ValueError(self._inactive())
        except ValueError as exc:
            self._drop("flex/setpoints", str(exc))
            return
        if self.p["restart_on_change"] and not np.array_equal(s, self.setpoints):
            self.acc = None
        self.setpoints = s

    def on_payload(self, msg: Float64MultiArray) -> None:
        """A new payload (replacing the previous one) at the last link's end frame origin:
        the arm's model is rebuilt with it (spatial/payload.with_payload), the state kept,
        the integrator restarted (the mass matrix changed)."""
        from .spatial.payload import payload_inertia
        try:
            m, inertia = payload_inertia(msg.data)
            largest = float(np.max(np.linalg.eigvalsh(inertia)))
            for value, name, limit, unit in (
                    (m, "mass", "max_payload_mass", "kg"),
                    (largest, "largest principal inertia", "max_payload_inertia", "kg m^2")):
                if value > self.limit(limit):
                    raise ValueError(f"payload {name}: got {fmt(value)} {unit}; expected at "
                                     f"most {limit} = {fmt(self.limit(limit))} {unit} (a "
                                     f"plausibility limit; raise {limit} if intended)")
            self._not_diverged()
        except ValueError as exc:
            self._drop("flex/payload", str(exc))
            return
        from .spatial.payload import model_with_payload
        self.model = model_with_payload(self.model0, self.arm0, m, inertia)
        self.payload = (m, inertia)
        self.acc = None
        self.get_logger().info(f"payload now {fmt(m)} kg, inertia diag "
                               f"{fmt(np.diag(inertia))} kg m^2 (end frame of "
                               f"{self.arm.links[-1].name})")

    def on_reset(self, request, response):
        """Back to the initial state, payload and a zero command at t = 0; after a
        Newton failure this restarts the loop (the diagnostic goes back to OK)."""
        if not self.active:
            response.success, response.message = False, self._inactive()
            return response
        was_diverged = self.diverged is not None
        self.reset_state()
        self.last_wall = time.monotonic()
        self.behind = 0.0
        if was_diverged:
            self.publish_diagnostic(diagnostic_status(
                self.get_fully_qualified_name(), self.arm.name, "ok",
                "reset after a Newton failure: running"))
            self.get_logger().info("reset after the Newton failure: the model runs again")
        self.publish()
        response.success, response.message = True, "initial state and payload, zero " \
            "command, t = 0"
        return response

    def on_pause(self, request, response):
        """Pause (true) or resume (false): paused, no period runs (the simulation time and
        /clock stand still); commands are still taken. Lockstep: resuming runs one period
        (it restarts the model-controller loop)."""
        if not self.active:
            response.success, response.message = False, self._inactive()
            return response
        was_paused, self.paused = self.paused, bool(request.data)
        self.last_wall = time.monotonic()
        self.behind = 0.0
        if self.p["mode"] == "lockstep" and was_paused and not self.paused:
            self.advance()
            self.publish()
        response.success, response.message = True, "paused" if self.paused else "running"
        return response

    # ------------------------------------------------------------- stepping
    def open_loop(self) -> np.ndarray:
        """The joint torques of the period that are not the PD's feedback: the command,
        with eq95 plus kp s."""
        return self.u + self.kp * self.setpoints if self.in_loop_pd else self.u

    def applied(self) -> np.ndarray:
        """The joint torques at the current state (joint_states' effort)."""
        if not self.in_loop_pd:
            return np.clip(self.u, -self.effort, self.effort)
        a = np.maximum(self.model.actuator_index, 0)
        fb = self.kp * self.q[a] + self.kd * self.v[a]
        return np.clip(self.open_loop() - np.where(self.act, fb, 0.0), -self.effort,
                       self.effort)

    def apply_command_timeout(self, stalled: bool = False) -> None:
        """After command_timeout s (simulation time) without a valid command, or at once
        on a lockstep watchdog step (``stalled``), timeout_action: a zero command (with
        eq95 a zero feed-forward), or hold."""
        timeout = self.p["command_timeout"]
        if timeout <= 0:
            return
        if stalled or self.t - self.command_time > timeout + 1e-12:
            if self.p["timeout_action"] == "zero" and np.any(self.u):
                self.u = np.zeros(self.model.n_links)
                self.acc = None if self.p["restart_on_change"] else self.acc
                self._warn_once("timeout", f"no valid command for command_timeout = "
                                f"{timeout:g} s (or a stalled lockstep loop): zero command")
            elif self.p["timeout_action"] == "hold":
                self._warn_once("timeout-hold", f"no valid command for command_timeout = "
                                f"{timeout:g} s: holding the last command")

    def advance(self) -> None:
        """One period (1/rate): the command timeout, then ``per`` steps of the compiled
        loop, then the joint limit check."""
        from .spatial.integrate import simulate_fixed_compiled
        if self.diverged is not None:
            self.drops.error(f"the model diverged at t = {fmt(self.diverged_at)} s and is "
                             "stopped; call ~/reset")
            return
        self.apply_command_timeout()
        K0 = self.model.K
        try:
            self.model.K = K0 + self.Kp
            run = simulate_fixed_compiled(self.model, self.q, self.v, self.h, self.per,
                                          joint_torques=self.open_loop(),
                                          rho_inf=self.p["rho_inf"], tol=self.p["newton_tol"],
                                          damping=self.Dp if self.in_loop_pd else None,
                                          pd_clip=(self.kp, self.kd) if self.in_loop_pd else None,
                                          acceleration=self.acc)
        except RuntimeError as exc:
            self.on_divergence(exc)
            return
        finally:
            self.model.K = K0
        self.q, self.v = run.q[-1].copy(), run.v[-1].copy()
        self.acc = run.acceleration
        self.steps += 1
        self.t = self.steps * self.period
        self.check_limits()

    def check_limits(self) -> None:
        """Log the URDF position and velocity limit violations (positions: pushed back by
        the arm file's joint_stops where it has them, else only reported), at most once a
        second per joint and kind."""
        qj, vj = self.q[self.model.off], self.v[self.model.off]
        lim = self.limits
        how = "in the end stop (joint_stops)" if self.model.stops else \
            "reported, not enforced: the arm file has no joint_stops"
        for i in np.flatnonzero((qj < lim["lower"]) | (qj > lim["upper"])):
            self.drops.warning(f"joint {self.names[i]} at {fmt(qj[i])} outside its URDF "
                               f"limits [{fmt(lim['lower'][i])}, {fmt(lim['upper'][i])}] "
                               f"({how})", key=("position", i))
        for i in np.flatnonzero(np.abs(vj) > lim["velocity"]):
            self.drops.warning(f"joint {self.names[i]} rate {fmt(vj[i])} beyond its URDF "
                               f"velocity limit {fmt(lim['velocity'][i])} (reported, not "
                               "enforced)", key=("velocity", i))

    def on_divergence(self, exc: Exception) -> None:
        """Newton failed: one error naming the held inputs, the ERROR diagnostic (repeated
        every second), a zero command, stepping stopped until ~/reset."""
        m = self.payload[0]
        self.diverged_at = self.t
        self.diverged = diagnostic_status(
            self.get_fully_qualified_name(), self.arm.name, "error",
            f"Newton failed in the period after t = {fmt(self.t)} s under the command "
            f"{fmt(self.u)} with a payload of {fmt(m)} kg: likely a command or payload beyond "
            "what this arm and step can follow; zero command, stepping stopped; call ~/reset "
            "to restart", t=fmt(self.t), command=fmt(self.u), payload_mass_kg=fmt(m),
            integrator=str(exc))
        self.u = np.zeros(self.model.n_links)
        self.get_logger().error(self.diverged.message + f" ({exc})")
        self.publish_diagnostic(self.diverged)
        self.next_diagnostic = time.monotonic() + 1.0

    def publish_diagnostic(self, status) -> None:
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.pub_diag.publish(msg)

    def on_status(self) -> None:
        """The OK status on /diagnostics every second of wall time, in every mode (an
        aggregator marks a silent node stale); after a Newton failure on_tick repeats the
        ERROR instead."""
        if self.diverged is None:
            self.publish_diagnostic(diagnostic_status(
                self.get_fully_qualified_name(), self.arm.name, "ok",
                f"{self._activity(self.paused)} ({self.p['mode']})",
                t=fmt(self.t)))

    def on_tick(self) -> None:
        now = time.monotonic()
        elapsed, self.last_wall = now - self.last_wall, now
        if self.diverged is not None:   # stopped until ~/reset: the diagnostic every second
            if now >= self.next_diagnostic:
                self.next_diagnostic = now + 1.0
                self.publish_diagnostic(self.diverged)
            return
        if self.paused:
            return
        if self.p["mode"] == "lockstep":   # watchdog: no command for lockstep_timeout
            if elapsed < self.p["lockstep_timeout"]:
                self.last_wall -= elapsed  # keep measuring from the last step
                return
            if self.commanded:  # the loop stalled
                self._warn_once("lockstep", "lockstep: no command within lockstep_timeout; "
                                "stepping with the held command (timeout_action at once)")
                self.apply_command_timeout(stalled=True)
            else:   # the start: a controller timed by /clock waits for this first step
                self._warn_once("start", "lockstep: no command yet; stepping with the held "
                                "command every lockstep_timeout until one arrives", "info")
            self.advance()
            self.publish()
            return
        self.behind += elapsed
        n = int(self.behind / self.period)
        if n == 0:
            return
        self.behind -= n * self.period
        if n > MAX_CATCH_UP:   # the machine cannot keep up: drop the backlog
            self.behind, n = 0.0, MAX_CATCH_UP
        for _ in range(n):
            self.advance()
        self.publish()

    # ------------------------------------------------------------- outputs
    def publish(self) -> None:
        t, q, v = self.t, self.q, self.v
        off = self.model.off
        self.pub_js.publish(sr.joint_state(JointState, self.names, q[off], v[off],
                                           self.applied(), t))
        pos, vel = sr.deflection_values(self.dindex, q, v)
        self.pub_defl.publish(sr.joint_state(JointState, self.dnames, pos, vel, (), t,
                                             effort=False))
        if self.pub_clock is not None:
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = sr.stamp(t)
            self.pub_clock.publish(msg)
        tip = self.model.tip_frame(q)
        pose = PoseStamped()
        pose.header.frame_id = self.base
        pose.header.stamp.sec, pose.header.stamp.nanosec = sr.stamp(t)
        o = np.real(tip.o)
        pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = map(float, o)
        x, y, z, w = quaternion_from_matrix(np.real(tip.R))
        o_ = pose.pose.orientation
        o_.x, o_.y, o_.z, o_.w = float(x), float(y), float(z), float(w)
        self.pub_tip.publish(pose)
        lf = None
        if self.pub_tf is not None:
            lf = []
            self.pub_tf.publish(self.tf_types.TFMessage(
                transforms=sr.transforms(self.tf_types, self.model, q, t, lf,
                                         self.p["frame_prefix"], self.p["frame_id"])))
        if self.pub_shape.get_subscription_count() > 0:
            self.pub_shape.publish(sr.shape_markers(self.model, q, t,
                                                    int(self.p["shape_points"]), lf,
                                                    self.p["frame_prefix"], self.p["frame_id"]))


def main(args=None) -> None:
    run_node(SpatialModelNode, args)


if __name__ == "__main__":
    main()
