"""Static-flexible kinematic inversion (thesis Ch. IV, Eqs. 85-94 generalized).

For a desired tip position p* (and, with three or more links, tip orientation phi*) find
the joint angles theta for which the STATIC deflected arm, joints held (clamped) at theta,
under gravity, payload and a known tip load, has its tip exactly at p*. The thesis writes
the two-link case in closed form (Eqs. 85-94, see :mod:`flex_planner.closed_form`) and
inverts it numerically; here the full nonlinear static model of flex_model is used for
any number of links and deformation variables. In joint coordinates z (q = T z, z = q
with alpha_i replaced by theta_i) the unknowns are all of z and the equations are

    S_f^T ( -K q - dU_g/dq + J_tip^T F + e_tip C ) = 0     static balance of the
                                                          deformation variables (Eq. 27,
                                                          q_dot = 0; clamped joints;
                                                          flex_model's static_residual)
    p_tip(q) - p* = 0                                      tip position (Eq. 85)
    alpha_n + gamma_n - phi* = 0                           tip orientation (>= 3 links)

with S_f the columns of T of the deformation variables (S_f spans the null space of
G = H_c^T, so the joint torques drop out: they are the clamping reactions). They are solved
by Levenberg-Marquardt (Newton as the damping vanishes) with Broyden updates of a
finite-difference Jacobian, the balance rows divided by the diagonal stiffness (units of
m), from the rigid inverse kinematics of :mod:`flex_planner.rigid_kinematics`. Should that
fail, a reduced Levenberg-Marquardt over the joint angles alone, each evaluation a clamped
static equilibrium of flex_model, either finds the pose or stops at a stationary tip
error: the target is then outside the reach of the sagging arm and the distance of the
closest static tip is reported (:class:`UnreachableError`), never a wrong answer.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.statics import (StaticConvergenceError, TipLoad, static_equilibrium,
                               static_residual)

from .rigid_kinematics import chain_guess, elbow_bend

#: convergence: tip position (m), orientation (rad) and scaled static balance (m)
TIP_TOLERANCE = 1e-11
BALANCE_TOLERANCE = 1e-11
MAX_ITERATIONS = 60
#: iterations of the reduced fallback/diagnosis over the joint angles alone
REDUCED_ITERATIONS = 40
#: largest change of a joint angle in one iteration (rad)
MAX_ANGLE_STEP = 0.5


class UnreachableError(ValueError):
    """A waypoint has no static-flexible inverse: ``index`` (0-based), ``reason``, ``point``."""

    def __init__(self, index: int, reason: str, point=None):
        self.index, self.reason = int(index), reason
        self.point = None if point is None else tuple(float(c) for c in point)
        where = "" if point is None else " at ({:.6g}, {:.6g}) m".format(*self.point)
        super().__init__(f"waypoint {self.index}{where} is unreachable: {reason}")


@dataclass
class StaticInverse:
    """One inverted pose: joint angles (rad), the static equilibrium q, its tip (m, rad)."""

    joint_angles: np.ndarray
    q: np.ndarray
    tip_position: np.ndarray
    tip_orientation: float
    iterations: int


def check_rigid_joints(model: FlexArmModel) -> None:
    """The chain of thesis Ch. IV-V assumes joints held at theta (no joint springs)."""
    elastic = list(getattr(model, "elastic_joints", []))
    if elastic:
        names = [model.arm.joint_names[i] for i in elastic]
        raise ValueError(f"model: got elastic joints {names}; expected rigid joints (the "
                         "static-flexible inversion and nominal input of thesis Ch. IV-V "
                         "hold the joints at theta)")


def _wrap(angle):
    return (angle + np.pi) % (2.0 * np.pi) - np.pi


class StaticInverter:
    """Static-flexible inversion for one model and one known tip load (reusable)."""

    def __init__(self, model: FlexArmModel, tip_load: TipLoad | None = None):
        check_rigid_joints(model)
        if model.n_links < 2:
            raise ValueError(f"model: got an arm with {model.n_links} link; expected at "
                             "least 2 links for planning a tip position")
        self.model = model
        self.load = tip_load if tip_load is not None else TipLoad()
        self.T = model.joint_coordinate_matrix()
        self.off = np.asarray(model.off)
        self.free = np.setdiff1d(np.arange(model.nq), self.off)
        self.Sf = self.T[:, self.free]
        self.lengths = np.array([lk.length for lk in model.arm.links])
        kff = np.diag(self.Sf.T @ model.K @ self.Sf)
        self.row_scale = 1.0 / kff
        self.e_phi_T = model.tip_torque_vector() @ self.T
        self.zero_torque = np.zeros(model.n_links)

    # ------------------------------------------------------------------ equations
    def static_force(self, q) -> np.ndarray:
        """Generalized static force Q - K q - dU_g/dq with the tip load and zero joint
        torque (flex_model's ``static_residual``; thesis Eq. 27 with q_dot = 0)."""
        return static_residual(self.model, q, self.zero_torque, self.load)

    def _residual(self, z, target, phi):
        q = self.T @ z
        parts = [self.row_scale * (self.Sf.T @ self.static_force(q)),
                 self.model.link_origins(q)[-1] - target]
        if phi is not None:
            parts.append([_wrap(self.e_phi_T @ z - phi)])
        return np.concatenate(parts), q

    def _jacobian(self, z, q, phi):
        m = self.model
        f0 = self.static_force(q)
        dF = np.empty((m.nq, m.nq))
        for j in range(m.nq):  # forward differences (K q is linear, gravity smooth)
            h = 1e-7 * max(1.0, abs(q[j]))
            qp = q.copy()
            qp[j] += h
            dF[:, j] = (self.static_force(qp) - f0) / h
        rows = [self.row_scale[:, None] * (self.Sf.T @ dF @ self.T),
                m.tip_jacobian(q) @ self.T]
        if phi is not None:
            rows.append(self.e_phi_T[None, :])
        return np.vstack(rows)

    def _converged(self, r, n_balance):
        return (np.max(np.abs(r[:n_balance])) <= BALANCE_TOLERANCE
                and np.max(np.abs(r[n_balance:])) <= TIP_TOLERANCE)

    # ------------------------------------------------------------------ solver
    def solve(self, target, orientation=None, *, bend: int, theta_guess=None,
              flex_guess=None, index: int = 0) -> StaticInverse:
        """Invert one tip pose; raises :class:`UnreachableError` with ``index``."""
        m = self.model
        target = np.asarray(target, float)
        if theta_guess is None:
            theta_guess = chain_guess(self.lengths, target, bend, orientation)
        z = np.zeros(m.nq)
        z[self.off] = theta_guess
        if flex_guess is not None:
            z[self.free] = flex_guess
        nb = len(self.free)
        r, q = self._residual(z, target, orientation)
        merit = r @ r
        mu, J, fresh = 1e-12, None, False
        for it in range(1, MAX_ITERATIONS + 1):
            if self._converged(r, nb):
                break
            if J is None:
                J, fresh = self._jacobian(z, q, orientation), True
            A, g = J.T @ J, J.T @ r
            try:
                dz = np.linalg.solve(A + mu * np.diag(np.diag(A)), -g)
            except np.linalg.LinAlgError:
                dz = None
            if dz is not None:
                dz *= min(1.0, MAX_ANGLE_STEP / max(np.max(np.abs(dz[self.off])), 1e-300))
                r_new, q_new = self._residual(z + dz, target, orientation)
            if dz is not None and r_new @ r_new < merit:
                # Broyden's update keeps the Jacobian current without new differences
                J = J + np.outer(r_new - r - J @ dz, dz) / (dz @ dz)
                z, r, q, merit = z + dz, r_new, q_new, r_new @ r_new
                mu, fresh = max(mu / 10.0, 1e-15), False
            elif not fresh:
                J = None                      # retry with a fresh Jacobian first
            elif mu < 1e8:
                mu *= 10.0
            else:
                break                         # stationary: no descent left
        if not self._converged(r, nb):
            q, reason = self._reduced(target, orientation, m.joint_angles(q), q)
            if reason:
                raise UnreachableError(index, reason, target)
            z = np.linalg.solve(self.T, q)
        theta = m.joint_angles(q)
        if theta[1] * bend <= 0.0:
            raise UnreachableError(index, (
                f"the elbow branch would change (theta_2 = {theta[1]:.6g} rad, expected the "
                f"sign {bend:+d}): the path crosses the stretched or folded arm"), target)
        return StaticInverse(joint_angles=theta, q=q, tip_position=m.link_origins(q)[-1],
                             tip_orientation=float(self.e_phi_T @ z), iterations=it)

    def _static_error(self, theta, q_guess, target, phi):
        """Clamped static equilibrium at ``theta`` (flex_model) and its tip error."""
        q = static_equilibrium(self.model, theta, joints="clamped", load=self.load,
                               q_guess=q_guess).q
        e = self.model.link_origins(q)[-1] - target
        if phi is not None:
            e = np.append(e, _wrap(self.e_phi_T @ np.linalg.solve(self.T, q) - phi))
        return e, q

    def _reduced(self, target, phi, theta, q):
        """Fallback and diagnosis: Levenberg-Marquardt over the joint angles alone, every
        evaluation a clamped static equilibrium. Returns ``(q, None)`` on success, else
        ``(q, reason)``; a stationary tip error is the distance of the closest static tip
        (the target is outside the reach of the sagging arm)."""
        try:
            e, q = self._static_error(theta, q, target, phi)
        except StaticConvergenceError as exc:
            return q, f"no static equilibrium near the pose ({exc})"
        mu = 1e-9
        for it in range(REDUCED_ITERATIONS):
            if np.max(np.abs(e)) <= TIP_TOLERANCE:
                return q, None
            J = np.empty((len(e), len(theta)))
            for j in range(len(theta)):
                th = theta.copy()
                th[j] += 1e-7
                J[:, j] = (self._static_error(th, q, target, phi)[0] - e) / 1e-7
            A, g = J.T @ J, J.T @ e
            if np.linalg.norm(g) <= 1e-7 * np.linalg.norm(J, 2) * np.linalg.norm(e):
                break
            while mu < 1e10:
                step = np.linalg.solve(A + mu * np.diag(np.diag(A)), -g)
                step *= min(1.0, MAX_ANGLE_STEP / np.max(np.abs(step)))
                try:
                    e_new, q_new = self._static_error(theta + step, q, target, phi)
                except StaticConvergenceError:
                    e_new = None
                if e_new is not None and e_new @ e_new < e @ e:
                    theta, e, q, mu = theta + step, e_new, q_new, max(mu / 10.0, 1e-15)
                    break
                mu *= 10.0
            else:
                break
        else:
            return q, (f"no convergence of the static inversion after {REDUCED_ITERATIONS} "
                       f"iterations (tip error {np.linalg.norm(e[:2]):.3g} m)")
        reach = float(np.sum(self.lengths))
        return q, (f"outside the reach of the sagging arm: the closest static tip is "
                   f"{1e3 * np.linalg.norm(e[:2]):.4g} mm from the target (straight arm "
                   f"reach {reach:.4g} m)")


def invert_waypoints(model: FlexArmModel, waypoints, orientations=None, *,
                     elbow: str = "up", tip_load: TipLoad | None = None,
                     inverter: StaticInverter | None = None) -> list[StaticInverse]:
    """Invert a sequence of tip poses, keeping the elbow branch continuous (thesis Ch. IV).

    ``waypoints`` (N, 2) m; ``orientations`` (N,) rad, required with three or more links
    and not allowed with two (a two-link arm cannot also set its tip orientation). The
    branch is chosen at the first point by ``elbow`` (see
    :mod:`flex_planner.rigid_kinematics`) and each later point starts from the previous
    solution's sag correction. Raises :class:`UnreachableError` naming the first bad point.
    """
    inv = inverter or StaticInverter(model, tip_load)
    pts = np.asarray(waypoints, float)
    n = model.n_links
    if orientations is None and n >= 3:
        raise ValueError(f"orientations: got None; expected one tip orientation (rad) per "
                         f"waypoint for an arm with {n} links")
    if orientations is not None:
        if n == 2:
            raise ValueError("orientations: a two-link arm cannot also set its tip "
                             "orientation; expected None")
        orientations = np.asarray(orientations, float)
        if orientations.shape != (len(pts),) or not np.all(np.isfinite(orientations)):
            raise ValueError(f"orientations: got shape {orientations.shape}; expected "
                             f"({len(pts)},) finite angles (rad)")
    phis = [None] * len(pts) if orientations is None else list(orientations)
    wrist0 = pts[0] if n == 2 else pts[0] - inv.lengths[-1] * np.array(
        [np.cos(phis[0]), np.sin(phis[0])])
    l_rest = float(np.sum(inv.lengths[1:])) if n == 2 else float(np.sum(inv.lengths[1:-1]))
    bend = elbow_bend(inv.lengths[0], l_rest, wrist0, elbow)
    out = []
    for k, (p, phi) in enumerate(zip(pts, phis)):
        rigid = _wrap(chain_guess(inv.lengths, p, bend, phi))
        if out:
            prev = out[-1]
            # the angles are 2 pi periodic: stay next to the previous pose (continuity)
            rigid = prev.joint_angles + _wrap(rigid - prev.joint_angles)
            correction = prev.joint_angles - chain_guess(inv.lengths, pts[k - 1], bend,
                                                         phis[k - 1])
            try:
                flex = np.linalg.solve(inv.T, prev.q)[inv.free]
                guess = rigid + _wrap(correction)
                out.append(inv.solve(p, phi, bend=bend, theta_guess=guess,
                                     flex_guess=flex, index=k))
                continue
            except UnreachableError:
                pass  # retry from the rigid guess before reporting
        out.append(inv.solve(p, phi, bend=bend, theta_guess=rigid, index=k))
    return out


def invert_tip_pose(model: FlexArmModel, target, orientation=None, *, elbow: str = "up",
                    tip_load: TipLoad | None = None) -> StaticInverse:
    """Static-flexible inverse of one tip position (and orientation, rad, >= 3 links)."""
    phis = None if orientation is None else [orientation]
    return invert_waypoints(model, [target], phis, elbow=elbow, tip_load=tip_load)[0]
