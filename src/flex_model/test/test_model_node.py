"""Model node in-process: lockstep determinism against the core, commands, services."""
import time
import uuid

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool, Trigger
from visualization_msgs.msg import Marker, MarkerArray

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.ros.model_node import ModelNode
from flex_model.stepper import Stepper


@pytest.fixture
def harness(ros_graph):
    """``harness(**params)``: a ModelNode and a probe (states, shapes, diagnostics,
    commands, payload, ~/reset, ~/pause) in the conftest's ROS harness."""
    def make(**params):
        h = ros_graph(ModelNode, "m", **params)
        h.states = h.subscribe(JointState, "joint_states", 100)
        h.shapes = h.subscribe(MarkerArray, "flex/shape")
        h.diagnostics = h.subscribe(DiagnosticArray, "/diagnostics")
        h.cmd = h.probe.create_publisher(Float64MultiArray, "effort_controller/commands", 100)
        h.payload = h.probe.create_publisher(Float64MultiArray, "flex/payload", 10)
        h.reset = h.probe.create_client(Trigger, f"{h.ns}/flex_model/reset")
        h.pause = h.probe.create_client(SetBool, f"{h.ns}/flex_model/pause")
        h.discovered(h.cmd)
        return h
    return make


@pytest.fixture
def lockstep(harness):
    return harness(arm="thesis_example1", mode="lockstep", rate=1000.0, publish_rate=100.0,
                   initial_joint_angles_deg=[10.0, -20.0], lockstep_timeout=30.0)


def stamp_s(msg):
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def test_lockstep_reproduces_the_core_stepper(lockstep):
    h = lockstep
    commands = [np.array([2.0 * np.sin(0.3 * k), -0.5 + 0.01 * k]) for k in range(30)]
    for k, u in enumerate(commands):
        h.cmd.publish(Float64MultiArray(data=list(u)))
        h.spin_until(lambda: h.states and stamp_s(h.states[-1]) > k * 1e-3 + 5e-4,
                     f"state {k + 1}")
    model = FlexArmModel(load_arm("thesis_example1"))
    ref = Stepper(model, model.q_from_joint_angles(np.radians([10.0, -20.0])))
    for u in commands:
        ref.set_command(u)
        ref.advance(1e-3)
    last = h.states[-1]
    assert stamp_s(last) == pytest.approx(0.030, abs=1e-12)
    angles, rates, tau = ref.joint_state()
    np.testing.assert_allclose(last.position, angles, rtol=0, atol=1e-12)
    np.testing.assert_allclose(last.velocity, rates, rtol=0, atol=1e-10)
    np.testing.assert_allclose(last.effort, commands[-1], rtol=1e-15)
    assert last.name == ["joint1", "joint2"]


def test_bad_commands_are_dropped_and_the_last_valid_one_holds(lockstep):
    h = lockstep
    h.cmd.publish(Float64MultiArray(data=[1.0, 2.0]))
    h.spin_until(lambda: len(h.states) >= 1 and stamp_s(h.states[-1]) > 5e-4, "first step")
    for bad in ([1.0], [1.0, 2.0, 3.0], [np.nan, 0.0], [0.0, np.inf]):
        h.cmd.publish(Float64MultiArray(data=bad))
        h.ex.spin_once(timeout_sec=0.05)
    np.testing.assert_array_equal(h.node.stepper.u, [1.0, 2.0])
    h.cmd.publish(Float64MultiArray(data=[0.5, 0.5]))
    h.spin_until(lambda: np.array_equal(h.node.stepper.u, [0.5, 0.5]), "valid command")


