"""Static-flexible kinematic inversion (thesis Ch. IV) against independent forward solves,
the thesis closed form (Eqs. 85-94) and the own-weight deflection of VALIDATION.md B."""
import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.statics import TipLoad, static_equilibrium
from flex_planner import (SECTION_F_WAYPOINTS, UnreachableError, invert_tip_pose,
                          invert_waypoints)
from flex_planner import closed_form as cf


def wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


@pytest.fixture(scope="module")
def example1():
    return FlexArmModel(load_arm("thesis_example1"))


def forward_tip(model, theta, load=TipLoad()):
    """Independent forward check: flex_model's own clamped static equilibrium."""
    res = static_equilibrium(model, theta, joints="clamped", load=load)
    return np.asarray(res.tip_position), res


@pytest.mark.parametrize("elbow", ["up", "down"])
def test_section_F_poses_put_the_static_tip_on_the_waypoints(example1, elbow):
    poses = invert_waypoints(example1, SECTION_F_WAYPOINTS, elbow=elbow)
    bends = set()
    for p, pose in zip(SECTION_F_WAYPOINTS, poses):
        tip, res = forward_tip(example1, pose.joint_angles)
        assert np.linalg.norm(tip - p) < 1e-6
        # the arm really sags: the pose differs from the rigid one by the deflections
        assert np.max(np.abs(res.link_tip_deflection)) > 0.01
        elbow_point, tip_point = example1.link_origins(pose.q)[1:]
        # "up" = of the two mirror-image poses the one with the higher elbow
        mirror = 2 * (elbow_point @ tip_point / (tip_point @ tip_point)) * tip_point \
            - elbow_point
        assert (elbow_point[1] > mirror[1]) == (elbow == "up")
        bends.add(np.sign(pose.joint_angles[1]))
    assert len(bends) == 1  # one branch along the whole path


def test_gravity_makes_the_inverse_differ_from_rigid_kinematics(example1):
    rigid = invert_tip_pose(example1.with_gravity((0.0, 0.0)), SECTION_F_WAYPOINTS[0])
    flexible = invert_tip_pose(example1, SECTION_F_WAYPOINTS[0])
    assert np.max(np.abs(rigid.q[[1, 2, 4, 5]])) < 1e-12    # no load: no deflection
    assert np.max(np.abs(flexible.joint_angles - rigid.joint_angles)) > 0.01  # rad


def test_closed_form_reproduces_the_own_weight_deflection_of_section_B(example1):
    """Eqs. 86-93 on the straight horizontal arm (theta = 0): alpha_2 = gamma_1 and the
    superposed cantilever cases add up to q (L1 + L2)^4 / (8 EI) = 219.5 mm."""
    b = cf.TwoLinkBeams.from_model(example1)
    g1 = cf.deflections(b, 0.0, 0.0)[2]
    for _ in range(50):   # alpha_2 = alpha_1 + gamma_1(alpha_2), fixed point
        g1 = cf.deflections(b, 0.0, g1)[2]
    y = cf.tip_position(b, 0.0, g1)[1]
    exact = b.m1 * b.g * 4.0 ** 4 / (8 * b.EI1)
    assert -y == pytest.approx(exact, rel=2e-3)     # second-order terms of cos(gamma_1)
    assert abs(-1e3 * y - 219.5) < 0.5


@pytest.mark.parametrize("gravity_scale", [1.0, 0.1])
def test_closed_form_agrees_with_the_general_inversion_for_small_deflections(
        example1, gravity_scale):
    model = example1.with_gravity((0.0, -9.81 * gravity_scale))
    b = cf.TwoLinkBeams.from_model(model)
    poses = invert_waypoints(model, SECTION_F_WAYPOINTS, elbow="up")
    worst_angle = worst_deflection = 0.0
    for p, pose in zip(SECTION_F_WAYPOINTS, poses):
        closed = cf.invert(b, p, int(np.sign(pose.joint_angles[1])))
        worst_angle = max(worst_angle, np.max(np.abs(wrap(pose.joint_angles
                                                          - closed.joint_angles))))
        worst_deflection = max(worst_deflection, np.max(np.abs(
            model.tip_deflections(pose.q) - closed.tip_deflections)))
    # the closed form is the first-order (small deflection) model: the difference is of
    # second order in the deflections (about 50 mm here), so it falls 100x with gravity/10
    assert worst_angle < 4e-5 * gravity_scale ** 2
    assert worst_deflection < 8e-5 * gravity_scale ** 2


