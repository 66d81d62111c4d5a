"""Static-flexible inversion of a spatial arm (issue 25): the rigid limit against the
closed-form inverse kinematics of an anthropomorphic arm, a flexible arm checked by
forward statics, the minimum-norm step when redundant, the refusal when short of joints,
and ``flex-twin plan`` dispatching a spatial arm."""
from __future__ import annotations

import json

import numpy as np
import pytest

from flex_model.spatial import SpatialArmModel, load_spatial_arm, spatial_arm_from_dict
from flex_model.spatial.analysis import static_equilibrium
from flex_planner.spatial_inverse import invert_tip_position, tip_sensitivity

D1, A2, A3 = 0.35, 0.5, 0.7


def _rrr():
    """An anthropomorphic RRR arm (standard DH: d1 with alpha pi/2, then a2, a3), rigid."""
    return SpatialArmModel(spatial_arm_from_dict({"name": "rrr", "links": [
        {"joint": {"d": D1, "alpha": float(np.pi / 2)}, "end_body": {"mass": 1.0}},
        {"joint": {"a": A2}, "end_body": {"mass": 1.0}},
        {"joint": {"a": A3}, "end_body": {"mass": 0.5}}]}))


@pytest.mark.parametrize("p", [(0.6, 0.5, 0.6), (-0.3, 0.8, 0.1), (0.9, -0.2, 0.9)])
def test_rigid_limit_is_the_closed_form_inverse(p):
    x, y, z = p
    r, s = np.hypot(x, y), z - D1
    t3 = -np.arccos((r**2 + s**2 - A2**2 - A3**2) / (2 * A2 * A3))   # elbow branch
    t2 = np.arctan2(s, r) - np.arctan2(A3 * np.sin(t3), A2 + A3 * np.cos(t3))
    exact = np.array([np.arctan2(y, x), t2, t3])
    inv = invert_tip_position(_rrr(), p, guess=exact + [0.2, 0.2, -0.2])
    assert np.max(np.abs(inv.joint_values - exact)) < 1e-12


def test_flexible_arm_checked_by_forward_statics():
    """seed003_like_arm (elastic gear, sagging two-segment forearm): the inverse's static
    tip is the target (1e-9 m); the sag is far above that (a rigid inverse would miss)."""
    model = SpatialArmModel(load_spatial_arm("seed003_like_arm"))
    target = np.array([0.9, 0.3, 0.4])
    inv = invert_tip_position(model, target, guess=[0.0, 0.3, -0.6])
    fwd = static_equilibrium(model, inv.joint_values)
    assert np.max(np.abs(fwd.tip_position - target)) < 1e-9
    rigid = model.tip_position(np.where(np.isin(np.arange(model.nq), model.off),
                                        fwd.q, 0.0))
    assert np.linalg.norm(rigid - target) > 1e-4          # the deflection matters
    assert inv.iterations <= 10                           # Newton, exact Jacobian


def test_sensitivity_is_the_derivative_of_the_static_tip():
    model = SpatialArmModel(load_spatial_arm("seed003_like_arm"))
    th = np.array([0.2, 0.5, -0.9])
    S = tip_sensitivity(model, static_equilibrium(model, th).q)
    h = 1e-6
    for j in range(3):
        e = np.zeros(3)
        e[j] = h
        fd = (static_equilibrium(model, th + e).tip_position
              - static_equilibrium(model, th - e).tip_position) / (2 * h)
        assert np.max(np.abs(S[:, j] - fd)) < 1e-7


def test_redundant_minimum_norm_and_refusal():
    model = SpatialArmModel(load_spatial_arm("seed003_like_arm"))
    # x, z with three joints: the minimum-norm steps leave joint 1 (its column is
    # orthogonal to x, z in the arm's plane) where it is
    inv = invert_tip_position(model, [0.9, 0.4], ("x", "z"), guess=[0.0, 0.3, -0.6])
    fwd = static_equilibrium(model, inv.joint_values).tip_position
    assert abs(fwd[0] - 0.9) < 1e-9 and abs(fwd[2] - 0.4) < 1e-9
    assert abs(inv.joint_values[0]) < 1e-12
    one = SpatialArmModel(load_spatial_arm("seed000_real_arm_3d"))
    with pytest.raises(ValueError, match="1 actuated joint.*3 task coordinates"):
        invert_tip_position(one, [0.2, 0.1, 0.0])


