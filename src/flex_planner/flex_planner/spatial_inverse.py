"""Static-flexible inversion for a spatial arm (issue 25; thesis Ch. IV, Eqs. 85-94 carried
to 3D).

For a desired tip position p* (all three coordinates or a subset, e.g. ``("x", "z")``) find
the joint values theta (rad or m) for which the STATIC deflected arm, joints held at theta
under gravity (flex_model.spatial.analysis.static_equilibrium, Newton with the exact
tangent), has its tip (the last link's end frame origin) at p*:

    e(theta) = p_tip(q*(theta))[coords] - p* = 0,
    (K + d^2 U_g/dq^2)_ff dq_f = -(K + d^2 U_g/dq^2)_fj dtheta     (implicit function,
                                                                    the static balance)
    de/dtheta = J_tip,j + J_tip,f dq_f/dtheta                       (exact Jacobian)

Newton on theta with this Jacobian; with more joints than task coordinates the step is the
minimum-norm one (pseudo-inverse: the smallest joint change that removes the linearized
error), with fewer a clear refusal. The actuated joints are the unknowns (locked motors
stay held at their values). Steps are limited to 0.5 rad (or m) per joint.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

COORDINATES = ("x", "y", "z")
MAX_STEP = 0.5


@dataclass
class SpatialInverse:
    joint_values: np.ndarray      # rad or m, every joint
    q: np.ndarray                 # the static state
    tip_position: np.ndarray      # m, base frame
    iterations: int
    error_m: float                # |e| at the solution


def _coords(coordinates) -> list[int]:
    idx = []
    for c in coordinates:
        if c not in COORDINATES:
            raise ValueError(f"coordinates: got {c!r}; expected x, y and/or z")
        idx.append(COORDINATES.index(c))
    if len(set(idx)) != len(idx) or not idx:
        raise ValueError(f"coordinates: got {list(coordinates)}; expected distinct x, y, z")
    return idx


def check_joint_count(model, coordinates=COORDINATES) -> np.ndarray:
    """The actuated joints (indices); ValueError when fewer than the task coordinates."""
    active = np.flatnonzero(model.actuator_index >= 0)
    n_task = len(_coords(coordinates))
    if len(active) < n_task:
        raise ValueError(
            f"{model.arm.name}: {len(active)} actuated joint(s) for {n_task} task "
            f"coordinates ({', '.join(coordinates)}): no static-flexible inverse (it needs at "
            "least as many joints as task coordinates; give fewer coordinates)")
    return active


def tip_sensitivity(model, q) -> np.ndarray:
    """d p_tip / d theta (3 x n_joints) of the static arm at its equilibrium q (joints
    held): the tip Jacobian with the deformation's response through the static tangent."""
    free = np.setdiff1d(np.arange(model.nq), model.off)
    Kt = model.K + model.gravity_stiffness(q)
    J = model.tip_jacobian(q)[:3]
    if not len(free):                # a rigid arm
        return J[:, model.off]
    dqf = -np.linalg.solve(Kt[np.ix_(free, free)], Kt[np.ix_(free, model.off)])
    return J[:, model.off] + J[:, free] @ dqf


def invert_tip_position(model, target, coordinates=COORDINATES, guess=None, *,
                        tol: float = 1e-12, max_iter: int = 50) -> SpatialInverse:
    """Joint values whose static deflected tip is at ``target`` (the listed coordinates,
    m); ``guess``: start joint values (default zero)."""
    from flex_model.spatial.analysis import static_equilibrium
    idx = _coords(coordinates)
    active = check_joint_count(model, coordinates)
    target = np.asarray(target, float).reshape(len(idx))
    theta = np.zeros(model.n_links) if guess is None else np.array(guess, float)
    for it in range(1, max_iter + 1):
        st = static_equilibrium(model, theta)
        e = st.tip_position[idx] - target
        if np.max(np.abs(e)) < tol:
            return SpatialInverse(theta, st.q, st.tip_position, it - 1,
                                  float(np.linalg.norm(e)))
        J = tip_sensitivity(model, st.q)[np.ix_(idx, active)]
        if len(active) == len(idx):
            d = -np.linalg.solve(J, e)
        else:                              # redundant: the minimum-norm step
            d = -np.linalg.pinv(J) @ e
        big = np.max(np.abs(d))
        if big > MAX_STEP:
            d *= MAX_STEP / big
        theta[active] += d
    raise RuntimeError(f"{model.arm.name}: no static-flexible inverse of "
                       f"{target.tolist()} m after {max_iter} Newton steps (largest tip "
                       f"error {np.max(np.abs(e)):.3e} m): out of reach or a singular pose")
