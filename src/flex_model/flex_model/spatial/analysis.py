"""Statics and natural modes of a spatial arm (thesis §II.6 carried to 3D).

- ``static_equilibrium``: joints held at given values, K q + dU_g/dq = J^T F solved by
  Newton with the exact tangent K + d^2 U_g / dq^2 (complex-step Hessian of gravity);
  F a given tip force and the force of a ``contact_surface`` (at rest: k delta n, its
  tangent k J^T n n^T J).
- ``natural_modes``: K_t phi = omega^2 M phi about the unloaded configuration (gravity an
  input, as the planar ``modes``) or about the equilibrium under gravity
  (``gravity_preload``), joints ``clamped`` (the link-side joint variables removed; the
  motor coordinates of elastic gears stay free, as in the planar ``modes``) or ``hinged``
  (free); joints held by a locked motor behind a rigid gear are always removed.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from ..errors import StaticConvergenceError
from .dynamics import SpatialArmModel


@dataclass
class SpatialStatic:
    q: np.ndarray
    tip_position: np.ndarray        # m, base frame
    tip_rotation: np.ndarray        # 3 x 3, base frame
    deflections: dict               # per flexible link: v, w, dv, dw, phi at the tip
    iterations: int


def _q_at(model: SpatialArmModel, joint_values) -> np.ndarray:
    q = np.zeros(model.nq)
    if joint_values is not None:
        q[model.off] = joint_values
    return q


def static_equilibrium(model: SpatialArmModel, joint_values=None, *, tip_force=None,
                       linear: bool = False, tol: float = 1e-13,
                       max_iter: int = 30) -> SpatialStatic:
    """Equilibrium with the joints held at ``joint_values`` (rad or m) under gravity and
    an optional tip force (N, base frame, at the end frame's origin); ``linear``: one
    Newton step from the undeformed arm (the small-deflection static response)."""
    q = _q_at(model, joint_values)
    free = np.setdiff1d(np.arange(model.nq), model.off)
    F = np.zeros(3) if tip_force is None else np.asarray(tip_force, float)

    def residual(q):
        r = -model.K @ q - model.gravity_force(q) + model.contact_load(q) + \
            model.curvature_load(q)
        if np.any(F):
            r += model.tip_jacobian(q)[:3].T @ F
        return r[free]

    r = residual(q)
    scale = max(1.0, float(np.max(np.abs(r), initial=0.0)))
    for it in range(1, max_iter + 1):
        if not len(free):            # a rigid arm: nothing deforms
            it = 0
            break
        Kt = (model.K + model.gravity_stiffness(q) + model.contact_tangent(q)[0] +
              model.curvature_tangent(q))[np.ix_(free, free)]
        if np.any(F) and not linear:  # load stiffness of the tip force (central diff.)
            h = 1e-7
            for c, j in enumerate(free):
                qp, qm = q.copy(), q.copy()
                qp[j] += h
                qm[j] -= h
                Kt[:, c] -= ((model.tip_jacobian(qp)[:3] - model.tip_jacobian(qm)[:3]).T
                             @ F)[free] / (2 * h)
        dq = np.linalg.solve(Kt, r)
        q[free] += dq
        r = residual(q)
        if linear:
            break
        if np.max(np.abs(dq)) < tol * max(1.0, np.max(np.abs(q))) or \
                np.max(np.abs(r)) < 1e-14 * scale:
            break
    else:
        raise StaticConvergenceError(f"no static equilibrium after {max_iter} Newton steps "
                                     f"(largest residual {np.max(np.abs(r)):.3e})")
    tip = model.tip_frame(q)
    pos = np.real(tip.o)
    if linear:  # the linearized output as well (as the planar static --linear)
        q_rigid = _q_at(model, joint_values)
        pos = model.tip_position(q_rigid) + model.tip_jacobian(q_rigid)[:3] @ (q - q_rigid)
    return SpatialStatic(q=q, tip_position=pos, tip_rotation=np.real(tip.R),
                         deflections=model.tip_deflections(q), iterations=it)


@dataclass
class SpatialModes:
    omega: np.ndarray
    shapes_q: np.ndarray            # (nq, n_modes)
    q0: np.ndarray
    coordinates: np.ndarray         # indices of q kept

    @property
    def frequencies_hz(self) -> np.ndarray:
        return self.omega / (2 * np.pi)


def natural_modes(model: SpatialArmModel, joint_values=None, *, joints: str = "clamped",
                  gravity_preload: bool = False, coordinates=None) -> SpatialModes:
    """Undamped natural modes, lowest first. ``coordinates`` optionally restricts q to a
    subset (e.g. ``model.plane_indices('v')``: the in-plane motion of a planar arm, which
    decouples from the out-of-plane motion at a planar configuration)."""
    if joints not in ("clamped", "hinged"):
        raise ValueError(f"joints: got {joints!r}; expected clamped or hinged")
    if gravity_preload:
        q0 = static_equilibrium(model, joint_values).q
        Kt = model.K + model.gravity_stiffness(q0) + model.curvature_tangent(q0)
    else:
        q0 = _q_at(model, joint_values)
        Kt = model.K
    keep = np.arange(model.nq) if coordinates is None else np.asarray(coordinates, int)
    if joints == "clamped":
        keep = np.setdiff1d(keep, model.off)
    keep = np.setdiff1d(keep, model.held)      # joints held by a locked rigid motor
    M = model.mass_matrix(q0)[np.ix_(keep, keep)]
    K = Kt[np.ix_(keep, keep)]
    w2, vec = sla.eigh(K, M)
    shapes = np.zeros((model.nq, len(keep)))
    shapes[keep] = vec
    return SpatialModes(np.sqrt(np.clip(w2, 0.0, None)), shapes, q0, keep)
