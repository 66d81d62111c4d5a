"""URDF descriptions of spatial arms: a 2-link URDF equals the equivalent DH file (forward
kinematics, mass matrix, velocity terms, frequencies), limits, and clear errors."""
import numpy as np
import pytest

from flex_model.config import ConfigError
from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
from flex_model.spatial.analysis import natural_modes
from flex_model.spatial.kinematics import rot_x
from flex_model.spatial.limits import clip_efforts, joint_limits, limit_violations
from flex_model.spatial.urdf import spatial_arm_from_urdf

A1, AL1, D1, TH1 = 0.5, 0.7, 0.1, 0.3        # DH row of link 1 (flexible)
A2, AL2, D2 = 0.4, -0.4, 0.05                # DH row of link 2 (flexible), theta2 = 0
SEC1 = {"EI_y": 30.0, "EI_z": 12.0, "GJ": 9.0, "rhoA": 0.8, "rhoJ": 2e-4}
SEC2 = {"EI_y": 8.0, "EI_z": 5.0, "GJ": 4.0, "rhoA": 0.5, "rhoJ": 1e-4}
ROOT1 = {"mass": 0.4, "inertia": [1e-3, 2e-3, 3e-3], "offset": [0.01, 0.0, 0.02]}
END1 = {"mass": 0.3, "inertia": [[2e-3, 1e-4, 0], [1e-4, 1e-3, 0], [0, 0, 4e-3]],
        "offset": [0.0, 0.01, 0.03]}                 # in DH frame 1 (after Rot_x(alpha1))
TOOL_M, TOOL_I = 0.2, [5e-4, 6e-4, 7e-4]            # at the origin of DH frame 2

DH = {"name": "two_link_dh", "gravity": [0.0, -3.0, -9.81], "links": [
    {"joint": {"name": "j1", "a": A1, "alpha": AL1, "d": D1, "theta": TH1},
     "flexible": {"section": SEC1, "variables": 4}, "root_body": ROOT1, "end_body": END1},
    {"joint": {"name": "j2", "a": A2, "alpha": AL2, "d": D2},
     "flexible": {"section": SEC2, "variables": 4},
     "end_body": {"mass": TOOL_M, "inertia": TOOL_I}}]}


def _urdf():
    """The same arm in URDF: joint origins carry d, theta and the previous link's a, alpha;
    the tool frame (a2, alpha2) is a fixed joint with a massive tool link."""
    t2 = np.array([A1, 0.0, 0.0]) + rot_x(AL1) @ np.array([0.0, 0.0, D2])
    return f"""<?xml version="1.0"?>
<robot name="two_link">
  <link name="base"><inertial><mass value="5"/>
    <inertia ixx="1" iyy="1" izz="1"/></inertial></link>
  <link name="l1"/>
  <link name="l2"/>
  <link name="tool"><inertial><mass value="{TOOL_M}"/>
    <inertia ixx="{TOOL_I[0]}" iyy="{TOOL_I[1]}" izz="{TOOL_I[2]}"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/>
    <origin xyz="0 0 {D1}" rpy="0 0 {TH1}"/><axis xyz="0 0 1"/>
    <limit lower="-1.5" upper="1.5" effort="20" velocity="3"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
    <origin xyz="{float(t2[0])!r} {float(t2[1])!r} {float(t2[2])!r}" rpy="{AL1!r} 0 0"/>
    <axis xyz="0 0 1"/>
    <limit effort="5" velocity="4"/></joint>
  <joint name="tool_joint" type="fixed"><parent link="l2"/><child link="tool"/>
    <origin xyz="{A2} 0 0" rpy="{AL2!r} 0 0"/></joint>
</robot>"""


def _flex_links():
    R = rot_x(AL1)    # END1 is given in DH frame 1; the side file uses the tip-carried l1 frame
    end1 = {"mass": END1["mass"], "offset": list(R @ END1["offset"]),
            "inertia": (R @ np.array(END1["inertia"]) @ R.T).tolist()}
    return {"l1": {"section": SEC1, "variables": 4, "root_body": ROOT1, "end_body": end1},
            "l2": {"section": SEC2, "variables": 4}}


@pytest.fixture(scope="module")
def pair():
    dh = SpatialArmModel(spatial_arm_from_dict(DH))
    ur = SpatialArmModel(spatial_arm_from_urdf(_urdf(), "two_link.urdf",
                                               flexible_links=_flex_links(),
                                               gravity=DH["gravity"]))
    return dh, ur


