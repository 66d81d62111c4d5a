"""The arm's robot description and frames (issue 23: TF, URDF, REP 103).

Core (no ROS): the URDF of flex_model.urdf against the ArmModel's numbers (joints, axes,
limits, masses and inertia about each joint, thesis Eqs. 7 and 26), and the frame chain
base_link -> arm_plane -> link_i -> link_i_tip at a deflected state against the model's
kinematics (link_origins, tip_pose), closed form to 1e-9, with z up (REP 103). Live: a
late-joining transient-local subscriber receives robot_description; /flex/shape is drawn
in the base frame with z up and /flex/tip_pose in arm_plane.
"""
import math
import time
import uuid
import xml.etree.ElementTree as ET

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64MultiArray, String
from visualization_msgs.msg import MarkerArray

from flex_model import urdf
from flex_model.arm import load_arm, resolve_preset
from flex_model.dynamics import FlexArmModel
from flex_model.kernels import P_JROT, P_MTOT, P_NTOT


@pytest.fixture(scope="module")
def three_link():
    """End masses and inertias on every link (M-, M+, J-, J+ = 1) and a payload."""
    model = FlexArmModel(load_arm("thesis_three_link"))
    model.set_payload(0.7, 0.05)
    return model


def deflected_state(model, seed=3):
    rng = np.random.default_rng(seed)
    theta = np.radians([35.0, -50.0, 20.0][:model.n_links])
    flex = 0.02 * rng.standard_normal(len(model.flex_indices))
    return model.q_from_joint_angles(theta, flex)


def test_urdf_joints_and_masses_equal_the_model(three_link):
    model = three_link
    root = ET.fromstring(urdf.robot_description(model, effort_limits=[50.0, 40.0, 30.0]))
    assert root.tag == "robot" and root.get("name") == "thesis_three_link"
    revolute = [j for j in root.iter("joint") if j.get("type") == "continuous"]
    assert [j.get("name") for j in revolute] == model.arm.joint_names  # no rotors here
    links = {lk.get("name"): lk for lk in root.iter("link")}
    names = [lk.name for lk in model.arm.links]
    for i, j in enumerate(revolute):
        assert [float(v) for v in j.find("axis").get("xyz").split()] == [0.0, 0.0, 1.0]
        lim = j.find("limit")
        assert float(lim.get("effort")) == [50.0, 40.0, 30.0][i]
        assert lim.get("lower") is None and lim.get("upper") is None  # no stops
        assert j.find("parent").get("link") == ("arm_plane" if i == 0 else
                                                f"{names[i - 1]}_tip")
        assert j.find("child").get("link") == names[i]
        tip = next(f for f in root.iter("joint") if f.get("name") == f"{names[i]}_tip_joint")
        assert tip.get("type") == "fixed"
        assert [float(v) for v in tip.find("origin").get("xyz").split()] == \
            [model.arm.links[i].length, 0.0, 0.0]

    def inertial(name):
        el = links[name].find("inertial")
        if el is None:
            return 0.0, 0.0, 0.0
        x = float(el.find("origin").get("xyz").split()[0])
        return float(el.find("mass").get("value")), x, float(el.find("inertia").get("izz"))
    mtot, ntot, jrot = model.P[P_MTOT], model.P[P_NTOT], model.P[P_JROT]
    total = 0.0
    for i, lk in enumerate(model.arm.links):
        m, x, izz = inertial(lk.name)
        m_tip, _, izz_tip = inertial(f"{lk.name}_tip")
        L = lk.length
        total += m + m_tip
        # the model's lumped link data (mass, first and second moment about the joint)
        assert m + m_tip == pytest.approx(mtot[i], rel=1e-12)
        assert m * x + m_tip * L == pytest.approx(ntot[i], rel=1e-12)
        assert izz + m * x * x + izz_tip + m_tip * L * L == pytest.approx(jrot[i], rel=1e-12)
    assert m_tip == pytest.approx(1.0 + 0.7) and izz_tip == pytest.approx(1.0 + 0.05)
    assert total == pytest.approx(model.total_mass, rel=1e-12)


