"""The model node in observer mode (issue 45): a real rclpy graph feeds a simulated arm's
joint_states (joint angles, the torque as effort) sample by sample into the ObserverNode,
which publishes the estimate; the estimated deflections are checked against the
simulation's, and bad messages are dropped with a logged reason while the node runs on."""

import re

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState

from flex_model.arm import load_arm
from flex_model.ros.cdr_messages import read_joint_state, read_joint_state_names
from flex_model.dynamics import FlexArmModel
from flex_model.ros.main import ParameterError
from flex_model.ros.model_node import _arm_argument
from flex_model.ros.observer_node import ObserverNode, measurements_named
from flex_model.stepper import Stepper

RELIABLE = QoSProfile(depth=2000, reliability=ReliabilityPolicy.RELIABLE)
ARM, T, SAMPLES = "thesis_example1", 1e-3, 1200


class Log:
    """Stands in for the node's logger: (level, message) records."""

    def __init__(self):
        self.records = []

    def __getattr__(self, level):
        return lambda msg, **kwargs: self.records.append((level, str(msg)))


@pytest.fixture(scope="module")
def truth():
    """SAMPLES samples of the arm under a smooth torque (times, torques, joint angles,
    rates, tip deflections per link): the real arm the observer follows."""
    model = FlexArmModel(load_arm(ARM))
    st = Stepper(model, model.q_from_joint_angles(np.zeros(model.n_links)), max_step=T)
    t = np.arange(SAMPLES) * T
    u = np.column_stack([2.0 * np.sin(2 * np.pi * 1.5 * t), 0.8 * np.sin(2 * np.pi * t)])
    angles, rates, defl = [], [], []
    for k in range(SAMPLES):
        a, r, _ = st.joint_state()
        angles.append(a)
        rates.append(r)
        defl.append(st.deflections()[0])
        st.set_command(u[k])
        st.advance(T)
    return t, u, np.array(angles), np.array(rates), np.array(defl)


@pytest.fixture
def observer_graph(ros_graph):
    """``observer_graph(**params)``: an ObserverNode (its logger recorded in ``g.log``)
    and a probe publishing the real arm's joint_states (``g.pub``, ``g.send``) and
    collecting the estimate (``g.got``), in the conftest's ROS harness."""
    def make(**params):
        g = ros_graph(ObserverNode, "obs",
                      **{"arm": ARM, "measure": "q", "sample_period": T, **params})
        g.log, g.timeout = Log(), 60.0
        g.node.get_logger = lambda: g.log
        g.pub = g.probe.create_publisher(JointState, "joint_states", RELIABLE)
        g.got = {key: g.subscribe(cls, topic, qos) for key, cls, topic, qos in (
            ("js", JointState, "flex/estimate/joint_states", RELIABLE),
            ("defl", JointState, "flex/deflections", RELIABLE),
            ("tip", PoseWithCovarianceStamped, "flex/estimate/tip_pose", RELIABLE),
            ("diag", DiagnosticArray, "/diagnostics", 10))}
        g.send = lambda *args, **kwargs: send(g.pub, *args, **kwargs)
        g.discovered(g.pub)
        return g
    return make


def send(pub, t, position, velocity=(), effort=(), names=("joint1", "joint2")):
    msg = JointState(name=list(names), position=list(map(float, position)),
                     velocity=list(map(float, velocity)), effort=list(map(float, effort)))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(int(round(t * 1e9)), 10 ** 9)
    pub.publish(msg)


@pytest.fixture
def observer(observer_graph):
    return observer_graph()


def _values(diagnostic) -> dict:
    return {kv.key: kv.value for kv in diagnostic.status[0].values}


def warnings(g):
    return [m for level, m in g.log.records if level in ("warning", "warn")]


