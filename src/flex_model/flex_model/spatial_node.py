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
    flex/shape          visualization_msgs/MarkerArray  per flexible link the deformed centre
                        line and its chord in base_link, z up (only while subscribed)
    /tf                 tf2_msgs/TFMessage       link roots, deflected tips, link ends (only
                        where tf2_msgs can be imported: not in the pip venv; one log line)
    robot_description   std_msgs/String          the rigid skeleton's URDF (latched)
    /clock              rosgraph_msgs/Clock      lockstep mode
Subscriptions:
    effort_controller/commands  std_msgs/Float64MultiArray  joint torques/forces, joint
                                order (with eq95: feed-forward added to the PD)
    flex/setpoints              std_msgs/Float64MultiArray  eq95 set-points (rad or m)
Services: ~/reset (std_srvs/Trigger: initial state, zero command, t = 0).

Parameters: arm (spatial preset or file; with from_planar a planar preset or file,
embedded by spatial.from_planar), mode (realtime | lockstep), rate (Hz: the model loop and
the publications; lockstep: a command advances 1/rate), step (s: the integration step,
1/rate is split into ceil((1/rate)/step) equal steps), rho_inf, newton_tol,
initial_joint_values (rad or m: one per joint or one for all), start_static (at rest,
deflected under gravity, joints held; with eq95 the PD's equilibrium), controller (none |
eq95: thesis Eq. 95 with constant gains, tau = kp (s - theta_a) - kd theta_a', inside the
compiled loop as spatial/scenario.py runs it: -kp, -kd as stiffness and damping on the
actuator coordinate), kp, kd, setpoints (one per joint or one for all), shape_points,
publish_tf. A bad value at start is one line naming the parameter, value and what is
allowed (exit status 2).