def _frame_angle(model, q, frames, frame):
    """The rotation (rad) about the plane's z of ``frame`` in arm_plane (TF chain)."""
    r, _ = urdf.compose(urdf.arm_transforms(model, q, frames), frame, frames.plane)
    return math.atan2(r[1, 0], r[0, 0])


def test_urdf_motors_are_the_gear_of_the_arm_file():
    """Issue 46 item 6: thesis_example1_motors' geared motors (ratio 100, rotor 5e-5 kg m^2
    in its arm file) are in the URDF: a SimpleTransmission with mechanicalReduction 100
    per joint, and per joint a massless rotor link (Izz = J_r) on the joint's parent
    frame, mimicking the joint with multiplier 100 (n^2 J_r = 0.5 kg m^2 at the joint).
    Its kinetic energy, from the URDF's numbers and the rotor frames' rates (TF chain),
    equals the energy the gear adds to the model's mass matrix, at a deflected state and
    random rates, to 1e-12 relative; joint1 at 3.25 rad (where the demo ends) is inside
    the URDF (continuous joints, no stops)."""
    import dataclasses
    arm = load_arm("thesis_example1_motors")
    gear_yaml = {e.target: (e["ratio"], e["rotor_inertia"]) for e in arm.effects
                 if e.TYPE == "gear"}
    assert gear_yaml == {"joint1": (100.0, 5e-5), "joint2": (100.0, 5e-5)}
    model = FlexArmModel(arm)
    bare = FlexArmModel(dataclasses.replace(arm, effects=()))
    frames = urdf.Frames.of(model, "robot1/")
    root = ET.fromstring(urdf.robot_description(model, "robot1/", effort_limits=[1.0, 1.0]))
    joints = {j.get("name"): j for j in root.findall("joint")}  # not transmissions
    links = {lk.get("name"): lk for lk in root.iter("link")}
    reductions = {t.find("joint").get("name"):
                  float(t.find("actuator").find("mechanicalReduction").text)
                  for t in root.iter("transmission")}
    assert reductions == {"joint1": 100.0, "joint2": 100.0}
    rotors = []
    for name in ("joint1", "joint2"):
        assert joints[name].get("type") == "continuous"
        assert joints[name].find("limit").get("upper") is None
        rj = next(j for j in joints.values() if j.find("mimic") is not None
                  and j.find("mimic").get("joint") == name)
        assert rj.find("parent").get("link") == joints[name].find("parent").get("link")
        child = rj.find("child").get("link")
        inertial = links[child].find("inertial")
        assert float(inertial.find("mass").get("value")) == 0.0
        izz = float(inertial.find("inertia").get("izz"))
        n = float(rj.find("mimic").get("multiplier"))
        rotors.append((name, rj.find("parent").get("link"), n, izz))
    assert [n * n * izz for _, _, n, izz in rotors] == pytest.approx([0.5, 0.5], rel=1e-12)
    rng = np.random.default_rng(7)
    q = deflected_state(model)
    q[model.alpha_index(0)] += 3.25 - model.joint_angles(q)[0]  # joint1 = 3.25 rad
    assert model.joint_angles(q)[0] == pytest.approx(3.25)
    for _ in range(3):
        v = rng.standard_normal(model.nq)
        dB = model.mass_matrix(q) - bare.mass_matrix(q)
        energy_model = 0.5 * v @ dB @ v
        eps = 1e-6
        theta_dot = (model.joint_angles(q + eps * v) - model.joint_angles(q - eps * v)) / (
            2 * eps)
        energy_urdf = 0.0
        for i, (name, stator, n, izz) in enumerate(rotors):
            omega = 0.0 if stator == frames.plane else (
                _frame_angle(model, q + eps * v, frames, stator)
                - _frame_angle(model, q - eps * v, frames, stator)) / (2 * eps)
            energy_urdf += 0.5 * izz * (n * theta_dot[i] + omega) ** 2
        assert energy_urdf == pytest.approx(energy_model, rel=1e-7)
        assert energy_model > 0.01


