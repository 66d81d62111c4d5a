"""The arm under the PD of thesis Eq. (95), linearized along a nominal trajectory (thesis V.2).

Closed loop (thesis Eq. 27 with the law of Eq. 95 and the nominal torque as feed-forward)::

    B(q) a + c(q, v) + K q + D v = G^T tau,
    tau = tau_nom(t) + Kp (theta_hat(t) - G q) + Kd (theta_hat_dot(t) - G v),
    Kp = diag(h_i a_i^2),  Kd = diag(sqrt(2) h_i a_i),

with ``q = [alpha_1, q_f1, alpha_2, q_f2, ...]`` (flex_model ordering) and joint angles
``theta = G q``. With ``x = [q; v]`` and ``f(x, t)`` the right-hand side, the variation
``dx = x - x_nom(t)`` obeys ``dx' = A(t) dx`` to first order, where

    A(t) = A0(t) - Bu(t) [Kp G, Kd G],   Bu = [0; B(q_nom)^-1 G^T],

``A0`` being the Jacobian of ``f`` with the torque held at ``tau_nom`` (central differences
of the model's ``acceleration``) evaluated at ``x_nom(t) = [q_nom(t); v_nom(t)]``. The
feedback term is exact because the law is linear in ``(q, v)`` and vanishes on the nominal
trajectory (``theta_hat = G q_nom``); a gain schedule ``Kp(theta)`` contributes nothing more
to first order for the same reason.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.trajectory import JointTrajectoryData

SQRT2 = float(np.sqrt(2.0))


def pd_gains(h, a) -> tuple[np.ndarray, np.ndarray]:
    """Joint stiffness and damping of thesis Eq. (95): ``Kp = h a^2``, ``Kd = sqrt(2) h a``.

    With a unit joint inertia the loop is ``s^2 + sqrt(2) a s + a^2``: natural frequency
    ``a`` (rad/s) and damping ratio ``1/sqrt(2)``; ``h`` (kg m^2) scales it to the arm.
    """
    h = np.asarray(h, float)
    a = np.asarray(a, float)
    return h * a * a, SQRT2 * h * a


@dataclass
class NominalTrajectory:
    """Nominal state and input on the sample grid ``t`` (s).

    ``q`` (N, nq) and ``v`` (N, nq) the generalized coordinates and velocities, ``tau``
    (N, n_joints) the nominal joint torques (N m), ``theta``/``theta_dot`` the joint angles
    (rad) and rates (rad/s) the controller tracks.
    """

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray

    @classmethod
    def from_data(cls, model: FlexArmModel, data: JointTrajectoryData) -> "NominalTrajectory":
        """From a planner trajectory; ``v`` is the time derivative of ``q_nominal``
        (second-order finite differences on the sample grid)."""
        if data.q_nominal is None:
            raise ValueError("q_nominal: got None; expected the nominal generalized "
                             f"coordinates, shape ({len(data.t)}, {model.nq})")
        q = np.asarray(data.q_nominal, float)
        if q.shape != (len(data.t), model.nq) or not np.all(np.isfinite(q)):
            raise ValueError(f"q_nominal: got shape {q.shape}; expected ({len(data.t)}, "
                             f"{model.nq}) finite values for arm {model.arm.name}")
        if list(data.joint_names) != list(model.arm.joint_names):
            raise ValueError(f"joint_names: got {list(data.joint_names)}; expected the "
                             f"arm's {model.arm.joint_names}")
        v = np.gradient(q, data.t, axis=0, edge_order=2) if len(data.t) > 2 else \
            np.zeros_like(q)
        return cls(t=np.asarray(data.t, float), q=q, v=v, tau=np.asarray(data.efforts, float),
                   theta=np.asarray(data.positions, float),
                   theta_dot=np.asarray(data.velocities, float))

    def at(self, t: float):
        """(q, v, tau, theta, theta_dot) at time t: linear interpolation, held outside."""
        t = float(np.clip(t, self.t[0], self.t[-1]))
        k = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 1))
        if k == len(self.t) - 1:
            return self.q[k], self.v[k], self.tau[k], self.theta[k], self.theta_dot[k]
        w = (t - self.t[k]) / (self.t[k + 1] - self.t[k])
        return tuple((1 - w) * arr[k] + w * arr[k + 1]
                     for arr in (self.q, self.v, self.tau, self.theta, self.theta_dot))


def open_loop_jacobian(model: FlexArmModel, q, v, tau, eps: float = 1e-6):
    """``(A0, Bu)`` at the state ``(q, v)`` with the joint torques ``tau`` held.

    ``A0 = d f / d x`` (2 nq x 2 nq) by central differences of
    ``a = B^-1 (G^T tau - c - K q - D v)``; ``Bu = d f / d tau = [0; B^-1 G^T]``.
    """
    q = np.asarray(q, float)
    v = np.asarray(v, float)
    nq = model.nq
    Q = model.G.T @ np.asarray(tau, float)
    A0 = np.zeros((2 * nq, 2 * nq))
    A0[:nq, nq:] = np.eye(nq)
    for j in range(nq):
        for block, base in ((0, q), (1, v)):
            hj = eps * max(1.0, abs(base[j]))
            xp, xm = base.copy(), base.copy()
            xp[j] += hj
            xm[j] -= hj
            if block == 0:
                d = model.acceleration(xp, v, Q) - model.acceleration(xm, v, Q)
            else:
                d = model.acceleration(q, xp, Q) - model.acceleration(q, xm, Q)
            A0[nq:, block * nq + j] = d / (2 * hj)
    Bu = np.zeros((2 * nq, model.n_links))
    Bu[nq:] = np.linalg.solve(model.mass_matrix(q), model.G.T)
    return A0, Bu


def closed_loop_matrix(A0, Bu, G, kp, kd) -> np.ndarray:
    """``A = A0 - Bu [diag(kp) G, diag(kd) G]`` (the Eq. 95 feedback, see module doc)."""
    n = G.shape[0]
    kp = np.broadcast_to(np.asarray(kp, float), (n,))
    kd = np.broadcast_to(np.asarray(kd, float), (n,))
    F = np.hstack([kp[:, None] * G, kd[:, None] * G])
    return A0 - Bu @ F


@dataclass(frozen=True)
class EigenSummary:
    """Frozen-time stability figures of a closed-loop matrix.

    ``zeta_min``: smallest damping ratio ``-Re(l)/|l|`` over the eigenvalues (negative if
    one is unstable); ``tau_max``: largest time constant ``1/(-Re l)`` (s; ``inf`` if an
    eigenvalue has ``Re l >= 0``); ``decay_rate``: ``-max Re l`` (1/s, > 0 when stable).
    """

    zeta_min: float
    tau_max: float
    decay_rate: float

    @property
    def stable(self) -> bool:
        return self.decay_rate > 0


def eigen_summary(A) -> EigenSummary:
    """ζ_min, τ_max and the decay rate of ``A`` (thesis V.2's two design figures)."""
    lam = np.linalg.eigvals(A)
    mag = np.abs(lam)
    zeta = np.where(mag > 0, -lam.real / np.where(mag > 0, mag, 1.0), 0.0)
    sigma = -float(np.max(lam.real))
    tau_max = 1.0 / sigma if sigma > 0 else float("inf")
    return EigenSummary(zeta_min=float(np.min(zeta)), tau_max=tau_max, decay_rate=sigma)


class LinearizedTrajectory:
    """``A0(t)`` and ``Bu(t)`` on a time grid along a nominal trajectory.

    The nominal trajectory of thesis V.3 is slow compared with the closed-loop dynamics, so
    ``A0`` and ``Bu`` are interpolated linearly between grid points ``grid_period`` apart
    (the tests check this against the Jacobian computed at the query time).
    """

    def __init__(self, model: FlexArmModel, nominal: NominalTrajectory,
                 grid_period: float = 0.05):
        if not grid_period > 0:
            raise ValueError(f"grid_period: got {grid_period!r}; expected a time > 0 s")
        self.model = model
        self.nominal = nominal
        t0, t1 = float(nominal.t[0]), float(nominal.t[-1])
        n = max(2, int(np.ceil((t1 - t0) / grid_period - 1e-9)) + 1)
        self.t = np.linspace(t0, t1, n)
        A0, Bu = [], []
        for tk in self.t:
            q, v, tau, _, _ = nominal.at(tk)
            a0, bu = open_loop_jacobian(model, q, v, tau)
            A0.append(a0)
            Bu.append(bu)
        self.A0 = np.array(A0)
        self.Bu = np.array(Bu)

    def matrices(self, t: float):
        """(A0, Bu) at time t (linear interpolation on the grid, held outside)."""
        t = float(np.clip(t, self.t[0], self.t[-1]))
        k = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2))
        w = (t - self.t[k]) / (self.t[k + 1] - self.t[k])
        return ((1 - w) * self.A0[k] + w * self.A0[k + 1],
                (1 - w) * self.Bu[k] + w * self.Bu[k + 1])

    def closed_loop(self, t: float, kp, kd) -> np.ndarray:
        A0, Bu = self.matrices(t)
        return closed_loop_matrix(A0, Bu, self.model.G, kp, kd)
