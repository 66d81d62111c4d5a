"""The spatial model node (issue 25) in-process: lockstep against the compiled loop,
the in-loop Eq. 95 PD, bad messages dropped and counted."""
import time
import uuid

import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, String
from visualization_msgs.msg import MarkerArray

from flex_model.spatial import SpatialArmModel, load_spatial_arm
from flex_model.spatial.integrate import simulate_fixed_compiled
from flex_model.spatial_node import SpatialModelNode

ARM = "seed003_like_arm"


class Harness:
    def __init__(self, **params):
        self.ctx = rclpy.Context()
        rclpy.init(context=self.ctx)
        ns = f"/s{uuid.uuid4().hex[:8]}"
        self.node = SpatialModelNode(context=self.ctx, namespace=ns, parameter_overrides=[
            Parameter(k, value=v) for k, v in params.items()])
        self.probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=self.ctx,
                                       namespace=ns)
        self.states, self.defl, self.shapes, self.desc = [], [], [], []
        self.probe.create_subscription(JointState, "joint_states", self.states.append, 100)
        self.probe.create_subscription(JointState, "flex/deflections", self.defl.append, 100)
        self.probe.create_subscription(MarkerArray, "flex/shape", self.shapes.append, 100)
        from flex_model.spatial_node import LATCHED
        self.probe.create_subscription(String, "robot_description", self.desc.append, LATCHED)
        self.cmd = self.probe.create_publisher(Float64MultiArray,
                                               "effort_controller/commands", 100)
        self.sp = self.probe.create_publisher(Float64MultiArray, "flex/setpoints", 10)
        self.ex = SingleThreadedExecutor(context=self.ctx)
        self.ex.add_node(self.node)
        self.ex.add_node(self.probe)
        self.spin_until(lambda: self.cmd.get_subscription_count() > 0 and
                        self.node.pub_shape.get_subscription_count() > 0 and self.desc,
                        "discovery")

    def spin_until(self, pred, what, timeout=20.0):
        end = time.monotonic() + timeout
        while not pred():
            assert time.monotonic() < end, f"timed out waiting for {what}"
            self.ex.spin_once(timeout_sec=0.005)

    def command(self, u):
        n = self.node.steps
        self.cmd.publish(Float64MultiArray(data=list(map(float, u))))
        self.spin_until(lambda: self.node.steps > n and
                        len(self.states) > n + 1 - self._skip, "a lockstep period")

    def close(self):
        self.ex.shutdown()
        self.node.destroy_node()
        self.probe.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


@pytest.fixture
def harness():
    made = []

    def make(**params):
        h = Harness(**params)
        h._skip = 0 if h.states else 1   # the initial state may arrive before discovery
        made.append(h)
        return h
    yield make
    for h in made:
        h.close()


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
    from flex_model.ros_spatial import frame_poses
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
    from flex_model.ros_main import ParameterError
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        for params, text in (({"arm": "no_such_arm"}, "parameter arm:"),
                             ({"kp": [1.0, 2.0]}, "parameter kp: got [1, 2]; expected 3"),
                             ({"mode": "fast"}, "parameter mode: got 'fast'")):
            with pytest.raises(ParameterError, match=text.replace("[", r"\[")):
                SpatialModelNode(context=ctx, parameter_overrides=[
                    Parameter(k, value=v) for k, v in params.items()])
    finally:
        rclpy.try_shutdown(context=ctx)


def test_model_node_entry_point_dispatches_spatial_arms():
    """``flex-model-node -p arm:=<spatial>`` runs the spatial node, a planar arm the planar."""
    from flex_model.model_node import _arm_argument
    from flex_model.spatial.description import is_spatial_arm
    argv = ["flex-model-node", "--ros-args", "-p", "arm:=thesis_example1",
            "-p", "arm:=seed003_like_arm"]
    assert _arm_argument(argv) == "seed003_like_arm"
    assert is_spatial_arm(_arm_argument(argv))
    assert not is_spatial_arm(_arm_argument(argv[:4]))
    assert _arm_argument(["flex-model-node"]) is None
