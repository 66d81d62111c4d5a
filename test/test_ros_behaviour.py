"""Issue 46: the nodes behave as a ROS user expects, checked with real rclpy clients.

1. list parameters set through the parameter service (what ``ros2 param set`` sends);
2. an oversized planner request is refused at once, the node keeps serving and stops on
   SIGINT; 4. ``~/reset`` with an in-loop controller drops its trajectory; 5. a command
   pulse within the limits is integrated (finer steps), a divergence names the commands and
   the node keeps publishing; 8. controller restarts do not creep, a default start holds;
   9. a renamed planner still publishes on flex_planner/trajectory.
"""
import queue
import signal
import struct
import subprocess
import sys
import threading
import time
import uuid

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Path
from rcl_interfaces.srv import SetParameters
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flex_control.controller_node import ControllerNode
from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.ros.model_node import ModelNode
from flex_model.simulate import SimulationDivergedError
from flex_model.stepper import Stepper
from flex_planner.planner_node import PlannerNode
from flex_planner.ros_messages import waypoints_msg

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


@pytest.fixture
def graph(ros_graph):
    """A private context, its executor and a probe node in namespace ``g.ns`` (the
    conftest's ROS harness), waiting 30 s."""
    g = ros_graph(prefix="b")
    g.timeout = 30.0
    return g


class Recorder:
    """Stands in for a node's logger: (level, message) records."""

    def __init__(self):
        self.records = []

    def __getattr__(self, level):
        return lambda msg, **kwargs: self.records.append((level, str(msg)))


def set_remotely(g, node, values: dict):
    """Set parameters through the node's set_parameters service, as ``ros2 param set``
    does (a list of floats goes as DOUBLE_ARRAY, of integers as INTEGER_ARRAY)."""
    client = g.probe.create_client(SetParameters,
                                   f"{node.get_fully_qualified_name()}/set_parameters")
    request = SetParameters.Request(parameters=[
        Parameter(name, value=value).to_parameter_msg() for name, value in values.items()])
    return g.call(client, request, timeout=120.0).results  # (a first tick may compile)


# ------------------------------------------------------------------ item 1
def test_list_parameters_set_through_the_parameter_service(graph):
    """Issue 46.1: h, a, torque_limits sent as ros2 param set sends them (DOUBLE_ARRAY,
    INTEGER_ARRAY) were refused with "got array('d', ...)"; now they are taken, checked and
    the controller rebuilt; a bad one is refused with the reason. The model node's in-loop
    controller_params.* are refused with a reason (before: accepted and ignored)."""
    g = graph
    ctrl = g.add(ControllerNode(context=g.ctx, namespace=g.ns))
    results = set_remotely(g, ctrl, {"h": [25.0, 20.0], "a": [4, 6],
                                     "torque_limits": [50.0, 60.0]})
    assert [r.successful for r in results] == [True] * 3, [r.reason for r in results]
    assert ctrl.params.h == (25.0, 20.0) and ctrl.params.a == (4.0, 6.0)
    assert ctrl.params.torque_limits == (50.0, 60.0)
    np.testing.assert_array_equal(ctrl.controller.h, [25.0, 20.0])
    np.testing.assert_array_equal(ctrl.controller.torque_limits, [50.0, 60.0])
    bad = set_remotely(g, ctrl, {"h": [-1.0]})[0]
    assert not bad.successful and "h: got [-1.0]; expected 1 or 2 finite gains > 0" in \
        bad.reason, bad.reason
    assert ctrl.params.h == (25.0, 20.0)
    model = g.add(ModelNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
        Parameter("mode", value="lockstep"), Parameter("controller", value="eq95"),
        Parameter("controller_params.h", value=[25.0])]))
    res = set_remotely(g, model, {"controller_params.h": [5.0]})[0]
    assert not res.successful and "controller_params.h is read-only at run time" in \
        res.reason, res.reason
    res = set_remotely(g, model, {"max_torque": 300.0, "initial_joint_angles_deg": [1.0]})
    assert res[0].successful and model.p["max_torque"] == 300.0
    assert not res[1].successful and "read-only" in res[1].reason and \
        "initial_joint_angles_deg" in res[1].reason, res[1].reason


