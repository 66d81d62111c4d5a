"""PlannerNode in-process: the published numbers are the core's, bad requests publish
nothing and name the point in the error log, and the node keeps answering."""
import os
import time
import uuid

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path
from rcl_interfaces.msg import Log
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_planner import SECTION_F_TIMES, SECTION_F_WAYPOINTS, plan_tip_path
from flex_planner.planner_node import PlannerNode

TIMEOUT_S = 10.0
SAMPLE_PERIOD = 0.02
ERROR = 40  # rcl_interfaces/Log.ERROR


class Harness:
    """The node under test, a probe node and their executor on a private context."""

    def __init__(self):
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        self.ns = f"/t{os.getpid()}_{uuid.uuid4().hex[:6]}"
        self.node = PlannerNode(context=self.ctx, namespace=self.ns, parameter_overrides=[
            Parameter("sample_period", value=SAMPLE_PERIOD),
            Parameter("arm", value="thesis_example1")])   # the section F arm of its figures
        self.probe = rclpy.create_node("planner_probe", namespace=self.ns, context=self.ctx)
        self.executor = SingleThreadedExecutor(context=self.ctx)
        self.executor.add_node(self.node)
        self.executor.add_node(self.probe)
        qos = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.got = {"trajectory": [], "nominal_path": [], "nominal_deflections": []}
        base = f"{self.ns}/flex_planner"
        self.probe.create_subscription(JointTrajectory, f"{base}/trajectory",
                                       self.got["trajectory"].append, qos)
        self.probe.create_subscription(Path, f"{base}/nominal_path",
                                       self.got["nominal_path"].append, latched)
        self.probe.create_subscription(JointTrajectory, f"{base}/nominal_deflections",
                                       self.got["nominal_deflections"].append, latched)
        self.logs = []
        log_qos = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.probe.create_subscription(Log, "/rosout", self.on_log, log_qos)
        self.pub = self.probe.create_publisher(Path, f"{base}/waypoints", qos)
        self.spin_until(lambda: self.pub.get_subscription_count() > 0
                        and self.node.pub_trajectory.get_subscription_count() > 0
                        and self.node.pub_path.get_subscription_count() > 0
                        and self.node.pub_deflections.get_subscription_count() > 0)

    def on_log(self, msg):
        if msg.name.endswith("flex_planner") and msg.level >= ERROR:
            self.logs.append(msg.msg)

    def spin_until(self, condition, timeout=TIMEOUT_S):
        deadline = time.monotonic() + timeout
        while not condition() and time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)
        return condition()

    def request(self, points, times, frame_id="arm_plane"):
        msg = Path()
        msg.header.frame_id = frame_id
        for (x, y), t in zip(points, times):
            ps = PoseStamped()
            ps.header.stamp.sec, ps.header.stamp.nanosec = int(t), int(round((t % 1) * 1e9))
            ps.pose.position.x, ps.pose.position.y = float(x), float(y)
            ps.pose.orientation.w = 1.0
            msg.poses.append(ps)
        self.pub.publish(msg)

    def close(self):
        self.executor.shutdown()
        self.probe.destroy_node()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


@pytest.fixture
def harness(request):
    h = Harness()
    request.addfinalizer(h.close)
    return h


def trajectory_arrays(msg):
    t = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
                  for p in msg.points])
    fields = {f: np.array([list(getattr(p, f)) for p in msg.points])
              for f in ("positions", "velocities", "accelerations", "effort")}
    return t, fields


def test_valid_path_gives_the_core_plan(harness):
    harness.request(SECTION_F_WAYPOINTS, SECTION_F_TIMES)
    assert harness.spin_until(lambda: all(harness.got.values()))
    expected = plan_tip_path(FlexArmModel(load_arm("thesis_example1")), SECTION_F_WAYPOINTS,
                             SECTION_F_TIMES, sample_period=SAMPLE_PERIOD)
    msg = harness.got["trajectory"][0]
    assert list(msg.joint_names) == ["joint1", "joint2"]
    t, arrays = trajectory_arrays(msg)
    np.testing.assert_allclose(t, expected.t, atol=1e-9)
    np.testing.assert_allclose(arrays["positions"], expected.positions, atol=1e-12)
    np.testing.assert_allclose(arrays["velocities"], expected.velocities, atol=1e-12)
    np.testing.assert_allclose(arrays["accelerations"], expected.accelerations, atol=1e-12)
    np.testing.assert_allclose(arrays["effort"], expected.efforts, atol=1e-9)
    path = harness.got["nominal_path"][0]
    assert path.header.frame_id == "arm_plane"
    tip = np.array([[p.pose.position.x, p.pose.position.y] for p in path.poses])
    np.testing.assert_allclose(tip, expected.tip, atol=1e-12)
    defl = harness.got["nominal_deflections"][0]
    assert list(defl.joint_names) == ["link1/delta1", "link1/gamma1", "link2/delta1",
                                      "link2/gamma1"]
    values = np.array([list(p.positions) for p in defl.points])
    np.testing.assert_allclose(values, expected.q_nominal[:, [1, 2, 4, 5]], atol=1e-12)
    assert not harness.logs


