"""Closed-loop linearization of the arm under Eq. (95) along a nominal trajectory."""
import numpy as np
import pytest

from flex_model.arm import arm_from_dict, load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.modes import linearize

from flex_control.closed_loop import (LinearizedTrajectory, NominalTrajectory,
                                      closed_loop_matrix, eigen_summary, open_loop_jacobian,
                                      pd_gains)


def test_pd_gains_give_damping_ratio_one_over_sqrt2():
    kp, kd = pd_gains(1.0, 5.0)
    assert (kp, kd) == (25.0, pytest.approx(5 * np.sqrt(2)))
    s = eigen_summary(np.array([[0.0, 1.0], [-kp, -kd]]))      # unit inertia
    assert s.zeta_min == pytest.approx(1 / np.sqrt(2), rel=1e-12)
    assert s.tau_max == pytest.approx(np.sqrt(2) / 5.0, rel=1e-12)
    unstable = eigen_summary(np.array([[0.0, 1.0], [4.0, -1.0]]))
    assert not unstable.stable and unstable.tau_max == np.inf and unstable.zeta_min < 0


def test_open_loop_jacobian_matches_flex_model_linearize():
    """Single link at rest, no gravity: A0 equals modes.linearize (hinged), an independent
    implementation (static tangent stiffness); Bu is B^-1 G^T."""
    model = FlexArmModel(load_arm("seed000_table3", vars_per_link=4))
    A0, Bu = open_loop_jacobian(model, np.zeros(model.nq), np.zeros(model.nq), [0.0])
    ref = linearize(model, [0.0], joints="hinged")
    scale = np.max(np.abs(ref.A))
    np.testing.assert_allclose(A0, ref.A, atol=1e-6 * scale)
    np.testing.assert_allclose(Bu, ref.B[:, :1], rtol=1e-9, atol=1e-12)


def test_closed_loop_matrix_equals_finite_differences(section_f_model, section_f_quasi_static):
    model, data = section_f_model, section_f_quasi_static
    nom = NominalTrajectory.from_data(model, data)
    q, v, tau, _, _ = nom.at(7.3)
    theta_hat, dtheta_hat = model.G @ q, model.G @ v
    kp, kd = pd_gains(np.array([3.0, 0.7]), np.array([2.0, 4.0]))

    def f(x):
        qq, vv = x[:model.nq], x[model.nq:]
        t_fb = tau + kp * (theta_hat - model.G @ qq) + kd * (dtheta_hat - model.G @ vv)
        return np.concatenate([vv, model.acceleration(qq, vv, model.G.T @ t_fb)])

    x0 = np.concatenate([q, v])
    n = len(x0)
    A_fd = np.empty((n, n))
    for j in range(n):
        e = np.zeros(n)
        e[j] = 1e-6
        A_fd[:, j] = (f(x0 + e) - f(x0 - e)) / 2e-6
    A0, Bu = open_loop_jacobian(model, q, v, tau)
    A = closed_loop_matrix(A0, Bu, model.G, kp, kd)
    np.testing.assert_allclose(A, A_fd, atol=1e-6 * np.max(np.abs(A_fd)))
    assert np.max(np.abs(v)) > 1e-3        # a moving point: Coriolis terms are in A0


def test_interpolated_matrices_close_to_exact(section_f_model, section_f_quasi_static):
    model = section_f_model
    lin = LinearizedTrajectory(model, NominalTrajectory.from_data(model,
                                                                  section_f_quasi_static))
    t = 7.321     # between the grid points 7.30 and 7.35 s, off the sample grid
    A0, Bu = lin.matrices(t)
    q, v, tau, _, _ = lin.nominal.at(t)
    A0x, Bux = open_loop_jacobian(model, q, v, tau)
    assert np.max(np.abs(A0 - A0x)) < 1e-3 * np.max(np.abs(A0x))
    assert np.max(np.abs(Bu - Bux)) < 1e-3 * np.max(np.abs(Bux))


def test_nominal_from_data_errors(section_f_model, section_f_quasi_static):
    from dataclasses import replace
    with pytest.raises(ValueError, match="q_nominal: got None"):
        NominalTrajectory.from_data(section_f_model, replace(section_f_quasi_static,
                                                             q_nominal=None))
    other = FlexArmModel(arm_from_dict({"name": "x", "links": [
        {"length": 1.0, "section": {"shape": "explicit", "EI": 1.0, "m": 1.0}}] * 2,
        "joints": [{"name": "a"}, {"name": "b"}]}))
    with pytest.raises(ValueError, match=r"joint_names: got \['joint1', 'joint2'\]"):
        NominalTrajectory.from_data(other, section_f_quasi_static)
