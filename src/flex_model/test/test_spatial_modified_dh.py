"""Craig's modified DH convention in a spatial arm file (issue 25): forward kinematics by
hand, equality with the standard-convention description of the same arm (rigid and
flexible), the compiled terms, and the refusal of a dh_x beam without a next row."""
import numpy as np
import pytest

from flex_model.config import ConfigError
from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
from flex_model.spatial.compiled import CompiledSpatialModel

HALF_PI = 0.5 * np.pi
SECTION = {"EI_y": 3.0, "EI_z": 2.0, "GJ": 1.0, "rhoA": 0.5, "rhoJ": 1e-4}


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


def craig(a_prev, alpha_prev, d, theta):
    """Craig's modified DH: Rot_x(alpha_{i-1}) Trans_x(a_{i-1}) Rot_z(theta_i) Trans_z(d_i)."""
    return rot("x", alpha_prev) @ trans(a_prev, 0, 0) @ rot("z", theta) @ trans(0, 0, d)


def arm(convention, rows, prismatic=False, flexible=False, bodies=True):
    links = []
    for i, (a, alpha, d, theta) in enumerate(rows):
        lk = {"joint": {"type": "prismatic" if (i == 1 and prismatic) else "revolute",
                        "a": a, "alpha": alpha, "d": d, "theta": theta}}
        if flexible and i == 0:
            lk["flexible"] = {"section": SECTION, "variables": 4}
        if bodies:
            lk["end_body"] = {"mass": 0.7 + i, "inertia": [0.01, 0.02, 0.03],
                              "offset": [0.05, -0.02, 0.01]}
        links.append(lk)
    return SpatialArmModel(spatial_arm_from_dict({"name": "two", "convention": convention,
                                                  "links": links}))


# modified rows (a_{i-1}, alpha_{i-1}, d_i, theta_i), with a base offset a_0, alpha_0
MOD = [(0.2, -0.6, 0.25, 0.3), (0.4, HALF_PI, 0.1, -0.2)]


@pytest.mark.parametrize("prismatic", [False, True])
def test_modified_dh_is_the_craig_product(prismatic):
    """Rigid 2-link arm, revolute (and prismatic) joints, a base offset a_0, alpha_0: the
    tip frame is Craig's A_1 A_2 exactly."""
    model = arm("modified_dh", MOD, prismatic)
    rng = np.random.default_rng(7)
    (a0, al0, d1, t1), (a1, al1, d2, t2) = MOD
    for _ in range(5):
        qj = rng.uniform(-2, 2, 2)
        q = np.zeros(model.nq)
        q[model.off] = qj
        A1 = craig(a0, al0, d1, t1 + qj[0])
        A2 = craig(a1, al1, d2 + qj[1], t2) if prismatic else craig(a1, al1, d2, t2 + qj[1])
        frames = model.frames(q)
        # the end frame of link 1 is Craig's frame 1 carried to joint 2 (Rot_x Trans_x
        # of row 2, at joint 2's axis); the last link's is Craig's frame 2
        assert np.max(np.abs(frames[0] - A1 @ rot("x", al1) @ trans(a1, 0, 0))) < 1e-15
        assert np.max(np.abs(frames[1] - A1 @ A2)) < 1e-15


@pytest.mark.parametrize("flexible", [False, True])
def test_both_conventions_describe_the_same_arm(flexible):
    """Standard rows (a_i, alpha_i, d_i, theta_i) = modified rows (a_{i-1}, alpha_{i-1},
    d_i, theta_i) with a_0 = alpha_0 = 0 and a_2 = alpha_2 = 0: frames, mass matrix,
    velocity terms, stiffness and gravity equal (a flexible dh_x link 1 runs to joint 2)."""
    std = [(0.4, HALF_PI, 0.25, 0.3), (0.0, 0.0, 0.1, -0.2)]
    mod = [(0.0, 0.0, 0.25, 0.3), (0.4, HALF_PI, 0.1, -0.2)]
    ms, mm = arm("standard_dh", std, flexible=flexible), arm("modified_dh", mod,
                                                             flexible=flexible)
    assert ms.nq == mm.nq == (2 + (2 * 4 + 5 if flexible else 0))
    rng = np.random.default_rng(11)
    for _ in range(3):
        q, v = rng.normal(scale=0.3, size=(2, ms.nq))
        for Fs, Fm in zip(ms.frames(q), mm.frames(q)):
            assert np.max(np.abs(Fs - Fm)) < 1e-12
        Ms, cs = ms.terms(q, v)
        Mm, cm = mm.terms(q, v)
        assert np.max(np.abs(Ms - Mm)) < 1e-12 and np.max(np.abs(cs - cm)) < 1e-12
        assert np.max(np.abs(ms.gravity_force(q) - mm.gravity_force(q))) < 1e-12
    assert np.array_equal(ms.K, mm.K)


def test_compiled_terms_of_a_modified_arm_with_a_base_offset():
    """The base offset Rot_x(alpha_0) Trans_x(a_0) is a fixed origin before joint 1: the
    compiled recursion = the Python reference (1e-10)."""
    mod = [(0.2, -0.6, 0.25, 0.3), (0.4, HALF_PI, 0.1, -0.2), (0.3, -0.3, 0.0, 0.1)]
    model = arm("modified_dh", mod, flexible=True)
    cm = CompiledSpatialModel(model)
    rng = np.random.default_rng(13)
    for _ in range(3):
        q, v = rng.normal(scale=0.3, size=(2, model.nq))
        M, c = model.terms(q, v)
        Mc, cc = cm.terms(q, v)
        assert np.max(np.abs(M - Mc)) < 1e-10 * np.max(np.abs(M))
        assert np.max(np.abs(c - cc)) < 1e-10 * max(1.0, np.max(np.abs(c)))


def test_modified_dh_x_beam_needs_the_next_row():
    with pytest.raises(ConfigError, match=r"links\[0\]\.flexible.*modified_dh"):
        spatial_arm_from_dict({"name": "one", "convention": "modified_dh", "links": [
            {"joint": {"a": 0.3}, "flexible": {"section": SECTION}}]}, "one.yaml")
    with pytest.raises(ConfigError, match=r"links\[1\]\.joint\.a"):
        spatial_arm_from_dict({"name": "two", "convention": "modified_dh", "links": [
            {"joint": {"a": 0.3}, "flexible": {"section": SECTION}}, {"joint": {}}]},
            "two.yaml")
    with pytest.raises(ConfigError, match="convention"):
        spatial_arm_from_dict({"name": "x", "convention": "craig", "links": [{}]}, "x.yaml")