def test_urdf_equals_dh_kinematics_mass_matrix_terms(pair):
    dh, ur = pair
    assert dh.nq == ur.nq == 2 * (1 + 8 + 5)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v = rng.normal(scale=0.3, size=dh.nq), rng.normal(size=dh.nq)
        (F1d, F2d), (F1u, F2u) = dh.frames(q), ur.frames(q)
        # frame 1: the DH frame is the URDF tip frame rotated by alpha1 (joint 2's origin)
        assert np.max(np.abs(F1d[:3, :3] @ rot_x(AL1).T - F1u[:3, :3])) < 1e-12
        assert np.max(np.abs(F1d[:3, 3] - F1u[:3, 3])) < 1e-12
        assert np.max(np.abs(F2d - F2u)) < 1e-12
        Md, cd = dh.terms(q, v)
        Mu, cu = ur.terms(q, v)
        assert np.max(np.abs(Md - Mu)) < 1e-10 * np.max(np.abs(Md))
        assert np.max(np.abs(cd - cu)) < 1e-10 * np.max(np.abs(cd))


def test_urdf_equals_dh_frequencies(pair):
    dh, ur = pair
    for joints, rigid in (("clamped", 0), ("hinged", 2)):   # hinged: 2 rigid-body modes
        fd = natural_modes(dh, joints=joints).frequencies_hz[:6 + rigid]
        fu = natural_modes(ur, joints=joints).frequencies_hz[:6 + rigid]
        assert np.all(fd[:rigid] < 1e-4) and np.all(fu[:rigid] < 1e-4)
        assert fd[rigid] > 1.0
        assert np.max(np.abs(fd[rigid:] - fu[rigid:]) / fd[rigid:]) < 1e-10


def test_urdf_limits_kept_and_clipped(pair):
    _, ur = pair
    lim = joint_limits(ur.arm)
    assert lim["lower"].tolist() == [-1.5, -np.inf] and lim["upper"].tolist() == [1.5, np.inf]
    assert lim["effort"].tolist() == [20.0, 5.0]
    assert clip_efforts(ur.arm, [30.0, -7.0]).tolist() == [20.0, -5.0]
    q = np.zeros(ur.nq)
    q[ur.off] = [1.6, 9.0]
    v = np.zeros(ur.nq)
    v[ur.off] = [0.0, -5.0]
    msgs = limit_violations(ur, q, v)
    assert len(msgs) == 2 and "j1: position 1.6" in msgs[0] and "j2: velocity -5" in msgs[1]


@pytest.mark.parametrize("edit, where", [
    (lambda s: s.replace('type="continuous"', 'type="floating"'),
     "robot/joint[@name='j2']/@type"),
    (lambda s: s.replace('<child link="l2"/>', '<child link="l9"/>'),
     "robot/joint[@name='j2']/child/@link"),
    (lambda s: s.replace('<axis xyz="0 0 1"/>\n    <limit effort="5"',
                         '<axis xyz="0 0 x"/>\n    <limit effort="5"'),
     "robot/joint[@name='j2']/axis/@xyz"),
    (lambda s: s.replace('<limit lower="-1.5"', '<limit lower="2.5"'),
     "robot/joint[@name='j1']/limit/@lower"),
    (lambda s: s.replace("</robot>", "<joint name=\"j3\" type=\"fixed\"><parent link=\"l1\"/>"
                                     "<child link=\"extra\"/></joint><link name=\"extra\"/>"
                                     "</robot>"),
     "robot/joint[@name='j3']/parent/@link"),
    (lambda s: s.replace("</robot>", "<link"), "xml"),
])
def test_bad_urdf_one_clear_error(edit, where):
    with pytest.raises(ConfigError) as exc:
        spatial_arm_from_urdf(edit(_urdf()), "bad_arm.urdf", flexible_links=_flex_links())
    msg = str(exc.value)
    assert msg.startswith("bad_arm.urdf: ") and where in msg, msg


def test_side_file_errors_name_the_side_file(tmp_path):
    (tmp_path / "arm.urdf").write_text(_urdf())
    data = {"name": "x", "urdf": "arm.urdf", "flexible_links": {"l7": {"section": SEC1}}}
    with pytest.raises(ConfigError, match=r"side.yaml: flexible_links.l7"):
        spatial_arm_from_dict(data, str(tmp_path / "side.yaml"))
    data["flexible_links"] = {"l1": {"section": dict(SEC1, EI_z=-1.0)}}
    with pytest.raises(ConfigError, match=r"side.yaml: flexible_links.l1.section.EI_z"):
        spatial_arm_from_dict(data, str(tmp_path / "side.yaml"))
