"""Robustness of the suite's nodes (issue 23): bad inputs, each answered by a clear log
line (a drop with its reason, or a refusal) while the node stays alive and keeps
publishing; bad parameters at start are one line naming the parameter, the value and what
is allowed.

One private context holds the model (lockstep), the controller and the planner, each in
its own namespace (relative topic names), and a probe that feeds them. Each node's logger
is replaced by a recorder, so every case asserts on the exact line it caused.
"""
import math
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path as FilePath

import numpy as np
import pytest
import rclpy
import yaml
from nav_msgs.msg import Path
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from flex_control.controller_node import ControllerNode
from flex_model.ros.model_node import ModelNode
from flex_model.ros.main import ParameterError
from flex_planner.planner_node import PlannerNode
from flex_planner.ros_messages import waypoints_msg

RELIABLE = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
NAN, INF = math.nan, math.inf


class Recorder:
    """Stands in for a node's logger: (level, message) records."""

    def __init__(self):
        self.records = []

    def __getattr__(self, level):
        return lambda msg, **kwargs: self.records.append((level, str(msg)))

    def since(self, k):
        return [m for _, m in self.records[k:]]


class Suite:
    def __init__(self):
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        tag = f"{os.getpid()}_{uuid.uuid4().hex[:6]}"
        self.ns = {k: f"/{k}{tag}" for k in ("model", "ctrl", "plan")}
        self.model = ModelNode(context=self.ctx, namespace=self.ns["model"],
                               parameter_overrides=[Parameter("mode", value="lockstep"),
                                                    Parameter("lockstep_timeout", value=30.0)])
        self.ctrl = ControllerNode(context=self.ctx, namespace=self.ns["ctrl"],
                                   parameter_overrides=[Parameter("state_timeout", value=30.0)])
        self.plan = PlannerNode(context=self.ctx, namespace=self.ns["plan"],
                                parameter_overrides=[Parameter("sample_period", value=0.05)])
        self.logs = {}
        for key in ("model", "ctrl", "plan"):
            rec = self.logs[key] = Recorder()
            getattr(self, key).get_logger = lambda rec=rec: rec
        self.probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=self.ctx)
        p, m, c, q = self.probe, self.ns["model"], self.ns["ctrl"], self.ns["plan"]
        self.states, self.commands, self.trajectories = [], [], []
        p.create_subscription(JointState, f"{m}/joint_states", self.states.append, RELIABLE)
        p.create_subscription(Float64MultiArray, f"{c}/effort_controller/commands",
                              self.commands.append, RELIABLE)
        p.create_subscription(JointTrajectory, f"{q}/flex_planner/trajectory",
                              self.trajectories.append, RELIABLE)
        self.pub = {
            "command": p.create_publisher(Float64MultiArray, f"{m}/effort_controller/commands",
                                          RELIABLE),
            "payload": p.create_publisher(Float64MultiArray, f"{m}/flex/payload", RELIABLE),
            "joint_states": p.create_publisher(JointState, f"{c}/joint_states", RELIABLE),
            "trajectory": p.create_publisher(JointTrajectory, f"{c}/flex_planner/trajectory",
                                             RELIABLE),
            "waypoints": p.create_publisher(Path, f"{q}/flex_planner/waypoints", RELIABLE),
        }
        self.ex = SingleThreadedExecutor(context=self.ctx)
        for node in (self.model, self.ctrl, self.plan, self.probe):
            self.ex.add_node(node)
        self.spin_until(lambda: all(pub.get_subscription_count() > 0
                                    for pub in self.pub.values()), "discovery")
        self.send_state([0.1, -0.2], [0.0, 0.0])
        self.spin_until(lambda: self.ctrl.names is not None and self.commands,
                        "the controller's first command")
        # the model's first lockstep step compiles its kernels (a fresh clone: tens of s
        # with the other test worker compiling too): before any case waits 20 s for a state
        self.model_alive(timeout=600.0)

    def spin_until(self, pred, what, timeout=20.0):
        end = time.monotonic() + timeout
        while not pred():
            assert time.monotonic() < end, f"timed out waiting for {what}"
            self.ex.spin_once(timeout_sec=0.005)

    def send_state(self, pos, vel, names=("joint1", "joint2")):
        self.pub["joint_states"].publish(JointState(
            name=list(names), position=[float(x) for x in pos],
            velocity=[float(x) for x in vel]))

    def close(self):
        self.ex.shutdown()
        for node in (self.model, self.ctrl, self.plan, self.probe):
            node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)

    # ---------------------------------------------------------------- liveness
    def model_alive(self, timeout=20.0):
        """A valid command steps the lockstep model: a new state is published."""
        n = len(self.states)
        self.pub["command"].publish(Float64MultiArray(data=[0.0, 0.0]))
        self.spin_until(lambda: len(self.states) > n, "a model state after the bad input",
                        timeout)
        assert self.model.diverged is None

    def ctrl_alive(self):
        """The controller keeps commanding finite torques at its rate."""
        self.send_state([0.1, -0.2], [0.0, 0.0])
        n = len(self.commands)
        self.spin_until(lambda: len(self.commands) > n + 3, "controller commands")
        assert all(math.isfinite(x) for x in self.commands[-1].data)

    def plan_alive(self):
        """A valid request is still planned and published."""
        n = len(self.trajectories)
        self.pub["waypoints"].publish(waypoints_msg([(-1.0, -1.0, 0.0), (-2.0, -1.0, 1.0)]))
        self.spin_until(lambda: len(self.trajectories) > n, "a plan after the bad input",
                        timeout=60.0)


