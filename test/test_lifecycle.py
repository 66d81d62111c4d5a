"""Lifecycle nodes (issue 46): a real lifecycle client (lifecycle_msgs ChangeState and
GetState on <node>/change_state, <node>/get_state, what ``ros2 lifecycle set`` calls) in
another node drives the suite's nodes through configure, activate, deactivate, cleanup."""
import time
import uuid

import numpy as np
import pytest
import rclpy
from lifecycle_msgs.msg import State, Transition
from lifecycle_msgs.srv import ChangeState, GetState
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.ros.model_node import ModelNode
from flex_model.stepper import Stepper


def stamp_s(msg) -> float:
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


@pytest.fixture
def manager(ros_graph):
    """``manager(factory, name, **params)``: the node in its own namespace, spun with a
    manager (``h.mgr``: the conftest harness's probe) holding its lifecycle clients and
    a probe of its topics."""
    def make(factory, name, **params):
        h = ros_graph(factory, "lc", **params)
        h.mgr = h.probe
        h.change = h.mgr.create_client(ChangeState, f"{h.ns}/{name}/change_state")
        h.get = h.mgr.create_client(GetState, f"{h.ns}/{name}/get_state")
        h.states = h.subscribe(JointState, "joint_states", 100)
        h.cmd = h.mgr.create_publisher(Float64MultiArray, "effort_controller/commands", 100)
        h.state = lambda: h.call(h.get, GetState.Request()).current_state.label
        h.transition = lambda transition_id: h.call(h.change, ChangeState.Request(
            transition=Transition(id=transition_id))).success
        h.spin_until(lambda: h.change.service_is_ready() and h.get.service_is_ready(),
                     "the lifecycle services")
        return h
    return make


def core(arm: str, angles_deg, steps: int):
    """The core's joint state after ``steps`` lockstep steps of 1 ms at zero torque."""
    model = FlexArmModel(load_arm(arm))
    ref = Stepper(model, model.q_from_joint_angles(np.radians(angles_deg)))
    for _ in range(steps):
        ref.advance(1e-3)
    return ref.joint_state()


@pytest.fixture
def managed(manager):
    return manager(ModelNode, "flex_model", autostart=False, mode="lockstep", rate=1000.0,
                   publish_rate=1000.0, lockstep_timeout=100.0, hold_until_command=False,
                   initial_joint_angles_deg=[30.0, -20.0])


def step(h, k: int) -> None:
    """``k`` zero-torque commands, one lockstep step (and joint_states) each."""
    h.spin_until(lambda: h.cmd.get_subscription_count() > 0, "the command subscription")
    for _ in range(k):
        n = len(h.states)
        h.cmd.publish(Float64MultiArray(data=[0.0, 0.0]))
        h.spin_until(lambda: len(h.states) > n, "a step")


def activate_configured(h):
    """A configured (inactive) node publishes nothing until activated; on activate it
    publishes its state at t = 0."""
    h.spin_for(0.2)
    assert h.states == []  # configured, not active: nothing stepping-related
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    assert h.state() == "active"
    h.spin_until(lambda: h.states, "the state published on activate")
    assert stamp_s(h.states[0]) == 0.0


