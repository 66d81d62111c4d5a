"""The spatial model node (issue 25) in-process: lockstep against the compiled loop,
the in-loop Eq. 95 PD, bad messages dropped and counted."""
import re

import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from visualization_msgs.msg import MarkerArray

from flex_model.spatial import SpatialArmModel, load_spatial_arm
from flex_model.spatial.integrate import simulate_fixed_compiled
from flex_model.ros.model_node import LATCHED, SpatialModelNode

ARM = "seed003_like_arm"


@pytest.fixture(scope="module")
def compiled_loop():
    """Compile (or load) the spatial loop before any node waits for a period: a cold numba
    cache takes longer than spin_until's timeout on a loaded machine."""
    model = SpatialArmModel(load_spatial_arm(ARM))
    simulate_fixed_compiled(model, np.zeros(model.nq), np.zeros(model.nq), 1e-3, 1)


@pytest.fixture
def harness(compiled_loop, ros_graph):
    """``harness(**params)``: a spatial model node and a probe (states, deflections,
    shapes, robot_description, commands, set-points) in the conftest's ROS harness;
    ``h.command(u)``: one lockstep period."""
    def make(**params):
        # lockstep: no watchdog step while a test waits for discovery (unless asked for)
        params.setdefault("lockstep_timeout", 60.0)
        h = ros_graph(SpatialModelNode, "s", **params)
        h.timeout = 20.0
        h.states = h.subscribe(JointState, "joint_states", 100)
        h.defl = h.subscribe(JointState, "flex/deflections", 100)
        h.shapes = h.subscribe(MarkerArray, "flex/shape", 100)
        h.desc = h.subscribe(String, "robot_description", LATCHED)
        h.cmd = h.probe.create_publisher(Float64MultiArray, "effort_controller/commands", 100)
        h.sp = h.probe.create_publisher(Float64MultiArray, "flex/setpoints", 10)
        h.spin_until(lambda: h.cmd.get_subscription_count() > 0 and
                     h.node.pub_shape.get_subscription_count() > 0 and h.desc, "discovery")
        skip = 0 if h.states else 1   # the initial state may arrive before discovery
        h.command = lambda u: command(h, u, skip)
        return h
    return make


def command(h, u, skip: int) -> None:
    n = h.node.steps
    h.cmd.publish(Float64MultiArray(data=list(map(float, u))))
    h.spin_until(lambda: h.node.steps > n and len(h.states) > n + 1 - skip,
                 "a lockstep period")


def stamp_s(msg):
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def reference(model, q, v, h, per, torques, **kw):
    """The compiled loop, one call per period, restarted (consistent acceleration) at
    each new command (as the node and the planar Stepper)."""
    out = []
    for u in torques:
        run = simulate_fixed_compiled(model, q, v, h, per, joint_torques=u, **kw)
        q, v = run.q[-1], run.v[-1]
        out.append((q, v))
    return out


