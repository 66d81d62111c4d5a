"""Joint and tip trajectories: thesis V.3 splines, seed 002 Eqs. (27)-(30), rigid kinematics."""
import numpy as np
import pytest

from flex_planner.rigid_kinematics import (elbow_bend, forward_kinematics, rigid_path_inverse,
                                           two_link_ik)
from flex_planner.trajectories import (check_times, polynomial_fourier,
                                       polynomial_fourier_coefficients, sample_times,
                                       spline_joint_trajectory, trapezoidal_duration,
                                       trapezoidal_line)


def test_polynomial_fourier_meets_the_boundary_conditions_of_eq_28():
    th0, thf = np.radians([60.0, -120.0]), np.radians([-45.0, -90.0])   # seed 002 Eq. 29
    traj = polynomial_fourier(th0, thf, 1.5, 1e-3, hold=0.5)
    k_f = int(np.argmin(np.abs(traj.t - 1.5)))
    np.testing.assert_allclose(traj.p[0], th0, atol=1e-12)
    np.testing.assert_allclose(traj.p[k_f], thf, atol=1e-12)
    for arr in (traj.v, traj.a):
        np.testing.assert_allclose(arr[[0, k_f]], 0.0, atol=1e-10)
    np.testing.assert_allclose(traj.p[k_f:], np.tile(thf, (len(traj.t) - k_f, 1)), atol=1e-12)
    # the velocity and acceleration are the derivatives of the position
    np.testing.assert_allclose(np.gradient(traj.p[:k_f], traj.t[:k_f], axis=0)[1:-1],
                               traj.v[1:k_f - 1], atol=2e-5)
    np.testing.assert_allclose(np.gradient(traj.v[:k_f], traj.t[:k_f], axis=0)[1:-1],
                               traj.a[1:k_f - 1], atol=2e-5)


def test_polynomial_fourier_uses_its_cosine_term():
    lam0, lam1, lam2, lam3, lam4, a0 = polynomial_fourier_coefficients(0.0, 1.0, 2.0)
    # six conditions, six unknowns: a unique solution with both parts active
    assert abs(a0) > 1e-3 and abs(lam3) > 1e-3
    assert lam0 + a0 == pytest.approx(0.0, abs=1e-14)


def test_trapezoidal_line_of_seed_002_path_2():
    start, end = (0.0, 1.0), (0.75, 1.5)
    d = np.hypot(0.75, 0.5)
    assert round(trapezoidal_duration(d, 0.75, 3.0), 3) == 1.452      # seed 002 text
    line = trapezoidal_line(start, end, 0.75, 3.0, 1e-3)
    assert line.t[-1] == pytest.approx(1.4518504, abs=1e-7)
    np.testing.assert_allclose(line.p[-1], end, atol=1e-12)
    speed = np.linalg.norm(line.v, axis=1)
    assert speed.max() == pytest.approx(0.75, abs=1e-12)
    assert np.max(np.linalg.norm(line.a, axis=1)) == pytest.approx(3.0)
    # straight: every sample on the segment
    u = np.array(end) - np.array(start)
    cross = (line.p[:, 0] - start[0]) * u[1] - (line.p[:, 1] - start[1]) * u[0]
    assert np.max(np.abs(cross)) < 1e-12
    # the position is the integral of the speed
    s = np.linalg.norm(line.p - start, axis=1)
    np.testing.assert_allclose(np.gradient(s, line.t)[1:-1], speed[1:-1], atol=3e-3)


def test_triangular_profile_when_v_max_is_never_reached():
    assert trapezoidal_duration(0.1, 1.0, 1.0) == pytest.approx(2 * np.sqrt(0.1))


def test_spline_passes_the_waypoints_at_rest_ends():
    times = [0.0, 5.0, 10.0, 15.0]
    theta = np.array([[0.1, 0.2], [0.5, -0.1], [0.3, 0.4], [0.0, 0.0]])
    traj = spline_joint_trajectory(times, theta, 1e-2)
    for tk, th in zip(times, theta):
        k = int(np.argmin(np.abs(traj.t - tk)))
        np.testing.assert_allclose(traj.p[k], th, atol=1e-12)
    np.testing.assert_allclose(traj.v[[0, -1]], 0.0, atol=1e-12)


def test_sample_times_end_on_the_final_time():
    t = sample_times(0.0, 1.0, 0.3)
    np.testing.assert_allclose(t, [0.0, 0.3, 0.6, 0.9, 1.0])
    assert len(sample_times(0.0, 15.0, 1e-3)) == 15001
    with pytest.raises(ValueError, match=r"sample_period: got -1.0; expected a time > 0 s"):
        sample_times(0.0, 1.0, -1.0)


def test_times_must_increase():
    with pytest.raises(ValueError, match=r"times\[2\]: got 4.0 s after 5.0 s; expected "
                       "strictly increasing times"):
        check_times([0.0, 5.0, 4.0])
    with pytest.raises(ValueError, match=r"times: got shape \(1,\)"):
        check_times([0.0])


def test_rigid_inverse_of_the_tip_line_is_exact():
    line = trapezoidal_line((0.0, 1.0), (0.75, 1.5), 0.75, 3.0, 1e-3)
    bend = elbow_bend(1.0, 1.0, (0.0, 1.0), "up")
    assert bend == -1              # tie (point above the base): "up" is the negative bend
    th, thd, thdd = rigid_path_inverse([1.0, 1.0], line.p, line.v, line.a, bend)
    np.testing.assert_allclose(forward_kinematics([1.0, 1.0], th), line.p, atol=1e-12)
    np.testing.assert_allclose(np.degrees(th[0]), [150.0, -120.0], atol=1e-9)
    tip_rate = np.gradient(forward_kinematics([1.0, 1.0], th), line.t, axis=0)
    np.testing.assert_allclose(tip_rate[1:-1], line.v[1:-1], atol=2e-3)
    with pytest.raises(ValueError, match="sample 0 at"):
        rigid_path_inverse([1.0, 1.0], [[3.0, 0.0]], [[0.0, 0.0]], [[0.0, 0.0]], 1)


def test_two_link_ik_branches_mirror_each_other():
    p = np.array([1.2, 0.7])
    up, down = two_link_ik(1.0, 1.0, p, -1), two_link_ik(1.0, 1.0, p, 1)
    for sol in (up, down):
        np.testing.assert_allclose(forward_kinematics([1.0, 1.0], sol), p, atol=1e-12)
    assert elbow_bend(1.0, 1.0, p, "up") == -1 and elbow_bend(1.0, 1.0, p, "down") == 1
    # to the left of the base the higher elbow has the positive bend
    assert elbow_bend(2.0, 2.0, (-1.0, -1.0), "up") == 1
