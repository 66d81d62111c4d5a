"""The Jazzy ``main()`` idiom shared by the suite's nodes, with this workplace's ROS setup.

Every node of the suite spins in rclpy's SingleThreadedExecutor (the stack's rule: the
experimental EventsExecutor cannot be stopped). That executor rebuilds its wait set in
Python on every wait, at a cost proportional to the number of entities of all its nodes,
so the nodes keep that number small (see :func:`lean_node` and bench/bench_ros_suite.py).
"""
from __future__ import annotations

import math
import re
from array import array
import sys
import time
from dataclasses import dataclass
from typing import Callable

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.clock import Clock as SteadyClock, ClockType
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from sensor_msgs.msg import JointState

from flex_model.ros import ros_environment
from flex_model.command import stop_on_signals
from .conversions import joint_state_cdr


PARAMETER_SERVICES = ("describe_parameters", "get_parameter_types", "get_parameters",
                      "list_parameters", "set_parameters", "set_parameters_atomically")


def lean_node(node, parameter_services: bool, qos_event_warnings: bool) -> None:
    """Take entities the executor would wait on out of ``node`` (call it at the end of
    the node's ``__init__``).

    Without ``parameter_services`` the six parameter services rclpy made are destroyed
    (parameters can then not be listed or set from outside the process). Without
    ``qos_event_warnings`` the node's QoS-event handlers (rclpy gives every publisher and
    subscription one for incompatible QoS and one for incompatible types, which only log a
    warning) are destroyed, so no wait set gathers them."""
    if not parameter_services:
        for srv in list(node.services):
            if srv.srv_name.rsplit("/", 1)[-1] in PARAMETER_SERVICES:
                node.destroy_service(srv)
    if not qos_event_warnings:
        for entity in (*node.publishers, *node.subscriptions):
            for handler in entity.event_handlers:
                node.remove_waitable(handler)
                handler.destroy()
            entity.event_handlers = []


def follow_clock(node, topic: str) -> None:
    """With ``use_sim_time`` take the simulation clock from ``topic`` instead of /clock
    (rclpy's TimeSource subscribes to the absolute /clock only): a relative ``clock`` is
    the namespace's, the one a model node with ``clock_topic: clock`` publishes, so two
    lockstep twins in two namespaces each run on their own clock. Best effort, depth 1, as
    rclpy's TimeSource and ROS clock publishers (ClockQoS). Read at start."""
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from rclpy.time import Time
    from rosgraph_msgs.msg import Clock

    resolved = node.resolve_topic_name(topic)
    if resolved == "/clock" or not node.get_parameter("use_sim_time").value:
        return
    for sub in list(node.subscriptions):
        if sub.topic_name == "/clock":
            node.destroy_subscription(sub)
    clock = node.get_clock()
    node.create_subscription(
        Clock, resolved, lambda msg: clock.set_ros_time_override(Time.from_msg(msg.clock)),
        QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))


def clock_topic_param(doc_user: str) -> "Param":
    """The ``clock_topic`` parameter of the nodes that follow a simulation clock."""
    return Param("clock_topic", "/clock", f"with use_sim_time: the clock's topic "
                 f"({doc_user}); a relative name (clock) is the namespace's, as a model node "
                 "with clock_topic: clock publishes it (two lockstep twins)",
                 check=lambda v: None if v else "a topic name")


class ParameterError(ValueError):
    """A node parameter out of its domain: one line naming the parameter, the value and
    what is allowed (:func:`run_node` prints it and exits with status 2, no traceback)."""


def planar_arm_parameter(p: dict):
    """The planar arm of a node's ``arm``, ``vars_per_link`` (0: the arm file's) and
    ``kinematics`` ('': the arm file's) parameters; a ParameterError naming ``arm``."""
    from ..arm import load_arm
    try:
        arm = load_arm(p["arm"], p["vars_per_link"] or None)
        return arm.with_kinematics(p["kinematics"]) if p["kinematics"] else arm
    except (ValueError, OSError) as exc:
        raise ParameterError(f"parameter arm: {exc}") from None


