"""Forward kinematics of a spatial flexible arm: DH chain (seed 000 Eqs. 17-21) with Jacobians.

Frames are propagated with their position and angular-velocity Jacobians (Jo, Jw: 3 x nq):
a point at r from a frame's origin has J_p = Jo + Jw x r. A revolute joint adds the
column z_{i-1} to Jw, a prismatic one adds z_{i-1} to Jo. A flexible link's tip is the
transform of seed 000 Eq. 19,

    E = [Ry(-w') Rz(v') Rx(phi) | (L, v, w)]      (beam frame: x along the beam)

with small-deflection kinematics (thesis Eq. 1): the centre line at arc length s lies at
(s, v(s), w(s)); the section frame is rotated by Ry(-w'(s)) Rz(v'(s)) Rx(phi(s)): the
twist last, about the centre line's tangent (issue 47: Eq. 19's Rx(phi) first turns the
section's x axis off the tangent by phi times the slopes; docs/model.md).
Every function is analytic in q (no abs, no conjugate) so that a complex step q + i h v
gives the time derivatives of the Jacobians exactly (used for the velocity terms).
"""
from __future__ import annotations

import numpy as np


def _rot(t, i, j):
    """Rotation by t (scalar or array) in the (i, j) plane: (..., 3, 3)."""
    t = np.asarray(t)
    c, s = np.cos(t), np.sin(t)
    R = np.zeros(t.shape + (3, 3), dtype=np.result_type(t, float))
    k = 3 - i - j
    R[..., k, k] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def rot_x(t):
    return _rot(t, 1, 2)


def rot_y(t):
    return _rot(t, 2, 0)


def rot_z(t):
    return _rot(t, 0, 1)


def skew(r):
    """[r]x (..., 3, 3): skew(r) @ u = r x u."""
    r = np.asarray(r)
    S = np.zeros(r.shape[:-1] + (3, 3), dtype=r.dtype)
    S[..., 0, 1], S[..., 0, 2] = -r[..., 2], r[..., 1]
    S[..., 1, 0], S[..., 1, 2] = r[..., 2], -r[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -r[..., 1], r[..., 0]
    return S


def cross(a, b):
    """a x b along the last axis (analytic, broadcasting)."""
    return np.stack([a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
                     a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
                     a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]], axis=-1)


def rot_axis(u, t):
    """Rotation by t about the unit axis u (Rodrigues; analytic in t)."""
    S = skew(np.asarray(u, float))
    return np.eye(3) + np.sin(t) * S + (1.0 - np.cos(t)) * (S @ S)


def rpy_matrix(rpy) -> np.ndarray:
    """URDF fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = (float(x) for x in rpy)
    return rot_z(y) @ rot_y(p) @ rot_x(r)


def homogeneous(R, t) -> np.ndarray:
    T = np.eye(4, dtype=np.result_type(R, t, float))
    T[:3, :3] = R
    T[:3, 3] = t
    return T


#: the beam frame of placement aux_z: x_beam = z_i, y_beam = y_i, z_beam = -x_i
P_AUX = np.array([[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])


class Frame:
    """Rotation R (3 x 3), origin o (3) and Jacobians Jo, Jw (3 x nq), base frame."""

    __slots__ = ("R", "o", "Jo", "Jw")

    def __init__(self, R, o, Jo, Jw):
        self.R, self.o, self.Jo, self.Jw = R, o, Jo, Jw

    @staticmethod
    def base(nq: int, dtype=float) -> "Frame":
        return Frame(np.eye(3, dtype=dtype), np.zeros(3, dtype=dtype),
                     np.zeros((3, nq), dtype=dtype), np.zeros((3, nq), dtype=dtype))

    def fixed(self, Rc, tc) -> "Frame":
        """Move by a constant transform (Rc, tc) expressed in this frame."""
        r = self.R @ tc
        return Frame(self.R @ Rc, self.o + r, self.Jo - skew(r) @ self.Jw, self.Jw)

    def revolute(self, q, k: int) -> "Frame":
        """Rotate about the local z axis by q (coordinate k)."""
        Jw = self.Jw.copy()
        Jw[:, k] += self.R[:, 2]
        return Frame(self.R @ rot_z(q), self.o, self.Jo, Jw)

    def revolute_axis(self, q, k: int, u) -> "Frame":
        """Rotate about the local unit axis u by q (coordinate k)."""
        Jw = self.Jw.copy()
        Jw[:, k] += self.R @ u
        return Frame(self.R @ rot_axis(u, q), self.o, self.Jo, Jw)

    def prismatic_axis(self, q, k: int, u) -> "Frame":
        """Translate along the local unit axis u by q (coordinate k)."""
        e = self.R @ u
        r = e * q
        Jo = self.Jo - skew(r) @ self.Jw
        Jo[:, k] += e
        return Frame(self.R, self.o + r, Jo, self.Jw)

    def prismatic(self, q, k: int) -> "Frame":
        """Translate along the local z axis by q (coordinate k)."""
        r = self.R[:, 2] * q
        Jo = self.Jo - skew(r) @ self.Jw
        Jo[:, k] += self.R[:, 2]
        return Frame(self.R, self.o + r, Jo, self.Jw)

    def matrix(self) -> np.ndarray:
        return homogeneous(self.R, self.o)


def point_jacobians(frame: Frame, r_local):
    """Positions (n, 3) and Jacobians (n, 3, nq) of points at r_local (n, 3) in a frame."""
    r = r_local @ frame.R.T
    p = frame.o + r
    Jp = frame.Jo[None, :, :] - skew(r) @ frame.Jw
    return p, Jp