# ------------------------------------------------------------------ item 9
def test_renamed_planner_publishes_on_the_documented_topics(ros_graph):
    """Issue 46.9: the planner published under its node name (~/trajectory): renamed with
    ``-r flex_planner:__node:=arm_planner`` it went to /arm_planner/trajectory while the
    model and the controller listen on flex_planner/trajectory. Now its topics are
    flex_planner/... in its namespace whatever its name, and remapping still applies."""
    g = ros_graph(prefix="b", args=["--ros-args", "-r", "flex_planner:__node:=arm_planner",
                                    "-r", "flex_planner/nominal_path:=rviz/nominal_path"])
    g.timeout = 30.0
    plan = g.add(PlannerNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
        Parameter("sample_period", value=0.05)]))
    ctrl = g.add(ControllerNode(context=g.ctx, namespace=g.ns))
    assert plan.get_name() == "arm_planner"
    assert plan.pub_trajectory.topic_name == f"{g.ns}/flex_planner/trajectory"
    assert plan.pub_path.topic_name == f"{g.ns}/rviz/nominal_path"
    trajectories = []
    g.probe.create_subscription(JointTrajectory, "flex_planner/trajectory",
                                trajectories.append, RELIABLE)
    waypoints = g.probe.create_publisher(Path, "flex_planner/waypoints", RELIABLE)
    g.spin_until(lambda: waypoints.get_subscription_count() and
                 plan.pub_trajectory.get_subscription_count() >= 2, "discovery")
    waypoints.publish(waypoints_msg([(-1.0, -1.0, 0.0), (-2.0, -1.0, 1.0)]))
    g.spin_until(lambda: trajectories, "the renamed planner's trajectory", 120.0)
    assert len(trajectories[0].points) == 21  # 1 s every 0.05 s
    # the controller in the namespace has it too (kept until joint_states name joints)
    g.spin_until(lambda: "trajectory" in ctrl.pending, "the controller's trajectory")


# ------------------------------------------------------------------ item 2


def path_bytes(x, y, t, frame="arm_plane") -> bytes:
    """The serialized nav_msgs/Path (plain CDR) of poses at (x, y) with stamps t (s), built
    with numpy: rclpy takes ~10 us a pose to build and serialize one, 10 s for 10^6."""
    one = serialize_message(waypoints_msg([(0.0, 0.0, 0.0)], frame))
    # a PoseStamped with an empty frame_id: 12 bytes, the NUL, padding to 8, 7 doubles;
    # the first one's padding depends on where it starts (CDR aligns from byte 4)
    first = next(k for k in (72, 76) if struct.unpack_from(
        "<I", one, len(one) - k - 4)[0] == 1)
    head = bytearray(one[:len(one) - first])
    struct.pack_into("<I", head, len(head) - 4, len(t))

    def poses(pad, sl):
        a = np.zeros(len(t[sl]), [("sec", "<i4"), ("nsec", "<u4"), ("frame", "<u4"),
                                  ("nul", "u1", pad), ("xyz", "<f8", 3), ("q", "<f8", 4)])
        sec = np.floor(t[sl])
        a["sec"], a["nsec"] = sec, np.round((t[sl] - sec) * 1e9)
        a["frame"], a["q"][:, 3] = 1, 1.0
        a["xyz"][:, 0], a["xyz"][:, 1] = x[sl], y[sl]
        return a.tobytes()
    return bytes(head) + poses(first - 68, slice(0, 1)) + poses(4, slice(1, None))


def test_path_bytes_are_a_path():
    from rclpy.serialization import deserialize_message
    t = np.array([0.0, 0.25, 1.5])
    msg = deserialize_message(path_bytes(-np.arange(3.0), -1.0 - t, t), Path)
    assert msg.header.frame_id == "arm_plane" and len(msg.poses) == 3
    p = msg.poses[2]
    assert (p.header.stamp.sec, p.header.stamp.nanosec) == (1, 500_000_000)
    assert (p.pose.position.x, p.pose.position.y, p.pose.orientation.w) == (-2.0, -2.5, 1.0)