def test_the_estimate_follows_the_simulated_arm_from_its_joint_angles(observer, truth):
    """Joint angles alone (1 mrad noise) and the torque: after 0.4 s the estimated tip
    deflections are within 5 % of each link's peak deflection (RMS) and the estimated joint
    angles within 1 mrad; every sample is one estimate, stamped as the sample."""
    g = observer
    t, u, angles, _, defl = truth
    rng = np.random.default_rng(1)
    noisy = angles + 1e-3 * rng.standard_normal(angles.shape)
    for k in range(SAMPLES):
        g.send(t[k], noisy[k], effort=u[k])
        if k % 100 == 99:  # (the reliable queue holds them; spin while sending)
            g.spin_until(lambda: len(g.got["tip"]) >= k - 50, "the estimates")
    g.spin_until(lambda: len(g.got["tip"]) == SAMPLES, "every estimate")
    stamps = [m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for m in g.got["defl"]]
    np.testing.assert_allclose(stamps, t, atol=1e-9)
    est = np.array([m.position[0::2] for m in g.got["defl"]])  # (deflection, rotation)
    late = t >= 0.4
    peak = np.max(np.abs(defl[late]), axis=0)
    rms = np.sqrt(np.mean((est[late] - defl[late]) ** 2, axis=0))
    assert np.all(rms < 0.05 * peak), (rms, peak)
    est_angles = np.array([m.position for m in g.got["js"]])
    assert np.sqrt(np.mean((est_angles[late] - angles[late]) ** 2)) < 1e-3
    np.testing.assert_allclose([m.effort for m in g.got["js"]], u)  # the input used
    cov = np.array(g.got["tip"][-1].pose.covariance).reshape(6, 6)
    assert np.all(np.linalg.eigvalsh(cov[:3, :3]) > -1e-15) and cov[0, 0] > 0
    g.spin_until(lambda: g.got["diag"] and _values(g.got["diag"][-1])["samples"] == str(
        SAMPLES), "the health of every sample on /diagnostics", 5.0)
    values = _values(g.got["diag"][-1])
    assert values["dropped"] == values["late"] == values["missed"] == "0", values
    assert 0.3 < float(values["nis_mean"]) < 3.0, values
    assert warnings(g) == []


def test_a_gauge_topic_feeds_the_tip_deflection(observer_graph, truth):
    """measure q,w2: the joint angles from joint_states, link 2's tip deflection from
    flex/gauges (a JointState named w2 stamped as its sample, sent before it, 10 um noise;
    every 7th missing: that sample is corrected with the angles alone): after 0.4 s the
    estimated deflection of link 2 follows the truth within 3 gauge stds (RMS; the filter
    alone on the same readings: 8 um)."""
    t, u, angles, _, defl = truth
    g = observer_graph(measure="q,w2", measure_std=[1e-3, 1e-3, 1e-5])
    gauge = g.probe.create_publisher(JointState, "flex/gauges", RELIABLE)
    g.spin_until(lambda: gauge.get_subscription_count() > 0, "the gauge subscription")
    n = 600
    for k in range(n):
        if k % 7:  # every 7th reading missing
            reading = defl[k, 1] + 1e-5 * np.sin(1.7 * k)  # (a deterministic noise)
            msg = JointState(name=["w2"], position=[float(reading)])
            msg.header.stamp.sec, msg.header.stamp.nanosec = 0, int(round(t[k] * 1e9))
            gauge.publish(msg)
        g.send(t[k], angles[k], effort=u[k])
        if k % 100 == 99:
            g.spin_until(lambda: len(g.got["js"]) >= k - 50, "the estimates")
    g.spin_until(lambda: len(g.got["defl"]) == n, "every estimate")
    est = np.array([m.position[2] for m in g.got["defl"]])  # link2/tip_deflection
    late = t[:n] >= 0.4
    rms = np.sqrt(np.mean((est[late] - defl[:n][late, 1]) ** 2))
    assert rms < 3e-5 < 0.1 * np.max(np.abs(defl[:n][late, 1])), rms
    assert warnings(g) == [] and g.node.counts["gauge_dropped"] == 0
    # (two topics are not ordered by DDS: a reading that comes after its sample is
    # dropped and counted, not used for the next one)
    assert g.node.counts["gauge_late"] < 0.02 * n


def test_bad_messages_are_dropped_with_a_reason_and_the_node_runs_on(observer, truth):
    """A NaN angle, a missing joint, a wrong length and a repeated stamp are each dropped
    with their reason; a missing sample is predicted over; the good ones still go out."""
    g = observer
    t, u, angles, _, _ = truth
    g.send(t[0], angles[0], effort=u[0])
    g.send(t[1], [np.nan, 0.0], effort=u[1])                    # NaN
    g.send(t[1], angles[1], effort=u[1], names=("joint1", "elbow"))  # unknown joint
    g.send(t[1], angles[1][:1], effort=u[1])                    # one value for two names
    g.send(t[1], angles[1], effort=u[1])
    g.send(t[1], angles[1], effort=u[1])                        # the same stamp again
    g.pub.publish(b"\x00\x01\x00\x00" + bytes(12))           # cut short (raw bytes)
    g.send(t[3], angles[3], effort=u[3])                        # t[2] missing
    g.spin_until(lambda: len(g.got["js"]) == 3, "the three good samples")
    g.spin_until(lambda: len(warnings(g)) == 5, "the five reasons")
    text = "\n".join(warnings(g))
    for reason in ("position: got non-finite values", "the joints ['joint2'] of the arm "
                   "are missing", "position: got 1 values for 2 names",
                   "is not after the previous sample's", "a malformed JointState (16 bytes"):
        assert reason in text, text
    assert g.node.counts["dropped"] == 4 and g.node.counts["late"] == 1
    assert g.node.counts["missed"] == 1 and g.node.counts["samples"] == 3
    level, message, _ = g.node.health()
    assert level == "warn" and "5 input(s) dropped" in message


