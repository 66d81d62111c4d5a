"""Natural frequencies, mode shapes and linearization about an equilibrium (thesis §II.6).

The arm is linearized in joint coordinates z (q with each alpha_i replaced by the joint
angle theta_i) about a static equilibrium, with the joints

- ``clamped``: theta removed from the coordinates,
- ``hinged``: theta free, the holding torques of the equilibrium kept constant,
- ``pd``: tau = Kp (theta_set - theta) - Kd theta_dot + holding torque.

By default gravity is an input of the linear model, not a preload (thesis §II.6: the model
is linearized about the unloaded configuration, gravity and tip loads acting as inputs);
``gravity_preload=True`` linearizes about the equilibrium under gravity instead, with its
geometric stiffness (needed, e.g., for a hinged arm hanging under gravity).

    M dz'' + C dz' + K_t dz = B_u du,        M = T^T B(q0) T

with ``K_t`` the tangent stiffness (elastic + gravity + PD), by central differences of the
exact force balance. Outputs of the state-space model: joint angles, tip x, y and
orientation, and the tip deflection of every link.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .dynamics import FlexArmModel
from .statics import TipLoad, static_equilibrium, static_residual


@dataclass
class LinearModel:
    """x' = A x + B u, y = C x + D u about an equilibrium q0 (x = [dz_free; dz_free'])."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    M: np.ndarray
    K: np.ndarray
    Cd: np.ndarray
    q0: np.ndarray
    free: np.ndarray            # indices of z kept as coordinates
    T: np.ndarray               # q = T z
    input_names: list
    output_names: list


def linearize(model: FlexArmModel, joint_angles=None, *, joints: str = "clamped", kp=None,
              kd=None, q0=None, gravity_preload: bool = False,
              eps: float = 1e-6) -> LinearModel:
    """Linearize about the static equilibrium at ``joint_angles`` (rad).

    Inputs: joint torques (N m; not for clamped joints), tip force x, y (N), tip torque
    (N m). The equilibrium is computed with the holding torques that make it one: zero
    for clamped and PD-held joints at rest without gravity.
    """
    if not gravity_preload:
        model = model.with_gravity((0.0, 0.0))
    nl, nq = model.n_links, model.nq
    theta_set = np.zeros(nl) if joint_angles is None else np.asarray(joint_angles, float)
    kp = np.zeros(nl) if kp is None else np.broadcast_to(np.asarray(kp, float), (nl,))
    kd = np.zeros(nl) if kd is None else np.broadcast_to(np.asarray(kd, float), (nl,))
    T = model.joint_coordinate_matrix()
    if q0 is None:
        if joints == "hinged":
            # hold the pose: equilibrium with clamped joints, then their reaction torques
            q0 = static_equilibrium(model, theta_set, joints="clamped").q
        else:
            q0 = static_equilibrium(model, theta_set, joints=joints, kp=kp).q
    q0 = np.asarray(q0, float)
    # holding torques: actuator torques that balance the equilibrium exactly
    r0 = static_residual(model, q0, np.zeros(nl), TipLoad())
    tau_hold = -np.linalg.lstsq(model.Ga.T, r0, rcond=None)[0]
    free = np.arange(nq) if joints != "clamped" else np.setdiff1d(np.arange(nq), model.off)
    z0 = np.linalg.solve(T, q0)

    def force(z):
        q = T @ z
        tau = tau_hold + (kp * (theta_set - model.Ga @ q) if joints == "pd" else 0.0)
        return T.T @ static_residual(model, q, tau, TipLoad())

    n = len(free)
    Kt = np.empty((nq, n))
    for c, j in enumerate(free):
        h = eps * max(1.0, abs(z0[j]))
        zp, zm = z0.copy(), z0.copy()
        zp[j] += h
        zm[j] -= h
        Kt[:, c] = -(force(zp) - force(zm)) / (2 * h)
    Kt = Kt[free]
    Kt = 0.5 * (Kt + Kt.T)
    Mz = (T.T @ model.mass_matrix(q0) @ T)[np.ix_(free, free)]
    # damping: structural, PD (through the actuator coordinates), joint springs, friction
    # slope and back-EMF at rest (flex_model.integrators.joint_tangent)
    from .integrators import joint_tangent
    from .inputs import JointPD, input_data
    pd = JointPD(kp, kd if joints == "pd" else np.zeros(nl), theta_set)
    Cj = joint_tangent(np.zeros(nq), input_data(model, pd, (), np.zeros(nl)))[1]
    Cz = (T.T @ (model.damping_matrix() + Cj) @ T)[np.ix_(free, free)]
    # inputs: actuator torques, tip force, tip torque
    Bq_tau = model.Ga.T
    Jt = model.tip_jacobian(q0)
    Bq = np.column_stack([Bq_tau, Jt.T, model.tip_torque_vector()])
    names_in = [f"{j}/torque" for j in model.arm.joint_names] + ["tip/force_x", "tip/force_y",
                                                                 "tip/torque"]
    if joints == "clamped":
        Bq = Bq[:, nl:]
        names_in = names_in[nl:]
    Bz = (T.T @ Bq)[free]
    Minv = np.linalg.inv(Mz)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv @ Kt, -Minv @ Cz]])
    B = np.vstack([np.zeros((n, Bz.shape[1])), Minv @ Bz])
    # outputs in terms of dz: joint angles, tip x, y, phi, link tip deflections
    Cq = np.vstack([model.G, Jt, model.tip_torque_vector()[None, :],
                    np.eye(nq)[[model.tip_deflection_index(i) for i in range(nl)]]])
    Cz_out = (Cq @ T)[:, free]
    C = np.hstack([Cz_out, np.zeros_like(Cz_out)])
    names_out = ([f"{j}/angle" for j in model.arm.joint_names] + ["tip/x", "tip/y", "tip/angle"]
                 + [f"{lk.name}/tip_deflection" for lk in model.arm.links])
    return LinearModel(A=A, B=B, C=C, D=np.zeros((C.shape[0], B.shape[1])), M=Mz, K=Kt,
                       Cd=Cz, q0=q0, free=free, T=T, input_names=names_in,
                       output_names=names_out)