def test_planner_refuses_a_million_waypoints_at_once_and_keeps_serving(graph):
    """Issue 46.2: 10^6 waypoints 0.1 ms apart (a 100 s plan, within max_samples) hung
    the planner for minutes (rclpy alone takes ~46 s to build the message) and it ignored
    SIGINT. Now, in its own process, it refuses the request from its serialized size in
    one line, plans the next valid request and stops on SIGINT."""
    ns = f"/q{uuid.uuid4().hex[:8]}"
    proc = subprocess.Popen(
        [sys.executable, "-m", "flex_planner.planner_node", "--ros-args", "-r",
         f"__ns:={ns}", "-p", "sample_period:=0.05"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = queue.Queue()
    threading.Thread(target=lambda: [lines.put(ln) for ln in proc.stdout],
                     daemon=True).start()

    def wait_line(text, timeout):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            try:
                line = lines.get(timeout=0.1)
            except queue.Empty:
                continue
            if text in line:
                return line
        raise AssertionError(f"no line with {text!r} within {timeout} s")

    g = graph
    try:
        trajectories = []
        g.probe.create_subscription(JointTrajectory, f"{ns}/flex_planner/trajectory",
                                    trajectories.append, RELIABLE)
        waypoints = g.probe.create_publisher(Path, f"{ns}/flex_planner/waypoints", RELIABLE)
        g.spin_until(lambda: waypoints.get_subscription_count(), "the planner", 120.0)
        wait_line("planning for", 120.0)
        n = 1_000_000
        t = np.arange(n) * 1e-4
        big = path_bytes(-1.0 - 0.5 * t / t[-1], np.full(n, -1.0), t)
        start = time.monotonic()
        waypoints.publish(big)
        line = wait_line("waypoints rejected", 60.0)
        refused_after = time.monotonic() - start
        assert "Path.poses: got 1000000 poses; expected at most max_waypoints = 1000" in line
        print(f"10^6 waypoints ({len(big) / 1e6:.0f} MB) refused {refused_after:.2f} s "
              "after publishing")
        waypoints.publish(waypoints_msg([(-1.0, -1.0, 0.0), (-2.0, -1.0, 1.0)]))
        g.spin_until(lambda: trajectories, "the next valid plan", 120.0)
        assert len(trajectories[0].points) == 21
        start = time.monotonic()
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10.0) == 0
        print(f"SIGINT: exited after {time.monotonic() - start:.2f} s")
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def test_planner_refuses_a_long_plan_from_its_first_and_last_stamps(graph):
    """Issue 46.2: the sample bound is checked from the first and last stamps before the
    poses are converted (a 3-pose request spanning 1e5 s: ~1e8 samples)."""
    g = graph
    plan = g.add(PlannerNode(context=g.ctx, namespace=g.ns))
    msg = serialize_message(waypoints_msg([(-1.0, -1.0, 0.0), (float("nan"), 0.0, 1.0),
                                           (-2.0, -1.0, 1e5)]))
    with pytest.raises(ValueError, match=r"needing 100000002 samples .* expected at most "
                       r"max_samples = 200000"):
        plan.bounded_request(msg)  # not the NaN of pose 1: the size comes first
    res = set_remotely(g, plan, {"max_waypoints": 2})[0]
    assert res.successful and plan.max_waypoints == 2
    with pytest.raises(ValueError, match="got 3 poses; expected at most max_waypoints = 2"):
        plan.bounded_request(msg)


# ------------------------------------------------------------------ item 4
def ramp_trajectory(names, end=0.5, duration=1.0, effort=(20.0, 5.0)):
    msg = JointTrajectory(joint_names=list(names))
    for k in range(11):
        t = duration * k / 10
        pt = JointTrajectoryPoint(positions=[end * k / 10, 0.0], velocities=[0.0, 0.0],
                                  effort=list(effort))
        pt.time_from_start.sec = int(t)
        pt.time_from_start.nanosec = int(round((t - int(t)) * 1e9))
        msg.points.append(pt)
    return msg


def test_reset_drops_the_in_loop_trajectory(graph):
    """Issue 46.4: after ~/reset the in-loop controller kept the old trajectory and its
    start time (the old task replayed). Now it commands zero, the initial state held, until
    a new trajectory comes, which then starts at its arrival."""
    g = graph
    model = g.add(ModelNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
        Parameter("mode", value="lockstep"), Parameter("controller", value="eq95"),
        Parameter("controller_params.h", value=[25.0]),
        Parameter("publish_rate", value=100.0)]))
    states = []
    g.probe.create_subscription(JointState, "joint_states", states.append, RELIABLE)
    trajectory = g.probe.create_publisher(JointTrajectory, "flex_planner/trajectory",
                                          RELIABLE)
    reset = g.probe.create_client(Trigger, f"{g.ns}/flex_model/reset")
    g.spin_until(lambda: trajectory.get_subscription_count(), "discovery")
    trajectory.publish(ramp_trajectory(model.names))
    g.spin_until(lambda: model.loop.t0 > 0.0, "the trajectory")  # (starts on arrival)
    t_task = model.loop.t0
    g.spin_until(lambda: model.stepper.t > t_task + 0.6, "the task under way")
    assert model.stepper.joint_state()[0][0] > 0.15  # joint 1 follows the ramp (0.3 rad)
    assert g.call(reset, Trigger.Request()).success
    states.clear()
    commands = set()  # the command at every return of the executor (lockstep: 20 ms slices)

    def newest_after_reset():  # (the old task's states, < 1.1 s, may still come first)
        commands.add(tuple(model.stepper.u))
        return states and states[-1].header.stamp.sec + 1e-9 * states[-1].header.stamp.nanosec \
            >= 1.5
    g.spin_until(newest_after_reset, "a state 1.5 s after the reset")
    assert commands == {(0.0, 0.0)}, commands
    # what a subscriber sees: zero effort, the initial state held (hold_until_command)
    assert list(states[-1].effort) == [0.0, 0.0], states[-1]
    assert list(states[-1].position) == [0.0, 0.0], states[-1]
    trajectory.publish(ramp_trajectory(model.names))
    g.spin_until(lambda: model.loop.idle is False, "the new trajectory")
    t_new = model.stepper.t
    g.spin_until(lambda: model.stepper.t > t_new + 0.6, "the new task under way")
    assert model.loop.t0 == pytest.approx(t_new, abs=0.05)
    assert model.stepper.u[0] != 0.0