def test_reset_pause_and_shape_markers(lockstep):
    h = lockstep
    for _ in range(12):
        n = len(h.states)
        h.cmd.publish(Float64MultiArray(data=[1.0, 0.0]))
        h.spin_until(lambda: len(h.states) > n, "a step")
    assert h.node.stepper.t == pytest.approx(0.012)
    # shape: a LINE_STRIP per link and its chord, starting at the base
    h.spin_until(lambda: h.shapes, "shape")
    markers = h.shapes[-1].markers
    assert len(markers) == 4 and all(m.type == Marker.LINE_STRIP for m in markers)
    assert len(markers[0].points) == 15 and markers[0].points[0].x == 0.0
    fut = h.pause.call_async(SetBool.Request(data=True))
    h.spin_until(fut.done, "pause")
    t_paused = h.node.stepper.t
    h.cmd.publish(Float64MultiArray(data=[1.0, 0.0]))
    end = time.monotonic() + 0.2
    while time.monotonic() < end:
        h.ex.spin_once(timeout_sec=0.01)
    assert h.node.stepper.t == t_paused
    fut = h.reset.call_async(Trigger.Request())
    h.spin_until(fut.done, "reset")
    assert fut.result().success and h.node.stepper.t == 0.0
    np.testing.assert_array_equal(h.node.stepper.q, h.node.stepper.q0)


def test_stamps_round_to_the_nanosecond_without_wrapping():
    from flex_model.ros.conversions import stamp
    for t, want in ((2.9999999999, (3, 0)), (3.0000000004, (3, 0)), (0.0015, (0, 1500000)),
                    (12.5, (12, 500000000))):
        s = stamp(t)
        assert (s.sec, s.nanosec) == want


def test_realtime_ticks_integrate_whole_steps_and_catch_up(monkeypatch, harness):
    """A tick integrates the wall time owed in steps of exactly max_step: late ticks catch
    up (rcl timers skip missed periods), the remainder waits, a tick up to a quarter step
    early still steps; the state equals the core stepper's after the same number of 1 ms
    steps, published at publish_rate."""
    h = harness(arm="thesis_example1", mode="realtime", rate=1000.0, publish_rate=250.0,
                initial_joint_angles_deg=[10.0, -20.0], hold_until_command=False)
    node, clock = h.node, [100.0]
    monkeypatch.setattr("flex_model.ros.model_node.time.monotonic", lambda: clock[0])
    node.last_wall = clock[0]
    published = []
    node.pub_js.publish = lambda raw: published.append(  # bytes: flex_model.ros.cdr_messages
        stamp_s(deserialize_message(raw, JointState)))
    for elapsed_ms, t_ms in ((1.0, 1), (3.4, 4), (0.7, 5), (0.95, 6), (0.2, 6), (0.55, 7)):
        clock[0] += 1e-3 * elapsed_ms
        node.on_tick()
        assert node.stepper.t == pytest.approx(1e-3 * t_ms, abs=1e-12)
    assert node.behind == pytest.approx(-0.2e-3, abs=1e-12)
    ref = Stepper(node.model, node.stepper.q0)
    for _ in range(7):
        ref.advance(1e-3)
    np.testing.assert_allclose(node.stepper.x, ref.x, rtol=0, atol=1e-12)
    # 250 Hz: at 1 ms (the first step) and at 5 ms
    assert published == pytest.approx([1e-3, 5e-3], abs=1e-9)


def test_lean_node_leaves_only_its_own_entities(harness):
    """parameter_services / qos_event_warnings false (ros2_ws/params/suite.yaml): of the
    services only ~/reset and ~/pause remain and no QoS-event waitables (rclpy makes one
    per publisher and subscription for incompatible QoS and one for incompatible types);
    the lockstep loop still runs (a command steps the model)."""
    full = harness(arm="thesis_example1", mode="lockstep")
    n_entities = len([*full.node.publishers, *full.node.subscriptions])
    assert len([*full.node.waitables]) == 2 * n_entities
    # own, parameters, type description, lifecycle (issue 46)
    assert len([*full.node.services]) == 2 + 6 + 1 + 5
    h = harness(arm="thesis_example1", mode="lockstep", lockstep_timeout=30.0,
                parameter_services=False, qos_event_warnings=False)
    assert sorted(s.srv_name.rsplit("/", 1)[-1] for s in h.node.services) == [
        "get_type_description", "pause", "reset"]
    assert not [*h.node.waitables]
    h.cmd.publish(Float64MultiArray(data=[0.0, 0.0]))
    h.spin_until(lambda: h.node.stepper.t > 0, "a lockstep step")
    assert h.node.stepper.t == pytest.approx(1e-3)