@pytest.mark.parametrize("points, times, frame, logged", [
    ([[-1.0, -1.0], [5.0, 0.0], [-2.0, -2.0]], [0.0, 5.0, 10.0], "arm_plane",
     "waypoint 1 at (5, 0) m is unreachable"),
    (SECTION_F_WAYPOINTS, [0.0, 5.0, 5.0, 15.0], "arm_plane",
     "Path.poses[2].header.stamp: got 5 s after 5 s"),
    ([], [], "arm_plane", "Path.poses: got 0 poses"),
    (SECTION_F_WAYPOINTS, SECTION_F_TIMES, "world",
     "Path.header.frame_id: got 'world'; expected 'arm_plane'"),
])
def test_bad_request_publishes_nothing_and_the_node_keeps_serving(harness, points, times,
                                                                  frame, logged):
    harness.request(points, times, frame)
    assert harness.spin_until(lambda: harness.logs)
    assert logged in harness.logs[0]
    harness.spin_until(lambda: False, timeout=0.5)
    assert not any(harness.got.values())
    harness.request(SECTION_F_WAYPOINTS[:2], SECTION_F_TIMES[:2])
    assert harness.spin_until(lambda: harness.got["trajectory"])
    assert len(harness.got["trajectory"]) == 1
    assert len(harness.got["trajectory"][0].points) == 251          # 5 s every 20 ms


def test_parameters_are_validated(harness):
    bad = harness.node.set_parameters([Parameter("elbow", value="sideways")])[0]
    assert not bad.successful and "elbow: got 'sideways'" in bad.reason
    assert not harness.node.set_parameters([Parameter("arm", value="thesis_example2")])[0] \
        .successful                                                  # read-only
    assert harness.node.set_parameters([Parameter("elbow", value="down")])[0].successful
    assert harness.node.config.elbow == "down"


def test_a_far_waypoint_is_refused_before_any_work(harness):
    """Issue 23 defect 9: a waypoint at t = 1e5 s asked for ~1e8 samples (minutes of
    work and gigabytes, deaf to SIGINT). The plan's sample count is bounded by
    max_samples: one error line naming the waypoint, the count and the bound, nothing
    published, at once; the node keeps serving."""
    start = time.monotonic()
    harness.request(SECTION_F_WAYPOINTS[:2], [0.0, 1e5])
    assert harness.spin_until(lambda: harness.logs)
    assert time.monotonic() - start < 5.0
    log = harness.logs[0]
    assert "Path.poses[1].header.stamp: got 100000 s" in log
    assert "100000002 samples" in log and "max_samples = 200000" in log
    assert not any(harness.got.values())
    assert harness.node.set_parameters([Parameter("max_samples", value=100)])[0].successful
    harness.request(SECTION_F_WAYPOINTS[:2], SECTION_F_TIMES[:2])      # 5 s: 5002 > 100
    assert harness.spin_until(lambda: len(harness.logs) == 2)
    assert "expected at most max_samples = 100" in harness.logs[1]
    assert harness.node.set_parameters([Parameter("max_samples", value=6000)])[0].successful
    harness.request(SECTION_F_WAYPOINTS[:2], SECTION_F_TIMES[:2])
    assert harness.spin_until(lambda: harness.got["trajectory"])


def test_runtime_parameters_refused_with_a_reason_and_ints_taken_for_floats(harness):
    """Issue 23 defect 10: node parameters are read-only at run time (refused with a
    reason, not accepted and ignored); an integer is taken where a float is expected."""
    res = harness.node.set_parameters([Parameter("parameter_services", value=False)])[0]
    assert not res.successful and "read-only parameter: parameter_services" in res.reason
    res = harness.node.set_parameters([Parameter("max_samples", value=1)])[0]
    assert not res.successful and "parameter max_samples: got 1; expected an integer >= 2" \
        in res.reason
    res = harness.node.set_parameters([Parameter("sample_period", value=1)])[0]
    assert res.successful and harness.node.config.sample_period == 1.0
    assert isinstance(harness.node.config.sample_period, float)
    res = harness.node.set_parameters([Parameter("sample_period", value="fast")])[0]
    assert not res.successful and "parameter sample_period: got 'fast'; expected a finite " \
        "number" in res.reason