# ------------------------------------------------------------------ item 5
def pd_hold_with_pulse(theta, dtheta, k, joint=1, amplitude=300.0):
    """The controller node's default hold (h = a = 5: 125 N m/rad, 35.4 N m s/rad, at
    most 100 N m) about zero, replaced for steps 200-499 by a pulse on ``joint``."""
    if 200 <= k < 500:
        u = np.zeros(2)
        u[joint] = amplitude
        return u
    return np.clip(-125.0 * np.asarray(theta) - 35.36 * np.asarray(dtheta), -100.0, 100.0)


def test_a_pulse_within_the_limits_is_integrated_with_finer_steps():
    """Issue 46.5, the core: a 300 N m pulse on joint 2 (limit 487.8) for 0.6 s under the
    default hold makes 1 ms steps fail at t = 0.893 s; the stepper now integrates a failed
    stretch again in steps 4 (then 16) x shorter and the run completes."""
    model = FlexArmModel(load_arm("thesis_example1_motors"))
    plain, refining = Stepper(model), Stepper(model)
    with pytest.raises(SimulationDivergedError, match="t = 0.893 s"):
        for k in range(1500):
            plain.set_command(pd_hold_with_pulse(*plain.joint_state()[:2], k))
            plain.advance(2e-3)
    refined = 0
    for k in range(1500):
        refining.set_command(pd_hold_with_pulse(*refining.joint_state()[:2], k))
        refined += refining.advance_refining(2e-3) > 1
    assert refining.t == pytest.approx(3.0) and np.all(np.isfinite(refining.x))
    assert refining.max_step == 1e-3 and 1 <= refined <= 50, refined


def test_model_node_survives_a_pulse_within_the_limits(graph):
    """Issue 46.5, the node: the same pulse sent over effort_controller/commands, the hold
    computed from the /joint_states it publishes (lockstep, 500 Hz): the model diverged at
    t = 0.892 s; now it runs on (to 1.2 s here), with a warning line about the finer
    steps."""
    g = graph
    model = g.add(ModelNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
        Parameter("mode", value="lockstep"), Parameter("rate", value=500.0),
        Parameter("lockstep_timeout", value=30.0)]))
    log = Recorder()
    model.get_logger = lambda: log
    states = []
    g.probe.create_subscription(JointState, "joint_states", states.append, RELIABLE)
    cmd = g.probe.create_publisher(Float64MultiArray, "effort_controller/commands", RELIABLE)
    g.spin_until(lambda: cmd.get_subscription_count(), "discovery")
    for k in range(600):
        n = len(states)
        u = pd_hold_with_pulse(states[-1].position, states[-1].velocity, k) if states \
            else np.zeros(2)  # at rest at the initial angles, zero
        cmd.publish(Float64MultiArray(data=[float(v) for v in u]))
        g.spin_until(lambda: len(states) > n or model.diverged is not None, f"step {k}")
        assert model.diverged is None, model.diverged.message
    assert model.stepper.t >= 1.2
    assert any(level == "warning" and "integrated again in steps 4 x shorter" in m
               for level, m in log.records), log.records