def fmt(value) -> str:
    """A value as a user reads it: plain floats (``nan``, ``1e+04``, not
    ``np.float64(nan)``), lists of them, strings quoted."""
    if isinstance(value, str):
        return repr(value)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple)) or (hasattr(value, "tolist")
                                            and getattr(value, "ndim", 0) > 0):
        items = value.tolist() if hasattr(value, "tolist") else value
        return "[" + ", ".join(fmt(v) for v in items) + "]"
    if hasattr(value, "item") and not isinstance(value, (int, float)):
        value = value.item()  # a numpy scalar
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)


@dataclass(frozen=True)
class Param:
    """A node parameter: name, default (its type is the parameter's: a float parameter
    takes integers too, ``rate:=500``; ``item`` is the item type of a list parameter,
    default that of the default's items, else float), description, whether
    ``set_parameters`` may change it while the node runs, and ``check(value) -> None |
    str``: None if the value is allowed, else what is allowed (the error then names the
    parameter and the value)."""

    name: str
    default: object
    doc: str
    runtime: bool = False
    check: Callable | None = None
    item: type | None = None

    @property
    def kind(self) -> str:
        d = self.default
        if isinstance(d, bool):
            return "true or false"
        if isinstance(d, int):
            return "an integer"
        if isinstance(d, float):
            return "a finite number"
        if isinstance(d, str):
            return "a string"
        return "a list of strings" if self.list_item is str else "a list of finite numbers"

    @property
    def list_item(self) -> type:
        if self.item is not None:
            return self.item
        return str if self.default and isinstance(self.default[0], str) else float


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def coerce_parameter(spec: Param, value):
    """``value`` as the type of ``spec.default`` (ints for floats, lists as lists), checked
    with ``spec.check``; raises :class:`ParameterError` in one line."""
    d = spec.default
    if isinstance(d, bool):
        ok = isinstance(value, bool)
    elif isinstance(d, int):
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(d, float):
        ok = _number(value) and math.isfinite(value)
    elif isinstance(d, str):
        ok = isinstance(value, str)
    else:  # a list (an empty one may come typed as a byte array)
        if value is None or isinstance(value, (bytes, bytearray)) and not value:
            value = []  # an empty list reaches rclpy untyped (NOT_SET) or as bytes
        if isinstance(value, array):  # a list through the parameter service (ros2 param
            value = value.tolist()    # set, --params-file): rclpy gives array('d'/'q')
        strings = spec.list_item is str
        ok = isinstance(value, (list, tuple)) and all(
            isinstance(v, str) if strings else _number(v) and math.isfinite(v)
            for v in value)
    if not ok:
        raise ParameterError(f"parameter {spec.name}: got {fmt(value)}; expected {spec.kind}")
    if isinstance(d, float):
        value = float(value)
    elif isinstance(d, (list, tuple)):
        value = [spec.list_item(v) for v in value]
    if spec.check is not None:
        allowed = spec.check(value)
        if allowed:
            raise ParameterError(f"parameter {spec.name}: got {fmt(value)}; expected "
                                 f"{allowed}")
    return value


#: the upper end of an open range (a FloatingPointRange / IntegerRange needs one)
FLOAT_MAX, INT_MAX = sys.float_info.max, 2 ** 63 - 1


def descriptor(spec: Param, bounds=None) -> ParameterDescriptor:
    """The ROS descriptor of ``spec``: read_only unless it may change at run time,
    ``bounds`` (lo, hi[, integer step]) as its floating-point or integer range (the range
    a tool such as rqt_reconfigure shows; the spec's check stays the full rule)."""
    desc = ParameterDescriptor(description=spec.doc, dynamic_typing=True,
                               read_only=not spec.runtime)
    if bounds is not None:
        lo, hi, *step = bounds
        if isinstance(spec.default, float):
            desc.floating_point_range = [FloatingPointRange(
                from_value=float(lo), to_value=float(hi), step=0.0)]
        else:
            desc.integer_range = [IntegerRange(from_value=int(lo), to_value=int(hi),
                                               step=int(step[0]) if step else 1)]
    return desc