def test_lockstep_equals_the_compiled_loop_and_bad_commands_are_dropped(harness):
    h = harness(arm=ARM, mode="lockstep", rate=200.0, step=1e-3,
                initial_joint_values=[0.1, -0.2, 0.3])
    node = h.node
    assert node.per == 5 and node.h == pytest.approx(1e-3, abs=1e-15)
    torques = [np.array([2.0 * np.sin(0.7 * k), -1.0 + 0.1 * k, 0.5]) for k in range(12)]
    for k, u in enumerate(torques):
        h.command(u)
        if k == 5:   # bad commands: wrong lengths, NaN, inf -> dropped, counted, no step
            for bad in ([1.0], [1.0, 2.0, 3.0, 4.0], [np.nan, 0.0, 0.0], [0.0, np.inf, 0.0]):
                h.cmd.publish(Float64MultiArray(data=bad))
            h.spin_until(lambda: node.dropped == 4, "four drops")
            assert node.steps == 6
    model = SpatialArmModel(load_spatial_arm(ARM))
    ref = reference(model, node.q0, node.v0, 1e-3, 5, torques)
    assert node.steps == 12 and node.t == pytest.approx(0.06, abs=1e-15)
    by_time = {round(stamp_s(m) * 200): m for m in h.states}
    assert sorted(by_time)[-12:] == list(range(1, 13))
    for k, (q, v) in enumerate(ref):
        m = by_time[k + 1]
        np.testing.assert_allclose(m.position, q[model.off], rtol=0, atol=1e-12)
        np.testing.assert_allclose(m.velocity, v[model.off], rtol=0, atol=1e-12)
        np.testing.assert_array_equal(m.effort, torques[k])
    assert m.name == ["joint1", "joint2", "joint3"]
    # deflections: per flexible link y, z, twist of the tip variables
    h.spin_until(lambda: any(round(stamp_s(x) * 200) == 12 for x in h.defl) and
                 any(round(stamp_s(x.markers[0]) * 200) == 12 for x in h.shapes),
                 "the last period")
    d = [x for x in h.defl if round(stamp_s(x) * 200) == 12][-1]
    assert d.name == ["forearm/tip_deflection_y", "forearm/tip_deflection_z",
                      "forearm/tip_twist"]
    b = model.beams[2]
    s = model.flex_slice(2).start
    q = ref[-1][0]
    np.testing.assert_allclose(d.position[:2], [q[s + b.tip_v], q[s + b.tip_w]], rtol=0,
                               atol=1e-15)
    assert abs(d.position[1]) > 1e-6      # the arm moves: not a zero test
    # /flex/shape: the forearm's centre line ends at its tip frame
    from flex_model.ros.spatial import frame_poses
    tip = [T for _, c, T in frame_poses(model, q) if c == "forearm_tip"][0]
    line = [m for m in h.shapes if round(stamp_s(m.markers[0]) * 200) == 12][-1].markers[0]
    np.testing.assert_allclose([line.points[-1].x, line.points[-1].y, line.points[-1].z],
                               tip[:3, 3], atol=1e-12)
    assert h.desc[0].data.startswith("<robot name=")


def test_in_loop_eq95_equals_the_compiled_loop_with_the_pd(harness):
    kp, kd = [40.0, 60.0, 30.0], [2.0, 3.0, 1.5]
    h = harness(arm=ARM, mode="lockstep", rate=100.0, step=2.5e-3, controller="eq95",
                kp=kp, kd=kd, setpoints=[0.0])
    node = h.node
    sp = [0.2, -0.1, 0.3]
    h.sp.publish(Float64MultiArray(data=sp))
    h.spin_until(lambda: np.array_equal(node.setpoints, sp), "set-points")
    h.sp.publish(Float64MultiArray(data=[0.1, 0.2]))   # wrong length: dropped
    h.spin_until(lambda: node.dropped == 1, "a dropped set-point")
    ff = np.array([0.0, 1.5, 0.0])
    for _ in range(10):   # one held input: the periods continue one run (no restarts)
        h.command(ff)
    model = SpatialArmModel(load_spatial_arm(ARM))
    Kp, Dp = np.zeros((2, model.nq, model.nq))
    a = model.actuator_index
    Kp[a, a], Dp[a, a] = kp, kd
    model.K = model.K + Kp
    u = ff + np.array(kp) * sp
    run = simulate_fixed_compiled(model, node.q0, node.v0, 2.5e-3, 40, joint_torques=u,
                                  damping=Dp, clip_to_effort=False)
    q, v = run.q[-1], run.v[-1]
    # restarted every period instead: a different (equally consistent) run, 1e-6 apart
    ref = reference(model, node.q0, node.v0, 2.5e-3, 4, [u] * 10, damping=Dp,
                    clip_to_effort=False)
    assert np.max(np.abs(ref[-1][0] - q)) > 1e-9
    last = h.states[-1]
    assert stamp_s(last) == pytest.approx(0.1, abs=1e-12)
    np.testing.assert_allclose(last.position, q[model.off], rtol=0, atol=1e-12)
    # effort = kp (s - theta_a) - kd theta_a' + feed-forward (thesis Eq. 95)
    tau = np.array(kp) * (np.array(sp) - q[a]) - np.array(kd) * v[a] + ff
    np.testing.assert_allclose(last.effort, tau, rtol=1e-13, atol=1e-12)
    assert np.max(np.abs(q[model.off])) > 0.01     # the PD moved the arm