def test_plane_is_vertical_under_gravity_and_horizontal_without():
    """REP 103: gravity (0, -g) in the plane is -z of the base; plane (x, y) -> (x, 0, y),
    joint axes along -y. Without gravity the plane is the base's x-y plane."""
    r = urdf.plane_rotation([0.0, -9.81])
    np.testing.assert_allclose(r @ [0.0, -9.81, 0.0], [0.0, 0.0, -9.81], atol=1e-15)
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(r @ [0.0, 0.0, 1.0], [0.0, -1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(urdf.plane_rotation([0.0, 0.0]), np.eye(3))
    g = np.array([3.0, -4.0])  # a tilted base: -g is still +z
    np.testing.assert_allclose(urdf.plane_rotation(g) @ [*g, 0.0], [0.0, 0.0, -5.0],
                               atol=1e-14)
    for gravity in ([0.0, -9.81], [3.0, -4.0], [0.0, 0.0]):  # the URDF's rpy is R
        roll, pitch, yaw = urdf.plane_rpy(gravity)
        cr, sr, cp, sp, cy, sy = (math.cos(roll), math.sin(roll), math.cos(pitch),
                                  math.sin(pitch), math.cos(yaw), math.sin(yaw))
        rpy = (np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]) @
               np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]]) @
               np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]]))
        np.testing.assert_allclose(rpy, urdf.plane_rotation(gravity), atol=1e-15)


@pytest.mark.parametrize("arm", ["thesis_three_link", "thesis_example1_motors"])
def test_tip_frames_are_the_deflected_tips(arm):
    """Chaining the TF transforms at a deflected state puts every link tip at the model's
    link_origins and the arm's tip frame at tip_pose (x, y, phi), in the base frame with z
    up: (x, 0, y), rotated by phi about the joint axis (-y): closed form to 1e-9."""
    model = FlexArmModel(load_arm(arm))
    q = deflected_state(model)
    frames = urdf.Frames.of(model, "r1/")
    tfs = urdf.static_transforms(model, frames) + urdf.arm_transforms(model, q, frames)
    assert len(tfs) == 1 + 2 * model.n_links + len(urdf.rotors(model))
    org = model.link_origins(q)
    assert np.max(np.abs(model.tip_deflections(q))) > 1e-3  # really deflected
    for i in range(model.n_links):
        r, p = urdf.compose(tfs, frames.tips[i], frames.base)
        np.testing.assert_allclose(p, [org[i + 1, 0], 0.0, org[i + 1, 1]], rtol=0, atol=1e-9)
        r, p = urdf.compose(tfs, frames.links[i], frames.base)
        np.testing.assert_allclose(p, [org[i, 0], 0.0, org[i, 1]], rtol=0, atol=1e-9)
        a = q[model.alpha_index(i)]  # root tangent: the link frame's x axis
        np.testing.assert_allclose(r[:, 0], [math.cos(a), 0.0, math.sin(a)], atol=1e-9)
    x, y, phi = model.tip_pose(q)
    r, p = urdf.compose(tfs, frames.tips[-1], frames.base)
    np.testing.assert_allclose(p, [x, 0.0, y], rtol=0, atol=1e-9)
    np.testing.assert_allclose(r, [[math.cos(phi), -math.sin(phi), 0.0], [0.0, 0.0, -1.0],
                                   [math.sin(phi), math.cos(phi), 0.0]], rtol=0, atol=1e-9)