def declare_only(node, specs) -> None:
    """Declare ``specs`` with dynamic typing and writable descriptors, unchecked (a
    lifecycle node's constructor: ``ros2 param`` works while it is unconfigured)."""
    for spec in specs:
        desc = ParameterDescriptor(description=spec.doc, dynamic_typing=True)
        default = list(spec.default) if isinstance(spec.default, tuple) else spec.default
        node.declare_parameter(spec.name, default, desc)


def read_parameters(node, specs, ranges=None) -> dict:
    """The checked values of the declared ``specs`` (:class:`ParameterError` naming the
    first bad one), then each its full :func:`descriptor` (read_only, range)."""
    values = {s.name: coerce_parameter(s, node.get_parameter(s.name).value) for s in specs}
    for spec in specs:
        node.set_descriptor(spec.name, descriptor(spec, (ranges or {}).get(spec.name)))
    return values


def unlock_parameters(node, specs) -> None:
    """Writable descriptors again (a lifecycle cleanup: the next configure reads new
    values). rclpy's set_descriptor refuses a read_only parameter, so the descriptor is
    replaced in the node's table (``Node._descriptors``, rclpy Jazzy)."""
    for spec in specs:
        node._descriptors[spec.name] = ParameterDescriptor(description=spec.doc,
                                                           dynamic_typing=True)


def guard_parameters(node, specs, apply: Callable | None = None,
                     frozen: Callable | None = None) -> None:
    """Refuse ``set_parameters`` with a reason for parameters that cannot change at run
    time (``runtime`` false; a lifecycle node: only while ``frozen()``, i.e. configured)
    and for bad values; hand the accepted values of runtime parameters to
    ``apply(dict)``. Parameters not in ``specs`` (rclpy's ``use_sim_time``) are left to
    rclpy. Call after declaring (rclpy runs the callback on declarations)."""
    by_name = {s.name: s for s in specs}

    def callback(changes) -> SetParametersResult:
        accepted = {}
        for p in changes:
            spec = by_name.get(p.name)
            if spec is None:
                continue
            if not spec.runtime and (frozen is None or frozen()):
                return SetParametersResult(successful=False, reason=(
                    f"parameter {p.name} is read-only at run time (the node is built from "
                    f"it); restart the node with -p {p.name}:=..."))
            try:
                accepted[p.name] = coerce_parameter(spec, p.value)
            except ParameterError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        if accepted and apply is not None and (frozen is None or frozen()):
            try:
                apply(accepted)
            except ValueError as exc:
                return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)
    node.add_on_set_parameters_callback(callback)


#: the ``autostart`` parameter of the lifecycle nodes (:class:`Managed`)
def positive(v):
    """A parameter check: ``v`` > 0."""
    return None if v > 0 else "a number > 0"


#: the parameters the model node and its observer mode declare alike (ModelPlumbing)
MODEL_PARAMETERS = {p.name: p for p in (
    Param("vars_per_link", 0, "planar: deformation variables per link (0: as in the arm "
          "file)",
          check=lambda v: None if v >= 0 and v % 2 == 0 else "0 or an even integer >= 2"),
    Param("kinematics", "", "kinematics override of the flexible links: small_deflection, "
          "second_order, exact (empty: the arm's)"),
    Param("frame_id", "base_link", "the robot's base frame (REP 105): root of "
          "robot_description and of the TF tree; flex/shape is drawn in it, z up (REP 103)",
          check=lambda v: None if v else "a non-empty frame name"),
    Param("frame_prefix", "", "prefix of every frame name (frame_id too), e.g. robot1/ for "
          "two arms in one TF tree"),
    Param("parameter_services", True, "false: no parameter services (lean_node)"),
    Param("qos_event_warnings", True, "false: no QoS-event handlers (lean_node)"))}

