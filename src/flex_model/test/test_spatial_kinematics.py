"""Spatial arms: description validation and DH kinematics (seed 000 Eqs. 17-21, Fig. 5)."""
import numpy as np
import pytest

from flex_model.config import ConfigError
from flex_model.spatial import SpatialArmModel, load_spatial_arm, spatial_arm_from_dict

HALF_PI = 0.5 * np.pi


def trans(x, y, z):
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def rot(axis, t):
    """Elementary rotation written out by hand (independent of spatial.kinematics)."""
    c, s = np.cos(t), np.sin(t)
    T = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def eq17(a, alpha, d, theta):
    """Seed 000 Eq. 17: Trans_z(d) Rot_z(theta) Trans_x(a) Rot_x(alpha)."""
    return trans(0, 0, d) @ rot("z", theta) @ trans(a, 0, 0) @ rot("x", alpha)


def eq19(v, w, dv, dw, phi, length):
    """Seed 000 Eq. 19 in the beam frame with the twist about the tangent (issue 47):
    Ry(-w') Rz(v') Rx(phi) and (L, v, w)."""
    E = rot("y", -dw) @ rot("z", dv) @ rot("x", phi)
    E[:3, 3] = [length, v, w]
    return E


ROWS = [(0.4, HALF_PI, 0.25, 0.3), (0.35, -0.4, 0.1, -0.2)]  # a, alpha, d, theta offset


def two_link(flexible: bool, second_prismatic=False, placement="dh_x"):
    links = []
    for i, (a, alpha, d, theta) in enumerate(ROWS):
        lk = {"joint": {"type": "prismatic" if (i == 1 and second_prismatic) else "revolute",
                        "a": a, "alpha": alpha, "d": d, "theta": theta}}
        if flexible:
            lk["flexible"] = {"section": {"EI_y": 3.0, "EI_z": 2.0, "GJ": 1.0, "rhoA": 0.5,
                                          "rhoJ": 1e-4}, "variables": 4}
            if placement == "aux_z" and i == 0:
                lk["flexible"]["placement"] = "aux_z"
                lk["flexible"]["length"] = 0.3
        links.append(lk)
    return spatial_arm_from_dict({"name": "two", "links": links})


@pytest.mark.parametrize("prismatic", [False, True])
def test_rigid_two_link_dh_is_eq17_product(prismatic):
    """Rigid limit (flexible links with zero deflection, and rigid links): frame 2 is
    A_1 A_2 of Eq. 17-18 exactly, joint variable added to theta (or d if prismatic)."""
    rng = np.random.default_rng(3)
    for flexible in (False, True):
        model = SpatialArmModel(two_link(flexible, prismatic))
        for _ in range(5):
            qj = rng.uniform(-2, 2, 2)
            q = np.zeros(model.nq)
            q[model.off] = qj
            (a1, al1, d1, t1), (a2, al2, d2, t2) = ROWS
            A2 = eq17(a2, al2, d2 + qj[1], t2) if prismatic else eq17(a2, al2, d2, t2 + qj[1])
            expect = eq17(a1, al1, d1, t1 + qj[0]) @ A2
            frames = model.frames(q)
            assert np.max(np.abs(frames[-1] - expect)) < 1e-15
            assert np.max(np.abs(frames[0] - eq17(a1, al1, d1, t1 + qj[0]))) < 1e-15


def test_flexible_two_link_is_eq20_with_eq19():
    """Deflected links: T_2 = A_1' E_1 Rot_x(alpha_1) A_2' E_2 Rot_x(alpha_2) (Eq. 20 with the
    flexible transform E of Eq. 19 at the beam's end, before Rot_x(alpha))."""
    model = SpatialArmModel(two_link(True))
    rng = np.random.default_rng(5)
    q = rng.normal(scale=0.05, size=model.nq)
    T = np.eye(4)
    for i, (a, alpha, d, theta) in enumerate(ROWS):
        f = q[model.flex_slice(i)]
        v, w, phi = f[:4], f[4:8], f[8:]
        E = eq19(v[2], w[2], v[3], w[3], phi[-2], a)
        T = T @ trans(0, 0, d) @ rot("z", theta + q[model.off[i]]) @ E @ rot("x", alpha)
        assert np.max(np.abs(model.frames(q)[i] - T)) < 1e-14