def test_unreachable_point_is_reported_with_its_index_and_reason(example1):
    path = [SECTION_F_WAYPOINTS[0], [5.0, 0.0], SECTION_F_WAYPOINTS[2]]
    with pytest.raises(UnreachableError, match=r"waypoint 1 at \(5, 0\) m is unreachable: "
                       r"outside the reach of the sagging arm") as info:
        invert_waypoints(example1, path)
    assert isinstance(info.value, ValueError)
    assert info.value.index == 1 and info.value.point == (5.0, 0.0)
    # the closest static tip is the stretched sagging arm, about 4 m from the base
    closest = float(info.value.reason.split("closest static tip is ")[1].split(" mm")[0])
    assert 990.0 < closest < 1000.0


def test_just_beyond_the_straight_arm_is_unreachable(example1):
    with pytest.raises(UnreachableError, match="outside the reach") as info:
        invert_tip_pose(example1, [0.0, -4.05])
    assert info.value.index == 0


def test_branch_stays_continuous_around_the_base(example1):
    """A half circle of radius 3 m through the negative x axis: atan2 jumps by 2 pi there,
    the joint angles must not."""
    a = np.linspace(0.5 * np.pi, 1.5 * np.pi, 41)
    pts = 3.0 * np.c_[np.cos(a), np.sin(a)]
    poses = invert_waypoints(example1, pts, elbow="down")
    theta = np.array([p.joint_angles for p in poses])
    assert np.max(np.abs(np.diff(theta, axis=0))) < 0.1
    assert np.all(np.sign(theta[:, 1]) == np.sign(theta[0, 1]))
    for p, pose in zip(pts[::10], poses[::10]):
        assert np.linalg.norm(forward_tip(example1, pose.joint_angles)[0] - p) < 1e-6


def test_tip_load_and_payload_enter_the_inversion():
    model = FlexArmModel(load_arm("thesis_example1"))
    model.set_payload(0.2, 0.0)
    load = TipLoad(force=(0.0, -2.0), torque=0.5)
    target = SECTION_F_WAYPOINTS[1]
    loaded = invert_tip_pose(model, target, tip_load=load)
    assert np.linalg.norm(forward_tip(model, loaded.joint_angles, load)[0] - target) < 1e-6
    plain = invert_tip_pose(model, target)
    assert np.max(np.abs(loaded.joint_angles - plain.joint_angles)) > 0.01


def test_three_links_need_and_reach_the_tip_orientation():
    model = FlexArmModel(load_arm("thesis_three_link", 2))
    pts = np.array([[5.0, -2.0], [4.0, 1.0], [3.0, 3.0]])
    phis = np.array([-0.8, 0.2, 1.0])
    poses = invert_waypoints(model, pts, phis)
    for p, phi, pose in zip(pts, phis, poses):
        res = static_equilibrium(model, pose.joint_angles, joints="clamped")
        x, y, angle = model.tip_pose(res.q)
        assert np.hypot(x - p[0], y - p[1]) < 1e-6
        assert abs(wrap(angle - phi)) < 1e-8
    with pytest.raises(ValueError, match="orientations: got None; expected one tip "
                       "orientation"):
        invert_waypoints(model, pts)
    with pytest.raises(ValueError, match="a two-link arm cannot also set its tip "
                       "orientation"):
        invert_waypoints(FlexArmModel(load_arm("thesis_example1")), pts, phis)