@pytest.fixture(scope="module")
def suite():
    s = Suite()
    yield s
    s.close()


def trajectory(names, points):
    """points: (t, positions, velocities)."""
    msg = JointTrajectory(joint_names=list(names))
    for t, pos, vel in points:
        pt = JointTrajectoryPoint(positions=[float(x) for x in pos],
                                  velocities=[float(x) for x in vel])
        pt.time_from_start.sec = int(t)
        pt.time_from_start.nanosec = int(round((t - int(t)) * 1e9))
        msg.points.append(pt)
    return msg


J = ("joint1", "joint2")
# (node, topic, message, expected text in one new log line)
INPUTS = [
    ("model", "command", Float64MultiArray(data=[1.0]),
     "dropped effort_controller/commands: command: got 1 values; expected 2 (one per joint: "
     "joint1, joint2)"),
    ("model", "command", Float64MultiArray(data=[1.0, 2.0, 3.0]), "got 3 values; expected 2"),
    ("model", "command", Float64MultiArray(data=[]), "got 0 values; expected 2"),
    ("model", "command", Float64MultiArray(data=[NAN, 0.0]),
     "command: got non-finite values [nan, 0]; expected finite numbers"),
    ("model", "command", Float64MultiArray(data=[0.0, -INF]), "non-finite values [0, -inf]"),
    ("model", "command", Float64MultiArray(data=[1e4, 0.0]),
     "command: joint1 = 10000 N m is beyond max_torque = 487.76"),
    ("model", "command", Float64MultiArray(data=[0.0, -1e300]), "joint2 = -1e+300 N m is beyond"),
    ("model", "payload", Float64MultiArray(data=[1.0]),
     "dropped flex/payload: payload [mass, inertia]: got 1 values; expected 2"),
    ("model", "payload", Float64MultiArray(data=[NAN, 0.0]), "non-finite values [nan, 0]"),
    ("model", "payload", Float64MultiArray(data=[-2.0, 0.0]),
     "payload mass: got -2 kg; expected >= 0"),
    ("model", "payload", Float64MultiArray(data=[0.0, -0.5]),
     "payload inertia: got -0.5 kg m^2; expected >= 0"),
    ("model", "payload", Float64MultiArray(data=[1e6, 0.0]),
     "payload mass: got 1e+06 kg; expected at most max_payload_mass = 8.2"),
    ("model", "payload", Float64MultiArray(data=[1.0, 1e6]),
     "payload inertia: got 1e+06 kg m^2; expected at most max_payload_inertia"),
    ("ctrl", "joint_states", JointState(name=list(J), position=[NAN, 0.0], velocity=[0.0, 0.0]),
     "joint state rejected: JointState.position[0]: got nan; expected finite values"),
    ("ctrl", "joint_states", JointState(name=list(J), position=[0.0, 0.0], velocity=[0.0, INF]),
     "JointState.velocity[1]: got inf; expected finite values"),
    ("ctrl", "joint_states", JointState(name=list(J), position=[0.0], velocity=[0.0, 0.0]),
     "JointState.position: got 1 values for 2 names; expected one per name"),
    ("ctrl", "joint_states", JointState(name=list(J), position=[0.0, 0.0], velocity=[0.0]),
     "JointState.velocity: got 1 values for 2 names; expected one per name (or none)"),
    ("ctrl", "joint_states", JointState(name=["joint1", "elbow"], position=[0.0, 0.0],
                                        velocity=[0.0, 0.0]),
     "joint mismatch: joint_states names ['joint1', 'elbow'] lack the controller's joints "
     "['joint2']"),
    ("ctrl", "joint_states", JointState(name=list(J), position=[0.1, -0.2]),
     "joint_states without velocities: the rates are the differentiated positions"),
    ("ctrl", "trajectory", trajectory(["joint1", "elbow"], [(0.0, [0, 0], [])]),
     "trajectory rejected: JointTrajectory.joint_names: got ['joint1', 'elbow']"),
    ("ctrl", "trajectory", trajectory(J, []),
     "JointTrajectory.points: got 0 points; expected at least 1"),
    ("ctrl", "trajectory", trajectory(J, [(1.0, [0, 0], []), (1.0, [0.1, 0], [])]),
     "JointTrajectory.points.time_from_start: got [1.0, 1.0] s; expected strictly increasing"),
    ("ctrl", "trajectory", trajectory(J, [(0.0, [NAN, 0], [])]),
     "JointTrajectory.points[0].positions[0]: got nan; expected finite values"),
    ("ctrl", "trajectory", trajectory(J, [(0.0, [0, 0], [1.0])]),
     "JointTrajectory.points[0].velocities: got 1 values; expected 0 or 2"),
    ("ctrl", "trajectory", trajectory(J, [(0.0, [0], [])]),
     "JointTrajectory.points[0].positions: got 1 values; expected 2"),
    ("plan", "waypoints", waypoints_msg([(-1.0, -1.0, 0.0), (9.0, 0.0, 1.0)]),
     "waypoints rejected, nothing published: waypoint 1 at (9, 0) m is unreachable"),
    ("plan", "waypoints", waypoints_msg([(-1.0, -1.0, 0.0), (-2.0, -1.0, 1e5)]),
     "expected at most max_samples = 200000"),
    ("plan", "waypoints", waypoints_msg([(-1.0, -1.0, 0.0), (-2.0, -1.0, 1.0)], frame_id="world"),
     "Path.header.frame_id: got 'world'; expected 'arm_plane'"),
    ("plan", "waypoints", waypoints_msg([(-1.0, -1.0, 0.0), (NAN, -1.0, 1.0)]),
     "Path.poses[1].pose.position: got (nan, -1.0); expected finite x, y (m)"),
    ("plan", "waypoints", waypoints_msg([(-1.0, -1.0, 0.0)]),
     "Path.poses: got 1 poses; expected at least 2"),
    ("plan", "waypoints", waypoints_msg([(-1.0, -1.0, 2.0), (-2.0, -1.0, 1.0)]),
     "Path.poses[1].header.stamp: got 1 s after 2 s; expected strictly increasing"),
]