def test_bad_parameters_name_the_parameter():
    from flex_model.ros.main import ParameterError
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        for params, text in (({"arm": "no_such_arm"}, "parameter arm:"),
                             ({"kp": [1.0, 2.0]}, "parameter kp: got [1, 2]; expected 3"),
                             ({"mode": "fast"}, "parameter mode: got 'fast'"),
                             ({"payload": [-1.0]}, "parameter payload: got [-1]; expected a "
                              "payload vector (payload mass: got -1 kg; expected >= 0)"),
                             ({"payload": [1.0, 2.0, 3.0]}, "parameter payload: got [1, 2, 3]"
                              "; expected a payload vector (got 3 values; expected one of "
                              "[mass], [mass, J_z]"),
                             ({"arm": "quanser_cuboulder_calibrated", "from_planar": True,
                               "controller": "eq95"}, "parameter controller: got eq95 on an "
                              "arm with dc_motor joints (joint1); expected none: their "
                              "commands are voltages")):
            with pytest.raises(ParameterError, match=re.escape(text)):
                SpatialModelNode(context=ctx, parameter_overrides=[
                    Parameter(k, value=v) for k, v in params.items()])
    finally:
        rclpy.try_shutdown(context=ctx)


def test_model_node_entry_point_dispatches_spatial_arms():
    """``flex-model-node -p arm:=<spatial>`` runs the spatial node, a planar arm the planar."""
    from flex_model.ros.model_node import _arm_argument
    from flex_model.spatial.description import is_spatial_arm
    argv = ["flex-model-node", "--ros-args", "-p", "arm:=thesis_example1",
            "-p", "arm:=seed003_like_arm"]
    assert _arm_argument(argv) == "seed003_like_arm"
    assert is_spatial_arm(_arm_argument(argv))
    assert not is_spatial_arm(_arm_argument(argv[:4]))
    assert _arm_argument(["flex-model-node"]) is None


# ---------------------------------------------------------------- payload, pause, watchdog
SEED000 = "seed000_real_arm_3d"   # one link about a vertical axis, droop w with EI_y = 248


def call(h, srv_type, name, request):
    """Call a service of the node from the probe (in the executor)."""
    client = h.probe.create_client(srv_type, name)
    h.spin_until(client.service_is_ready, f"service {name}")
    future = client.call_async(request)
    h.spin_until(future.done, f"the answer of {name}")
    return future.result()


def test_payload_changes_the_static_droop_to_the_closed_form_and_bad_ones_are_dropped(harness):
    """A tip payload m at rest: the droop grows by m g L^3 / (3 EI_y) (cantilever with a
    tip load; the arm's own droop q L^4 / (8 EI) + m_tip g L^3 / (3 EI)). From the node's
    start_static, a payload on flex/payload makes the tip oscillate about the new static
    droop (the mid-range of the oscillation) and the run equals the compiled loop on the
    arm with the payload lumped into its end body (1e-12)."""
    from geometry_msgs.msg import PoseStamped
    from flex_model.spatial.payload import with_payload
    L, EI, g, rhoA, m_tip, m = 0.28, 248.0, 9.81, 0.1289, 0.025607, 0.1
    w0 = -(rhoA * g * L ** 4 / (8 * EI) + m_tip * g * L ** 3 / (3 * EI))
    w1 = w0 - m * g * L ** 3 / (3 * EI)
    # the initial payload (parameter) with start_static: the closed form at once
    hp = harness(arm=SEED000, mode="lockstep", rate=1000.0, step=2.5e-4, start_static=True,
                 payload=[m])
    z = hp.node.model.tip_position(hp.node.q0)[2]
    assert z == pytest.approx(w1, rel=1e-9)
    # a payload at run time, from rest at the arm's own droop
    h = harness(arm=SEED000, mode="lockstep", rate=1000.0, step=2.5e-4, start_static=True)
    node = h.node
    assert node.model.tip_position(node.q0)[2] == pytest.approx(w0, rel=1e-9)
    tips = []
    h.probe.create_subscription(PoseStamped, "flex/tip_pose", tips.append, 200)
    pub = h.probe.create_publisher(Float64MultiArray, "flex/payload", 10)
    h.spin_until(lambda: pub.get_subscription_count() > 0, "flex/payload discovery")
    pub.publish(Float64MultiArray(data=[m]))
    h.spin_until(lambda: node.payload[0] == m, "the payload")
    for _ in range(100):      # 0.1 s: eight periods of the ~80 Hz vertical mode
        h.command([0.0])
    arm = with_payload(load_spatial_arm(SEED000), m)
    model = SpatialArmModel(arm)
    run = simulate_fixed_compiled(model, node.q0, node.v0, 2.5e-4, 400)
    np.testing.assert_allclose(node.q, run.q[-1], rtol=0, atol=1e-12)
    zs = np.array([model.tip_position(q)[2] for q in run.q])
    assert 0.5 * (zs.min() + zs.max()) == pytest.approx(w1, rel=1e-3)
    assert zs.min() < w1 - 0.9 * (w0 - w1)       # it swings (not a zero test)
    h.spin_until(lambda: any(round(stamp_s(x) * 1000) == 100 for x in tips), "tip pose")
    last = [x for x in tips if round(stamp_s(x) * 1000) == 100][-1]
    np.testing.assert_allclose([last.pose.position.x, last.pose.position.y,
                                last.pose.position.z], model.tip_position(node.q),
                               rtol=0, atol=1e-12)
    # bad payloads: logged, dropped, counted; the payload and the node keep going
    for bad in ([0.1, 0.2, 0.3], [np.nan], [-1.0], [1e6], [0.1, 1.0, 1.0, 1.0, 5.0, 0, 0]):
        pub.publish(Float64MultiArray(data=bad))
    h.spin_until(lambda: node.dropped == 5, "five dropped payloads")
    assert node.payload[0] == m
    h.command([0.0])
    assert node.steps == 101
    # ~/reset: the initial state and payload (none)
    from std_srvs.srv import Trigger
    call(h, Trigger, "flex_model/reset", Trigger.Request())
    assert node.payload[0] == 0.0 and node.steps == 0
    assert node.model.tip_position(node.q)[2] == pytest.approx(w0, rel=1e-9)