@dataclass
class ModalResult:
    """Natural angular frequencies (rad/s), damping ratios and mode shapes (in q)."""

    omega: np.ndarray
    damping_ratio: np.ndarray
    shapes_q: np.ndarray        # (nq, n_modes): mode shapes as increments of q
    inertia_condition_number: float

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)

    def as_dict(self, count: int | None = None) -> dict:
        k = slice(0, count)
        return {"frequencies_hz": [float(f) for f in self.frequencies_hz[k]],
                "omega_rad_s": [float(w) for w in self.omega[k]],
                "damping_ratio": [float(z) for z in self.damping_ratio[k]],
                "inertia_condition_number": float(self.inertia_condition_number)}


def natural_modes(model: FlexArmModel, joint_angles=None, *, joints: str = "clamped",
                  kp=None, kd=None, q0=None, gravity_preload: bool = False) -> ModalResult:
    """Natural frequencies and modes about an equilibrium, lowest first.

    Undamped systems are solved as the symmetric problem K phi = omega^2 M phi; with
    damping (internal friction or PD) the eigenvalues of A give omega_n = |lambda| and
    zeta = -Re(lambda)/|lambda|. Rigid-body modes of hinged joints have omega = 0.
    """
    lin = linearize(model, joint_angles, joints=joints, kp=kp, kd=kd, q0=q0,
                    gravity_preload=gravity_preload)
    cond = float(np.linalg.cond(lin.M))
    n = lin.M.shape[0]
    full = np.zeros((model.nq, n))
    if not np.any(lin.Cd):
        w2, vec = sla.eigh(lin.K, lin.M)
        omega = np.sqrt(np.clip(w2, 0.0, None))
        zeta = np.zeros_like(omega)
        full[lin.free] = vec
        shapes = lin.T @ full
        return ModalResult(omega, zeta, shapes, cond)
    lam, vec = np.linalg.eig(lin.A)
    keep = lam.imag >= -1e-12 * np.maximum(1.0, np.abs(lam))
    lam, vec = lam[keep], vec[:, keep]
    order = np.argsort(np.abs(lam))
    lam, vec = lam[order], vec[:, order]
    omega = np.abs(lam)
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = np.where(omega > 0, -lam.real / omega, 1.0)
    phi = np.zeros((model.nq, len(lam)))
    z = np.zeros((model.nq, len(lam)), dtype=complex)
    z[lin.free] = vec[:n]
    phi = np.real(lin.T @ z)
    return ModalResult(omega, zeta, phi, cond)