def test_plan_command_on_a_spatial_arm(tmp_path, capsys):
    from flex_planner.cli import main
    wp = tmp_path / "wp.yaml"
    wp.write_text("guess: [0.0, 0.3, -0.6]\nwaypoints:\n"
                  "  - {t: 0.0, x: 1.1, y: 0.0, z: 0.3}\n"
                  "  - {t: 1.0, x: 0.9, y: 0.3, z: 0.4}\n")
    assert main(["plan", "seed003_like_arm", str(wp), "--out", str(tmp_path / "o"),
                 "--json", "--sample-period", "0.01"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["spatial"] and len(s["waypoints"]) == 2
    assert max(w["static_tip_error_m"] for w in s["waypoints"]) < 1e-9
    assert s["nominal_torque"].startswith("none") and "elastic gear" in s["nominal_torque"]
    data = np.genfromtxt(s["csv"], delimiter=",", names=True)
    assert len(data) == 101
    assert data["joint1_position"][-1] == pytest.approx(s["waypoints"][1]["joint_values"][0],
                                                        abs=1e-15)
    assert main(["plan", "seed000_real_arm_3d", str(wp), "--out", str(tmp_path / "p")]) == 2
    assert "no static-flexible inverse" in capsys.readouterr().err


def test_section_F_waypoints_embedded_equal_the_planar_static_inverse():
    """VALIDATION.md section F: the static-flexible inverse of thesis example 1 (vertical
    plane, gravity) at the tip waypoints P1..P4 by the planar planner (thesis Ch. IV) and
    by the spatial one on the arm embedded in 3D (x, y targets, the planar solution's
    branch as the guess): the same joint angles (1e-10 rad) and deflected tips."""
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_model.spatial import SpatialArmModel, from_planar
    from flex_planner import SECTION_F_WAYPOINTS, invert_waypoints
    from flex_planner.spatial_inverse import invert_tip_position
    arm = load_arm("thesis_example1")
    planar = invert_waypoints(FlexArmModel(arm), SECTION_F_WAYPOINTS)
    spatial = SpatialArmModel(from_planar(arm))
    for p, inv in zip(SECTION_F_WAYPOINTS, planar):
        theta = np.asarray(inv.joint_angles, float)
        res = invert_tip_position(spatial, p, coordinates=("x", "y"),
                                  guess=theta + 0.05)
        np.testing.assert_allclose(res.joint_values, theta, rtol=0, atol=1e-10)
        np.testing.assert_allclose(res.tip_position[:2], p, rtol=0, atol=1e-11)


def test_pose_inverse_of_the_six_joint_arm():
    """UR5-like arm with the flexible forearm under gravity (6 joints, position + roll,
    pitch, yaw of the tool frame): the static pose at theta0 inverted from a guess 0.05
    rad off returns theta0 (1e-9 rad) and the pose (1e-12 m, rad); the rigid arm's
    inverse (the same URDF, no flexible link) is a different joint set (the forearm's
    static deflection, ~0.1 mm at the wrist, is compensated); 3 joints for a pose:
    refused."""
    from flex_model.spatial import SpatialArmModel, load_spatial_arm
    from flex_model.spatial.analysis import static_equilibrium
    from flex_model.spatial.description import SPATIAL_PRESET_DIR
    from flex_model.spatial.urdf import load_urdf_arm
    from flex_planner.spatial_inverse import invert_tip_pose
    from scipy.spatial.transform import Rotation
    model = SpatialArmModel(load_spatial_arm("ur5_like_flexible_forearm"))
    theta0 = np.array([0.3, -1.2, 1.4, -0.8, 1.1, 0.4])
    st = static_equilibrium(model, theta0)
    F = model.tip_frame(st.q)
    rpy = Rotation.from_matrix(np.real(F.R)).as_euler("xyz")
    inv = invert_tip_pose(model, st.tip_position, rpy, guess=theta0 + 0.05)
    np.testing.assert_allclose(inv.joint_values, theta0, rtol=0, atol=1e-9)
    assert inv.error_m < 1e-12 and inv.error_rad < 1e-12
    np.testing.assert_allclose(inv.tip_rpy, rpy, rtol=0, atol=1e-12)
    rigid = SpatialArmModel(load_urdf_arm(SPATIAL_PRESET_DIR / "ur5_like_arm.urdf"))
    inv_r = invert_tip_pose(rigid, st.tip_position, rpy, guess=theta0 + 0.05)
    assert np.max(np.abs(inv_r.joint_values - theta0)) > 1e-5
    with pytest.raises(ValueError, match="3 actuated joint"):
        invert_tip_pose(SpatialArmModel(load_spatial_arm("seed003_like_arm")),
                        [0.5, 0.0, 0.5], [0.0, 0.0, 0.0])


def test_plan_command_with_orientation_waypoints(tmp_path, capsys):
    """``flex-twin plan`` on the 6-joint arm with x, y, z, roll, pitch, yaw waypoints:
    every waypoint's static pose is met (1e-9 m, rad); a file with only two of the three
    angles is refused naming the field."""
    import yaml

    from flex_twin.cli import main
    from flex_model.spatial import SpatialArmModel, load_spatial_arm
    from flex_model.spatial.analysis import static_equilibrium
    from scipy.spatial.transform import Rotation
    model = SpatialArmModel(load_spatial_arm("ur5_like_flexible_forearm"))
    pts = []
    for t, th in ((0.0, [0.3, -1.2, 1.4, -0.8, 1.1, 0.4]),
                  (1.5, [0.5, -1.0, 1.2, -0.9, 1.0, 0.2])):
        st = static_equilibrium(model, np.array(th))
        rpy = Rotation.from_matrix(np.real(model.tip_frame(st.q).R)).as_euler("xyz")
        x, y, z = st.tip_position
        pts.append({"t": t, "x": float(x), "y": float(y), "z": float(z), "roll": float(rpy[0]),
                    "pitch": float(rpy[1]), "yaw": float(rpy[2])})
    wp = tmp_path / "pose.yaml"
    wp.write_text(yaml.safe_dump({"coordinates": ["x", "y", "z", "roll", "pitch", "yaw"],
                                  "guess": [0.35, -1.15, 1.35, -0.75, 1.05, 0.35],
                                  "waypoints": pts}))
    assert main(["plan", "ur5_like_flexible_forearm", str(wp), "--out", str(tmp_path / "o"),
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for w, p in zip(out["waypoints"], pts):
        assert w["static_tip_error_m"] < 1e-9 and w["static_orientation_error_rad"] < 1e-9
        np.testing.assert_allclose(w["static_tip_rpy_rad"], [p["roll"], p["pitch"], p["yaw"]],
                                   atol=1e-9)
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"coordinates": ["x", "y", "z", "roll", "pitch"],
                                   "waypoints": pts}))
    assert main(["plan", "ur5_like_flexible_forearm", str(bad), "--out",
                 str(tmp_path / "b")]) == 2
    assert "coordinates" in capsys.readouterr().err


def test_plan_writes_the_nominal_torques_of_a_rigid_joint_arm(tmp_path, capsys):
    """The UR5-like plan's CSV carries the nominal torques along the path: at the first
    sample (at rest) they are the static holding torques of the deflected arm (the joint
    rows of K q + dU_g/dq at the static equilibrium), 1e-8 N m; seed003_like_arm (an
    elastic gear) plans without them and says why."""
    import yaml

    from flex_twin.cli import main
    from flex_model.spatial import SpatialArmModel, load_spatial_arm
    from flex_model.spatial.analysis import static_equilibrium
    model = SpatialArmModel(load_spatial_arm("ur5_like_flexible_forearm"))
    wp = tmp_path / "w.yaml"
    wp.write_text(yaml.safe_dump({"guess": [0.3, -1.2, 1.4, -0.8, 1.1, 0.4], "waypoints": [
        {"t": 0.0, "x": 0.45, "y": 0.15, "z": 0.45},
        {"t": 1.0, "x": 0.4, "y": 0.25, "z": 0.5}]}))
    assert main(["plan", "ur5_like_flexible_forearm", str(wp), "--out", str(tmp_path / "o"),
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["nominal_torque"].startswith("in plan.csv")
    data = np.genfromtxt(out["csv"], delimiter=",", names=True)
    names = model.arm.joint_names
    tau0 = np.array([data[f"{j}_effort"][0] for j in names])
    theta0 = np.array([data[f"{j}_position"][0] for j in names])
    q = static_equilibrium(model, theta0).q
    hold = (model.K @ q + model.gravity_force(q) - model.effect_force(np.zeros(model.nq), q))
    np.testing.assert_allclose(tau0, hold[model.off], rtol=0, atol=1e-8)
    assert np.max(np.abs(tau0)) > 1.0