def test_lockstep_survives_commands_stopping_and_resuming(harness):
    """Issue 23 defect 1: the watchdog's first step logged at INFO and the stall at WARN from
    one call site, which rclpy refuses (ValueError) about 1 s after commands stopped. Ten
    stops and resumes: the node keeps stepping with the held command through each stall and
    answers every command again afterwards."""
    h = harness(arm="thesis_example1", mode="lockstep", rate=1000.0, publish_rate=100.0,
                lockstep_timeout=0.02)
    h.spin_until(lambda: h.states and stamp_s(h.states[-1]) > 0, "the start step")
    for cycle in range(10):
        for _ in range(5):  # commands flow: one step each
            n = len(h.states)
            h.cmd.publish(Float64MultiArray(data=[0.1, 0.0]))
            h.spin_until(lambda: len(h.states) > n, f"a step of cycle {cycle}")
        t_stop = stamp_s(h.states[-1])
        # commands stop: the watchdog steps with the held command, twice at least
        h.spin_until(lambda: stamp_s(h.states[-1]) >= t_stop + 2e-3 - 1e-9,
                     f"watchdog steps after stop {cycle}")
    assert "lockstep" in h.node.warned and "start" in h.node.warned
    stamps = [stamp_s(m) for m in h.states]
    assert np.all(np.diff(stamps) > 0)  # every state a new step, none lost or repeated
    assert np.allclose(np.diff(stamps), 1e-3, atol=1e-9)


class Logs:
    """Stands in for a node's logger: records (level, message)."""

    def __init__(self):
        self.records = []

    def __getattr__(self, level):
        return lambda msg, **kwargs: self.records.append((level, str(msg)))

    def count(self, text, level=None):
        return sum(1 for lv, m in self.records if text in m and level in (None, lv))


def test_divergence_reports_diagnostic_zero_torque_and_reset_restarts(harness):
    """Issue 23 defect 2: a 10 kN m command (the plausibility limit raised to let it
    through) makes the hub-less arm's integration fail (within 0.15 s; with the finer
    steps of issue 46 after its 0.5 s command timeout, ~9 s). The node stays up: one ERROR
    diagnostic on /diagnostics naming the command, zero torque, commands answered with a
    reason, the last good state published with zero effort (issue 46); ~/reset restarts
    the realtime loop (states flow again, the diagnostic goes back to OK). Before: the
    timer was cancelled for good, the message said "reduce max_step"."""
    h = harness(arm="thesis_example1", mode="realtime", rate=1000.0, publish_rate=100.0,
                max_torque=1e5)
    log = Logs()
    h.node.get_logger = lambda: log
    h.spin_until(lambda: h.node.pub_diag.get_subscription_count() > 0 and h.states,
                 "the diagnostics probe and a state")
    h.cmd.publish(Float64MultiArray(data=[1e4, 0.0]))
    h.spin_until(lambda: h.node.diverged is not None, "the divergence", timeout=60.0)
    h.spin_until(lambda: h.diagnostics and h.diagnostics[-1].status[0].level ==
                 DiagnosticStatus.ERROR, "the diagnostic")  # (OK ones every second)
    status = h.diagnostics[-1].status[0]
    assert status.level == DiagnosticStatus.ERROR
    assert "diverged" in status.message and "10000" in status.message
    assert "command" in status.message and "reduce max_step" not in status.message
    assert log.count("model diverged at t =", "error") == 1
    np.testing.assert_array_equal(h.node.stepper.u, [0.0, 0.0])     # zero torque
    t_div, n_states = h.node.stepper.t, len(h.states)
    h.cmd.publish(Float64MultiArray(data=[1.0, 0.0]))
    h.spin_until(lambda: log.count("call ~/reset", "warning") >= 1, "a drop reason")
    h.spin_for(1.2)                                  # stopped, yet alive: diagnostic again
    assert h.node.stepper.t == t_div and len(h.states) > n_states + 50  # held, 100 Hz
    assert all(stamp_s(m) == pytest.approx(t_div) for m in h.states[n_states:])
    assert all(list(m.effort) == [0.0, 0.0] for m in h.states[n_states:])
    n_states = len(h.states)
    assert len(h.diagnostics) >= 2 and not h.node.timer.is_canceled()
    fut = h.reset.call_async(Trigger.Request())
    h.spin_until(fut.done, "reset")
    assert fut.result().success
    h.spin_until(lambda: len(h.states) > n_states + 20, "states after the reset")
    assert 0.0 < stamp_s(h.states[-1]) < 5.0 and h.node.diverged is None
    h.spin_until(lambda: h.diagnostics[-1].status[0].level == DiagnosticStatus.OK,
                 "the OK diagnostic")
    h.cmd.publish(Float64MultiArray(data=[1.0, 0.0]))
    h.spin_until(lambda: np.array_equal(h.node.stepper.u, [1.0, 0.0]), "a command")


