"""The driven-link Kalman filter: a link's first clamped mode driven by its hub's measured
motion (issue 45; docs/estimation.md, "Real Quanser arm").

A link whose root turns with the hub obeys, in its first clamped mode (base excitation),

    d'' + 2 zeta w d' + w^2 d = -gain theta'' + n_d

with d the tip deflection and n_d the link's model error (white, ``link_noise`` m/s^2 per
sqrt(Hz)). The hub is not modelled by its motor and friction (a stuck or slipping hub is
what the motor model gets wrong) but kinematically: theta''' = n_j, white jerk of
``jerk_noise`` rad/s^3 per sqrt(Hz), pinned by the encoder (its quantum adds quantum^2/12
to the variance). State x = [theta, theta', theta'', d, d']: linear and time-invariant, so
the discretization is exact (Van Loan: expm of the block [[-A, Q], [0, A^T]] T) and the gain
tends to the discrete Riccati equation's (the test checks both).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.linalg import expm


@dataclass(frozen=True)
class LinkMode:
    """The link's first clamped mode as its hub drives it: frequency (Hz), damping ratio,
    gain (m per rad/s^2 of hub acceleration)."""

    frequency_hz: float
    damping_ratio: float
    gain: float

    def __post_init__(self):
        if not self.frequency_hz > 0 or self.damping_ratio < 0:
            raise ValueError(f"LinkMode: frequency {self.frequency_hz} Hz must be > 0 and "
                             f"damping ratio {self.damping_ratio} >= 0")


def continuous_model(mode: LinkMode, jerk_noise: float, link_noise: float):
    """(A, Q): x' = A x + w, E[w w^T] = Q delta(t), x = [theta, theta', theta'', d, d']."""
    w = 2 * np.pi * mode.frequency_hz
    A = np.zeros((5, 5))
    A[0, 1] = A[1, 2] = A[3, 4] = 1.0
    A[4] = [0.0, 0.0, -mode.gain, -w * w, -2 * mode.damping_ratio * w]
    Q = np.diag([0.0, 0.0, jerk_noise ** 2, 0.0, link_noise ** 2])
    return A, Q


def discretize(A, Q, T: float):
    """(F, Q_d) of x' = A x + w over T, exact (Van Loan 1978)."""
    n = len(A)
    M = np.zeros((2 * n, 2 * n))
    M[:n, :n], M[:n, n:], M[n:, n:] = -A, Q, A.T
    E = expm(M * T)
    F = E[n:, n:].T
    Qd = F @ E[:n, n:]
    return F, 0.5 * (Qd + Qd.T)


@dataclass
class DrivenLinkResult:
    """The estimate over time: hub angle, rate, acceleration, tip deflection d and their
    stds; the innovations' NIS (one reading per sample)."""

    theta: np.ndarray
    theta_std: np.ndarray
    rate: np.ndarray
    acceleration: np.ndarray
    deflection: np.ndarray
    deflection_std: np.ndarray
    nis: np.ndarray


def estimate_driven_link(theta_meas, T: float, mode: LinkMode, jerk_noise: float,
                         link_noise: float, encoder_std: float, quantum: float = 0.0,
                         initial_deflection_std: float = 0.005) -> DrivenLinkResult:
    """Kalman filter of the driven link over an encoder record (one angle per sample,
    rad): starts at rest at the first reading, the deflection with
    ``initial_deflection_std`` (m)."""
    F, Qd = discretize(*continuous_model(mode, jerk_noise, link_noise), T)
    R = encoder_std ** 2 + quantum ** 2 / 12.0
    y = np.ascontiguousarray(theta_meas, dtype=float)
    P0 = np.diag([R, 1e-4, 1e-2, initial_deflection_std ** 2, 1e-4])
    out = _filter(F, Qd, R, y, P0)
    sd = np.sqrt(np.maximum(out[:, [1, 5]], 0.0))
    return DrivenLinkResult(out[:, 0], sd[:, 0], out[:, 2], out[:, 3], out[:, 4], sd[:, 1],
                            out[:, 6])


@njit(cache=True)
def _filter(F, Qd, R, y, P0):
    """The filter's loop (one scalar reading of x[0] per sample): rows of theta, its
    variance, theta', theta'', d, its variance and the NIS."""
    x = np.zeros(5)
    x[0] = y[0]
    P = P0.copy()
    out = np.empty((len(y), 7))
    for k in range(len(y)):
        S = P[0, 0] + R
        Kg = P[:, 0] / S
        nu = y[k] - x[0]
        x = x + Kg * nu
        P = P - np.outer(Kg, P[0])
        out[k, 0], out[k, 1], out[k, 2], out[k, 3] = x[0], P[0, 0], x[1], x[2]
        out[k, 4], out[k, 5], out[k, 6] = x[3], P[3, 3], nu * nu / S
        x = F @ x
        P = F @ P @ F.T + Qd
    return out