@pytest.mark.parametrize("node, topic, msg, text", INPUTS,
                         ids=[f"{n}-{t}-{i}" for i, (n, t, _, _) in enumerate(INPUTS)])
def test_bad_input_is_logged_and_the_node_keeps_publishing(suite, node, topic, msg, text):
    log = suite.logs[node]
    k = len(log.records)
    drops = getattr(getattr(suite, node), "drops", None)
    if drops is not None:  # each case on its own: forget the once-a-second-per-reason limit
        drops.last.clear()
    suite.pub[topic].publish(msg)
    suite.spin_until(lambda: any(text in m for m in log.since(k)),
                     f"the line {text!r}; got {log.since(k)}")
    assert all("\n" not in m for m in log.since(k))
    assert all("np.float64" not in m for m in log.since(k))
    getattr(suite, f"{node}_alive")()


RUNTIME = [  # (node, parameter, value, expected text of the refusal)
    ("model", "mode", "realtime", "read-only parameter: mode"),  # descriptor.read_only
    ("model", "arm", "thesis_example2", "read-only parameter: arm"),
    ("model", "command_timeout", -1.0, "Parameter command_timeout out of range"),  # range
    ("model", "publish_rate", 0.0, "parameter publish_rate: got 0; expected a number > 0"),
    ("model", "max_torque", "big", "parameter max_torque: got 'big'; expected a finite number"),
    ("ctrl", "law", "eq45", "read-only parameter: law"),
    ("ctrl", "joint_names", ["a", "b"], "read-only parameter: joint_names"),
    ("ctrl", "h", [-1.0], "h: got [-1.0]; expected 1 or 2 finite gains > 0"),
    ("ctrl", "torque_limits", [1.0, 2.0, 3.0], "torque_limits"),
    ("ctrl", "state_timeout", math.nan, "parameter state_timeout: got nan; expected a finite"),
    ("plan", "arm", "thesis_example2", "read-only parameter: arm"),
    ("plan", "elbow", "sideways", "elbow: got 'sideways'; expected one of up, down"),
    ("plan", "sample_period", 5.0, "sample_period: got 5.0; expected a time in [1e-5, 1] s"),
    ("plan", "max_samples", 0, "parameter max_samples: got 0; expected an integer >= 2"),
]


