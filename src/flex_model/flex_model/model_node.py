"""ModelNode: the flexible arm as a ROS 2 node (a thin adapter around flex_model.stepper).

Publications (simulation time in every header):
    /joint_states        sensor_msgs/JointState   joint angles (encoder), rates, applied torques
    /flex/deflections    sensor_msgs/JointState   link<i>/tip_deflection (m), tip_rotation (rad)
    /flex/tip_pose       geometry_msgs/PoseStamped  tip of the arm in ``frame_id``
    /flex/shape          visualization_msgs/MarkerArray  deflected centre lines and chords
    /flex/tip_imu        sensor_msgs/Imu          when the arm has a tip_accelerometer sensor
    /clock               rosgraph_msgs/Clock      in lockstep mode (or publish_clock)
Subscriptions:
    /effort_controller/commands  std_msgs/Float64MultiArray  joint torques, joint order
    /flex/payload                std_msgs/Float64MultiArray  [mass kg, inertia kg m^2]
Services: ~/reset (std_srvs/Trigger), ~/pause (std_srvs/SetBool).
Parameters: arm, vars_per_link, kinematics, mode (realtime | lockstep), rate (Hz, model
loop), publish_rate (Hz), shape_rate (Hz, /flex/shape, at most publish_rate), max_step (s),
initial_joint_angles_deg, start_static (start deflected at rest under gravity),
start_paused (until ~/pause false), command_timeout (s, 0 = never), timeout_action (hold |
zero), lockstep_timeout (s, wall), frame_id, shape_points, publish_clock,
realtime_priority (0 = off; 1-99: SCHED_FIFO priority of the thread that creates and spins
the node, realtime mode, as ros2_control's thread_priority; needs CAP_SYS_NICE),
parameter_services and qos_event_warnings (default true; false: the node has no parameter
services, resp. no QoS-event handlers, which only log incompatible QoS or types: fewer
entities in every wait of the SingleThreadedExecutor, a faster lockstep loop, see
flex_model.ros_main).

realtime: a timer at ``rate`` integrates the wall time elapsed since the last tick in steps
of exactly ``max_step`` (rcl timers skip missed periods: a late tick catches up with several
steps; simulation time stays on the step grid, within a step of the wall clock).
/joint_states, /flex/deflections, /flex/tip_pose, /flex/tip_imu go out at publish_rate,
/flex/shape at shape_rate. lockstep: deterministic; each command advances the model by
1/rate and publishes the new /joint_states (and /clock) at once, the other topics at their
rates, so simulation time moves only as the model-controller loop completes; without a
command for ``lockstep_timeout`` (wall) the model steps with the held one (a warning once
the loop ran; before the first command this is the start: a controller timed by /clock
needs that first step). Messages are built once and updated in place (the per-step cost
is what limits the loop rate).
"""
from __future__ import annotations

import os
import time

import numpy as np
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray, Header
from std_srvs.srv import SetBool, Trigger
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import Imu, JointState
from visualization_msgs.msg import MarkerArray

from . import ros_conversions as conv
from .arm import load_arm
from .dynamics import FlexArmModel
from .ros_main import lean_node, run_node
from .stepper import Stepper