def test_divergence_names_the_pulse_and_the_node_keeps_publishing(graph, monkeypatch):
    """Issue 46.5: when the integration fails after a pulse (here forced at t = 0.05 s,
    every step size failing), the diagnostic names the command applied then ([0, 0]) and
    the largest before, the pulse ([0, 300] at t = 0.02 s); /joint_states goes on with the
    last good state and zero effort until ~/reset (before: it stopped)."""
    g = graph
    model = g.add(ModelNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
        Parameter("mode", value="lockstep"), Parameter("rate", value=500.0),
        Parameter("lockstep_timeout", value=30.0), Parameter("publish_rate", value=50.0)]))
    advance = model.stepper.advance

    def failing_advance(duration):
        if model.stepper.t >= 0.05 - 1e-9:
            raise SimulationDivergedError("Newton iterations did not converge (forced)")
        advance(duration)
    monkeypatch.setattr(model.stepper, "advance", failing_advance)
    states, diagnostics = [], []
    g.probe.create_subscription(JointState, "joint_states", states.append, RELIABLE)
    g.probe.create_subscription(DiagnosticArray, "/diagnostics", diagnostics.append, 10)
    cmd = g.probe.create_publisher(Float64MultiArray, "effort_controller/commands", RELIABLE)
    reset = g.probe.create_client(Trigger, f"{g.ns}/flex_model/reset")
    g.spin_until(lambda: cmd.get_subscription_count(), "discovery")
    for k in range(40):
        u = [0.0, 300.0] if 10 <= k < 15 else [0.0, 0.0]
        cmd.publish(Float64MultiArray(data=u))
        g.spin_until(lambda: model.stepper.t >= (k + 1) * 2e-3 - 1e-9 or
                     model.diverged is not None, f"step {k}")
        if model.diverged is not None:
            break
    assert model.diverged is not None and model.diverged_at == pytest.approx(0.05)
    g.spin_until(lambda: any(s.message == model.diverged.message for d in diagnostics
                             for s in d.status), "the diagnostic")
    text = model.diverged.message
    assert "under the joint command [0, 0] applied when it failed" in text, text
    assert "the largest command before: [0, 300] at t = 0.02 s" in text, text
    n = len(states)
    g.spin_until(lambda: len(states) >= n + 5, "states after the divergence", 10.0)
    held = states[n:]
    assert all(list(m.effort) == [0.0, 0.0] for m in held)
    assert {(m.header.stamp.sec, m.header.stamp.nanosec) for m in held} == {(0, 50_000_000)}
    np.testing.assert_array_equal(held[-1].position, model.stepper.joint_state()[0])
    monkeypatch.setattr(model.stepper, "advance", advance)
    assert g.call(reset, Trigger.Request()).success and model.diverged is None


# ------------------------------------------------------------------ item 8
def test_default_start_holds_the_arm_until_the_first_command(graph):
    """Issue 46.8: with zero torque from the start the default arm fell until a controller
    connected. Now (hold_until_command, default true) the initial state is held while time
    runs; the first command releases it; after ~/reset it is held again."""
    g = graph
    model = g.add(ModelNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
        Parameter("initial_joint_angles_deg", value=[30.0, -20.0])]))
    start = model.stepper.joint_state()[0].copy()
    states = []
    g.probe.create_subscription(JointState, "joint_states", states.append, RELIABLE)
    cmd = g.probe.create_publisher(Float64MultiArray, "effort_controller/commands", RELIABLE)
    reset = g.probe.create_client(Trigger, f"{g.ns}/flex_model/reset")
    g.spin_until(lambda: model.stepper.t > 0.5 and states, "0.5 s of simulation time")
    np.testing.assert_array_equal(states[-1].position, start)  # held, to the last bit
    np.testing.assert_array_equal(model.stepper.q, model.stepper.q0)
    cmd.publish(Float64MultiArray(data=[0.0, 0.0]))  # zero torque, commanded: it falls
    g.spin_until(lambda: not model.braked, "the command")
    t_free = model.stepper.t
    g.spin_until(lambda: model.stepper.t > t_free + 0.3, "0.3 s free")
    fallen = model.stepper.joint_state()[0]
    assert fallen[0] < start[0] - np.radians(5.0), np.degrees(fallen)
    assert g.call(reset, Trigger.Request()).success and model.braked
    g.spin_until(lambda: model.stepper.t > 0.3, "0.3 s after the reset")
    np.testing.assert_array_equal(model.stepper.joint_state()[0], start)