def test_late_subscriber_gets_the_description_and_outputs_are_z_up(tmp_path):
    """robot_description is latched (transient local, depth 1, as robot_state_publisher):
    a subscriber created after the node published it still receives it. With
    ``frame_prefix: robot1/`` (the two-arm file) its links are prefixed and its joints are
    the names of the received /joint_states (issue 46 item 3: on main the URDF said
    robot1/joint1, /joint_states joint1). /flex/shape is in the base frame with z up (its
    last point is the tip (x, 0, y)), /flex/tip_pose in that same frame (issue 46 item
    10e: it was in arm_plane): its position is the shape's last point, its orientation
    R_plane Rz(phi); /flex/tip_imu in link2_tip, its orientation that frame's in the
    base."""
    arm = tmp_path / "imu_arm.yaml"
    arm.write_text(resolve_preset("thesis_example1_motors").read_text()
                   + "sensors:\n  - {kind: tip_accelerometer}\n")
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    from flex_model.ros.model_node import ModelNode
    ns = f"/u{uuid.uuid4().hex[:8]}"
    node = probe = None
    try:
        node = ModelNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter("arm", value=str(arm)),
            Parameter("mode", value="lockstep"), Parameter("lockstep_timeout", value=300.0),
            Parameter("publish_rate", value=1000.0), Parameter("shape_rate", value=1000.0),
            Parameter("initial_joint_angles_deg", value=[40.0, -30.0]),
            Parameter("frame_prefix", value="robot1/")])
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        for _ in range(5):
            ex.spin_once(timeout_sec=0.01)
        probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:8]}", context=ctx, namespace=ns)
        got = {"description": [], "shape": [], "tip": [], "imu": [], "js": []}
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        probe.create_subscription(String, "robot_description", got["description"].append,
                                  latched)
        probe.create_subscription(MarkerArray, "flex/shape", got["shape"].append, 10)
        probe.create_subscription(JointState, "joint_states", got["js"].append, 10)
        probe.create_subscription(PoseStamped, "flex/tip_pose", got["tip"].append, 10)
        probe.create_subscription(Imu, "flex/tip_imu", got["imu"].append, 10)
        cmd = probe.create_publisher(Float64MultiArray, "effort_controller/commands", 10)
        ex.add_node(probe)
        end = time.monotonic() + 20.0
        while not (got["description"] and cmd.get_subscription_count()):
            assert time.monotonic() < end, "timed out waiting for robot_description"
            ex.spin_once(timeout_sec=0.01)
        root = ET.fromstring(got["description"][0].data)
        movable = [j.get("name") for j in root.findall("joint")
                   if j.get("type") != "fixed" and j.find("mimic") is None]
        assert all(lk.get("name").startswith("robot1/") for lk in root.iter("link"))
        got["shape"].clear(), got["tip"].clear(), got["imu"].clear()
        cmd.publish(Float64MultiArray(data=[5.0, -3.0]))
        end = time.monotonic() + 120.0  # a first step may compile the kernels (numba)
        while not (got["shape"] and got["tip"] and got["imu"] and got["js"]
                   and node.stepper.t > 0):
            assert time.monotonic() < end, "timed out waiting for shape and tip pose"
            ex.spin_once(timeout_sec=0.01)
        assert node.stepper.t == pytest.approx(1e-3)  # the one step: no watchdog step
        assert movable == list(got["js"][-1].name) == ["joint1", "joint2"]
        x, y, phi = node.model.tip_pose(node.stepper.q)
        last = got["shape"][-1].markers[2]  # link2's centre line
        assert last.header.frame_id == "robot1/base_link"
        tip = got["tip"][-1]
        assert tip.header.stamp.nanosec == last.header.stamp.nanosec == 1_000_000
        assert tip.header.frame_id == last.header.frame_id
        p, tp = last.points[-1], tip.pose.position
        assert (p.x, p.y, p.z) == pytest.approx((x, 0.0, y), abs=1e-9)
        assert (tp.x, tp.y, tp.z) == pytest.approx((p.x, p.y, p.z), abs=1e-9)
        o = tip.pose.orientation
        np.testing.assert_allclose(
            urdf.matrix_from_quaternion((o.x, o.y, o.z, o.w)),
            [[math.cos(phi), -math.sin(phi), 0.0], [0.0, 0.0, -1.0],
             [math.sin(phi), math.cos(phi), 0.0]], rtol=0, atol=1e-9)
        assert y > 0.5  # the arm raised 40 deg: above the base, along +z
        imu = got["imu"][-1]
        assert imu.header.frame_id == "robot1/link2_tip"
        o = imu.orientation
        np.testing.assert_allclose(
            urdf.matrix_from_quaternion((o.x, o.y, o.z, o.w)),
            [[math.cos(phi), -math.sin(phi), 0.0], [0.0, 0.0, -1.0],
             [math.sin(phi), math.cos(phi), 0.0]], rtol=0, atol=1e-9)
        ex.shutdown()
    finally:
        for n in (node, probe):
            if n is not None:
                n.destroy_node()
        rclpy.try_shutdown(context=ctx)


