"""Static equilibrium of the arm under gravity, payload, joint torques and tip loads.

Solves K q + dU_g/dq = H_c tau + J_tip^T F + e_tip C (thesis Eq. 27 with q_dot = 0) by
Newton's method in joint coordinates z (q with alpha_i replaced by the joint angle
theta_i), with the joints

- ``clamped``: theta held at the given angles (thesis "clamped joints"),
- ``pd``: tau = Kp (theta_set - theta) + tau_0,
- ``hinged``: tau = tau_0 given.

With the wavelet basis the deflections at the interval end points are exact
(thesis Theorem 1), already with two variables per link.

``linear=True`` gives the small-deflection static response: one Newton step from the
undeformed arm at the set angles, i.e. the static gain of the model linearized about that
configuration (thesis §II.6 validation guidelines; the quantities of Tables II-V). The
default solves the full equilibrium of the model, whose inter-link kinematics is
geometrically nonlinear (thesis Eqs. 1, 20).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .dynamics import FlexArmModel
from .errors import StaticConvergenceError  # noqa: F401 (raised here; public here)

JOINT_MODES = ("clamped", "pd", "hinged")


@dataclass(frozen=True)
class TipLoad:
    """A load at the arm's end: force (N, base frame) and torque (N m, counter-clockwise)."""

    force: tuple = (0.0, 0.0)
    torque: float = 0.0

    @staticmethod
    def from_magnitude(force: float = 0.0, angle_deg: float = 90.0, torque: float = 0.0):
        """A tip force of magnitude ``force`` at ``angle_deg`` from the x axis (90 = up)."""
        a = np.radians(angle_deg)
        return TipLoad((force * np.cos(a), force * np.sin(a)), torque)


@dataclass
class StaticResult:
    """Equilibrium q and the tip quantities of thesis Tables II-V."""

    q: np.ndarray
    joint_angles: np.ndarray
    tip_rotation: float          # rad, tip tangent relative to the undeformed straight arm
    tip_displacement: float      # m, vertical tip displacement (base frame, up positive)
    tip_position: tuple          # m
    link_tip_deflection: np.ndarray = field(default_factory=lambda: np.zeros(0))
    link_tip_rotation: np.ndarray = field(default_factory=lambda: np.zeros(0))
    iterations: int = 0

    def as_dict(self) -> dict:
        return {"tip_rotation_deg": float(np.degrees(self.tip_rotation)),
                "tip_displacement_mm": float(1e3 * self.tip_displacement),
                "tip_position_m": [float(v) for v in self.tip_position],
                "joint_angles_deg": [float(v) for v in np.degrees(self.joint_angles)],
                "links": [{"tip_deflection_m": float(d), "tip_rotation_rad": float(r)}
                          for d, r in zip(self.link_tip_deflection, self.link_tip_rotation)]}


def static_residual(model: FlexArmModel, q, tau, load: TipLoad) -> np.ndarray:
    """Generalized force balance Q - K q - dU_g/dq in q coordinates (zero at equilibrium),
    with the tip load and the contact force of a contact surface."""
    r = model.Ga.T @ tau - model.K @ q - model.gravity_force(q) + model.joint_forces(q)
    force = np.asarray(load.force, float) + model.contact_force(q)
    if force[0] or force[1]:
        r += model.tip_jacobian(q).T @ force
    if load.torque:
        r += load.torque * model.tip_torque_vector()
    return r


def static_equilibrium(model: FlexArmModel, joint_angles=None, *, joints: str = "clamped",
                       kp=None, joint_torques=None, load: TipLoad = TipLoad(),
                       q_guess=None, linear: bool = False, tol: float = 1e-12,
                       max_iter: int = 50) -> StaticResult:
    """Static equilibrium for joint set angles ``joint_angles`` (rad, default zero).

    ``kp`` (N m/rad, per joint) is required for ``joints='pd'``; ``joint_torques`` (N m)
    are constant joint torques added to the joint law (the holding torques of a hinged arm).
    """
    if joints not in JOINT_MODES:
        raise ValueError(f"joints: got {joints!r}; expected one of {', '.join(JOINT_MODES)}")
    nl, nq = model.n_links, model.nq
    theta_set = np.zeros(nl) if joint_angles is None else np.asarray(joint_angles, float)
    tau0 = np.zeros(nl) if joint_torques is None else np.asarray(joint_torques, float)
    kp = np.zeros(nl) if kp is None else np.broadcast_to(np.asarray(kp, float), (nl,))
    if joints == "pd" and np.any(kp <= 0):
        raise ValueError(f"kp: got {kp.tolist()}; expected gains > 0 for joints='pd'")
    T = model.joint_coordinate_matrix()
    free = np.ones(nq, dtype=bool)
    if joints == "clamped":
        free[model.off] = False

    def residual(z):
        q = T @ z
        tau = tau0 + (kp * (theta_set - model.Ga @ q) if joints == "pd" else 0.0)
        return (T.T @ static_residual(model, q, tau, load))[free]

    z = np.linalg.solve(T, model.q_from_joint_angles(theta_set))
    if q_guess is not None:
        z = np.linalg.solve(T, np.asarray(q_guess, float))
        if joints == "clamped":
            z[model.off] = theta_set
    r = residual(z)
    scale = max(1.0, float(np.max(np.abs(r))))  # the unbalanced force at the start
    for it in range(1, max_iter + 1):
        # Jacobian by central differences (the residual is smooth; cost is negligible)
        nfree = int(free.sum())
        J = np.empty((nfree, nfree))
        idx = np.flatnonzero(free)
        for c, j in enumerate(idx):
            h = 1e-6 * max(1.0, abs(z[j]))
            zp, zm = z.copy(), z.copy()
            zp[j] += h
            zm[j] -= h
            J[:, c] = (residual(zp) - residual(zm)) / (2 * h)
        dz = np.linalg.solve(J, -r)
        z[idx] += dz
        r = residual(z)
        if linear:
            break
        if np.max(np.abs(dz)) < tol * max(1.0, np.max(np.abs(z))) or \
                np.max(np.abs(r)) < 1e-14 * scale:
            break
    else:
        raise StaticConvergenceError(
            f"no static equilibrium after {max_iter} Newton steps "
            f"(largest residual {np.max(np.abs(r)):.3e})")
    q = T @ z
    th = model.joint_angles(q)
    rigid = model.q_from_joint_angles(theta_set)
    x, y, phi = model.tip_pose(q)
    xr, yr, phir = model.tip_pose(rigid)
    if linear:  # outputs of the linearized model as well
        x, y = np.array([xr, yr]) + model.tip_jacobian(rigid) @ (q - rigid)
    return StaticResult(q=q, joint_angles=th, tip_rotation=phi - phir, tip_displacement=y - yr,
                        tip_position=(x, y), link_tip_deflection=model.tip_deflections(q),
                        link_tip_rotation=model.tip_rotations(q), iterations=it)
