"""Quasi-static nominal trajectories, NPZ files and the node parameters (no ROS)."""
import numpy as np
import pytest

from flex_model.statics import TipLoad, static_residual

from flex_control.laws import DecentralizedPD, PDLikeCascade
from flex_control.nominal import load_trajectory, quasi_static_trajectory, save_trajectory
from flex_control.params import ControllerParams, build_controller


def test_quasi_static_trajectory_hits_the_waypoints(section_f_model, section_f_quasi_static,
                                                   section_f_waypoints):
    model, data = section_f_model, section_f_quasi_static
    for t, p in zip(*section_f_waypoints):
        k = int(np.argmin(np.abs(data.t - t)))
        assert data.t[k] == pytest.approx(t)
        np.testing.assert_allclose(data.tip[k], p, atol=1e-9)      # statically on the point
    np.testing.assert_allclose(data.velocities[[0, -1]], 0.0, atol=1e-12)
    # q_nominal: static equilibrium with the joints held (residual only on the joints)
    q = data.q_nominal[100]
    r = static_residual(model, q, np.zeros(2), TipLoad())
    free = np.setdiff1d(np.arange(model.nq), model.off)
    T = model.joint_coordinate_matrix()
    assert np.max(np.abs((T.T @ r)[free])) < 1e-8
    np.testing.assert_allclose(model.joint_angles(q), data.positions[100], atol=1e-12)


def test_quasi_static_errors(section_f_model):
    with pytest.raises(ValueError, match=r"joint_angles: got shape \(2, 3\); expected \(2, 2\)"):
        quasi_static_trajectory(section_f_model, [0, 1], np.zeros((2, 3)))
    with pytest.raises(ValueError, match=r"times: got \[1.0, 0.0\]"):
        quasi_static_trajectory(section_f_model, [1, 0], np.zeros((2, 2)))


def test_npz_round_trip_and_errors(section_f_quasi_static, tmp_path):
    path = save_trajectory(tmp_path / "plan.npz", section_f_quasi_static)
    back = load_trajectory(path)
    assert back.joint_names == ["joint1", "joint2"]
    for name in ("t", "positions", "velocities", "accelerations", "efforts", "q_nominal", "tip"):
        np.testing.assert_array_equal(getattr(back, name), getattr(section_f_quasi_static, name))
    np.savez(tmp_path / "bad.npz", t=np.arange(3.0))
    with pytest.raises(ValueError, match=r"bad.npz: joint_names: got <missing>"):
        load_trajectory(tmp_path / "bad.npz")
    (tmp_path / "junk.npz").write_text("not a zip")
    with pytest.raises(ValueError, match="junk.npz: got an unreadable file"):
        load_trajectory(tmp_path / "junk.npz")


def test_params_defaults_and_builders():
    p = ControllerParams()
    assert p.law == "eq95" and p.h == (25.0,) and p.a == (5.0,) and p.rate_hz == 500.0
    c = build_controller(p, hold_positions=[0.1, 0.2])
    assert isinstance(c, DecentralizedPD)
    np.testing.assert_array_equal(c.torque_limits, [100.0, 100.0])
    c45 = build_controller(ControllerParams(law="eq45", joint_names=("j",)))
    assert isinstance(c45, PDLikeCascade) and c45.gear_ratio[0] == 50.0


@pytest.mark.parametrize("kwargs,match", [
    ({"law": "pid"}, "law: got 'pid'; expected one of eq95, eq45"),
    ({"stale_action": "brake"}, "stale_action: got 'brake'; expected one of zero, hold"),
    ({"h": (1.0, 2.0, 3.0)}, r"h: got \[1.0, 2.0, 3.0\]; expected 1 or 2 finite gains > 0"),
    ({"a": (-1.0,)}, r"a: got \[-1.0\]; expected 1 or 2 finite gains > 0"),
    ({"torque_limits": (0.0,)}, r"torque_limits: got \[0.0, 0.0\]; expected limits > 0"),
    ({"rate_hz": 0.5}, r"rate_hz: got 0.5; expected a number in \[1, 20000\]"),
    ({"state_timeout": float("nan")}, "state_timeout: got nan"),
    ({"joint_names": ("a", "a")}, r"joint_names: got \['a', 'a'\]; expected unique"),
])
def test_params_errors_name_the_field(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ControllerParams(**kwargs)


def test_params_from_mapping_rejects_unknown_names():
    with pytest.raises(ValueError, match="gain: got an unknown parameter"):
        ControllerParams.from_mapping({"gain": 3})
