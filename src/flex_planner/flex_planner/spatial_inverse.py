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
#: the tip frame's orientation as URDF fixed-axis roll, pitch, yaw (R = Rz Ry Rx), rad
ORIENTATION = ("roll", "pitch", "yaw")
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


def check_joint_count(model, coordinates=COORDINATES, orientation: bool = False
                      ) -> np.ndarray:
    """The actuated joints (indices); ValueError when fewer than the task coordinates
    (with ``orientation`` the three of the tip frame's orientation count too)."""
    active = np.flatnonzero(model.actuator_index >= 0)
    n_task = len(_coords(coordinates)) + (3 if orientation else 0)
    if orientation:
        coordinates = tuple(coordinates) + ORIENTATION
    if len(active) < n_task:
        raise ValueError(
            f"{model.arm.name}: {len(active)} actuated joint(s) for {n_task} task "
            f"coordinates ({', '.join(coordinates)}): no static-flexible inverse (it needs at "
            "least as many joints as task coordinates; give fewer coordinates)")
    return active


def tip_sensitivity(model, q, rows: int = 3) -> np.ndarray:
    """d p_tip / d theta (3 x n_joints; ``rows=6``: with the tip frame's angular
    velocity per joint rate below) of the static arm at its equilibrium q (joints held):
    the tip Jacobian with the deformation's response through the static tangent."""
    free = np.setdiff1d(np.arange(model.nq), model.off)
    Kt = model.K + model.gravity_stiffness(q)
    J = model.tip_jacobian(q)[:rows]
    if not len(free):                # a rigid arm
        return J[:, model.off]
    dqf = -np.linalg.solve(Kt[np.ix_(free, free)], Kt[np.ix_(free, model.off)])
    return J[:, model.off] + J[:, free] @ dqf


def invert_tip_position(model, target, coordinates=COORDINATES, guess=None, *,
                        tol: float = 1e-12, max_iter: int = 50) -> SpatialInverse:
    """Joint values whose static deflected tip is at ``target`` (the listed coordinates,
    m); ``guess``: start joint values (default zero)."""
    idx = _coords(coordinates)
    active = check_joint_count(model, coordinates)
    target = np.asarray(target, float).reshape(len(idx))
    theta, st, e, it = _newton(model, active, guess, idx, lambda st: (
        st.tip_position[idx] - target), f"{target.tolist()} m", tol, max_iter)
    return SpatialInverse(theta, st.q, st.tip_position, it, float(np.linalg.norm(e)))


def _newton(model, active, guess, rows, error, what, tol, max_iter):
    """Newton on the actuated joints' values with the static sensitivity's ``rows``
    (0-2 tip position, 3-5 the tip frame's angular velocity) and the error ``error(static
    state)``; the minimum-norm step with more joints than rows, steps limited to
    MAX_STEP. Returns (theta, static state, error, Newton steps taken)."""
    from flex_model.spatial.analysis import static_equilibrium
    theta = np.zeros(model.n_links) if guess is None else np.array(guess, float)
    for it in range(1, max_iter + 1):
        st = static_equilibrium(model, theta)
        e = error(st)
        if np.max(np.abs(e)) < tol:
            return theta, st, e, it - 1
        J = tip_sensitivity(model, st.q, rows=6 if max(rows) > 2 else 3)[
            np.ix_(rows, active)]
        if len(active) == len(rows):
            d = -np.linalg.solve(J, e)
        else:                              # redundant: the minimum-norm step
            d = -np.linalg.pinv(J) @ e
        big = np.max(np.abs(d))
        if big > MAX_STEP:
            d *= MAX_STEP / big
        theta[active] += d
    raise RuntimeError(f"{model.arm.name}: no static-flexible inverse of {what} after "
                       f"{max_iter} Newton steps (largest error {np.max(np.abs(e)):.3e}): "
                       "out of reach or a singular pose")


@dataclass
class SpatialPoseInverse(SpatialInverse):
    tip_rpy: np.ndarray = None        # rad, the static tip frame's roll, pitch, yaw
    error_rad: float = 0.0            # |rotation vector of R R*^T| at the solution


def _rpy(R) -> np.ndarray:
    from scipy.spatial.transform import Rotation
    return Rotation.from_matrix(R).as_euler("xyz")      # fixed axes x, y, z = URDF rpy


def invert_tip_pose(model, position, rpy, coordinates=COORDINATES, guess=None, *,
                    tol: float = 1e-12, max_iter: int = 50) -> SpatialPoseInverse:
    """Joint values whose static deflected tip frame (the last link's end frame) is at
    ``position`` (the listed coordinates, m) with the orientation ``rpy`` (URDF roll,
    pitch, yaw, rad: R* = Rz(yaw) Ry(pitch) Rx(roll)): Newton on theta with the error
    [p - p*; the rotation vector of R R*^T] (base frame) and the 6-row sensitivity of
    :func:`tip_sensitivity` (the orientation rows: the tip's angular velocity per joint
    rate, exact at the solution); minimum-norm with more joints than the task's
    len(coordinates) + 3, a refusal with fewer."""
    from scipy.spatial.transform import Rotation

    from flex_model.spatial.kinematics import rpy_matrix
    idx = _coords(coordinates)
    active = check_joint_count(model, coordinates, orientation=True)
    target = np.asarray(position, float).reshape(len(idx))
    Rt = rpy_matrix(np.asarray(rpy, float).reshape(3))

    def error(st):
        ew = Rotation.from_matrix(np.real(model.tip_frame(st.q).R) @ Rt.T).as_rotvec()
        return np.concatenate([st.tip_position[idx] - target, ew])

    theta, st, e, it = _newton(model, active, guess, idx + [3, 4, 5], error,
                               f"the pose {target.tolist()} m, rpy "
                               f"{np.asarray(rpy, float).tolist()} rad", tol, max_iter)
    return SpatialPoseInverse(theta, st.q, st.tip_position, it,
                              float(np.linalg.norm(e[:len(idx)])),
                              tip_rpy=_rpy(np.real(model.tip_frame(st.q).R)),
                              error_rad=float(np.linalg.norm(e[len(idx):])))