class ModelNode(Node):
    """The arm simulated at ``rate`` and published at ``publish_rate``."""

    def __init__(self, **kwargs):
        super().__init__("flex_model", **kwargs)
        p = {name: self.declare_parameter(name, default).value for name, default in (
            ("arm", "thesis_example1"), ("vars_per_link", 0), ("kinematics", ""),
            ("mode", "realtime"), ("rate", 1000.0), ("publish_rate", 250.0), ("shape_rate", 50.0),
            ("max_step", 1e-3), ("initial_joint_angles_deg", [0.0]),
            ("command_timeout", 0.0), ("timeout_action", "hold"),
            ("lockstep_timeout", 1.0), ("frame_id", "base_link"), ("shape_points", 15),
            ("publish_clock", False), ("start_static", False), ("start_paused", False),
            ("realtime_priority", 0), ("parameter_services", True),
            ("qos_event_warnings", True))}
        if p["mode"] not in ("realtime", "lockstep"):
            raise ValueError(f"parameter mode: got {p['mode']!r}; expected realtime or lockstep")
        if p["timeout_action"] not in ("hold", "zero"):
            raise ValueError(f"parameter timeout_action: got {p['timeout_action']!r}; "
                             "expected hold or zero")
        if not all(p[k] > 0 for k in ("rate", "publish_rate", "shape_rate", "max_step")):
            raise ValueError("parameters rate, publish_rate, shape_rate and max_step must be "
                             "> 0")
        arm = load_arm(p["arm"], p["vars_per_link"] or None)
        if p["kinematics"]:
            arm = arm.with_kinematics(p["kinematics"])
        self.model = FlexArmModel(arm)
        theta0 = np.radians(np.resize(np.asarray(p["initial_joint_angles_deg"], float),
                                      self.model.n_links))
        q0 = self.model.q_from_joint_angles(theta0)
        if p["start_static"]:  # at rest, deflected under gravity with the joints held
            from .statics import static_equilibrium
            q0 = static_equilibrium(self.model, theta0, joints="clamped").q
        self.stepper = Stepper(self.model, q0, max_step=p["max_step"])
        self.p = p
        self.names = arm.joint_names
        self.links = [lk.name for lk in arm.links]
        self.has_imu = any(s.kind == "tip_accelerometer" for s in arm.sensors)
        self.paused = bool(p["start_paused"])
        self.command_time = 0.0
        self.commanded = False  # a valid command has arrived (lockstep: the loop runs)
        self.next_publish = self.next_shape = 0.0
        self.behind = 0.0  # realtime: wall time not yet integrated (s)
        self.warned = set()
        frame = p["frame_id"]
        self.msg_js = JointState(name=list(self.names))
        self.msg_defl = JointState(name=conv.deflection_names(self.links))
        self.msg_tip = PoseStamped(header=Header(frame_id=frame))
        self.msg_shape = conv.ShapeMarkers(self.model.n_links, int(p["shape_points"]), frame)
        self.msg_clock = Clock()
        qos = 10
        self.pub_js = self.create_publisher(JointState, "/joint_states", qos)
        self.pub_defl = self.create_publisher(JointState, "/flex/deflections", qos)
        self.pub_tip = self.create_publisher(PoseStamped, "/flex/tip_pose", qos)
        self.pub_shape = self.create_publisher(MarkerArray, "/flex/shape", qos)
        self.pub_imu = self.create_publisher(Imu, "/flex/tip_imu", qos) if self.has_imu \
            else None
        self.pub_clock = self.create_publisher(Clock, "/clock", qos) \
            if p["mode"] == "lockstep" or p["publish_clock"] else None
        self.create_subscription(Float64MultiArray, "/effort_controller/commands",
                                 self.on_command, qos)
        self.create_subscription(Float64MultiArray, "/flex/payload", self.on_payload, qos)
        self.create_service(Trigger, "~/reset", self.on_reset)
        self.create_service(SetBool, "~/pause", self.on_pause)
        self.last_wall = time.monotonic()
        # realtime: the model loop; lockstep: steps happen on commands, this is the watchdog
        period = 1.0 / p["rate"] if p["mode"] == "realtime" else 0.05
        self.timer = self.create_timer(period, self.on_tick)
        if p["mode"] == "realtime" and p["realtime_priority"]:
            self._set_realtime_priority(int(p["realtime_priority"]))
        lean_node(self, p["parameter_services"], p["qos_event_warnings"])
        self.publish_state(full=True)
        self.get_logger().info(f"arm {arm.name} ({self.model.nq} coordinates), {p['mode']} "
                               f"at {p['rate']:g} Hz, publishing at {p['publish_rate']:g} Hz")

    def _set_realtime_priority(self, priority: int) -> None:
        """SCHED_FIFO for this thread (Linux: the other threads, DDS's, keep theirs)."""
        if not 1 <= priority <= 99:
            raise ValueError(f"parameter realtime_priority: got {priority}; expected 0 (off) "
                             "or 1-99")
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
        except (OSError, AttributeError) as exc:
            self.get_logger().warning(f"realtime_priority {priority}: {exc}; running with "
                                      "the normal scheduler")

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
            u = conv.finite_array(msg.data, self.model.n_links, "command")
        except ValueError as exc:
            self.get_logger().warning(f"dropped /effort_controller/commands: {exc}; "
                                      "holding the last valid command",
                                      throttle_duration_sec=1.0)
            return
        self.stepper.set_command(u)
        self.command_time, self.commanded = self.stepper.t, True
        if self.p["mode"] == "lockstep" and not self.paused:
            self.last_wall = time.monotonic()
            self.step(1.0 / self.p["rate"])

    def on_payload(self, msg: Float64MultiArray) -> None:
        try:
            m, j = conv.finite_array(msg.data, 2, "payload [mass, inertia]")
            self.stepper.set_payload(m, j)
        except ValueError as exc:
            self.get_logger().warning(f"dropped /flex/payload: {exc}")
            return
        self.get_logger().info(f"payload now {m:g} kg, {j:g} kg m^2")

    def on_reset(self, request, response):
        self.stepper.reset()
        self.command_time = self.next_publish = self.next_shape = self.behind = 0.0
        self.publish_state(full=True)
        response.success, response.message = True, "reset to the initial state at t = 0"
        return response

    def on_pause(self, request, response):
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
        if self.paused:
            return
        if self.p["mode"] == "lockstep":  # watchdog: no command for lockstep_timeout
            if elapsed < self.p["lockstep_timeout"]:
                self.last_wall -= elapsed  # keep measuring from the last step
                return
            if self.commanded:  # the loop stalled
                self._warn_once("lockstep", "lockstep: no command within lockstep_timeout; "
                                "stepping with the held command")
            else:  # the start: a time-triggered controller waits for this first step
                self._warn_once("start", "lockstep: no command yet; stepping with the held "
                                "command every lockstep_timeout until one arrives", "info")
            self.step(1.0 / self.p["rate"])
            return
        # the owed wall time in whole steps, with a quarter step of slack: timer jitter about
        # the step grid must not alternate ticks of 0 and 2 steps (the state may then run
        # up to h/4 ahead of the wall clock); a stalled process owes at most 0.1 s
        h = self.p["max_step"]
        self.behind = min(self.behind + elapsed, 0.1)
        n = int(self.behind / h + 0.25)
        if n:
            self.behind -= n * h
            self.step(n * h)

    def step(self, dt: float) -> None:
        """Advance the model by dt (s), apply the command timeout, publish."""
        timeout = self.p["command_timeout"]
        if timeout > 0 and self.stepper.t - self.command_time > timeout:
            if self.p["timeout_action"] == "zero" and np.any(self.stepper.u):
                self.stepper.set_command(np.zeros(self.model.n_links))
            self._warn_once("timeout", f"no valid command for {timeout:g} s: "
                            f"{self.p['timeout_action']}")
        try:
            self.stepper.advance(dt)
        except Exception as exc:  # a diverged model stops the loop, loudly
            self.get_logger().error(f"model stopped: {exc}")
            self.timer.cancel()
            return
        t = self.stepper.t
        full = t >= self.next_publish - 1e-12
        if full:
            self.next_publish = t + 1.0 / self.p["publish_rate"]
        shape = full and t >= self.next_shape - 1e-12
        if shape:
            self.next_shape = t + 1.0 / self.p["shape_rate"]
        if full or self.p["mode"] == "lockstep":
            self.publish_state(full=full, shape=shape)

    def publish_state(self, full: bool = True, shape: bool = True) -> None:
        """/joint_states, then /clock (a sim-time controller, woken by the clock, then has
        the new state also across processes); with ``full`` the other topics (/flex/shape
        only with ``shape`` too)."""
        st, t = self.stepper, self.stepper.t
        self.pub_js.publish(conv.fill_joint_state(self.msg_js, t, *st.joint_state()))
        if self.pub_clock is not None:
            conv.set_time(self.msg_clock.clock, t)
            self.pub_clock.publish(self.msg_clock)
        if not full:
            return
        self.pub_defl.publish(conv.fill_deflection_state(self.msg_defl, t, *st.deflections()))
        x, y, phi = st.tip_pose()
        self.pub_tip.publish(conv.fill_tip_pose(self.msg_tip, t, x, y, phi))
        if shape:
            shapes = self.model.shape(st.q, int(self.p["shape_points"]))
            self.pub_shape.publish(self.msg_shape.update(t, shapes))
        if self.pub_imu is not None:
            rate = float(self.model.tip_torque_vector() @ st.v)  # tip frame rotation rate
            self.pub_imu.publish(conv.imu(t, st.tip_specific_force(), rate, phi))


def main(args=None) -> None:
    run_node(ModelNode, args)


if __name__ == "__main__":
    main()