Every period (a command in lockstep, a timer tick in realtime) is one call of the
compiled loop, continued from the previous one (its accelerations carried over: periods
under one held input equal one run); a new command or set-point restarts the method
(consistent acceleration) as the planar Stepper does (``restart_on_change``: false
continues through input changes too, as one compiled run over a torque array).
Bad messages (wrong length, NaN/inf) are dropped with a
logged reason (at most once a second per reason) and counted (``dropped``); a Newton
failure logs an error, stops stepping and keeps the node up (~/reset restarts).
"""
from __future__ import annotations

import math
import time
from types import SimpleNamespace

import numpy as np
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from std_srvs.srv import Trigger
from visualization_msgs.msg import MarkerArray

from . import ros_spatial as sr
from .config import ConfigError
from .ros_main import Param, ParameterError, ReasonLog, declare_parameters, fmt, run_node

LATCHED = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: realtime: at most this many periods are caught up in one tick (the rest is dropped)
MAX_CATCH_UP = 20


def _positive(v):
    return None if v > 0 else "a number > 0"


def _choice(*options):
    return lambda v: None if v in options else "one of " + ", ".join(options)


def _gains(v):
    return None if v and all(x >= 0 for x in v) else "one or more gains >= 0"


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
          "with eq95: the PD's equilibrium)"),
    Param("controller", "none", "none | eq95 (in-loop PD, thesis Eq. 95, constant gains)",
          check=_choice("none", "eq95")),
    Param("kp", [0.0], "eq95: N m/rad (N/m), one per joint or one for all", check=_gains),
    Param("kd", [0.0], "eq95: N m s/rad (N s/m), one per joint or one for all",
          check=_gains),
    Param("setpoints", [0.0], "eq95: initial set-points (rad or m), one per joint or one "
          "for all"),
    Param("restart_on_change", True, "restart the integrator (consistent acceleration) when "
          "the command or a set-point changes, as the planar Stepper; false: continue"),
    Param("shape_points", 21, "points per flexible link of flex/shape",
          check=lambda v: None if 2 <= v <= 10000 else "an integer in [2, 10000]"),
    Param("publish_tf", True, "publish /tf (needs tf2_msgs; without it one log line)"),
)


def load_arm_parameter(arm: str, planar: bool):
    """The SpatialArm named by the ``arm`` parameter (ParameterError naming it)."""
    from .spatial.description import load_spatial_arm
    try:
        if planar:
            from .arm import load_arm
            from .spatial.description import from_planar
            return from_planar(load_arm(arm))
        return load_spatial_arm(arm)
    except (ConfigError, ValueError, OSError) as exc:
        raise ParameterError(f"parameter arm: {exc}") from None


class SpatialModelNode(Node):
    """A spatial arm stepped at ``rate`` (realtime) or per command (lockstep)."""

    def __init__(self, **kwargs):
        super().__init__("flex_model", **kwargs)
        from .spatial.dynamics import SpatialArmModel
        from .spatial.limits import joint_limits
        p = declare_parameters(self, PARAMETERS)
        self.p = p
        self.arm = load_arm_parameter(p["arm"], p["from_planar"])
        self.model = SpatialArmModel(self.arm)
        self.names = list(self.arm.joint_names)
        vec = {k: self._per_joint(k, p[k]) for k in ("initial_joint_values", "kp", "kd",
                                                      "setpoints")}
        self.period = 1.0 / p["rate"]
        self.per = max(1, int(math.ceil(self.period / p["step"] - 1e-9)))
        self.h = self.period / self.per
        self.eq95 = p["controller"] == "eq95"
        self.kp, self.kd = vec["kp"], vec["kd"]
        self.setpoints0 = vec["setpoints"]
        self.act = self.model.actuator_index >= 0
        self.Kp, self.Dp = np.zeros((2, self.model.nq, self.model.nq))
        if self.eq95:
            for i, a in enumerate(self.model.actuator_index):
                if a >= 0:
                    self.Kp[a, a] += self.kp[i]
                    self.Dp[a, a] += self.kd[i]
        self.effort = joint_limits(self.arm)["effort"]
        self.q0, self.v0 = self._initial_state(vec["initial_joint_values"],
                                               p["start_static"])
        self.dindex = sr.deflection_index(self.model)
        self.dnames = sr.deflection_names(self.model)
        self.dropped = 0
        self.drops = ReasonLog(self)
        self.reset_state()
        qos = 10
        self.pub_js = self.create_publisher(JointState, "joint_states", qos)
        self.pub_defl = self.create_publisher(JointState, "flex/deflections", qos)
        self.pub_shape = self.create_publisher(MarkerArray, "flex/shape", qos)
        self.pub_description = self.create_publisher(String, "robot_description", LATCHED)
        self.pub_clock = self.create_publisher(Clock, "/clock", qos) \
            if p["mode"] == "lockstep" else None
        self.pub_tf = self.tf_types = None
        if p["publish_tf"]:
            self._tf_setup()
        self.create_subscription(Float64MultiArray, "effort_controller/commands",
                                 self.on_command, qos)
        self.create_subscription(Float64MultiArray, "flex/setpoints", self.on_setpoints, qos)
        self.create_service(Trigger, "~/reset", self.on_reset)
        self.last_wall = time.monotonic()
        self.behind = 0.0
        if p["mode"] == "realtime":
            self.timer = self.create_timer(self.period, self.on_tick)
        self.pub_description.publish(String(data=sr.skeleton_urdf(self.model)))
        self.publish()
        self.get_logger().info(
            f"spatial arm {self.arm.name} ({self.model.nq} coordinates, joints "
            f"{', '.join(self.names)}), {p['mode']} at {p['rate']:g} Hz, {self.per} step(s) "
            f"of {self.h:.6g} s a period, controller {p['controller']}")

    # ------------------------------------------------------------- set-up
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
                             pd=SpatialPD(self.kp, self.kd, self.setpoints0) if self.eq95
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
            self.get_logger().info(f"TF off: tf2_msgs cannot be imported ({exc}; the pip "
                                   "ROS wheels have none, a ROS install has it); "
                                   "robot_description is published, /tf not")
            return
        self.tf_types = SimpleNamespace(TFMessage=TFMessage, Time=Time, Header=Header,
                                        Quaternion=Quaternion, Transform=Transform,
                                        TransformStamped=TransformStamped, Vector3=Vector3)
        self.pub_tf = self.create_publisher(TFMessage, "/tf", 100)

    def reset_state(self) -> None:
        self.q, self.v = self.q0.copy(), self.v0.copy()
        self.t = 0.0
        self.steps = 0
        self.u = np.zeros(self.model.n_links)
        self.setpoints = self.setpoints0.copy()
        self.diverged = None
        self.acc = None   # the method's (a, abar): None restarts it

    # ------------------------------------------------------------- inputs
    def _vector(self, msg, what, unit) -> np.ndarray:
        n = self.model.n_links
        data = np.asarray(msg.data, float)
        if data.shape != (n,):
            raise ValueError(f"got {len(data)} values; expected {n} ({unit}, one per joint: "
                             f"{', '.join(self.names)})")
        if not np.all(np.isfinite(data)):
            raise ValueError(f"got {fmt(data)}; expected finite values")
        return data

    def _drop(self, topic: str, why: str) -> None:
        self.dropped += 1
        self.drops.warning(f"dropped {topic}: {why}; holding the last valid one")

    def on_command(self, msg: Float64MultiArray) -> None:
        try:
            u = self._vector(msg, "command", "N m or N")
        except ValueError as exc:
            self._drop("effort_controller/commands", str(exc))
            return
        if self.p["restart_on_change"] and not np.array_equal(u, self.u):
            self.acc = None
        self.u = u
        if self.p["mode"] == "lockstep":
            self.advance()
            self.publish()

    def on_setpoints(self, msg: Float64MultiArray) -> None:
        try:
            if not self.eq95:
                raise ValueError("no set-point controller (parameter controller is none)")
            s = self._vector(msg, "set-points", "rad or m")
        except ValueError as exc:
            self._drop("flex/setpoints", str(exc))
            return
        if self.p["restart_on_change"] and not np.array_equal(s, self.setpoints):
            self.acc = None
        self.setpoints = s

    def on_reset(self, request, response):
        self.reset_state()
        self.publish()
        response.success, response.message = True, "initial state, zero command, t = 0"
        return response

    # ------------------------------------------------------------- stepping
    def open_loop(self) -> np.ndarray:
        """The joint torques of the period that are not the PD's feedback: the command,
        with eq95 plus kp s."""
        return self.u + self.kp * self.setpoints if self.eq95 else self.u

    def applied(self) -> np.ndarray:
        """The joint torques at the current state (joint_states' effort)."""
        if not self.eq95:
            return np.clip(self.u, -self.effort, self.effort)
        a = np.maximum(self.model.actuator_index, 0)
        fb = self.kp * self.q[a] + self.kd * self.v[a]
        return self.open_loop() - np.where(self.act, fb, 0.0)

    def advance(self) -> None:
        """One period (1/rate): ``per`` steps of the compiled loop."""
        from .spatial.integrate import simulate_fixed_compiled
        if self.diverged is not None:
            self.drops.error(f"the model diverged at t = {fmt(self.diverged)} s and is "
                             "stopped; call ~/reset")
            return
        K0 = self.model.K
        try:
            self.model.K = K0 + self.Kp
            run = simulate_fixed_compiled(self.model, self.q, self.v, self.h, self.per,
                                          joint_torques=self.open_loop(),
                                          rho_inf=self.p["rho_inf"], tol=self.p["newton_tol"],
                                          damping=self.Dp if self.eq95 else None,
                                          clip_to_effort=not self.eq95,
                                          acceleration=self.acc)
        except RuntimeError as exc:
            self.diverged = self.t
            self.get_logger().error(f"Newton failed in the period after t = {fmt(self.t)} s "
                                    f"({exc}) under the command {fmt(self.u)}; stepping "
                                    "stopped, ~/reset restarts")
            return
        finally:
            self.model.K = K0
        self.q, self.v = run.q[-1].copy(), run.v[-1].copy()
        self.acc = run.acceleration
        self.steps += 1
        self.t = self.steps * self.period

    def on_tick(self) -> None:
        now = time.monotonic()
        self.behind += now - self.last_wall
        self.last_wall = now
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
        lf = None
        if self.pub_tf is not None:
            lf = []
            self.pub_tf.publish(self.tf_types.TFMessage(
                transforms=sr.transforms(self.tf_types, self.model, q, t, lf)))
        if self.pub_shape.get_subscription_count() > 0:
            self.pub_shape.publish(sr.shape_markers(self.model, q, t,
                                                    int(self.p["shape_points"]), lf))


def main(args=None) -> None:
    run_node(SpatialModelNode, args)


if __name__ == "__main__":
    main()