def test_the_horizon_fit_is_a_node_parameter(observer_graph, truth):
    """adapt_horizon and adapt_block are EstimatorSettings' (the fit of flex-twin estimate
    --adapt-horizon): joint 1's viscous friction fitted over the last 0.2 s in blocks of
    0.05 s on the simulated arm (which has none: truth 0); /diagnostics reports its current
    value and std (param/, param_std/)."""
    g = observer_graph(adapt="viscous_friction:joint1", adapt_horizon=0.2, adapt_block=0.05)
    est = g.node.estimator
    assert (est.settings.adapt_horizon, est.settings.adapt_block) == (0.2, 0.05)
    assert est._fit is not None and est._fit.block_n == 50
    t, u, angles, _, _ = truth
    n = 400
    for k in range(n):
        g.send(t[k], angles[k], effort=u[k])
        if k % 100 == 99:
            g.spin_until(lambda: len(g.got["js"]) >= k - 50, "the estimates")
    g.spin_until(lambda: len(g.got["js"]) == n, "every estimate")
    _, _, values = g.node.health()
    fitted = float(values["param/viscous_friction:joint1"])
    std = float(values["param_std/viscous_friction:joint1"])
    assert 0.0 <= fitted < 0.05 and 0.0 < std < 0.5, values


def test_bad_horizon_fit_parameters_are_refused_naming_them():
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        for params, text in (
                ({"adapt_horizon": -1.0}, "parameter adapt_horizon: got -1; expected a "
                 "number >= 0 s (0: off)"),
                ({"adapt": "viscous_friction:0", "adapt_horizon": 0.5, "adapt_block": 1.0},
                 "parameter adapt_block: got 1.0; expected > 0 s and at most adapt_horizon "
                 "(0.5 s)"),
                ({"adapt_horizon": 0.5}, "parameter adapt_horizon: got 0.5 with adapt []; "
                 "expected a coulomb_friction:<joint> or viscous_friction:<joint> in adapt")):
            with pytest.raises(ParameterError, match=re.escape(text)):
                ObserverNode(context=ctx, parameter_overrides=[
                    Parameter(k, value=v) for k, v in {"arm": ARM, **params}.items()])
    finally:
        rclpy.try_shutdown(context=ctx)


def test_the_filter_starts_and_restarts_at_the_samples_joint_angles(observer):
    """The first sample (stamp 100 s, joints at 0.5 and -0.3 rad) starts the filter there
    (not at initial_joint_angles_deg, 0), a gap beyond max_gap (0.1 s) restarts it at the
    next sample's angles, a 3-period gap is predicted over (2 missed)."""
    g = observer
    g.send(100.0, [0.5, -0.3], effort=[0.0, 0.0])
    g.send(100.001, [0.5, -0.3], effort=[0.0, 0.0])
    g.send(101.0, [-0.2, 0.4], effort=[0.0, 0.0])
    g.send(101.003, [-0.2, 0.4], effort=[0.0, 0.0])
    g.spin_until(lambda: len(g.got["js"]) == 4, "four estimates")
    est = np.array([m.position for m in g.got["js"]])
    # (within the encoder's 1 mrad: the arm, unheld, starts to fall under gravity)
    np.testing.assert_allclose(est[:2], [[0.5, -0.3]] * 2, atol=2e-3)
    np.testing.assert_allclose(est[2:], [[-0.2, 0.4]] * 2, atol=2e-3)
    assert (g.node.counts["restarts"], g.node.counts["missed"]) == (1, 2)
    assert any("a gap of 0.999 s (max_gap 0.1 s): filter restarted" in m for m in warnings(g))


def test_a_serialized_joint_state_is_read_as_rclpy_reads_it():
    """cdr_messages.read_joint_state (the observer's raw subscription) against rclpy's
    deserialization, with odd string lengths (padding) and an empty array."""
    msg = JointState(name=["j", "elbow_joint"], position=[0.25, -1.5], velocity=[],
                     effort=[3.0, 1e-9])
    msg.header.stamp.sec, msg.header.stamp.nanosec = 7, 125_000_000
    msg.header.frame_id = "base"
    data = serialize_message(msg)
    t, key, count, position, velocity, effort = read_joint_state(data)
    assert (t, count, read_joint_state_names(data)) == (7.125, 2, ["j", "elbow_joint"])
    np.testing.assert_array_equal(position, msg.position)
    np.testing.assert_array_equal(effort, msg.effort)
    assert velocity.size == 0
    with pytest.raises(ValueError, match="malformed JointState"):
        read_joint_state(data[:40])