def test_model_node_transitions_with_a_lifecycle_client(managed):
    h = managed
    assert h.state() == "unconfigured"
    h.spin_for(0.2)
    assert h.states == []  # unconfigured: no arm, nothing published
    assert h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.state() == "inactive"
    activate_configured(h)
    step(h, 20)
    angles, rates, _ = core("thesis_example1_motors", [30.0, -20.0], 20)
    assert stamp_s(h.states[-1]) == pytest.approx(0.020, abs=1e-12)
    np.testing.assert_allclose(h.states[-1].position, angles, rtol=0, atol=1e-12)
    np.testing.assert_allclose(h.states[-1].velocity, rates, rtol=0, atol=1e-10)
    assert abs(rates[0]) > 1e-3  # the arm moves under gravity: a hold would fail this

    # deactivate: commands are refused, nothing is published, the state is held
    assert h.transition(Transition.TRANSITION_DEACTIVATE)
    assert h.state() == "inactive"
    held, n = h.states[-1], len(h.states)
    for _ in range(10):
        h.cmd.publish(Float64MultiArray(data=[0.0, 0.0]))
        h.spin_for(0.03)
    assert len(h.states) == n
    assert h.node.stepper.t == pytest.approx(0.020, abs=1e-12)

    # activate again: resumes from the held state, on the same time grid
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    h.spin_until(lambda: len(h.states) > n, "the held state on activate")
    assert stamp_s(h.states[n]) == stamp_s(held)
    np.testing.assert_array_equal(h.states[n].position, held.position)
    step(h, 20)
    angles, rates, _ = core("thesis_example1_motors", [30.0, -20.0], 40)
    assert stamp_s(h.states[-1]) == pytest.approx(0.040, abs=1e-12)
    np.testing.assert_allclose(h.states[-1].position, angles, rtol=0, atol=1e-12)

    # cleanup: unconfigured, the arm released; configure another arm and run it
    assert h.transition(Transition.TRANSITION_DEACTIVATE)
    assert h.transition(Transition.TRANSITION_CLEANUP)
    assert h.state() == "unconfigured"
    assert not list(h.node.timers)
    assert h.node.set_parameters([Parameter("arm", value="thesis_example1")])[0].successful
    assert h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.node.model.arm.name == "thesis_example1"
    assert h.node.describe_parameter("arm").read_only  # configured: built from it
    # new publishers (cleanup released the old ones): the probe matches them first
    h.spin_until(lambda: h.node.pub_js.get_subscription_count() > 0, "discovery")
    n = len(h.states)
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    h.spin_until(lambda: len(h.states) > n, "the new arm's first state")
    assert stamp_s(h.states[n]) == 0.0
    step(h, 20)
    angles, rates, _ = core("thesis_example1", [30.0, -20.0], 20)
    np.testing.assert_allclose(h.states[-1].position, angles, rtol=0, atol=1e-12)
    other, _, _ = core("thesis_example1_motors", [30.0, -20.0], 20)
    assert np.max(np.abs(np.asarray(other) - angles)) > 1e-6  # the two arms differ


def test_a_bad_configure_fails_and_the_node_stays_unconfigured(managed):
    h = managed
    assert h.node.set_parameters([Parameter("arm", value="no_such_arm")])[0].successful
    assert not h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.state() == "unconfigured"
    assert not list(h.node.timers) and h.states == []
    # the node keeps running: a good value configures it
    assert h.node.set_parameters([Parameter("arm", value="thesis_example1")])[0].successful
    assert h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.state() == "inactive"


def test_a_bad_value_fails_configure_with_the_start_line(manager):
    """A value the parameter check refuses: configure FAILURE, logged with the same line
    that autostart (run_node) prints and exits with."""
    h = manager(ModelNode, "flex_model", autostart=False, rate=-5.0)
    assert not h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.state() == "unconfigured"
    assert str(h.node.configure_error) == "parameter rate: got -5; expected a number > 0"
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        with pytest.raises(ValueError, match="parameter rate: got -5; expected a number > 0"):
            ModelNode(context=ctx, parameter_overrides=[Parameter("rate", value=-5.0)])
    finally:
        rclpy.try_shutdown(context=ctx)


def test_autostart_default_is_active(manager):
    h = manager(ModelNode, "flex_model")
    assert h.state() == "active"
    h.spin_until(lambda: len(h.states) >= 3, "joint_states of the autostarted node")