def test_implausible_command_and_payload_are_dropped_with_a_reason(lockstep):
    """Issue 23 defect 2: plausibility limits (automatic from the arm by default: 438 N m,
    8.2 kg, 44 kg m^2 for thesis_example1): a 10 kN m command or a 1e6 kg payload is
    dropped with a reason naming the limit; the model keeps stepping."""
    h = lockstep
    log = Logs()
    h.node.get_logger = lambda: log
    h.cmd.publish(Float64MultiArray(data=[1e4, 0.0]))
    h.spin_until(lambda: log.count("beyond max_torque"), "the torque drop")
    assert log.count("command: joint1 = 10000 N m is beyond max_torque = 437.76", "warning")
    h.payload.publish(Float64MultiArray(data=[1e6, 0.0]))
    h.spin_until(lambda: log.count("dropped flex/payload"), "the payload drop")
    assert log.count("payload mass: got 1e+06 kg; expected at most max_payload_mass = 8.208")
    h.payload.publish(Float64MultiArray(data=[-1.0, 0.0]))
    h.spin_until(lambda: log.count("payload mass: got -1 kg; expected >= 0"), "negative")
    assert h.node.stepper.model.payload == (0.0, 0.0)
    n = len(h.states)
    h.cmd.publish(Float64MultiArray(data=[1.0, 0.0]))
    h.spin_until(lambda: len(h.states) > n, "a step")
    np.testing.assert_array_equal(h.node.stepper.u, [1.0, 0.0])
    h.payload.publish(Float64MultiArray(data=[2.0, 0.1]))
    h.spin_until(lambda: h.node.stepper.model.payload == (2.0, 0.1), "a plausible payload")


def test_runtime_parameters_refused_with_a_reason_or_applied(lockstep):
    """Issue 23 defect 10: set_parameters was accepted and ignored. Parameters the node is
    built from are refused with a reason; the runtime ones are checked and applied; an
    integer is taken for a float."""
    node = lockstep.node
    res = node.set_parameters([Parameter("rate", value=10.0)])[0]
    assert not res.successful and "read-only parameter: rate" in res.reason  # descriptor
    res = node.set_parameters([Parameter("command_timeout", value=-1.0)])[0]
    assert not res.successful and "command_timeout out of range" in res.reason  # its range
    res = node.set_parameters([Parameter("timeout_action", value="brake")])[0]
    assert not res.successful and "expected one of hold, zero" in res.reason
    res = node.set_parameters([Parameter("max_torque", value=50)])[0]
    assert res.successful and node.limit("max_torque") == 50.0
    assert isinstance(node.p["max_torque"], float)
    assert node.set_parameters([Parameter("use_sim_time", value=False)])[0].successful