@pytest.mark.parametrize("node, name, value, text", RUNTIME,
                         ids=[f"{n}-{p}" for n, p, _, _ in RUNTIME])
def test_bad_runtime_parameter_is_refused_with_a_reason(suite, node, name, value, text):
    before = getattr(suite, node).get_parameter(name).value
    res = getattr(suite, node).set_parameters([Parameter(name, value=value)])[0]
    assert not res.successful and text in res.reason, res.reason
    assert getattr(suite, node).get_parameter(name).value == before
    getattr(suite, f"{node}_alive")()


STARTUP = [  # (factory, parameters, the one line)
    (ModelNode, {"shape_points": 0},
     "parameter shape_points: got 0; expected an integer in [2, 10000]"),
    (ModelNode, {"initial_joint_angles_deg": [10.0, 20.0, 30.0]},
     "parameter initial_joint_angles_deg: got [10, 20, 30]; expected 2 angles"),
    (ModelNode, {"command_timeout": -0.5}, "parameter command_timeout: got -0.5; expected"),
    (ModelNode, {"rate": math.inf}, "parameter rate: got inf; expected a finite number"),
    (ModelNode, {"realtime_priority": 120}, "parameter realtime_priority: got 120; expected "
     "0 (off) or 1-99"),
    (ModelNode, {"arm": "no_such_arm"}, "parameter arm: no_such_arm"),
    (ModelNode, {"vars_per_link": 3}, "parameter vars_per_link: got 3; expected 0 or an even"),
    (ModelNode, {"max_payload_mass": -1.0}, "parameter max_payload_mass: got -1; expected a "
     "number >= 0"),
    (ControllerNode, {"joint_names": ["a", "a"]}, "parameter joint_names: got ['a', 'a']; "
     "expected unique"),
    (ControllerNode, {"rate_hz": 0.5}, "parameter rate_hz: got 0.5; expected a number in "
     "[1, 20000]"),
    (ControllerNode, {"law": "pid"}, "parameter law: got 'pid'; expected one of eq95, eq45"),
    (ControllerNode, {"joint_names": ["a", "b"], "h": [1.0, 2.0, 3.0]},
     "parameter h: got [1.0, 2.0, 3.0]; expected 1 or 2 finite gains > 0"),
    (ControllerNode, {"torque_limits": ["x"]}, "parameter torque_limits: got ['x']; expected a "
     "list of finite numbers"),
    (PlannerNode, {"sample_period": 5.0}, "parameter sample_period: got 5.0; expected a time"),
    (PlannerNode, {"elbow": "sideways"}, "parameter elbow: got 'sideways'"),
    (PlannerNode, {"vars_per_link": -2}, "parameter vars_per_link: got -2"),
]


@pytest.mark.parametrize("factory, params, text", STARTUP,
                         ids=[f"{f.__name__}-{'-'.join(p)}" for f, p, _ in STARTUP])