def test_a_paused_node_keeps_its_clock(harness):
    """Lockstep: commands while paused are taken but step nothing (no /clock); resuming
    runs one period. Realtime: paused, the simulation time stands still."""
    from rosgraph_msgs.msg import Clock
    from std_srvs.srv import SetBool
    h = harness(arm=ARM, mode="lockstep", rate=200.0, start_paused=True, clock_topic="clock",
                frame_prefix="robot1/", frame_id="world")
    node = h.node
    # frame_id, frame_prefix: every frame of robot_description and flex/shape, not the
    # joints
    import xml.etree.ElementTree as ET
    robot = ET.fromstring(h.desc[0].data)
    assert {x.get("name") for x in robot.findall("link")} == {
        "robot1/" + x for x in ("world", "column", "column_end", "upper_arm",
                                "upper_arm_end", "forearm", "forearm_tip", "forearm_end")}
    assert {x.get("name") for x in robot.findall("joint")} >= {"joint1", "joint2", "joint3"}
    clocks = []
    h.probe.create_subscription(Clock, "clock", clocks.append, 100)
    h.spin_until(lambda: node.pub_clock.get_subscription_count() > 0, "clock discovery")
    n_clock = len(clocks)
    for k in range(3):
        h.cmd.publish(Float64MultiArray(data=[0.5 * k, 0.0, 0.0]))
    h.spin_until(lambda: node.u[0] == 1.0, "the last command")
    h.spin_for(0.2)
    assert node.steps == 0 and node.t == 0.0 and len(clocks) == n_clock
    assert call(h, SetBool, "flex_model/pause", SetBool.Request(data=False)).message == \
        "running"
    assert node.steps == 1 and node.t == pytest.approx(0.005, abs=1e-15)
    h.spin_until(lambda: len(clocks) > n_clock, "the clock")
    assert clocks[-1].clock.nanosec == 5_000_000
    h.spin_until(lambda: h.shapes, "a shape")
    assert h.shapes[-1].markers[0].header.frame_id == "robot1/world"
    # realtime
    r = harness(arm=ARM, mode="realtime", rate=100.0, step=2e-3, start_paused=True)
    r.spin_for(0.3)
    assert r.node.t == 0.0
    call(r, SetBool, "flex_model/pause", SetBool.Request(data=False))
    r.spin_until(lambda: r.node.t >= 0.05, "the realtime loop")
    call(r, SetBool, "flex_model/pause", SetBool.Request(data=True))
    t = r.node.t
    r.spin_for(0.3)
    assert r.node.t == t