AUTOSTART = Param("autostart", True, "configure and activate at start (lifecycle); "
                  "false: start unconfigured, a lifecycle manager (ros2 lifecycle set, "
                  "lifecycle_msgs/srv/ChangeState on <node>/change_state) drives it")


def _entities(node) -> dict:
    return {"publishers": set(node.publishers), "subscriptions": set(node.subscriptions),
            "services": set(node.services), "timers": set(node.timers),
            "clients": set(node.clients), "waitables": set(node.waitables)}


def destroy_since(node, before: dict) -> None:
    """Destroy what ``node`` made since ``before`` (:func:`_entities`): publishers,
    subscriptions, services, timers, clients, then the rest of its waitables (an action
    server)."""
    now = _entities(node)
    for kind in ("publishers", "subscriptions", "services", "timers", "clients"):
        destroy = getattr(node, "destroy_" + kind[:-1])
        for entity in now[kind] - before[kind]:
            destroy(entity)
    for waitable in set(node.waitables) - before["waitables"]:
        waitable.destroy()  # an ActionServer removes itself from the node
        if waitable in node.waitables:
            node.remove_waitable(waitable)


class Managed:
    """The lifecycle of a suite node (a mixin before rclpy's LifecycleNode, issue 46), as
    ros2_control's managed nodes: configure loads and checks (``_configure``: a
    :class:`ParameterError` is FAILURE with that line, the node stays unconfigured),
    activate starts the loop (``_activate``), deactivate holds (``_deactivate``), cleanup
    destroys what configure and activate made (``_cleanup`` first, also after a failed
    configure: it must take a partly built node) and unlocks the parameters, shutdown
    does what is due of those. Another exception of configure is FAILURE too (autostart:
    raised as before). ``specs`` are the node's parameters:
    declared in the constructor (``ros2 param`` works unconfigured), read_only while
    configured. ``autostart`` (default true) configures and activates in the
    constructor; there a configure failure raises its :class:`ParameterError`.
    ``configure_error``: the exception of the last failed configure, else None."""

    configured = active = False

    def _start_lifecycle(self, specs, apply) -> None:
        """Call at the end of ``__init__``: declare ``specs`` (``ros2 param`` works while
        unconfigured), guard them (``apply`` takes the accepted changes; those a node is
        built from are refused while configured), then autostart or wait."""
        declare_only(self, specs)
        guard_parameters(self, specs, apply, frozen=lambda: self.configured)
        self._specs, self._made, self.configure_error = specs, None, None
        declare_only(self, [AUTOSTART])
        self.set_descriptor("autostart", descriptor(AUTOSTART))
        if not self.get_parameter("autostart").value:
            self.get_logger().info("unconfigured (autostart false): waiting for a "
                                   "lifecycle manager")
            return
        self._autostarting = True
        try:
            self.trigger_configure()
        finally:
            self._autostarting = False
        if self.configure_error is not None:
            self.destroy_node()
            raise self.configure_error
        self.trigger_activate()
        if self.has_parameter("parameter_services") and \
                not self.get_parameter("parameter_services").value:
            self._unmanaged()

    def _unmanaged(self) -> None:
        """A lean autostarted node (parameter_services false: its parameters cannot be
        reached from outside either) leaves its five lifecycle services out of the
        executor's wait set, as lean_node leaves out the parameter services: no outside
        manager then, and no cost per wait. (They are taken out of the node's service
        list, not destroyed: the rcl state machine owns them.)"""
        lifecycle = {"change_state", "get_state", "get_available_states",
                     "get_available_transitions", "get_transition_graph"}
        for srv in list(self.services):
            if srv.srv_name.rsplit("/", 1)[-1] in lifecycle:
                self._services.remove(srv)

    def on_configure(self, state):
        from rclpy.lifecycle import TransitionCallbackReturn as R
        self._made, self.configure_error = _entities(self), None
        try:
            self._configure()
        except Exception as exc:  # a ParameterError: its line; else the exception's
            self._cleanup()       # (what was made of it: a live view's server)
            destroy_since(self, self._made)
            unlock_parameters(self, self._specs)
            self._made, self.configure_error = None, exc
            if not getattr(self, "_autostarting", False):  # (autostart: run_node prints it)
                why = exc if isinstance(exc, ParameterError) else repr(exc)
                self.get_logger().error(f"configure failed: {why}")
            return R.FAILURE
        self.configured = True
        return R.SUCCESS

    def on_activate(self, state):
        from rclpy.lifecycle import TransitionCallbackReturn as R
        self.active = True
        self._activate()
        return R.SUCCESS

    def on_deactivate(self, state):
        from rclpy.lifecycle import TransitionCallbackReturn as R
        self.active = False
        self._deactivate()
        return R.SUCCESS

    def on_cleanup(self, state):
        from rclpy.lifecycle import TransitionCallbackReturn as R
        self._release()
        return R.SUCCESS

    def on_shutdown(self, state):
        from rclpy.lifecycle import TransitionCallbackReturn as R
        if self.active:
            self.active = False
            self._deactivate()
        self._release()
        return R.SUCCESS

    def on_error(self, state):
        from rclpy.lifecycle import TransitionCallbackReturn as R
        self.active = False
        self._release()
        return R.SUCCESS

    def _inactive(self) -> str | None:
        """Why an input is refused in the inactive state, or None (active)."""
        return None if self.active else "the node is inactive (lifecycle): activate it"

    def _activity(self, paused: bool) -> str:
        """A model node's state word on /diagnostics: inactive, paused or running."""
        return "inactive" if not self.active else "paused" if paused else "running"

    def _start_loop(self, period: float) -> None:
        """A model node's activate: its loop timer (``self.timer``, calling ``on_tick``)
        from now on; the wall time spent inactive is not integrated (``last_wall``,
        ``behind``)."""
        self.last_wall, self.behind = time.monotonic(), 0.0
        self.timer = self.create_timer(period, self.on_tick)

    def _stop_loop(self, t: float) -> None:
        """A model node's deactivate: its loop timer destroyed at simulation time ``t``
        (s), logged; time and state stand still."""
        self.destroy_timer(self.timer)
        self.timer = None
        self.get_logger().info(f"inactive: stepping stopped at t = {fmt(t)} s, the state "
                               "held")

    def _release(self) -> None:
        if self._made is not None:
            self._cleanup()
            destroy_since(self, self._made)
            self._made = None
        self.configured = False
        unlock_parameters(self, self._specs)

    def _configure(self) -> None:
        """Read the parameters, build the node's objects, publishers, subscriptions."""

    def _activate(self) -> None:
        """Start the timers (the loop) and publishing."""

    def _deactivate(self) -> None:
        """Stop the timers; hold."""

    def _cleanup(self) -> None:
        """Release what is not an entity of the node (a live view's server)."""