def test_controller_restarts_hold_the_declared_pose_without_creeping(graph):
    """Issue 46.8: each restart of the controller re-anchored to the pose the arm had
    sagged to under its PD (joint 1 at 151 deg: +7 deg a restart with the default gains
    here, +1 deg in the audit). With hold_joint_angles_deg (the model's initial angles)
    every restart holds the same pose: the arm settles at the same angles each time."""
    g = graph
    model = g.add(ModelNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
        Parameter("mode", value="lockstep"),
        Parameter("initial_joint_angles_deg", value=[151.0, 10.0])]))
    settled, held = [], []
    for restart in range(3):
        ctrl = g.add(ControllerNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
            Parameter("hold_joint_angles_deg", value=[151.0, 10.0])]))
        t_end = model.stepper.t + 1.5
        g.spin_until(lambda: model.stepper.t >= t_end, f"1.5 s with controller {restart}",
                     120.0)
        held.append(np.degrees(ctrl.controller.reference.positions[0]))
        settled.append(np.degrees(model.stepper.joint_state()[0]))
        ctrl.stop()  # as on SIGINT: zero torques, then gone
        g.remove(ctrl)
    settled = np.array(settled)
    assert 6.5 < settled[0][0] - 151.0 < 7.5  # the sag of the h = a = 5 PD there
    np.testing.assert_allclose(settled, np.broadcast_to(settled[0], settled.shape),
                               atol=1.0)  # no creep (1.5 s: within 0.3 deg of rest)
    np.testing.assert_allclose(held, [[151.0, 10.0]] * 3, rtol=0, atol=1e-12)


def test_reset_ends_a_running_follow_joint_trajectory_goal(graph):
    """Issue 46.4 with the FollowJointTrajectory action (control_msgs, built by
    scripts/bootstrap.sh): ~/reset ends the running goal (INVALID_GOAL, "ended by
    ~/reset"; before, it went on from the reset state), the arm then holds with zero
    command, and a new goal drives it again."""
    pytest.importorskip("control_msgs.action")
    from builtin_interfaces.msg import Duration
    from control_msgs.action import FollowJointTrajectory as FJT
    from rclpy.action import ActionClient
    g = graph
    model = g.add(ModelNode(context=g.ctx, namespace=g.ns, parameter_overrides=[
        Parameter("mode", value="lockstep"), Parameter("controller", value="eq95"),
        Parameter("controller_params.h", value=[25.0]),
        Parameter("publish_rate", value=100.0)]))
    client = ActionClient(g.probe, FJT, "joint_trajectory_controller/follow_joint_trajectory")
    reset = g.probe.create_client(Trigger, f"{g.ns}/flex_model/reset")
    g.spin_until(client.server_is_ready, "the action server", 120.0)

    def goal(target, duration):
        msg = FJT.Goal()
        msg.trajectory.joint_names = list(model.names)
        msg.trajectory.points.append(JointTrajectoryPoint(
            positions=list(target), time_from_start=Duration(sec=int(duration))))
        return msg

    def send(msg):
        future = client.send_goal_async(msg)
        g.spin_until(future.done, "the goal response")
        return future.result()
    handle = send(goal([0.5, 0.0], 3))
    result = handle.get_result_async()
    t_goal = model.stepper.t
    g.spin_until(lambda: model.stepper.t > t_goal + 0.5, "the goal under way")
    assert g.call(reset, Trigger.Request()).success
    g.spin_until(result.done, "the goal's result")
    assert result.result().result.error_code == FJT.Result.INVALID_GOAL
    assert result.result().result.error_string == "ended by ~/reset"
    g.spin_until(lambda: model.stepper.t > 1.0, "1 s after the reset")
    assert list(model.stepper.u) == [0.0, 0.0]
    np.testing.assert_array_equal(model.stepper.q, model.stepper.q0)  # held
    handle = send(goal([0.3, 0.0], 1))
    result = handle.get_result_async()
    g.spin_until(result.done, "the new goal's result", 120.0)
    assert result.result().result.error_code == FJT.Result.SUCCESSFUL
    assert model.stepper.joint_state()[0][0] == pytest.approx(0.3, abs=0.05)