def test_controller_node_transitions_with_a_lifecycle_client(manager):
    """Active: Eq. 45 about the first measured pose; deactivate: zero torques once, then
    silence; activate: the same held reference; cleanup and a configure with another
    hold pose; a bad law fails configure."""
    from flex_control.controller_node import ControllerNode
    from flex_control.laws import PDLikeCascade, hold_reference
    h = manager(ControllerNode, "flex_controller", autostart=False, law="eq45",
                joint_names=["j"], torque_limits=[1e9], state_timeout=30.0)
    got = []
    h.mgr.create_subscription(Float64MultiArray, "effort_controller/commands",
                              lambda m: got.append(list(m.data)), 100)
    js = h.mgr.create_publisher(JointState, "joint_states", 10)

    def command_for(pos, vel, expected=None):
        """The command once the timer has used the state (pos, vel): the first one, or
        the first equal to ``expected`` within 1 s (commands come at rate_hz)."""
        n = len(got)
        js.publish(JointState(name=["j"], position=[pos], velocity=[vel]))
        h.spin_until(lambda: len(got) > n, "a command")
        end = time.monotonic() + 1.0
        while expected is not None and got[-1][0] != pytest.approx(expected, rel=1e-12) \
                and time.monotonic() < end:
            h.ex.spin_once(timeout_sec=0.005)
        return got[-1][0]

    def want(ref, pos, vel):
        return PDLikeCascade(hold_reference(["j"], [ref])).torque(0.0, [pos], [vel])[0]

    assert h.state() == "unconfigured"
    assert h.transition(Transition.TRANSITION_CONFIGURE)
    h.spin_until(lambda: js.get_subscription_count() > 0, "discovery")
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    command_for(0.2, 0.0)  # the first measured pose becomes the held reference
    w = want(0.2, 0.1, 0.01)
    assert command_for(0.1, 0.01, w) == pytest.approx(w, rel=1e-12)
    assert h.transition(Transition.TRANSITION_DEACTIVATE)
    h.spin_for(0.1)
    assert got[-1] == [0.0]  # zero torques once
    n = len(got)
    for _ in range(5):
        js.publish(JointState(name=["j"], position=[0.1], velocity=[0.01]))
        h.spin_for(0.05)
    assert len(got) == n  # inactive: no commands
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    w = want(0.2, 0.1, 0.01)
    assert command_for(0.1, 0.01, w) == pytest.approx(w, rel=1e-12)
    assert h.transition(Transition.TRANSITION_DEACTIVATE)
    assert h.transition(Transition.TRANSITION_CLEANUP)
    assert h.node.set_parameters([Parameter("law", value="no_such_law")])[0].successful
    assert not h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.state() == "unconfigured"
    assert h.node.set_parameters([Parameter("law", value="eq45"), Parameter(
        "hold_joint_angles_deg", value=[-10.0])])[0].successful
    assert h.transition(Transition.TRANSITION_CONFIGURE)
    h.spin_until(lambda: h.node.pub.get_subscription_count() > 0, "discovery")
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    w = want(np.radians(-10.0), 0.1, 0.01)
    assert command_for(0.1, 0.01, w) == pytest.approx(w, rel=1e-12)


def test_planner_node_plans_only_while_active(manager):
    from nav_msgs.msg import Path
    from geometry_msgs.msg import PoseStamped
    from trajectory_msgs.msg import JointTrajectory
    from flex_planner import SECTION_F_TIMES, SECTION_F_WAYPOINTS
    from flex_planner.planner_node import PlannerNode
    h = manager(PlannerNode, "flex_planner", autostart=False, arm="thesis_example1",
                sample_period=0.02)
    got = []
    h.mgr.create_subscription(JointTrajectory, "flex_planner/trajectory", got.append, 5)
    pub = h.mgr.create_publisher(Path, "flex_planner/waypoints", 5)
    path = Path()
    path.header.frame_id = "arm_plane"
    for (x, y), t in zip(SECTION_F_WAYPOINTS, SECTION_F_TIMES):
        ps = PoseStamped()
        ps.header.stamp.sec, ps.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9))
        ps.pose.position.x, ps.pose.position.y, ps.pose.orientation.w = x, y, 1.0
        path.poses.append(ps)
    assert h.transition(Transition.TRANSITION_CONFIGURE)
    h.spin_until(lambda: pub.get_subscription_count() > 0 and
                 h.node.pub_trajectory.get_subscription_count() > 0, "discovery")
    pub.publish(path)  # inactive: refused
    h.spin_for(0.3)
    assert got == []
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    pub.publish(path)
    h.spin_until(lambda: got, "a plan", timeout=30.0)
    assert list(got[0].joint_names) == ["joint1", "joint2"]
    assert len(got[0].points) == pytest.approx(SECTION_F_TIMES[-1] / 0.02, abs=2)
    assert h.transition(Transition.TRANSITION_DEACTIVATE)
    assert h.transition(Transition.TRANSITION_CLEANUP)
    assert h.node.set_parameters([Parameter("arm", value="no_such_arm")])[0].successful
    assert not h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.state() == "unconfigured"