class ModelPlumbing(Managed):
    """What the model node and its observer mode share (issue 43: one node plumbing, the
    arm or the filter behind it): the lifecycle (:class:`Managed`), the parameters of
    :data:`MODEL_PARAMETERS`, joint_states and flex/deflections as CDR templates
    (published as bytes, flex_model.ros.cdr_messages), /diagnostics with the node's
    ``on_status`` every second of wall time (simulation time may stand still)."""

    def _state_publishers(self, js_topic: str, deflection_names, qos) -> None:
        """``pub_js``/``cdr_js`` (``self.names``: position, velocity, effort) and
        ``pub_defl``/``cdr_defl`` (``deflection_names``: positions and rates)."""
        self.cdr_js = joint_state_cdr(self.names, len(self.names))
        self.cdr_defl = joint_state_cdr(deflection_names, len(deflection_names), False)
        self.pub_js = self.create_publisher(JointState, js_topic, qos)
        self.pub_defl = self.create_publisher(JointState, "flex/deflections", qos)

    def _diagnostics(self) -> None:
        """/diagnostics (global: ROS tools, the aggregator, expect it there) and the
        1 s wall-clock timer of ``on_status``."""
        self.pub_diag = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(1.0, self.on_status, clock=SteadyClock(clock_type=ClockType.STEADY_TIME))

    def publish_diagnostic(self, status) -> None:
        msg = DiagnosticArray(status=[status])
        msg.header.stamp = self.get_clock().now().to_msg()
        self.pub_diag.publish(msg)