def test_bad_parameter_at_start_is_one_line(factory, params, text):
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        with pytest.raises(ParameterError) as err:
            factory(context=ctx, namespace=f"/s{uuid.uuid4().hex[:8]}",
                    parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
        assert text in str(err.value) and "\n" not in str(err.value), str(err.value)
    finally:
        rclpy.try_shutdown(context=ctx)


def test_integer_parameters_are_taken_for_floats():
    """rate:=500 on the command line (an integer) where a float is expected."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx, args=["--ros-args", "-p", "rate:=500", "-p", "rate_hz:=250",
                                  "-p", "h:=[5, 5]", "-p", "sample_period:=1"])
    try:
        ns = f"/i{uuid.uuid4().hex[:8]}"
        nodes = [ModelNode(context=ctx, namespace=ns), ControllerNode(context=ctx, namespace=ns),
                 PlannerNode(context=ctx, namespace=ns)]
        model, ctrl, plan = nodes
        assert model.p["rate"] == 500.0 and ctrl.params.rate_hz == 250.0
        assert ctrl.params.h == (5.0, 5.0) and plan.config.sample_period == 1.0
        for node in nodes:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def test_controller_with_empty_joint_names_takes_the_models():
    """joint_names:=[] on the command line raised TypeError; now it is the default: the
    joints of the first joint_states message."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx, args=["--ros-args", "-p", "joint_names:=[]"])
    try:
        node = ControllerNode(context=ctx, namespace=f"/e{uuid.uuid4().hex[:8]}")
        assert node.names is None
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


@pytest.mark.parametrize("module, arg, text", [
    ("flex_model.ros.model_node", "shape_points:=0",
     "parameter shape_points: got 0; expected an integer in [2, 10000]"),
    ("flex_control.controller_node", "rate_hz:=0.5",
     "parameter rate_hz: got 0.5; expected a number in [1, 20000]"),
])
def test_bad_parameter_process_exits_2_with_one_line(module, arg, text):
    proc = subprocess.run([sys.executable, "-m", module, "--ros-args", "-r",
                           f"__ns:=/x{uuid.uuid4().hex[:8]}", "-p", arg],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and text in lines[0], proc.stderr


TWO_ARMS = FilePath(__file__).resolve().parents[1] / "docs" / "examples" / "two_arms.yaml"


def test_two_arm_parameter_file_closes_both_loops():
    """Issue 23: the two-arm parameter file of docs/ros.md (docs/examples/two_arms.yaml),
    passed as rcl's --params-file, configures two lockstep twins in /robot1 and /robot2:
    each controller holds its own model's start pose, runs on its own twin's clock
    (/robotN/clock, simulation time: within one 2 ms period of its model's) and neither
    twin publishes the global /clock."""
    text = TWO_ARMS.read_text()
    spec = yaml.safe_load(text)
    page = (TWO_ARMS.parents[1] / "ros.md").read_text()
    section = page[page.index("## Two arms side by side"):]
    block = section[section.index("```yaml\n") + 8:]
    assert block[:block.index("```")] == text  # docs/ros.md shows this very file
    ctx = rclpy.Context()
    rclpy.init(context=ctx, args=["--ros-args", "--params-file", str(TWO_ARMS)])
    nodes, twins = [], {}
    try:
        for ns in ("/robot1", "/robot2"):
            model = ModelNode(context=ctx, namespace=ns)
            ctrl = ControllerNode(context=ctx, namespace=ns)
            nodes += [model, ctrl]
            want = spec[f"{ns}/flex_model"]["ros__parameters"]
            assert model.p["initial_joint_angles_deg"] == want["initial_joint_angles_deg"]
            assert model.frames.base == want["frame_prefix"] + "base_link"
            assert model.pub_clock.topic_name == f"{ns}/clock"
            assert ctrl.get_parameter("use_sim_time").value is True
            assert "/clock" not in {s.topic_name for s in ctrl.subscriptions}
            twins[ns] = (model, ctrl, np.radians(want["initial_joint_angles_deg"]))
        ex = SingleThreadedExecutor(context=ctx)
        for node in nodes:
            ex.add_node(node)
        end = time.monotonic() + 60.0
        while not all(m.stepper.t >= 0.1 for m, _, _ in twins.values()):
            assert time.monotonic() < end, "timed out waiting for both loops"
            ex.spin_once(timeout_sec=0.01)
        probe = nodes[0]
        # no node of the two twins on the global /clock (other tests' nodes may be)
        assert not [i for i in probe.get_publishers_info_by_topic("/clock")
                    if i.node_namespace in twins]
        for ns, (model, ctrl, angles) in twins.items():
            assert probe.count_publishers(f"{ns}/clock") == 1
            assert probe.count_publishers(f"{ns}/effort_controller/commands") == 1
            np.testing.assert_allclose(ctrl.controller.reference.positions[0], angles,
                                       atol=1e-3)
            now = ctrl.get_clock().now().nanoseconds * 1e-9
            assert abs(now - model.stepper.t) <= 2e-3 + 1e-9, (now, model.stepper.t)
            np.testing.assert_allclose(ctrl.state[0], model.stepper.joint_state()[0],
                                       atol=0.05)
        ex.shutdown()
    finally:
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def test_lockstep_stall_applies_the_command_timeout():
    """Issue 23 (defect 10): the default command_timeout (0.5 s) with timeout_action zero;
    in lockstep a step of the watchdog (no command for lockstep_timeout of wall time)
    applies it at once, so a stalled loop no longer holds the last torque."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = None
    try:
        node = ModelNode(context=ctx, namespace=f"/c{uuid.uuid4().hex[:8]}",
                         parameter_overrides=[Parameter("mode", value="lockstep"),
                                              Parameter("lockstep_timeout", value=0.05)])
        assert node.p["command_timeout"] == 0.5 and node.p["timeout_action"] == "zero"
        node.on_command(Float64MultiArray(data=[3.0, -2.0]))
        assert list(node.stepper.u) == [3.0, -2.0] and node.stepper.t == pytest.approx(1e-3)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        end = time.monotonic() + 20.0
        while node.stepper.t < 2.5e-3:
            assert time.monotonic() < end, "timed out waiting for the watchdog step"
            ex.spin_once(timeout_sec=0.01)
        assert list(node.stepper.u) == [0.0, 0.0]
        node.on_command(Float64MultiArray(data=[1.0, 1.0]))  # commands resume
        assert list(node.stepper.u) == [1.0, 1.0]
        ex.shutdown()
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def test_planner_stamps_with_its_twins_simulation_clock():
    """use_sim_time: the planner's nominal_path is stamped with the simulation time of the
    clock named by clock_topic (here the namespace's clock, 12.5 s), not the wall clock."""
    from rosgraph_msgs.msg import Clock
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    ns = f"/p{uuid.uuid4().hex[:8]}"
    nodes = []
    try:
        plan = PlannerNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter("sample_period", value=0.05), Parameter("use_sim_time", value=True),
            Parameter("clock_topic", value="clock")])
        probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=ctx, namespace=ns)
        nodes += [plan, probe]
        clock = probe.create_publisher(Clock, "clock", 10)
        waypoints = probe.create_publisher(Path, "flex_planner/waypoints", RELIABLE)
        paths = []
        probe.create_subscription(Path, "flex_planner/nominal_path", paths.append, RELIABLE)
        ex = SingleThreadedExecutor(context=ctx)
        for node in nodes:
            ex.add_node(node)
        end = time.monotonic() + 60.0
        while not (clock.get_subscription_count() and waypoints.get_subscription_count()):
            assert time.monotonic() < end, "timed out waiting for discovery"
            ex.spin_once(timeout_sec=0.01)
        msg = Clock()
        msg.clock.sec, msg.clock.nanosec = 12, 500_000_000
        clock.publish(msg)
        while plan.get_clock().now().nanoseconds != 12_500_000_000:
            assert time.monotonic() < end, "timed out waiting for the clock"
            ex.spin_once(timeout_sec=0.01)
        waypoints.publish(waypoints_msg([(-1.0, -1.0, 0.0), (-2.0, -1.0, 1.0)]))
        while not paths:
            assert time.monotonic() < end, "timed out waiting for the plan"
            ex.spin_once(timeout_sec=0.01)
        assert (paths[0].header.stamp.sec, paths[0].header.stamp.nanosec) == (12, 500_000_000)
        ex.shutdown()
    finally:
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
