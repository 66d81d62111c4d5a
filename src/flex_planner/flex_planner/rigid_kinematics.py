"""Rigid-arm kinematics: the start of the static-flexible inversion and seed 002's Eq. (20).

The static-flexible inversion (thesis Ch. IV) is a Newton solve; its initial guess and its
elbow branch come from the closed-form inverse kinematics of the rigid two-link arm.
Seed 002 also plans its straight tip line (Eq. 30) with the rigid inverse kinematics
(its "Step 2") and measures the path deviation against the rigid forward kinematics,

    r_r = sum_k L_k (cos sum_{i<=k} theta_i, sin sum_{i<=k} theta_i)        (seed 002 Eq. 20)

Angles are relative joint angles (rad); positions in the base frame (m), y up.

Elbow branch
------------
For a tip (or wrist) point there are two mirror-image rigid configurations of a two-link
chain. ``elbow="up"`` picks the one whose elbow (the origin of link 2) is higher (larger
y, gravity along -y); ``"down"`` the lower one. When both elbows are equally high (the
point straight above or below the base) ``"up"`` picks the negative (clockwise) bend
``theta_2 < 0`` and ``"down"`` the positive one. Along a path the branch chosen at the first
point is kept (:func:`bend_sign` of the previous solution), so it never flips.
"""
from __future__ import annotations

import numpy as np

ELBOWS = ("up", "down")


def check_elbow(elbow: str) -> str:
    if elbow not in ELBOWS:
        raise ValueError(f"elbow: got {elbow!r}; expected one of {', '.join(ELBOWS)}")
    return elbow


def forward_kinematics(lengths, theta) -> np.ndarray:
    """Tip of the rigid chain (seed 002 Eq. 20) for joint angles ``theta`` (..., n) -> (..., 2)."""
    lengths = np.asarray(lengths, float)
    absolute = np.cumsum(np.asarray(theta, float), axis=-1)
    return np.stack([np.sum(lengths * np.cos(absolute), axis=-1),
                     np.sum(lengths * np.sin(absolute), axis=-1)], axis=-1)


def two_link_ik(l1: float, l2: float, point, bend: int, clamp: bool = True):
    """Joint angles (theta_1, theta_2) of the rigid two-link chain reaching ``point``.

    ``bend`` = +1 or -1 is the sign of theta_2. Outside the annulus
    ``|l1 - l2| <= r <= l1 + l2`` the chain is stretched (or folded) towards the point
    when ``clamp``, else ``None`` is returned.
    """
    x, y = float(point[0]), float(point[1])
    r2 = x * x + y * y
    c2 = (r2 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    if abs(c2) > 1.0:
        if not clamp:
            return None
        c2 = float(np.clip(c2, -1.0, 1.0))
    t2 = bend * np.arccos(c2)
    t1 = np.arctan2(y, x) - np.arctan2(l2 * np.sin(t2), l1 + l2 * np.cos(t2))
    return np.array([t1, t2])


def elbow_bend(l1: float, l2: float, point, elbow: str) -> int:
    """Sign of theta_2 (+1/-1) that puts the elbow ``up`` or ``down`` (module docstring)."""
    check_elbow(elbow)
    heights = {}
    for bend in (1, -1):
        t1 = two_link_ik(l1, l2, point, bend)[0]
        heights[bend] = l1 * np.sin(t1)
    if abs(heights[1] - heights[-1]) <= 1e-9 * (l1 + l2):
        return -1 if elbow == "up" else 1
    higher = 1 if heights[1] > heights[-1] else -1
    return higher if elbow == "up" else -higher


def chain_guess(lengths, point, bend: int, orientation=None) -> np.ndarray:
    """Rigid joint angles reaching ``point`` (and ``orientation``, rad, for >= 3 links).

    Two links: the closed form. Three or more: the last link is laid along
    ``orientation``, links 2..n-1 are kept straight and the first two "links" (link 1 and
    the straight rest) reach the wrist point in closed form. Used as the initial guess of
    the static-flexible inversion, which then solves the exact problem.
    """
    lengths = np.asarray(lengths, float)
    n = len(lengths)
    if n == 2:
        return two_link_ik(lengths[0], lengths[1], point, bend)
    wrist = np.asarray(point, float) - lengths[-1] * np.array([np.cos(orientation),
                                                               np.sin(orientation)])
    t1, t2 = two_link_ik(lengths[0], float(np.sum(lengths[1:-1])), wrist, bend)
    theta = np.zeros(n)
    theta[0], theta[1] = t1, t2
    theta[-1] = orientation - (t1 + t2)
    theta[-1] = (theta[-1] + np.pi) % (2 * np.pi) - np.pi
    return theta


def rigid_path_inverse(lengths, p, v, a, bend: int):
    """Joint positions, velocities and accelerations of a rigid two-link arm whose tip
    follows the samples ``p, v, a`` (N, 2) (seed 002 Step 2): theta by the closed form,
    theta_dot = J^-1 v, theta_ddot = J^-1 (a - J_dot theta_dot).

    Raises ``ValueError`` naming the first sample outside the annulus of reach or at the
    stretched/folded singularity.
    """
    l1, l2 = (float(x) for x in lengths)
    p, v, a = (np.atleast_2d(np.asarray(x, float)) for x in (p, v, a))
    n = len(p)
    th, thd, thdd = np.zeros((n, 2)), np.zeros((n, 2)), np.zeros((n, 2))
    for k in range(n):
        sol = two_link_ik(l1, l2, p[k], bend, clamp=False)
        if sol is None or abs(np.sin(sol[1])) < 1e-9:
            raise ValueError(f"tip path: sample {k} at {p[k].tolist()} m is outside the reach "
                             f"of the rigid arm or at its singularity; expected "
                             f"{abs(l1 - l2):g} m < |p| < {l1 + l2:g} m")
        t1, t12 = sol[0], sol[0] + sol[1]
        J = np.array([[-l1 * np.sin(t1) - l2 * np.sin(t12), -l2 * np.sin(t12)],
                      [l1 * np.cos(t1) + l2 * np.cos(t12), l2 * np.cos(t12)]])
        w = np.linalg.solve(J, v[k])
        w1, w12 = w[0], w[0] + w[1]
        jdot_w = np.array([-l1 * np.cos(t1) * w1 ** 2 - l2 * np.cos(t12) * w12 ** 2,
                           -l1 * np.sin(t1) * w1 ** 2 - l2 * np.sin(t12) * w12 ** 2])
        th[k], thd[k], thdd[k] = sol, w, np.linalg.solve(J, a[k] - jdot_w)
    th = np.unwrap(th, axis=0)
    return th, thd, thdd