def test_startup_parameters_accept_ints_and_refuse_bad_values_in_one_line(harness):
    """Issue 23 defect 10: rate:=500 (an integer) was refused where a float is expected;
    shape_points:=0 raised IndexError; a wrong-length initial_joint_angles_deg was
    silently resized; a negative command_timeout was accepted."""
    from flex_model.ros.main import ParameterError
    h = harness(arm="thesis_example1", mode="lockstep", rate=500, lockstep_timeout=30)
    assert h.node.p["rate"] == 500.0 and isinstance(h.node.p["rate"], float)
    assert h.node.p["lockstep_timeout"] == 30.0
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        for params, text in (
                ({"shape_points": 0}, "parameter shape_points: got 0; expected an integer "
                 "in [2, 10000]"),
                ({"initial_joint_angles_deg": [1.0, 2.0, 3.0]},
                 "parameter initial_joint_angles_deg: got [1, 2, 3]; expected 2 angles"),
                ({"command_timeout": -1.0}, "parameter command_timeout: got -1; expected a "
                 "time >= 0 s"),
                ({"rate": "fast"}, "parameter rate: got 'fast'; expected a finite number"),
                ({"max_step": 0.0}, "parameter max_step: got 0; expected a step in (0, 0.1]"),
                ({"mode": "turbo"}, "parameter mode: got 'turbo'; expected realtime or "
                 "lockstep (mode observer is flex_model.ros.observer_node")):
            with pytest.raises(ParameterError) as err:
                ModelNode(context=ctx, namespace=f"/b{uuid.uuid4().hex[:8]}",
                          parameter_overrides=[Parameter(k, value=v)
                                               for k, v in params.items()])
            assert text in str(err.value) and "\n" not in str(err.value)
    finally:
        rclpy.try_shutdown(context=ctx)


def test_root_namespace_topics_are_the_bags_absolute_names():
    """Issue 23 defect 8: relative names resolve in the root namespace to the absolute
    topics of the golden bags (test/data/bags) and of every tool."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        node = ModelNode(context=ctx, parameter_overrides=[Parameter("mode", value="lockstep")])
        topics = {p.topic_name for p in node.publishers} | {
            s.topic_name for s in node.subscriptions}
        assert {"/joint_states", "/flex/deflections", "/flex/tip_pose", "/flex/shape",
                "/clock", "/diagnostics", "/effort_controller/commands",
                "/flex/payload"} <= topics
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def test_drop_reasons_are_throttled_per_reason_not_per_call_site(lockstep):
    """Issue 23 defect 10: one 1 s throttle per call site hid a NaN command behind a
    wrong-length one. Each reason has its own once-a-second limit; repeats of one reason
    are counted into its next line."""
    h = lockstep
    log = Logs()
    h.node.get_logger = lambda: log
    for bad in ([1.0], [1.0, 2.0, 3.0], [np.nan, 0.0], [0.0, np.inf], [5e3, 0.0]):
        h.cmd.publish(Float64MultiArray(data=bad))
    h.spin_until(lambda: len(log.records) >= 3, "three drop lines")
    h.spin_for(0.1)
    lines = [m for _, m in log.records]
    assert len(lines) == 3, lines                 # wrong length, non-finite, beyond limit
    assert "got 1 values; expected 2" in lines[0]
    assert "got non-finite values [nan, 0]" in lines[1]
    assert "beyond max_torque" in lines[2]
    time.sleep(1.05)
    h.cmd.publish(Float64MultiArray(data=[1.0, 2.0, 3.0, 4.0]))
    h.spin_until(lambda: len(log.records) == 4, "the next wrong-length line")
    assert "got 4 values" in log.records[-1][1]
    assert "(1 more like this since the last report)" in log.records[-1][1]
