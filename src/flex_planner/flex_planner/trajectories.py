"""Joint and tip trajectories: thesis V.3 splines and seed 002's Eqs. (27)-(30).

- :func:`spline_joint_trajectory`: cubic splines through the inverted joint angles at the
  waypoint times (thesis V.3, Fig. 40), zero velocity at both ends (rest to rest).
- :func:`polynomial_fourier`: theta(t) = sum_{j=0..4} lambda_j t^j + a_0 cos(pi t / t_f)
  with theta(0), theta(t_f) given and zero velocity and acceleration at both ends
  (seed 002 Eqs. 27-29).
- :func:`trapezoidal_line`: a straight tip line at trapezoidal speed: constant
  acceleration a, cruise at v_max, constant deceleration (seed 002 Eq. 30; its example
  (0, 1) -> (0.75, 1.5) m, v_max = 0.75 m/s, a = 3 m/s^2 lasts T = 1.452 s).

Every function samples at ``t0 + k * sample_period`` and at the final time itself (the
end of the motion is always a sample; the last interval may be shorter) and returns
positions, velocities and accelerations, SI units and rad.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline


@dataclass
class SampledTrajectory:
    """Samples t (s) of positions p, velocities v and accelerations a, shape (N, dim)."""

    t: np.ndarray
    p: np.ndarray
    v: np.ndarray
    a: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


def sample_times(t0: float, t_final: float, sample_period: float) -> np.ndarray:
    """``t0, t0 + dt, ...`` and ``t_final`` itself as the last sample (a last interval
    shorter than ``dt`` when ``dt`` does not divide the duration; one within 1e-6 dt of
    ``t_final`` is merged into it)."""
    if not (np.isfinite(sample_period) and sample_period > 0):
        raise ValueError(f"sample_period: got {sample_period!r}; expected a time > 0 s")
    if not t_final > t0:
        raise ValueError(f"t_final: got {float(t_final)!r} s; expected a time after t0 = "
                         f"{float(t0)!r} s")
    n = int(np.floor((t_final - t0) / sample_period + 1e-6))
    t = t0 + sample_period * np.arange(n + 1)
    if t_final - t[-1] > 1e-6 * sample_period:
        t = np.append(t, t_final)
    t[-1] = t_final
    return t


def check_times(times, n_points: int | None = None) -> np.ndarray:
    """Strictly increasing finite times (s); errors name the first bad index."""
    times = np.asarray(times, float)
    if times.ndim != 1 or len(times) < 2 or (n_points is not None and len(times) != n_points):
        expected = f"{n_points}" if n_points is not None else "at least 2"
        raise ValueError(f"times: got shape {times.shape}; expected {expected} times (s), "
                         "one per waypoint and at least 2")
    if not np.all(np.isfinite(times)):
        k = int(np.flatnonzero(~np.isfinite(times))[0])
        raise ValueError(f"times[{k}]: got {float(times[k])!r}; expected a finite time (s)")
    bad = np.flatnonzero(np.diff(times) <= 0)
    if len(bad):
        k = int(bad[0]) + 1
        raise ValueError(f"times[{k}]: got {float(times[k])!r} s after "
                         f"{float(times[k - 1])!r} s; expected strictly increasing times")
    return times


def joint_spline(times, joint_angles) -> CubicSpline:
    """Cubic splines theta(t) through ``joint_angles`` (N, n) at ``times`` (N,), zero
    velocity at both ends (thesis V.3, Fig. 40)."""
    times = check_times(times)
    theta = np.asarray(joint_angles, float)
    if theta.ndim != 2 or len(theta) != len(times):
        raise ValueError(f"joint_angles: got shape {theta.shape}; expected ({len(times)}, n)")
    return CubicSpline(times, theta, axis=0, bc_type="clamped")


def sample_spline(spline: CubicSpline, t) -> SampledTrajectory:
    """Positions, velocities and accelerations of a spline at the times ``t``."""
    return SampledTrajectory(t, spline(t), spline(t, 1), spline(t, 2))


def spline_joint_trajectory(times, joint_angles, sample_period: float) -> SampledTrajectory:
    """:func:`joint_spline` sampled every ``sample_period`` over the waypoint times."""
    spline = joint_spline(times, joint_angles)
    return sample_spline(spline, sample_times(spline.x[0], spline.x[-1], sample_period))


def polynomial_fourier_coefficients(theta0: float, theta_f: float, t_f: float):
    """(lambda_0..lambda_4, a_0) of seed 002 Eq. (27) for the boundary conditions of
    Eq. (28): theta(0) = theta0, theta(t_f) = theta_f, zero rates and accelerations."""
    if not (np.isfinite(t_f) and t_f > 0):
        raise ValueError(f"t_f: got {t_f!r}; expected a motion time > 0 s")
    w = np.pi / t_f
    rows, rhs = [], []
    for t, value in ((0.0, theta0), (t_f, theta_f)):
        rows.append([1.0, t, t ** 2, t ** 3, t ** 4, np.cos(w * t)])
        rows.append([0.0, 1.0, 2 * t, 3 * t ** 2, 4 * t ** 3, -w * np.sin(w * t)])
        rows.append([0.0, 0.0, 2.0, 6 * t, 12 * t ** 2, -w * w * np.cos(w * t)])
        rhs += [value, 0.0, 0.0]
    return np.linalg.solve(np.array(rows), np.array(rhs))


def polynomial_fourier(theta0, theta_f, t_f: float, sample_period: float,
                       hold: float = 0.0) -> SampledTrajectory:
    """Joint motion of seed 002 Eqs. (27)-(29) for every joint (theta0, theta_f arrays, rad)
    over [0, t_f], then held at theta_f for ``hold`` seconds."""
    theta0, theta_f = np.atleast_1d(theta0).astype(float), np.atleast_1d(theta_f).astype(float)
    t = sample_times(0.0, t_f, sample_period)
    if hold > 0:
        t = np.concatenate([t, t_f + sample_times(0.0, hold, sample_period)[1:]])
    coef = np.array([polynomial_fourier_coefficients(a, b, t_f)
                     for a, b in zip(theta0, theta_f)])            # (n, 6)
    tm = np.minimum(t, t_f)[:, None]
    w = np.pi / t_f
    lam, a0 = coef[:, :5], coef[:, 5]
    p = sum(lam[:, j] * tm ** j for j in range(5)) + a0 * np.cos(w * tm)
    v = sum(j * lam[:, j] * tm ** (j - 1) for j in range(1, 5)) - a0 * w * np.sin(w * tm)
    a = (sum(j * (j - 1) * lam[:, j] * tm ** (j - 2) for j in range(2, 5))
         - a0 * w * w * np.cos(w * tm))
    after = t > t_f
    v[after], a[after] = 0.0, 0.0
    return SampledTrajectory(t, p, v, a)


def trapezoidal_duration(distance: float, v_max: float, accel: float) -> float:
    """Duration (s) of a rest-to-rest trapezoidal (or triangular) speed profile."""
    if not (v_max > 0 and accel > 0):
        raise ValueError(f"v_max, accel: got {v_max!r}, {accel!r}; expected both > 0")
    if distance * accel <= v_max * v_max:       # triangular: v_max never reached
        return 2.0 * np.sqrt(distance / accel)
    return distance / v_max + v_max / accel


def trapezoidal_line(start, end, v_max: float, accel: float, sample_period: float,
                     hold: float = 0.0) -> SampledTrajectory:
    """Straight tip line from ``start`` to ``end`` (m) with the speed of seed 002 Eq. (30),
    then held at ``end`` for ``hold`` seconds. Samples of tip position, velocity and
    acceleration (N, 2)."""
    start, end = np.asarray(start, float), np.asarray(end, float)
    d = float(np.linalg.norm(end - start))
    if d <= 0:
        raise ValueError(f"end: got {end.tolist()} m, the start itself; expected another point")
    u = (end - start) / d
    T = trapezoidal_duration(d, v_max, accel)
    ta = min(v_max / accel, T / 2.0)
    vc = accel * ta
    t = sample_times(0.0, T, sample_period)
    if hold > 0:
        t = np.concatenate([t, T + sample_times(0.0, hold, sample_period)[1:]])
    s = np.where(t < ta, 0.5 * accel * t ** 2,
                 np.where(t < T - ta, 0.5 * accel * ta ** 2 + vc * (t - ta),
                          d - 0.5 * accel * np.clip(T - t, 0.0, None) ** 2))
    sd = np.where(t < ta, accel * t, np.where(t < T - ta, vc, accel * np.clip(T - t, 0, None)))
    sdd = np.where(t < ta, accel, np.where(t < T - ta, 0.0, -accel))
    sdd = np.where(t > T, 0.0, sdd)
    s = np.minimum(s, d)
    return SampledTrajectory(t, start + s[:, None] * u, sd[:, None] * u, sdd[:, None] * u)
