"""Admissible nominal input along a desired joint trajectory (thesis Ch. V.1, Fig. 38).

The arm obeys (thesis Eq. 27, flex_model.dynamics)

    B(q) a + c(q, v) + D v + K q = H tau + J_tip^T F + e_tip C,      H = H_c = G^T.

Premultiplying by T^T with T = [H_perp  H] (V.1) splits it into nq - n homogeneous
equations, free of the joint torques because H_perp^T H = 0,

    H_perp^T ( B a + c + D v + K q - J_tip^T F - e_tip C ) = 0,                      (1)

and n equations that give the torques once q(t) is known,

    tau = (H^T H)^-1 H^T ( B a + c + D v + K q - J_tip^T F - e_tip C ).               (2)

H_perp is the block S_f of the joint-coordinate map q = S_theta theta + S_f q_f (the
columns of flex_model's ``joint_coordinate_matrix`` that belong to the deformation
variables): G S_f = 0, and S_f^T B S_f is the positive definite mass matrix of the
deformation variables with the joints held, so (1) is an ODE in q_f driven by the desired
theta(t) (it is seed 002's Eq. 16 as well: the flexible part of a flexible-link,
rigid-joint arm under a prescribed joint motion). It is integrated with the
generalized-alpha method (Chung-Hulbert, Arnold-Bruls form, as flex_model's fixed-step
simulator) with the equations satisfied exactly at every sample, so the torques (2) are
those of the model at the samples. Units: s, rad, m, N m.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from flex_model import kernels
from flex_model import integrators, iteration_matrix
from flex_model.dynamics import FlexArmModel
from flex_model.solvers import galpha as solvers_galpha
from flex_model.solvers.galpha import galpha_abar, galpha_coefficients
from flex_model.kernels import inverse_dynamics, link_origins, tip_jacobian
from flex_model.statics import TipLoad, static_equilibrium

from flex_model import numba_cache as _numba_cache
from .inverse_statics import check_rigid_joints
from .trajectories import SampledTrajectory

#: Newton tolerance on the position correction of one step (m or rad)
STEP_TOLERANCE = 1e-13
#: refresh the iteration matrix at least this often (steps)
REFRESH_EVERY = 25


@njit(cache=True)
def _generalized_force(q, v, a, K, D, gx, gy, P, fx, fy, torque, e_tip):
    """B a + c + D v + K q - J^T F - e_tip C (thesis Eq. 27 without H tau)."""
    r = inverse_dynamics(q, v, a, gx, gy, P) + D @ v + K @ q
    if fx != 0.0 or fy != 0.0:
        J = tip_jacobian(q, P)
        r -= J[0] * fx + J[1] * fy
    if torque != 0.0:
        r -= torque * e_tip
    return r


@njit(cache=True)
def _integrate(t, th, thd, thdd, zf0, vf0, St, Sf, K, D, Kff, Dff, torque_map, gx, gy, P,
               fx, fy, torque, e_tip, rho_inf, tol, refresh):
    """Generalized-alpha on Eq. (1) with theta prescribed; Eq. (2) at every sample.

    Returns (Q, V, A, tau, tip, worst balance residual, status, index); status 1 means
    Newton did not converge at sample ``index``.
    """
    n_s, nq = t.shape[0], St.shape[0]
    nf = Sf.shape[1]
    Q = np.zeros((n_s, nq))
    V = np.zeros((n_s, nq))
    A = np.zeros((n_s, nq))
    tau = np.zeros((n_s, torque_map.shape[0]))
    tip = np.zeros((n_s, 2))
    SfT = np.ascontiguousarray(Sf.T)
    zf, vf = zf0.copy(), vf0.copy()
    Q[0] = St @ th[0] + Sf @ zf
    V[0] = St @ thd[0] + Sf @ vf
    base_a = St @ thdd[0]
    r0 = SfT @ _generalized_force(Q[0], V[0], base_a, K, D, gx, gy, P, fx, fy, torque, e_tip)
    acc = -np.linalg.solve(SfT @ kernels.mass_matrix(Q[0], P) @ Sf, r0)
    A[0] = base_a + Sf @ acc
    abar = acc.copy()
    inv = np.zeros((nf, nf))
    h_used = -1.0
    age = refresh
    for k in range(1, n_s):
        h = t[k] - t[k - 1]
        c = galpha_coefficients(rho_inf, h)
        bp, gp, beta, gam = c.bp, c.gp, c.beta, c.gam
        if h != h_used or age >= refresh:
            M = SfT @ kernels.mass_matrix(Q[k - 1], P) @ Sf
            inv = np.ascontiguousarray(np.linalg.inv(M + gp * Dff + bp * Kff))
            h_used = h
            age = 0
        age += 1
        q_base = St @ th[k]
        v_base = St @ thd[k]
        a_base = St @ thdd[k]
        zf_pred = zf + h * vf + h * h * (0.5 - beta) * abar
        vf_pred = vf + h * (1.0 - gam) * abar
        a1 = acc.copy()
        ok = False
        for it in range(40):
            abar1 = galpha_abar(a1, acc, abar, c)
            q1 = q_base + Sf @ (zf_pred + h * h * beta * abar1)
            v1 = v_base + Sf @ (vf_pred + h * gam * abar1)
            res = SfT @ _generalized_force(q1, v1, a_base + Sf @ a1, K, D, gx, gy, P,
                                           fx, fy, torque, e_tip)
            da = -(inv @ res)
            a1 += da
            if bp * np.max(np.abs(da)) <= tol:
                ok = True
                break
        if not ok:
            return Q, V, A, tau, tip, 0.0, 1, k
        if it > 2:
            age = refresh  # slow convergence: refresh the iteration matrix next step
        abar1 = galpha_abar(a1, acc, abar, c)
        zf = zf_pred + h * h * beta * abar1
        vf = vf_pred + h * gam * abar1
        acc = a1
        abar = abar1
        Q[k] = q_base + Sf @ zf
        V[k] = v_base + Sf @ vf
        A[k] = a_base + Sf @ acc
    worst = 0.0
    for k in range(n_s):
        r = _generalized_force(Q[k], V[k], A[k], K, D, gx, gy, P, fx, fy, torque, e_tip)
        tau[k] = torque_map @ r
        worst = max(worst, np.max(np.abs(SfT @ r)))
        tip[k] = link_origins(Q[k], P)[-1]
    return Q, V, A, tau, tip, worst, 0, 0


_numba_cache.guard([_generalized_force, _integrate],
                   [kernels.__file__, integrators.__file__, iteration_matrix.__file__,
                    solvers_galpha.__file__])


@dataclass
class NominalInput:
    """Nominal motion and torque at the samples ``t`` (s).

    ``theta, theta_dot, theta_ddot`` (N, n) joint angles (rad) and derivatives; ``q, v,
    a`` (N, nq) generalized coordinates with the nominal deflections and their rates;
    ``tau`` (N, n) nominal joint torques (N m); ``tip`` (N, 2) nominal tip path (m);
    ``balance_residual`` the largest |H_perp^T (...)| of Eq. (1) at the samples (N or N m).
    """

    t: np.ndarray
    theta: np.ndarray
    theta_dot: np.ndarray
    theta_ddot: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    tip: np.ndarray
    balance_residual: float


class NominalInputSolver:
    """Eqs. (1)-(2) above for one model and one known tip load."""

    def __init__(self, model: FlexArmModel, tip_load: TipLoad | None = None):
        check_rigid_joints(model)
        self.model = model
        self.load = tip_load if tip_load is not None else TipLoad()
        self.T = T = model.joint_coordinate_matrix()
        self.off = np.asarray(model.off)
        self.free = np.setdiff1d(np.arange(model.nq), self.off)
        self.S_theta, self.H_perp = T[:, self.off], T[:, self.free]
        H = model.input_matrix()
        self.torque_map = np.linalg.solve(H.T @ H, H.T)        # (H^T H)^-1 H^T
        self.K_ff = self.H_perp.T @ model.K @ self.H_perp
        self.D_ff = self.H_perp.T @ model.D @ self.H_perp
        self.force = np.asarray(self.load.force, float)
        self.e_tip = np.asarray(model.tip_torque_vector(), float)

    def static_flex(self, theta0) -> np.ndarray:
        """Deformation variables of the clamped static equilibrium at theta0 (rest start)."""
        res = static_equilibrium(self.model, theta0, joints="clamped", load=self.load)
        return np.linalg.solve(self.T, res.q)[self.free]

    def solve(self, traj: SampledTrajectory, flex0=None, flex_rate0=None, *,
              rho_inf: float = 1.0) -> NominalInput:
        """Integrate Eq. (1) along ``traj`` (joint angles, rates, accelerations at its
        samples) from ``flex0`` (default: the clamped static equilibrium at theta(0)) and
        ``flex_rate0`` (default 0), and evaluate Eq. (2) at every sample."""
        if not 0.0 <= rho_inf <= 1.0:
            raise ValueError(f"rho_inf: got {rho_inf!r}; expected 0 <= rho_inf <= 1")
        m = self.model
        c = np.ascontiguousarray
        zf = self.static_flex(traj.p[0]) if flex0 is None else np.asarray(flex0, float)
        vf = np.zeros(len(self.free)) if flex_rate0 is None else np.asarray(flex_rate0, float)
        Q, V, A, tau, tip, worst, status, k = _integrate(
            c(traj.t, float), c(traj.p, float), c(traj.v, float), c(traj.a, float),
            c(zf, float), c(vf, float), c(self.S_theta), c(self.H_perp), c(m.K), c(m.D),
            c(self.K_ff), c(self.D_ff), c(self.torque_map), float(m.gravity[0]),
            float(m.gravity[1]), m.P, float(self.force[0]), float(self.force[1]),
            float(self.load.torque), c(self.e_tip, float), float(rho_inf), STEP_TOLERANCE,
            REFRESH_EVERY)
        if status:
            raise RuntimeError(f"nominal input: Newton did not converge at t = "
                               f"{traj.t[k]:.6g} s (step {traj.t[k] - traj.t[k - 1]:.3g} s); "
                               "reduce the integration step")
        return NominalInput(t=traj.t.copy(), theta=traj.p.copy(), theta_dot=traj.v.copy(),
                            theta_ddot=traj.a.copy(), q=Q, v=V, a=A, tau=tau, tip=tip,
                            balance_residual=float(worst))