def test_entry_point_with_autostart_false_is_managed_and_exits_cleanly():
    """The model node as a process (its console entry point's main) with autostart:=false:
    unconfigured and silent until a lifecycle client configures and activates it, then
    joint_states flow; SIGINT: exit status 0 after the shutdown transition."""
    import os
    import signal
    import subprocess
    import sys
    ns = f"/lcp{os.getpid()}_{uuid.uuid4().hex[:6]}"
    proc = subprocess.Popen([sys.executable, "-m", "flex_model.ros.model_node", "--ros-args",
                             "-r", f"__ns:={ns}", "-p", "autostart:=false"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    mgr = rclpy.create_node(f"lcmgr_{uuid.uuid4().hex[:6]}", context=ctx, namespace=ns)
    ex = SingleThreadedExecutor(context=ctx)
    ex.add_node(mgr)
    states = []
    mgr.create_subscription(JointState, "joint_states", states.append, 10)
    change = mgr.create_client(ChangeState, f"{ns}/flex_model/change_state")
    get = mgr.create_client(GetState, f"{ns}/flex_model/get_state")

    def until(pred, what, timeout=30.0):
        end = time.monotonic() + timeout
        while not pred():
            assert time.monotonic() < end, f"timed out waiting for {what}"
            assert proc.poll() is None, proc.stdout.read().decode()
            ex.spin_once(timeout_sec=0.01)

    def call(client, request):
        future = client.call_async(request)
        until(future.done, client.srv_name)
        return future.result()

    try:
        until(lambda: change.service_is_ready() and get.service_is_ready(), "the services")
        assert call(get, GetState.Request()).current_state.id == State.PRIMARY_STATE_UNCONFIGURED
        end = time.monotonic() + 0.3
        until(lambda: time.monotonic() > end, "a while")
        assert states == []
        for t in (Transition.TRANSITION_CONFIGURE, Transition.TRANSITION_ACTIVATE):
            assert call(change, ChangeState.Request(transition=Transition(id=t))).success
        assert call(get, GetState.Request()).current_state.id == State.PRIMARY_STATE_ACTIVE
        until(lambda: len(states) >= 5, "joint_states")
        assert stamp_s(states[-1]) > stamp_s(states[0])  # the realtime loop runs
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=20)
        assert proc.returncode == 0, out.decode()
        assert "inactive: stepping stopped" in out.decode()  # on_shutdown deactivated it
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        ex.shutdown()
        mgr.destroy_node()
        rclpy.try_shutdown(context=ctx)


# ---------------------------------------------------------------- the spatial model node
SPATIAL, SPATIAL_1 = "seed003_like_arm", "seed000_real_arm_3d"  # three joints, one joint


def spatial_core(arm: str, q, v, torques, per: int = 5):
    """The compiled spatial loop at rate 200 Hz, ``per`` steps a period, one call per
    period, restarted at each new command as the node does, from (q, v) (None: zeros):
    the model and [(q, v)] after each period."""
    from flex_model.spatial import SpatialArmModel, load_spatial_arm
    from flex_model.spatial.integrate import simulate_fixed_compiled
    model, out = SpatialArmModel(load_spatial_arm(arm)), []
    q, v = (np.zeros(model.nq) if x is None else x for x in (q, v))
    for u in torques:
        run = simulate_fixed_compiled(model, q, v, 5e-3 / per, per,
                                      joint_torques=np.asarray(u))
        q, v = run.q[-1], run.v[-1]
        out.append((q, v))
    return model, out


def spatial_periods(h, torques) -> None:
    """One lockstep period (and joint_states) per command of ``torques``."""
    for u in torques:
        n = len(h.states)
        h.cmd.publish(Float64MultiArray(data=[float(x) for x in u]))
        h.spin_until(lambda: len(h.states) > n, "a lockstep period")


def assert_spatial_states(h, model, ref, first: int) -> None:
    """joint_states at periods first, first + 1, ... equal the core's ``ref`` (1e-12)."""
    by_period = {round(stamp_s(m) * 200): m for m in h.states}
    for k, (q, v) in enumerate(ref[first - 1:], start=first):
        np.testing.assert_allclose(by_period[k].position, q[model.off], rtol=0, atol=1e-12)
        np.testing.assert_allclose(by_period[k].velocity, v[model.off], rtol=0, atol=1e-12)


def test_spatial_model_node_transitions_with_a_lifecycle_client(manager):
    """The spatial node (issue 25) managed as the planar one: silent until activate;
    lockstep periods equal the compiled loop; deactivate holds (inputs and ~/reset
    refused, nothing published, time stands still), activate resumes on the same grid;
    cleanup; a bad arm and a bad per-joint value fail configure with their line; another
    arm configures and runs."""
    from std_srvs.srv import Trigger
    from flex_model.ros.model_node import SpatialModelNode
    spatial_core(SPATIAL, None, None, [[0.0] * 3])  # compile before the node waits
    h = manager(SpatialModelNode, "flex_model", autostart=False, arm=SPATIAL,
                mode="lockstep", rate=200.0, step=1e-3, lockstep_timeout=100.0,
                initial_joint_values=[0.1, -0.2, 0.3])
    reset = h.mgr.create_client(Trigger, f"{h.node.get_fully_qualified_name()}/reset")
    torques = [[2.0 * np.sin(0.7 * k), -1.0 + 0.1 * k, 0.5] for k in range(16)]
    assert h.state() == "unconfigured"
    assert h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.state() == "inactive"
    h.spin_until(lambda: h.node.pub_js.get_subscription_count() > 0 and
                 h.cmd.get_subscription_count() > 0, "discovery")
    activate_configured(h)
    spatial_periods(h, torques[:8])
    q0, v0 = h.node.q0, h.node.v0
    model, ref = spatial_core(SPATIAL, q0, v0, torques)
    np.testing.assert_allclose(q0[model.off], [0.1, -0.2, 0.3], rtol=0, atol=1e-15)
    assert_spatial_states(h, model, ref[:8], 1)
    assert stamp_s(h.states[-1]) == pytest.approx(0.040, abs=1e-12)

    # deactivate: commands and ~/reset refused, nothing published, time stands still
    assert h.transition(Transition.TRANSITION_DEACTIVATE)
    assert h.state() == "inactive"
    held, n, dropped = h.states[-1], len(h.states), h.node.dropped
    for k in range(5):
        h.cmd.publish(Float64MultiArray(data=[1.0, 1.0, 1.0]))
        h.spin_for(0.04)
    assert not h.call(reset, Trigger.Request()).success
    h.spin_until(lambda: h.node.dropped == dropped + 5, "five refused commands")
    assert len(h.states) == n and h.node.t == 0.040 and h.node.steps == 8

    # activate again: the held state first, then the same time grid as the core
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    h.spin_until(lambda: len(h.states) > n, "the held state on activate")
    assert stamp_s(h.states[n]) == stamp_s(held)
    np.testing.assert_array_equal(h.states[n].position, held.position)
    spatial_periods(h, torques[8:])
    assert_spatial_states(h, model, ref, 9)
    assert stamp_s(h.states[-1]) == pytest.approx(0.080, abs=1e-12)

    # cleanup releases; bad values fail configure with their line; another arm runs
    assert h.transition(Transition.TRANSITION_DEACTIVATE)
    assert h.transition(Transition.TRANSITION_CLEANUP)
    assert h.state() == "unconfigured"
    assert not list(h.node.timers) and h.node.model is None
    for params, line in (({"arm": "no_such_arm"}, "parameter arm: "),
                         ({"arm": SPATIAL_1}, "parameter initial_joint_values: got "
                          "[0.1, -0.2, 0.3]; expected 1 values")):
        assert h.node.set_parameters([Parameter(k, value=v) for k, v in
                                      params.items()])[0].successful
        assert not h.transition(Transition.TRANSITION_CONFIGURE)
        assert h.state() == "unconfigured"
        assert str(h.node.configure_error).startswith(line)
    # seed000's slender link needs the short step (as in test_spatial_node)
    assert h.node.set_parameters([Parameter("initial_joint_values", value=[0.4]),
                                  Parameter("step", value=2.5e-4)])[0].successful
    assert h.transition(Transition.TRANSITION_CONFIGURE)
    assert h.node.names == ["joint1"] and h.node.describe_parameter("arm").read_only
    h.spin_until(lambda: h.node.pub_js.get_subscription_count() > 0, "discovery")
    n = len(h.states)
    assert h.transition(Transition.TRANSITION_ACTIVATE)
    h.spin_until(lambda: len(h.states) > n, "the new arm's first state")
    assert stamp_s(h.states[n]) == 0.0
    del h.states[:n]
    one = [[0.3 * np.cos(0.5 * k)] for k in range(6)]
    spatial_periods(h, one)
    model, ref = spatial_core(SPATIAL_1, h.node.q0, h.node.v0, one, per=20)
    assert h.node.q0[model.off] == pytest.approx([0.4], abs=1e-15)
    assert_spatial_states(h, model, ref, 1)
    assert abs(ref[-1][1][model.off][0]) > 1e-3  # the commands moved the joint


def test_spatial_autostart_default_is_active(manager):
    from flex_model.ros.model_node import SpatialModelNode
    h = manager(SpatialModelNode, "flex_model", arm=SPATIAL)
    assert h.state() == "active"
    h.spin_until(lambda: len(h.states) >= 3, "joint_states of the autostarted node")
    assert stamp_s(h.states[-1]) > stamp_s(h.states[0])  # the realtime loop runs