def test_transform_messages_carry_the_chain():
    """The geometry_msgs/TransformStamped the node puts on /tf (where tf2_msgs exists):
    frames, stamp and numbers of flex_model.urdf's transforms, updated in place."""
    from flex_model.ros import conversions as conv
    model = FlexArmModel(load_arm("thesis_example1_motors"))
    frames = urdf.Frames.of(model)
    q = deflected_state(model)
    tfs = urdf.arm_transforms(model, q, frames)
    msgs = conv.Transforms(urdf.arm_transforms(model, model.q_from_joint_angles([0, 0]),
                                               frames))
    out = msgs.update(1.25, tfs)
    assert [(m.header.frame_id, m.child_frame_id) for m in out] == [
        ("arm_plane", "link1"), ("link1", "link1_tip"), ("link1_tip", "link2"),
        ("link2", "link2_tip"), ("arm_plane", "link1_rotor"), ("link1_tip", "link2_rotor")]
    for m, tr in zip(out, tfs):
        assert (m.header.stamp.sec, m.header.stamp.nanosec) == (1, 250_000_000)
        t, r = m.transform.translation, m.transform.rotation
        assert (t.x, t.y, t.z) == tr.translation and (r.x, r.y, r.z, r.w) == tr.rotation
    # the tip of link 1 in its root frame: (L - u, delta) with the model's tip deflection
    assert out[1].transform.translation.y == pytest.approx(model.tip_deflections(q)[0],
                                                           abs=1e-12)


@pytest.mark.parametrize("arm", ["thesis_example1_motors", "thesis_example1"])
def test_tf_bytes_decode_to_the_transform_messages(arm):
    """The /tf bytes the node publishes (a CDR template filled from urdf.ArmTransforms)
    are the bytes of the TFMessage of urdf.arm_transforms (what it published as objects),
    and rclpy decodes them to those frames, stamps and numbers."""
    from rclpy.serialization import deserialize_message

    from flex_model.ros import conversions as conv
    from flex_model.ros.cdr_messages import encode
    from flex_model.ros.model_node import tf_message_type
    tf_type, why = tf_message_type()
    if tf_type is None:
        pytest.skip(f"tf2_msgs: {why}")
    model = FlexArmModel(load_arm(arm))
    frames = urdf.Frames.of(model, "robot1/")
    moving = urdf.ArmTransforms(model, frames)
    template = conv.transforms_cdr(tf_type, moving.pairs)
    for seed, t in ((3, 1.25), (4, 7.000000001)):
        q = deflected_state(model, seed)
        reference = urdf.arm_transforms(model, q, frames)
        msg = tf_type(transforms=conv.Transforms(reference).update(t, reference))
        data = template.fill(t, moving.values(q, model.link_origins(q)).ravel())
        assert data == encode(msg)
        got = deserialize_message(data, tf_type).transforms
        assert len(got) == len(reference) == (6 if arm.endswith("motors") else 4)
        for m, tr in zip(got, reference):
            assert (m.header.frame_id, m.child_frame_id) == (tr.parent, tr.child)
            assert m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec == \
                round(t * 1e9)
            tl, r = m.transform.translation, m.transform.rotation
            assert (tl.x, tl.y, tl.z, r.x, r.y, r.z, r.w) == (*tr.translation,
                                                              *tr.rotation)
        assert abs(got[1].transform.translation.y) > 1e-4  # a deflected tip, not zeros