@pytest.mark.parametrize("action", ["zero", "hold"])
def test_the_command_timeout_in_lockstep_time(harness, action):
    """command_timeout = 0.02 s at 200 Hz: after one command at t = 0, periods without a
    command keep it while t - 0 <= 0.02 s (periods from 0.005 to 0.02), then zero it (or
    hold it): the states = the compiled loop with that torque sequence (1e-12)."""
    h = harness(arm=ARM, mode="lockstep", rate=200.0, step=1e-3, command_timeout=0.02,
                timeout_action=action, initial_joint_values=[0.1, -0.2, 0.3])
    node = h.node
    u = np.array([3.0, -2.0, 1.0])
    h.command(u)
    for _ in range(6):        # periods without a command (as the realtime loop runs them)
        node.advance()
    assert node.t == pytest.approx(0.035, abs=1e-15)
    np.testing.assert_array_equal(node.u, u if action == "hold" else 0.0)
    model = SpatialArmModel(load_spatial_arm(ARM))
    if action == "hold":
        ref = simulate_fixed_compiled(model, node.q0, node.v0, 1e-3, 35, joint_torques=u)
    else:     # 5 periods under u (one run), then a restarted run under zero
        a = simulate_fixed_compiled(model, node.q0, node.v0, 1e-3, 25, joint_torques=u)
        ref = simulate_fixed_compiled(model, a.q[-1], a.v[-1], 1e-3, 10)
        other = simulate_fixed_compiled(model, node.q0, node.v0, 1e-3, 35, joint_torques=u)
        assert np.max(np.abs(other.q[-1] - ref.q[-1])) > 1e-6
    np.testing.assert_allclose(node.q, ref.q[-1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(node.v, ref.v[-1], rtol=0, atol=1e-12)


def test_a_stalled_lockstep_loop_steps_with_a_zero_command(harness):
    """lockstep_timeout (set at run time) without a command: the watchdog steps the model
    and applies timeout_action at once (zero); a bad run-time value is refused."""
    from rclpy.parameter import Parameter as P
    h = harness(arm=ARM, mode="lockstep", rate=200.0, step=1e-3)
    node = h.node
    u = np.array([3.0, -2.0, 1.0])
    h.command(u)
    bad = node.set_parameters([P("lockstep_timeout", value=-1.0)])[0]
    assert not bad.successful and "lockstep_timeout" in bad.reason
    assert not node.set_parameters([P("rate", value=10.0)])[0].successful
    assert node.set_parameters([P("lockstep_timeout", value=0.2)])[0].successful
    h.spin_until(lambda: node.steps == 2, "the watchdog step")
    np.testing.assert_array_equal(node.u, 0.0)
    model = SpatialArmModel(load_spatial_arm(ARM))
    a = simulate_fixed_compiled(model, node.q0, node.v0, 1e-3, 5, joint_torques=u)
    ref = simulate_fixed_compiled(model, a.q[-1], a.v[-1], 1e-3, 5)
    np.testing.assert_allclose(node.q, ref.q[-1], rtol=0, atol=1e-12)


def test_a_newton_failure_stops_stepping_with_a_diagnostic_and_reset_restarts(harness,
                                                                              monkeypatch):
    from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
    from std_srvs.srv import Trigger
    import flex_model.spatial.integrate as integrate
    h = harness(arm=ARM, mode="lockstep", rate=200.0)
    node = h.node
    diags = []
    h.probe.create_subscription(DiagnosticArray, "/diagnostics", diags.append, 10)
    h.spin_until(lambda: node.pub_diag.get_subscription_count() > 0, "diagnostics")
    h.command([1.0, 0.0, 0.0])
    real = integrate.simulate_fixed_compiled

    def fail(*args, **kw):
        raise RuntimeError("generalized-alpha: no convergence at t = 0.006 s")
    monkeypatch.setattr(integrate, "simulate_fixed_compiled", fail)
    h.cmd.publish(Float64MultiArray(data=[2.0, 0.0, 0.0]))
    h.spin_until(lambda: node.diverged is not None, "the failure")
    h.spin_until(lambda: diags, "the ERROR diagnostic")
    assert diags[-1].status[0].level == DiagnosticStatus.ERROR
    assert "t = 0.005 s" in diags[-1].status[0].message
    assert node.t == pytest.approx(0.005) and not np.any(node.u)
    h.cmd.publish(Float64MultiArray(data=[2.0, 0.0, 0.0]))    # answered with a reason
    h.spin_until(lambda: node.dropped == 1, "a dropped command")
    monkeypatch.setattr(integrate, "simulate_fixed_compiled", real)
    call(h, Trigger, "flex_model/reset", Trigger.Request())
    h.spin_until(lambda: diags[-1].status[0].level == DiagnosticStatus.OK, "OK")
    h.command([1.0, 0.0, 0.0])
    assert node.steps == 1 and node.diverged is None


def test_urdf_effort_and_position_limits_in_the_node(harness):
    """ur5_like_flexible_forearm_element (the flexible forearm given by a <flex:flexible>
    element of the URDF): a 400 N m command on joint 1 (effort limit 150 N m)
    acts and is published as 150 N m; 1000 N m is beyond the automatic plausibility limit
    max_torque (10 x the largest gravity torque, 516 N m) and dropped; a joint started
    beyond its position limit is reported (logged), not stopped."""
    h = harness(arm="ur5_like_flexible_forearm_element", mode="lockstep", rate=100.0,
                step=2.5e-3,
                initial_joint_values=[7.0, -0.5, 1.0, 0.0, 0.0, 0.0])
    node = h.node
    assert node.limit("max_torque") == pytest.approx(515.58, abs=0.01)
    h.cmd.publish(Float64MultiArray(data=[1000.0, 0.0, 0.0, 0.0, 0.0, 0.0]))
    h.spin_until(lambda: node.dropped == 1, "a command beyond max_torque")
    assert node.steps == 0
    u = np.array([400.0, 0.0, 0.0, 0.0, -30.0, 0.0])
    h.command(u)
    clipped = np.array([150.0, 0.0, 0.0, 0.0, -28.0, 0.0])
    np.testing.assert_array_equal(h.states[-1].effort, clipped)
    model = SpatialArmModel(load_spatial_arm("ur5_like_flexible_forearm"))
    ref = simulate_fixed_compiled(model, node.q0, node.v0, 2.5e-3, 4,
                                  joint_torques=clipped, clip_to_effort=False)
    np.testing.assert_allclose(node.q, ref.q[-1], rtol=0, atol=1e-12)
    assert ("position", 0) in node.drops.last and ("position", 1) not in node.drops.last


def test_eq45_in_the_node_is_the_clipped_joint_pd(harness):
    """controller eq45 (seed 000's cascade; no gear effects on this arm: n = 1, so the
    joint PD has kp = kpv kpp, kd = kpv) on the UR5-like arm, a 1 rad set-point step on
    the shoulder: the PD torque is clipped to the URDF efforts inside the loop (150 N m),
    the states equal the compiled loop with pd_clip and the published effort is the
    clipped law."""
    kpp, kpv = [20.0] * 6, [40.0] * 6
    h = harness(arm="ur5_like_flexible_forearm_element", mode="lockstep", rate=100.0,
                step=2.5e-3, controller="eq45", kpp=kpp, kpv=kpv, setpoints=[0.0])
    node = h.node
    np.testing.assert_array_equal(node.kp, np.array(kpp) * kpv)
    np.testing.assert_array_equal(node.kd, kpv)
    sp = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    h.sp.publish(Float64MultiArray(data=sp))
    h.spin_until(lambda: np.array_equal(node.setpoints, sp), "set-points")
    for _ in range(3):
        h.command(np.zeros(6))
    model = SpatialArmModel(load_spatial_arm("ur5_like_flexible_forearm"))
    kp, kd = node.kp, node.kd
    Kp, Dp = np.zeros((2, model.nq, model.nq))
    a = model.actuator_index
    Kp[a, a], Dp[a, a] = kp, kd
    model.K = model.K + Kp
    u = kp * np.array(sp)
    run = simulate_fixed_compiled(model, node.q0, node.v0, 2.5e-3, 12, joint_torques=u,
                                  damping=Dp, pd_clip=(kp, kd))
    q, v = run.q[-1], run.v[-1]
    np.testing.assert_allclose(h.states[-1].position, q[model.off], rtol=0, atol=1e-12)
    law = kp * (np.array(sp) - q[a]) - kd * v[a]
    effort = np.array([150.0, 150.0, 150.0, 28.0, 28.0, 28.0])
    np.testing.assert_allclose(h.states[-1].effort, np.clip(law, -effort, effort),
                               rtol=1e-12, atol=1e-9)
    assert h.states[-1].effort[0] == 150.0 and law[0] > 150.0      # saturated