def test_measurement_names_and_their_errors():
    model = FlexArmModel(load_arm(ARM))
    ms = measurements_named(model, ["q", "v2", "w1", "ax"], [1e-3, 2e-3, 0.1, 0.2, 0.3])
    assert [(m.kind, m.index, m.std) for m in ms[:4]] == [
        ("joint_angle", 0, 1e-3), ("joint_angle", 1, 2e-3), ("joint_rate", 1, 0.1),
        ("tip_deflection", 0, 0.2)]
    assert (ms[4].kind, ms[4].component) == ("tip_acceleration", 0)
    with pytest.raises(ValueError, match="got 'q3'; the arm has 2 joints"):
        measurements_named(model, ["q3"])
    with pytest.raises(ValueError, match="expected q<i>"):
        measurements_named(model, ["x1"])


def test_the_model_node_entry_point_dispatches_observer_mode():
    argv = ["model_node", "--ros-args", "-p", "mode:=observer", "-p", "arm:=thesis_example1"]
    assert _arm_argument(argv, "mode") == "observer"
    assert _arm_argument(argv) == "thesis_example1"


def test_flex_twin_observe_and_up_start_the_observer():
    """``flex-twin observe`` passes its options as the node's parameters; ``up`` starts
    ObserverNode for a flex_model section with mode observer, and folds no controller
    into it."""
    from flex_twin.cli import build_parser
    from flex_twin.ros_suite import in_loop_parameters, node_class, observer_arguments
    args = build_parser().parse_args(["observe", "--arm", "thesis_example1", "--measure",
                                      "q1,w1", "--namespace", "/arm1"])
    argv = observer_arguments(args)
    assert argv[:4] == ["flex-twin-observe", "--ros-args", "-r", "__ns:=/arm1"]
    assert {"mode:=observer", "arm:=thesis_example1", "measure:=q1,w1", "adapt:=''",
            "adapt_horizon:=0.0", "adapt_block:=0.05"} <= set(argv)
    assert node_class("flex_model", {"mode": "observer"}) == ("flex_model.ros.observer_node",
                                                              "ObserverNode")
    assert node_class("flex_model", {"mode": "lockstep"})[1] == "ModelNode"
    params = {"flex_model": {"mode": "observer"}, "flex_controller": {"rate_hz": 500.0}}
    assert in_loop_parameters(params) == params


def test_a_spatial_arm_is_observed_with_the_spatial_nodes_layout(observer_graph):
    """seed003_like_arm (spatial, issue 25) held at zero joint angles: every sample gives
    flex/deflections named and ordered as the spatial node's (ros_spatial), and the tip
    pose with its covariance is the end frame of the estimated state (tip_frame)."""
    from flex_model.ros import spatial as sr
    from flex_model.spatial.dynamics import SpatialArmModel
    from flex_model.spatial.loader import load_spatial_arm

    g = observer_graph(arm="seed003_like_arm", measure="q")
    names = ("joint1", "joint2", "joint3")
    for k in range(20):
        g.send(k * T, [0.0, 0.0, 0.0], effort=[0.0, 0.0, 0.0], names=names)
    g.spin_until(lambda: len(g.got["tip"]) == 20, "20 spatial estimates", 120.0)
    model = SpatialArmModel(load_spatial_arm("seed003_like_arm"))
    assert list(g.got["defl"][-1].name) == sr.deflection_names(model)
    q = g.node._last_sample.q  # (the published sample: corrected, not yet predicted)
    pose = g.got["tip"][-1].pose
    p = pose.pose.position
    np.testing.assert_allclose([p.x, p.y, p.z], model.tip_position(q), atol=1e-12)
    cov = np.array(pose.covariance).reshape(6, 6)
    np.testing.assert_allclose(cov, cov.T, atol=1e-15)
    assert np.min(np.linalg.eigvalsh(cov)) > -1e-12 and cov[2, 2] > 0
    assert warnings(g) == []


def test_one_default_noise_table_for_the_cli_and_the_observer():
    """flex-twin estimate and the observer default a channel's std alike (DEFAULT_STD;
    they were q 1e-4 against 1e-3 rad and w 5e-4 against 1e-4 m)."""
    from flex_model.estimation.measurements import DEFAULT_STD
    from flex_model.ros.observer_node import NAMED_KINDS
    from flex_twin.estimate import CHANNELS
    for k in "qvw":
        assert CHANNELS[k] == NAMED_KINDS[k]
    assert CHANNELS["q"] == ("joint_angle", 1e-3) and DEFAULT_STD["joint_angle"] == 1e-3