_NUMBER = re.compile(r"nan|inf|[-+]?\d[\d.]*(?:e[-+]?\d+)?", re.IGNORECASE)


class ReasonLog:
    """Log each distinct reason at most once per ``period`` (s), with the count of the
    ones held back. rclpy's ``throttle_duration_sec`` throttles per call site, so one site
    logging several reasons (a wrong length, then a NaN) would hide all but the first;
    here the reason is the text with its numbers taken out. Each severity has its own
    call site (rclpy binds one severity to each)."""

    def __init__(self, node, period: float = 1.0):
        self.node, self.period, self.last, self.held = node, float(period), {}, {}

    def _due(self, text: str, key) -> str | None:
        key = _NUMBER.sub("#", text) if key is None else key
        now = time.monotonic()
        if now - self.last.get(key, -math.inf) < self.period:
            self.held[key] = self.held.get(key, 0) + 1
            return None
        self.last[key] = now
        held = self.held.pop(key, 0)
        return text + (f" ({held} more like this since the last report)" if held else "")

    def warning(self, text: str, key=None) -> None:
        text = self._due(text, key)
        if text is not None:
            self.node.get_logger().warning(text)

    def error(self, text: str, key=None) -> None:
        text = self._due(text, key)
        if text is not None:
            self.node.get_logger().error(text)

    def info(self, text: str, key=None) -> None:
        text = self._due(text, key)
        if text is not None:
            self.node.get_logger().info(text)


def run_node(factory, args=None, on_stop=None) -> None:
    """init, spin the node made by ``factory`` in a SingleThreadedExecutor until SIGINT or
    SIGTERM, call ``on_stop(node)`` while the context is still valid (the controller
    commands zero torques there), a lifecycle node's shutdown transition, destroy, shut
    down.

    rclpy's signal handlers are replaced by :func:`stop_on_signals`, so no callback runs
    into a context that Ctrl-C has already shut down. A :class:`ParameterError` from the
    factory (a bad parameter) is one line on stderr and exit status 2. The ROS environment
    (LOCALHOST discovery; the user's ROS_DOMAIN_ID is kept) is set when flex_model is
    imported, before rclpy."""
    ros_environment()   # LOCALHOST discovery before the participant exists
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    try:
        with stop_on_signals() as stop:
            executor = SingleThreadedExecutor()
            try:
                node = factory()
            except ParameterError as exc:  # one line, no traceback
                print(f"{getattr(factory, '__name__', 'node')}: {exc}", file=sys.stderr)
                raise SystemExit(2) from None
            executor.add_node(node)
            while rclpy.ok() and not stop.is_set():
                executor.spin_once(timeout_sec=0.05)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            if on_stop is not None and rclpy.ok():
                on_stop(node)
            if isinstance(node, Managed) and rclpy.ok():
                node.trigger_shutdown()  # lifecycle: on_shutdown, to finalized
            if executor is not None:
                executor.shutdown()
            node.destroy_node()
        rclpy.try_shutdown()