def test_aux_placement_is_fig5_eq21():
    """Fig. 5 / Eq. 21: a beam along z_1 from the origin of frame 1, T = A_1 A_aux E_1 with
    A_aux = Trans_z(L_1); in the beam frame x_b = z_1, y_b = y_1, z_b = -x_1."""
    model = SpatialArmModel(two_link(True, placement="aux_z"))
    rng = np.random.default_rng(7)
    q = rng.normal(scale=0.05, size=model.nq)
    a, alpha, d, theta = ROWS[0]
    f = q[model.flex_slice(0)]
    P = np.eye(4)
    P[:3, :3] = [[0, 0, -1], [0, 1, 0], [1, 0, 0]]
    E = P @ eq19(f[2], f[6], f[3], f[7], f[-2], 0.0) @ P.T
    expect = eq17(a, alpha, d, theta + q[0]) @ trans(0, 0, 0.3) @ E
    assert np.max(np.abs(model.frames(q)[0] - expect)) < 1e-14


def test_tip_jacobian_matches_finite_differences():
    model = SpatialArmModel(two_link(True, second_prismatic=True))
    rng = np.random.default_rng(11)
    q = rng.normal(scale=0.1, size=model.nq)
    J = model.tip_jacobian(q)
    h = 1e-6
    for k in range(model.nq):
        dq = np.zeros(model.nq)
        dq[k] = h
        Tp, Tm = model.frames(q + dq)[-1], model.frames(q - dq)[-1]
        assert np.allclose((Tp[:3, 3] - Tm[:3, 3]) / (2 * h), J[:3, k], atol=1e-8)
        W = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ model.frames(q)[-1][:3, :3].T
        assert np.allclose([W[2, 1], W[0, 2], W[1, 0]], J[3:, k], atol=1e-8)


def test_preset_loads_and_errors_name_file_field_value():
    arm = load_spatial_arm("seed000_real_arm_3d")
    assert arm.links[0].flexible.length == pytest.approx(0.28)
    bad = {"name": "x", "links": [{"joint": {"type": "spherical"}}]}
    with pytest.raises(ConfigError) as e:
        spatial_arm_from_dict(bad, "arm.yaml")
    assert "arm.yaml" in str(e.value) and "links[0].joint.type" in str(e.value) \
        and "'spherical'" in str(e.value) and "revolute, prismatic" in str(e.value)
    bad = {"name": "x", "links": [{"joint": {"a": 0.5}, "flexible": {
        "section": {"EI_y": 1.0, "EI_z": -2.0, "GJ": 1.0, "rhoA": 1.0, "rhoJ": 1e-4}}}]}
    with pytest.raises(ConfigError, match=r"links\[0\]\.flexible\.section\.EI_z: got -2\.0"):
        spatial_arm_from_dict(bad, "arm.yaml")
    bad = {"name": "x", "links": [{"joint": {"a": 0.0}, "flexible": {
        "section": {"EI_y": 1.0, "EI_z": 2.0, "GJ": 1.0, "rhoA": 1.0, "rhoJ": 1e-4}}}]}
    with pytest.raises(ConfigError, match=r"links\[0\]\.joint\.a: got 0\.0; expected a > 0"):
        spatial_arm_from_dict(bad, "arm.yaml")
    bad = {"name": "x", "links": [{"joint": {}, "end_body": {"inertia": [1, 2]}}]}
    with pytest.raises(ConfigError, match=r"end_body\.inertia"):
        spatial_arm_from_dict(bad, "arm.yaml")
    with pytest.raises(ConfigError, match=r"links\[0\]\.colour: got"):
        spatial_arm_from_dict({"name": "x", "links": [{"colour": 1}]}, "arm.yaml")
