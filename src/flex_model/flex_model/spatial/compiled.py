"""Compiled (numba) equations of motion of a spatial arm and a compiled generalized-alpha loop.

The same model as :class:`SpatialArmModel` (dynamics.py, the Python reference and oracle):

    M = sum m Jp^T Jp + sum Jw^T I Jw,
    c = sum m Jp^T (a_p - g) + sum Jw^T (I alpha + w x I w),

but the velocity terms are computed **analytically** by a recursive Newton-Euler forward
pass instead of the complex step: along the chain every frame carries, besides its pose
and Jacobians, its angular velocity w = Jw v and the bias accelerations (the accelerations
at zero q-ddot, i.e. dJ/dt v) of its origin, a_o, and its rotation, alpha:

- fixed offset r = R t:        a_o += alpha x r + w x (w x r)
- revolute joint, axis e = R u: alpha += w x e qd;  w += e qd
- prismatic joint, r = e q:    a_o += alpha x r + w x (w x r) + 2 w x e qd
- beam point (s, v, w)_beam:   a_p = a_o + alpha x r + w x (w x r) + 2 w x (R_b rdot)
- section rotation Rx(phi) Ry(-w') Rz(v') (seed 000 Eq. 19) with relative rate
  w_rel = e_x phi' + a_w dw' + a_v dv' (a_w = -Rx e_y, a_v = Rx Ry e_z, beam frame):
  alpha_rel = e_x phi' x a_w dw' + (e_x phi' + a_w dw') x a_v dv';
  w += R_b w_rel;  alpha += w x R_b w_rel + R_b alpha_rel.

The model data is a :class:`SpatialData` built once by :func:`pack` (per link: joint type and
axis, the fixed transforms before and after the joint and the beam, bodies; per beam
Gauss point: mass weights, the section inertia weights rhoJ ds, rho I_y ds, rho I_z ds
(the last two zero without rotary inertia) and the sampled bases, padded).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from typing import NamedTuple

from .. import integrators, kernels
from ..effects.friction import friction_law_compiled
from ..integrators import dead_zone
from ..kernels import cholesky, solve_chol
from ..solvers import galpha, loop, newton, status
from ..solvers.galpha import galpha_coefficients, galpha_state, restart_choice
from ..solvers.loop import implements, residual, tangent
from .dynamics import SpatialArmModel
from .exact import curvature_energy, link_sums, point_row, shape_sums

_CACHE = True


class SpatialData(NamedTuple):
    """The model data of the compiled kernels (:func:`pack`; module docstring): per link
    i, and per beam Gauss point p (the points of link i: pstart[i] <= p < pstart[i + 1],
    arrays padded to the longest beam)."""
    jtype: np.ndarray      # joint type: 0 revolute, 1 prismatic
    koff: np.ndarray       # the joint's coordinate in q
    axis: np.ndarray       # (3,) joint axis in the frame before the joint
    T: np.ndarray          # (4, 3, 4) [R | t]: origin, pre, before-beam, after-beam
    P: np.ndarray          # (3, 3) beam axes in the link frame
    flex: np.ndarray       # 1: a flexible link (a beam)
    nv: np.ndarray         # bending variables per plane
    nt: np.ndarray         # torsion variables
    fstart: np.ndarray     # the beam's first coordinate in q
    length: np.ndarray     # beam length, m
    bm: np.ndarray         # (2,) root and end body mass, kg
    bc: np.ndarray         # (2, 3) their centres' offsets
    bI: np.ndarray         # (2, 3, 3) their inertias about the centres
    pstart: np.ndarray     # (n + 1) the links' first Gauss points
    zs: np.ndarray         # per point: abscissa, m
    mw: np.ndarray         # mass weight rhoA ds, kg
    pw: np.ndarray         # (3) section inertia weights rhoJ ds, rho I_y ds, rho I_z ds
    Wv: np.ndarray         # bending shapes, v plane, and their slopes (dWv); w plane
    dWv: np.ndarray
    Ww: np.ndarray
    dWw: np.ndarray
    Pt: np.ndarray         # torsion shapes
    g: np.ndarray          # gravity, m/s^2
    nq: int
    rot: np.ndarray        # (3) per joint: rotor J_r, gear ratio n, spin coordinate or -1
    mdiag: np.ndarray      # constant motor inertias (diagonal of M)
    Sv: np.ndarray         # second_order: S(z) per plane at the points, and at the tip
    Sw: np.ndarray
    SL: np.ndarray
    so: int                # 1: second_order kinematics
    CF: np.ndarray         # curvature coupling (BeamData._coupling)
    CW: np.ndarray
    ex: int                # 1: exact kinematics (exact.py): node slopes, weights and the
    XD: np.ndarray         # points' rows, the links' first node and node count
    XW: np.ndarray
    XR: np.ndarray
    xstart: np.ndarray


def _combine(A, B):
    """(R, t) of the transform A followed by B (both (R, t) pairs)."""
    return A[0] @ B[0], A[0] @ B[1] + A[1]


def _link_transforms(model: SpatialArmModel, i: int, b) -> np.ndarray:
    """Link i's four constant transforms [R | t] (4, 3, 4): origin, pre (before the
    joint), before the beam and after it (the beam axes P and the DH or end transform)."""
    (Rpre, tpre), (Rdh, tdh), _ = model._consts[i]
    origin, _, end = model._extra[i]
    eye = (np.eye(3), np.zeros(3))
    stages = [origin or eye, (Rpre, tpre), eye, eye]
    if b is not None:
        after = (b.P.T, np.zeros(3))
        if b.beam.placement == "aux_z":
            stages[2] = (Rdh, tdh)
        elif b.beam.placement == "dh_x":
            after = _combine(after, (Rdh, np.zeros(3)))
        stages[3] = after
    else:
        stages[3] = (Rdh, tdh)
    if end is not None:
        stages[3] = _combine(stages[3], end)
    T = np.zeros((4, 3, 4))
    for s, (R, t) in enumerate(stages):
        T[s, :, :3] = R
        T[s, :, 3] = t
    return T


#: SpatialData's per-point fields, and per-node (exact) fields
_POINT_FIELDS = ("zs", "mw", "pw", "Wv", "dWv", "Ww", "dWw", "Pt", "Sv", "Sw", "CF", "CW",
                 "XD", "XW", "XR")


def _beam_point_arrays(b, maxnv: int, maxnt: int, maxn: int, so: bool, ex: bool) -> dict:
    """One beam's per-point (and exact: per-node) arrays of :class:`SpatialData`, padded
    to maxnv bending, maxnt torsion and maxn coupling columns."""
    npt = len(b.z)
    out = {"zs": b.z, "mw": b.mass_w}
    cf = np.zeros((npt, 5, maxn))   # curvature coupling (BeamData._coupling)
    cw = np.zeros((npt, 3))
    if b.coupling is not None:
        cf[:, :, :b.n] = b.coupling[0].transpose(1, 0, 2)
        cw[:] = np.column_stack(b.coupling[1:])
    out["CF"], out["CW"] = cf, cw
    pwk = np.zeros((npt, 3))      # rhoJ ds, rho I_y ds, rho I_z ds
    pwk[:, 0] = b.polar_w
    if b.rotary is not None:
        pwk[:, 1:] = b.rotary
    out["pw"] = pwk
    for name, src in (("Wv", b.Wv), ("dWv", b.dWv), ("Ww", b.Ww), ("dWw", b.dWw)):
        a = np.zeros((npt, maxnv))
        a[:, :src.shape[1]] = src
        out[name] = a
    a = np.zeros((npt, maxnt))
    a[:, :b.Pt.shape[1]] = b.Pt
    out["Pt"] = a
    if so:
        for name, src in (("Sv", b.Sv), ("Sw", b.Sw)):
            a = np.zeros((npt, maxnv, maxnv))
            a[:, :b.nv, :b.nv] = src
            out[name] = a
    if ex:
        nodes, wts, nfull, rows = b.rule
        a = np.zeros((len(nodes), 2, maxnv))
        a[:, 0, :b.nv], a[:, 1, :b.nv] = b.ndv, b.ndw
        out["XD"], out["XW"] = a, wts
        out["XR"] = rows[:-1]         # the mass points (the last row: the tip)
    return out


def _cat(parts, width=None):
    """The parts concatenated (C-contiguous); empty (0, *width) without parts."""
    if parts:
        return np.ascontiguousarray(np.concatenate(parts))
    if width is None:
        return np.zeros((0,))
    return np.zeros((0,) + (tuple(width) if isinstance(width, tuple) else (width,)))


def pack(model: SpatialArmModel) -> SpatialData:
    """The model data of the compiled kernels (:class:`SpatialData`)."""
    arm = model.arm
    so = getattr(arm, "kinematics", "small_deflection") == "second_order"
    ex = getattr(arm, "kinematics", "small_deflection") == "exact"
    n = model.n_links
    jtype = np.zeros(n, np.int64)
    axis = np.zeros((n, 3))
    T = np.zeros((n, 4, 3, 4))      # origin, pre, before-beam, after-beam: [R | t]
    P = np.zeros((n, 3, 3))
    flex, nv, nt, fstart = (np.zeros(n, np.int64) for _ in range(4))
    length = np.zeros(n)
    bm = np.zeros((n, 2))            # root, end body mass
    bc = np.zeros((n, 2, 3))
    bI = np.zeros((n, 2, 3, 3))
    pstart = np.zeros(n + 1, np.int64)
    beams = [b for b in model.beams if b is not None]
    maxnv = max([b.nv for b in beams] + [1])
    maxnt = max([b.nt for b in beams] + [1])
    maxn = max([b.n for b in beams] + [1])
    parts = {name: [] for name in _POINT_FIELDS}
    SL = np.zeros((n, 2, maxnv, maxnv))   # second_order: S at the tip per plane
    xstart = np.zeros((n + 1, 2), np.int64)   # exact: node start and nfull per link
    count = 0
    for i, (lk, b) in enumerate(zip(arm.links, model.beams)):
        jtype[i] = 1 if lk.joint.type == "prismatic" else 0
        axis[i] = np.asarray(lk.joint.axis, float)
        T[i] = _link_transforms(model, i, b)
        P[i] = np.eye(3)
        xstart[i + 1, 0] = xstart[i, 0]
        if b is not None:
            flex[i] = 1
            nv[i], nt[i] = b.nv, b.nt
            fstart[i] = model.flex_slice(i).start
            length[i] = b.length
            P[i] = b.P
            for name, a in _beam_point_arrays(b, maxnv, maxnt, maxn, so, ex).items():
                parts[name].append(a)
            if so:
                SL[i, 0, :b.nv, :b.nv] = b.SvL
                SL[i, 1, :b.nv, :b.nv] = b.SwL
            if ex:
                xstart[i + 1] = xstart[i, 0] + len(b.rule[0]), b.rule[2]
            count += len(b.z)
        for j, body in enumerate(model._consts[i][2]):
            if body is not None:
                bm[i, j], bc[i, j], bI[i, j] = body
        pstart[i + 1] = count
    # joint effects: rotor (J_r, n, spin coordinate or -1) per joint, constant motor inertias
    rot = np.array([[jr, ratio, spin] for jr, ratio, spin in model.rotors], float)
    # a writable copy: np.diag gives a read-only view, another numba signature (recompiles)
    mdiag = np.diag(model.M_const).copy()
    S0 = np.zeros((0, maxnv, maxnv))
    return SpatialData(
        jtype=jtype, koff=np.asarray(model.off, np.int64), axis=axis, T=T, P=P, flex=flex,
        nv=nv, nt=nt, fstart=fstart, length=length, bm=bm, bc=bc, bI=bI, pstart=pstart,
        zs=_cat(parts["zs"]), mw=_cat(parts["mw"]), pw=_cat(parts["pw"], 3),
        Wv=_cat(parts["Wv"], maxnv), dWv=_cat(parts["dWv"], maxnv),
        Ww=_cat(parts["Ww"], maxnv), dWw=_cat(parts["dWw"], maxnv),
        Pt=_cat(parts["Pt"], maxnt), g=np.asarray(model.gravity, float), nq=int(model.nq),
        rot=rot.reshape(n, 3), mdiag=mdiag,
        Sv=np.ascontiguousarray(np.concatenate(parts["Sv"])) if parts["Sv"] else S0,
        Sw=np.ascontiguousarray(np.concatenate(parts["Sw"])) if parts["Sw"] else S0.copy(),
        SL=SL, so=int(so), CF=_cat(parts["CF"], (5, maxn)), CW=_cat(parts["CW"], 3),
        ex=int(ex), XD=_cat(parts["XD"], (2, maxnv)), XW=_cat(parts["XW"]),
        XR=np.concatenate(parts["XR"]) if parts["XR"] else np.zeros((0, 3), np.int64),
        xstart=xstart)


# ------------------------------------------------------------------ small vector helpers

@njit(cache=_CACHE)
def _slide(Jo, Jw, e, qk, k, ncols, rv):
    """A prismatic joint's displacement r = e q_k (into ``rv``) in the point's Jacobian:
    J_o += J_w x r over the first ``ncols`` columns, and column k += e."""
    for a in range(3):
        rv[a] = e[a] * qk
    for j in range(ncols):
        Jo[0, j] += Jw[1, j] * rv[2] - Jw[2, j] * rv[1]
        Jo[1, j] += Jw[2, j] * rv[0] - Jw[0, j] * rv[2]
        Jo[2, j] += Jw[0, j] * rv[1] - Jw[1, j] * rv[0]
    for a in range(3):
        Jo[a, k] += e[a]


@njit(cache=_CACHE)
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=_CACHE)
def _mv(A, x):
    """A x for a 3 x 3 A (no BLAS call: small products dominate otherwise)."""
    out = np.empty(3)
    for a in range(3):
        out[a] = A[a, 0] * x[0] + A[a, 1] * x[1] + A[a, 2] * x[2]
    return out


@njit(cache=_CACHE)
def _mm(A, B):
    out = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            out[a, b] = A[a, 0] * B[0, b] + A[a, 1] * B[1, b] + A[a, 2] * B[2, b]
    return out


@njit(cache=_CACHE)
def _matvec(A, x):
    n, m = A.shape
    out = np.zeros(n)
    for a in range(n):
        s = 0.0
        for b in range(m):
            s += A[a, b] * x[b]
        out[a] = s
    return out


@njit(cache=_CACHE)
def _rotx(t):
    c, s = np.cos(t), np.sin(t)
    R = np.zeros((3, 3))
    R[0, 0] = 1.0
    R[1, 1] = c
    R[2, 2] = c
    R[1, 2] = -s
    R[2, 1] = s
    return R


@njit(cache=_CACHE)
def _roty(t):
    c, s = np.cos(t), np.sin(t)
    R = np.zeros((3, 3))
    R[1, 1] = 1.0
    R[0, 0] = c
    R[2, 2] = c
    R[2, 0] = -s
    R[0, 2] = s
    return R


@njit(cache=_CACHE)
def _rotz(t):
    c, s = np.cos(t), np.sin(t)
    R = np.zeros((3, 3))
    R[2, 2] = 1.0
    R[0, 0] = c
    R[1, 1] = c
    R[0, 1] = -s
    R[1, 0] = s
    return R


@njit(cache=_CACHE)
def _fixed(R, o, Jo, Jw, w, ao, al, Tc, ncols, W):
    """Move the frame (in place) by the constant transform Tc = [Rc | tc] (in the
    frame); Jacobian columns < ncols; W a 3 x 3 work array."""
    t0, t1, t2 = Tc[0, 3], Tc[1, 3], Tc[2, 3]
    r0 = R[0, 0] * t0 + R[0, 1] * t1 + R[0, 2] * t2
    r1 = R[1, 0] * t0 + R[1, 1] * t1 + R[1, 2] * t2
    r2 = R[2, 0] * t0 + R[2, 1] * t1 + R[2, 2] * t2
    if r0 != 0.0 or r1 != 0.0 or r2 != 0.0:
        for j in range(ncols):   # Jo -= r x Jw  (= Jw x r)
            Jo[0, j] += Jw[1, j] * r2 - Jw[2, j] * r1
            Jo[1, j] += Jw[2, j] * r0 - Jw[0, j] * r2
            Jo[2, j] += Jw[0, j] * r1 - Jw[1, j] * r0
        u0 = w[1] * r2 - w[2] * r1
        u1 = w[2] * r0 - w[0] * r2
        u2 = w[0] * r1 - w[1] * r0
        ao[0] += (al[1] * r2 - al[2] * r1) + (w[1] * u2 - w[2] * u1)
        ao[1] += (al[2] * r0 - al[0] * r2) + (w[2] * u0 - w[0] * u2)
        ao[2] += (al[0] * r1 - al[1] * r0) + (w[0] * u1 - w[1] * u0)
        o[0] += r0
        o[1] += r1
        o[2] += r2
    for a in range(3):
        for b in range(3):
            W[a, b] = R[a, 0] * Tc[0, b] + R[a, 1] * Tc[1, b] + R[a, 2] * Tc[2, b]
    R[:, :] = W


@njit(cache=_CACHE)
def _add_column(C6, col, w, b, c0, c1, c2):
    """C6[:, col] += w [b; c], the force and moment columns of a point mass's coordinate
    (b its direction, c = r x b)."""
    C6[0, col] += w * b[0]
    C6[1, col] += w * b[1]
    C6[2, col] += w * b[2]
    C6[3, col] += w * c0
    C6[4, col] += w * c1
    C6[5, col] += w * c2


@njit(cache=_CACHE)
def _rotate_axis(R, u, t, W):
    """R <- R Rot(u, t) in place (Rodrigues)."""
    c, s = np.cos(t), np.sin(t)
    k = 1.0 - c
    u0, u1, u2 = u[0], u[1], u[2]
    Q = np.empty((3, 3))
    Q[0, 0] = c + k * u0 * u0
    Q[0, 1] = k * u0 * u1 - s * u2
    Q[0, 2] = k * u0 * u2 + s * u1
    Q[1, 0] = k * u1 * u0 + s * u2
    Q[1, 1] = c + k * u1 * u1
    Q[1, 2] = k * u1 * u2 - s * u0
    Q[2, 0] = k * u2 * u0 - s * u1
    Q[2, 1] = k * u2 * u1 + s * u0
    Q[2, 2] = c + k * u2 * u2
    for a in range(3):
        for b in range(3):
            W[a, b] = R[a, 0] * Q[0, b] + R[a, 1] * Q[1, b] + R[a, 2] * Q[2, b]
    R[:, :] = W


@njit(cache=_CACHE)
def _section(phi, dv, dw, phid, dvd, dwd):
    """Section rotation Rs = Ry(-w') Rz(v') Rx(phi) (the twist about the tangent), its
    axes a_w, a_v, a_t (beam frame) and the relative angular velocity and bias
    acceleration (beam frame)."""
    Ry = _roty(-dw)
    Ryz = _mm(Ry, _rotz(dv))
    Rs = _mm(Ryz, _rotx(phi))
    aw = np.array([0.0, -1.0, 0.0])
    av = np.empty(3)
    at = np.empty(3)
    for a in range(3):
        av[a] = Ry[a, 2]
        at[a] = Ryz[a, 0]
    w1 = np.empty(3)
    w2 = np.empty(3)
    w3 = np.empty(3)
    w12 = np.empty(3)
    wrel = np.empty(3)
    for a in range(3):
        w1[a] = aw[a] * dwd
        w2[a] = av[a] * dvd
        w3[a] = at[a] * phid
        w12[a] = w1[a] + w2[a]
        wrel[a] = w12[a] + w3[a]
    t1 = np.zeros(3)
    t2 = np.zeros(3)
    _cross(w1, w2, t1)
    _cross(w12, w3, t2)
    for a in range(3):
        t1[a] += t2[a]
    return Rs, aw, av, at, wrel, t1


@njit(cache=_CACHE)
def _group_point(G, m, r, acc):
    """Add a point mass m at r (from the group frame's origin, base axes) with absolute
    acceleration-minus-gravity acc to the group G = [m, S(3), J2(9), f_lin(3), f_ang(3)]."""
    G[0] += m
    rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    for a in range(3):
        G[1 + a] += m * r[a]
        for b in range(3):
            G[4 + 3 * a + b] += m * ((rr if a == b else 0.0) - r[a] * r[b])
        G[13 + a] += m * acc[a]
    G[16] += m * (r[1] * acc[2] - r[2] * acc[1])
    G[17] += m * (r[2] * acc[0] - r[0] * acc[2])
    G[18] += m * (r[0] * acc[1] - r[1] * acc[0])


@njit(cache=_CACHE)
def _flush(G, C6, c0, c1, Jo, Jw, ncols, M, c, X, want_m):
    """M += J6^T I6 J6 and c += J6^T f6 for the group G at a frame with Jacobians
    J6 = [Jo; Jw] (columns < ncols), I6 = [[m, -[S]x], [[S]x, J2]], f6 = [f_lin; f_ang];
    plus the coupling with the group's own columns [c0, c1): M[a, j] += J6[:, a] . C6[:, j]
    (a < ncols <= c0: upper triangle)."""
    if not want_m:
        for a in range(ncols):
            c[a] += (Jo[0, a] * G[13] + Jo[1, a] * G[14] + Jo[2, a] * G[15]
                     + Jw[0, a] * G[16] + Jw[1, a] * G[17] + Jw[2, a] * G[18])
        return
    m = G[0]
    S0, S1, S2 = G[1], G[2], G[3]
    for j in range(ncols):
        o0, o1, o2 = Jo[0, j], Jo[1, j], Jo[2, j]
        w0, w1, w2 = Jw[0, j], Jw[1, j], Jw[2, j]
        # top: m Jo - S x Jw ; bottom: S x Jo + J2 Jw
        X[0, j] = m * o0 - (S1 * w2 - S2 * w1)
        X[1, j] = m * o1 - (S2 * w0 - S0 * w2)
        X[2, j] = m * o2 - (S0 * w1 - S1 * w0)
        X[3, j] = (S1 * o2 - S2 * o1) + G[4] * w0 + G[5] * w1 + G[6] * w2
        X[4, j] = (S2 * o0 - S0 * o2) + G[7] * w0 + G[8] * w1 + G[9] * w2
        X[5, j] = (S0 * o1 - S1 * o0) + G[10] * w0 + G[11] * w1 + G[12] * w2
    for a in range(ncols):
        o0, o1, o2 = Jo[0, a], Jo[1, a], Jo[2, a]
        w0, w1, w2 = Jw[0, a], Jw[1, a], Jw[2, a]
        if o0 == 0.0 and o1 == 0.0 and o2 == 0.0 and w0 == 0.0 and w1 == 0.0 and w2 == 0.0:
            continue
        c[a] += o0 * G[13] + o1 * G[14] + o2 * G[15] + w0 * G[16] + w1 * G[17] + w2 * G[18]
        for b in range(a, ncols):
            M[a, b] += (o0 * X[0, b] + o1 * X[1, b] + o2 * X[2, b] + w0 * X[3, b]
                        + w1 * X[4, b] + w2 * X[5, b])
        for j in range(c0, c1):
            M[a, j] += (o0 * C6[0, j] + o1 * C6[1, j] + o2 * C6[2, j] + w0 * C6[3, j]
                        + w1 * C6[4, j] + w2 * C6[5, j])


@njit(cache=_CACHE)
def _nonzero(x):
    for a in range(x.shape[0]):
        if x[a] != 0.0:
            return True
    return False


@njit(cache=_CACHE)
def _body_into(G, R, or0, or1, or2, ao, al, w, m, off, Ib, g, rv, acc, W):
    """A rigid body (mass m at offset ``off`` in frame R, inertia Ib about its centre)
    fixed to the group's frame; (or0, or1, or2): frame origin minus the group origin."""
    if m != 0.0:
        for a in range(3):
            rv[a] = (R[a, 0] * off[0] + R[a, 1] * off[1] + R[a, 2] * off[2]
                     + (or0 if a == 0 else (or1 if a == 1 else or2)))
        r0, r1, r2 = rv[0], rv[1], rv[2]
        u0 = w[1] * r2 - w[2] * r1
        u1 = w[2] * r0 - w[0] * r2
        u2 = w[0] * r1 - w[1] * r0
        acc[0] = ao[0] + (al[1] * r2 - al[2] * r1) + (w[1] * u2 - w[2] * u1) - g[0]
        acc[1] = ao[1] + (al[2] * r0 - al[0] * r2) + (w[2] * u0 - w[0] * u2) - g[1]
        acc[2] = ao[2] + (al[0] * r1 - al[1] * r0) + (w[0] * u1 - w[1] * u0) - g[2]
        _group_point(G, m, rv, acc)
    if Ib[0, 0] != 0.0 or Ib[1, 1] != 0.0 or Ib[2, 2] != 0.0 or Ib[0, 1] != 0.0 \
            or Ib[0, 2] != 0.0 or Ib[1, 2] != 0.0:
        for a in range(3):     # W = R Ib
            for b in range(3):
                W[a, b] = R[a, 0] * Ib[0, b] + R[a, 1] * Ib[1, b] + R[a, 2] * Ib[2, b]
        for a in range(3):     # I = W R^T, into G; I w into rv, I alpha into acc
            rv[a] = 0.0
            acc[a] = 0.0
            for b in range(3):
                Iab = W[a, 0] * R[b, 0] + W[a, 1] * R[b, 1] + W[a, 2] * R[b, 2]
                G[4 + 3 * a + b] += Iab
                rv[a] += Iab * w[b]
                acc[a] += Iab * al[b]
        G[16] += acc[0] + w[1] * rv[2] - w[2] * rv[1]
        G[17] += acc[1] + w[2] * rv[0] - w[0] * rv[2]
        G[18] += acc[2] + w[0] * rv[1] - w[1] * rv[0]


@njit(cache=_CACHE)
def _rotor(jr, ratio, spin, e, w, al, Jw, ncols, v, qdd, M, c, a6, want_m):
    """A geared rotor on the stator frame (angular velocity w, acceleration al, Jacobian
    Jw, columns < ncols) about the joint axis e: omega_r = w + n e v[spin] (spin < 0:
    locked, no spin), inertia jr e e^T. Adds Jr^T (I alpha_r + omega_r x I omega_r) to c
    and jr a a^T to M (a = Jw^T e + n e_spin; upper triangle; a6: work, length nq)."""
    s = ratio * v[spin] if spin >= 0 else 0.0
    sa = ratio * qdd[spin] if spin >= 0 else 0.0
    ew = e[0] * w[0] + e[1] * w[1] + e[2] * w[2] + s
    ea = e[0] * al[0] + e[1] * al[1] + e[2] * al[2] + sa
    # torque: jr (e . alpha_r) e + jr (e . omega_r) (w x e)
    t0 = jr * (ea * e[0] + ew * (w[1] * e[2] - w[2] * e[1]))
    t1 = jr * (ea * e[1] + ew * (w[2] * e[0] - w[0] * e[2]))
    t2 = jr * (ea * e[2] + ew * (w[0] * e[1] - w[1] * e[0]))
    for j in range(ncols):
        c[j] += Jw[0, j] * t0 + Jw[1, j] * t1 + Jw[2, j] * t2
    if spin >= 0:
        c[spin] += ratio * jr * ea
    if not want_m:
        return
    nq = a6.shape[0]
    a6[:] = 0.0
    for j in range(ncols):
        a6[j] = Jw[0, j] * e[0] + Jw[1, j] * e[1] + Jw[2, j] * e[2]
    if spin >= 0:
        a6[spin] += ratio
    for a in range(nq):
        if a6[a] != 0.0:
            for b in range(a, nq):
                M[a, b] += jr * a6[a] * a6[b]


@njit(cache=_CACHE)
def _shortening(Sa, Sb, fv, fw, gv, gw, hv, hw, sa_out, sb_out):
    """second_order: the axial shortening u = 1/2 (f_v^T Sa f_v + f_w^T Sb f_w) of a point
    (Sa, Sb: S(z) of the v and w planes there; dynamics.BeamData.second_order), its rate
    and its acceleration (f' = g, f'' = h); Sa f_v and Sb f_w (the own columns' axial
    parts) into sa_out, sb_out."""
    u = 0.0
    du = 0.0
    ddu = 0.0
    for j in range(sa_out.shape[0]):
        sa = 0.0
        sc = 0.0
        ga = 0.0
        gc = 0.0
        for jj in range(sa_out.shape[0]):
            sa += Sa[j, jj] * fv[jj]
            sc += Sb[j, jj] * fw[jj]
            ga += Sa[j, jj] * gv[jj]
            gc += Sb[j, jj] * gw[jj]
        sa_out[j] = sa
        sb_out[j] = sc
        u += 0.5 * (sa * fv[j] + sc * fw[j])
        du += sa * gv[j] + sc * gw[j]
        ddu += ga * gv[j] + gc * gw[j] + sa * hv[j] + sc * hw[j]
    return u, du, ddu


@njit(cache=_CACHE)
def _beam_vector(Rb, x, k):
    """Rb @ x[k:k + 3] (a beam-frame vector to base axes)."""
    return (Rb[0, 0] * x[k] + Rb[0, 1] * x[k + 1] + Rb[0, 2] * x[k + 2],
            Rb[1, 0] * x[k] + Rb[1, 1] * x[k + 1] + Rb[1, 2] * x[k + 2],
            Rb[2, 0] * x[k] + Rb[2, 1] * x[k + 1] + Rb[2, 2] * x[k + 2])


@njit(cache=_CACHE)
def _own_columns(xdir, s0, mp, r, acc, C6, M, c, want_m):
    """exact: a mass point's own columns s0 + j along xdir[j] (base axes): c += mp xdir_j .
    acc, its force and moment columns into C6 and the own block of M (upper triangle)."""
    n = xdir.shape[0]
    for j in range(n):
        x0, x1, x2 = xdir[j, 0], xdir[j, 1], xdir[j, 2]
        c[s0 + j] += mp * (x0 * acc[0] + x1 * acc[1] + x2 * acc[2])
        if not want_m:
            continue
        _add_column(C6, s0 + j, mp, xdir[j], r[1] * x2 - r[2] * x1, r[2] * x0 - r[0] * x2,
                    r[0] * x1 - r[1] * x0)
        for jj in range(j, n):
            M[s0 + j, s0 + jj] += mp * (x0 * xdir[jj, 0] + x1 * xdir[jj, 1] + x2 * xdir[jj, 2])


def spatial_terms(Pm, q, v):
    """(M(q), c(q, v)) of the spatial arm ``Pm`` = :func:`pack` (model): c holds the
    velocity terms (analytic Newton-Euler bias accelerations) and gravity. (Plain Python:
    a compiled wrapper would link and compile spatial_eval once more.)"""
    q = np.ascontiguousarray(q, dtype=float)
    return spatial_eval(Pm, q, np.ascontiguousarray(v, dtype=float), np.zeros(q.shape[0]),
                        True)


@njit(cache=_CACHE)
def _joint(i, Pm, q, v, qdd, R, o, Jo, Jw, w, ao, al, e, rv, xv, t1, t2, t3, W, M, c, a6,
           want_m):
    """Link i up to its beam: the origin transform, the joint's rotor (:func:`_rotor`),
    the joint's motion (module docstring; revolute: alpha += w x e qd + e qdd,
    w += e qd; prismatic, r = e q: a_o += alpha x r + w x (w x r) + 2 w x e qd + e qdd)
    and the constant transforms before the beam."""
    k = Pm.koff[i]
    ncols = k + 1
    _fixed(R, o, Jo, Jw, w, ao, al, Pm.T[i, 0], ncols, W)
    u = Pm.axis[i]
    for a in range(3):
        e[a] = R[a, 0] * u[0] + R[a, 1] * u[1] + R[a, 2] * u[2]
    rot = Pm.rot
    if rot[i, 0] != 0.0:
        _rotor(rot[i, 0], rot[i, 1], int(rot[i, 2]), e, w, al, Jw, ncols, v, qdd, M, c,
               a6, want_m)
    qd = v[k]
    if Pm.jtype[i] == 0:
        e0, e1, e2 = e[0] * qd, e[1] * qd, e[2] * qd
        for a in range(3):
            Jw[a, k] += e[a]
        al[0] += w[1] * e2 - w[2] * e1 + e[0] * qdd[k]
        al[1] += w[2] * e0 - w[0] * e2 + e[1] * qdd[k]
        al[2] += w[0] * e1 - w[1] * e0 + e[2] * qdd[k]
        w[0] += e0
        w[1] += e1
        w[2] += e2
        _rotate_axis(R, u, q[k], W)
    else:
        _slide(Jo, Jw, e, q[k], k, ncols, rv)
        for a in range(3):
            xv[a] = e[a] * qd
        _cross(al, rv, t1)
        _cross(w, rv, t2)
        _cross(w, t2, t3)
        _cross(w, xv, t2)
        for a in range(3):
            ao[a] += t1[a] + t3[a] + 2.0 * t2[a] + e[a] * qdd[k]
            o[a] += rv[a]
    _fixed(R, o, Jo, Jw, w, ao, al, Pm.T[i, 1], ncols, W)
    if Pm.flex[i]:
        _fixed(R, o, Jo, Jw, w, ao, al, Pm.T[i, 2], ncols, W)


@njit(cache=_CACHE)
def _rigid_end(i, Pm, G, R, o, Jo, Jw, w, ao, al, rv, acc, W, o_root, ao_root, Jo_root, C6,
               M, c, X6, want_m):
    """Rigid link i past its joint: the end body joins the root group G (the same
    Jacobians up to the offset r from the root frame), then the end transform."""
    bm, bI, T = Pm.bm, Pm.bI, Pm.T
    ncols = Pm.koff[i] + 1
    zero = Pm.koff[0] * 0          # an int64, not a literal: one _flush signature
    if _nonzero(G) or bm[i, 1] != 0.0 or _nonzero(bI[i, 1].ravel()):
        for a in range(3):
            o_root[a] = o[a]
            ao_root[a] = ao[a]
            for j in range(ncols):
                Jo_root[a, j] = Jo[a, j]
        _fixed(R, o, Jo, Jw, w, ao, al, T[i, 3], ncols, W)
        _body_into(G, R, o[0] - o_root[0], o[1] - o_root[1], o[2] - o_root[2],
                   ao_root, al, w, bm[i, 1], Pm.bc[i, 1], bI[i, 1], Pm.g, rv, acc, W)
        _flush(G, C6, zero, zero, Jo_root, Jw, ncols, M, c, X6, want_m)
    else:
        _fixed(R, o, Jo, Jw, w, ao, al, T[i, 3], ncols, W)


@njit(cache=_CACHE, inline="always")   # per point: no call's reference counts
def _point_shapes(p, Wv, Ww, dWv, dWw, nv, fv, fw, gv, gw, hv, hw):
    """At Gauss point p: the deflections v, w (shapes W q_f) and their slopes v', w', their
    rates and their accelerations (Pm's arrays: see _beam_points)."""
    yv, sv, av_ = shape_sums(Wv, p, nv, fv, gv, hv)
    yw, sw, aw_ = shape_sums(Ww, p, nv, fw, gw, hw)
    ydv, sdv, adv = shape_sums(dWv, p, nv, fv, gv, hv)
    ydw, sdw, adw = shape_sums(dWw, p, nv, fw, gw, hw)
    return yv, yw, ydv, ydw, sv, sw, sdv, sdw, av_, aw_, adv, adw


@njit(cache=_CACHE, inline="always")   # per point: no call's reference counts
def _point_offset(p, zs, Sv, Sw, XR, so, ex, nv, y, fv, fw, gv, gw, hv, hw, Rb, bx, by, bz,
                  Xn, Pre, xrow, xdir, sva, swa):
    """Gauss point p from the beam frame's origin (base axes), its rate and its
    acceleration relative to the beam frame: (z, v, w) with small deflections (thesis
    Eq. 1), (z - u, v, w) with second_order (u the shortening) or r = int t ds
    exact (exact.py, its own columns into xdir); y = _point_shapes(...)."""
    yv, yw, ydv, ydw, sv, sw, sdv, sdw, av_, aw_, adv, adw = y
    zp = zs[p]
    ush = 0.0           # second_order: shortening u, its rate and acceleration
    dsh = 0.0
    ash = 0.0
    if so:
        ush, dsh, ash = _shortening(Sv[p], Sw[p], fv, fw, gv, gw, hv, hw, sva, swa)
        zp = zp - ush
    r0 = zp * bx[0] + yv * by[0] + yw * bz[0]
    r1 = zp * bx[1] + yv * by[1] + yw * bz[1]
    r2 = zp * bx[2] + yv * by[2] + yw * bz[2]
    d0 = sv * by[0] + sw * bz[0] - dsh * bx[0]
    d1 = sv * by[1] + sw * bz[1] - dsh * bx[1]
    d2 = sv * by[2] + sw * bz[2] - dsh * bx[2]
    ex0 = av_ * by[0] + aw_ * bz[0] - ash * bx[0]
    ex1 = av_ * by[1] + aw_ * bz[1] - ash * bx[1]
    ex2 = av_ * by[2] + aw_ * bz[2] - ash * bx[2]
    if ex:      # r = int t ds, its rate and acceleration, own columns (exact.py)
        point_row(Xn, Pre, XR[p, 0], XR[p, 1], XR[p, 2], xrow)
        r0, r1, r2 = _beam_vector(Rb, xrow, 0)
        d0, d1, d2 = _beam_vector(Rb, xrow, 3)
        ex0, ex1, ex2 = _beam_vector(Rb, xrow, 6)
        for j in range(2 * nv):
            xdir[j, 0], xdir[j, 1], xdir[j, 2] = _beam_vector(Rb, xrow, 9 + 3 * j)
    return r0, r1, r2, d0, d1, d2, ex0, ex1, ex2


@njit(cache=_CACHE)
def _point_acceleration(w, ao, al, g, x, acc):
    """acc = a_p - g of a beam point at r from the frame origin moving at rd and
    accelerating at rdd relative to the beam frame (x = (r, rd, rdd)):
    a_p = a_o + alpha x r + w x (w x r) + 2 w x rd + rdd (module docstring)."""
    r0, r1, r2, d0, d1, d2, ex0, ex1, ex2 = x
    u0 = w[1] * r2 - w[2] * r1
    u1 = w[2] * r0 - w[0] * r2
    u2 = w[0] * r1 - w[1] * r0
    acc[0] = ao[0] + (al[1] * r2 - al[2] * r1) + (w[1] * u2 - w[2] * u1) \
        + 2.0 * (w[1] * d2 - w[2] * d1) - g[0] + ex0
    acc[1] = ao[1] + (al[2] * r0 - al[0] * r2) + (w[2] * u0 - w[0] * u2) \
        + 2.0 * (w[2] * d0 - w[0] * d2) - g[1] + ex1
    acc[2] = ao[2] + (al[0] * r1 - al[1] * r0) + (w[0] * u1 - w[1] * u0) \
        + 2.0 * (w[0] * d1 - w[1] * d0) - g[2] + ex2


@njit(cache=_CACHE)
def _shortening_columns(s0, nv, mp, rv, bx, acc, sva, swa, C6, M, c, want_m):
    """second_order: the axial parts -b_x (Sv f_v)_j, -b_x (Sw f_w)_j of a point mass's own
    columns (c, their force and moment columns into C6, the own block of M)."""
    r0, r1, r2 = rv[0], rv[1], rv[2]
    ax = bx[0] * acc[0] + bx[1] * acc[1] + bx[2] * acc[2]
    cx0 = r1 * bx[2] - r2 * bx[1]
    cx1 = r2 * bx[0] - r0 * bx[2]
    cx2 = r0 * bx[1] - r1 * bx[0]
    for j in range(nv):
        c[s0 + j] -= mp * sva[j] * ax
        c[s0 + nv + j] -= mp * swa[j] * ax
        if not want_m:
            continue
        jv = s0 + j
        jw = s0 + nv + j
        mv = mp * sva[j]
        mwj = mp * swa[j]
        _add_column(C6, jv, -mv, bx, cx0, cx1, cx2)
        _add_column(C6, jw, -mwj, bx, cx0, cx1, cx2)
        for jj in range(j, nv):
            M[jv, s0 + jj] += mv * sva[jj]
            M[jw, s0 + nv + jj] += mwj * swa[jj]
        for jj in range(nv):
            M[jv, s0 + nv + jj] += mv * swa[jj]


@njit(cache=_CACHE)
def _bending_columns(p, Wv, Ww, s0, nv, mp, rv, by, bz, acc, C6, M, c, want_m):
    """The point mass's own bending columns b_y Wv_j (v) and b_z Ww_j (w): c, their
    force and moment columns into C6 and the own block of M (upper triangle)."""
    r0, r1, r2 = rv[0], rv[1], rv[2]
    ay = by[0] * acc[0] + by[1] * acc[1] + by[2] * acc[2]
    az = bz[0] * acc[0] + bz[1] * acc[1] + bz[2] * acc[2]
    cy0 = r1 * by[2] - r2 * by[1]
    cy1 = r2 * by[0] - r0 * by[2]
    cy2 = r0 * by[1] - r1 * by[0]
    cz0 = r1 * bz[2] - r2 * bz[1]
    cz1 = r2 * bz[0] - r0 * bz[2]
    cz2 = r0 * bz[1] - r1 * bz[0]
    for j in range(nv):
        c[s0 + j] += mp * Wv[p, j] * ay
        c[s0 + nv + j] += mp * Ww[p, j] * az
        if not want_m:
            continue
        wv = mp * Wv[p, j]
        ww = mp * Ww[p, j]
        jv = s0 + j
        jw = s0 + nv + j
        _add_column(C6, jv, wv, by, cy0, cy1, cy2)
        _add_column(C6, jw, ww, bz, cz0, cz1, cz2)
        for jj in range(j, nv):
            M[jv, s0 + jj] += wv * Wv[p, jj]
            M[jw, s0 + nv + jj] += ww * Ww[p, jj]


@njit(cache=_CACHE)
def _section_axes(p, Pt, nt, ft, gt, ht, y, Rb, ek, S):
    """The section rotation Rs = Ry(-w') Rz(v') Rx(phi) at Gauss point p (seed 000
    Eq. 19; y = _point_shapes(...)): its axes in base axes into the rows of ek (x = a_t,
    the tangent; y, z) and, in base axes, into the rows of S: the relative angular
    velocity w_rel = a_t phi' + a_w dw' + a_v dv', its bias acceleration plus the second
    derivatives' terms, and the axes a_v, a_w, a_t."""
    ydv, ydw, sdv, sdw, adv, adw = y[2], y[3], y[6], y[7], y[10], y[11]
    phi = 0.0
    sphi = 0.0
    for j in range(nt):
        phi += Pt[p, j] * ft[j]
        sphi += Pt[p, j] * gt[j]
    aphi = 0.0
    for j in range(nt):
        aphi += Pt[p, j] * ht[j]
    cf, sf = np.cos(phi), np.sin(phi)
    cp, sp = np.cos(ydw), -np.sin(ydw)          # Ry(-w')
    ct, st = np.cos(ydv), np.sin(ydv)
    # Rs = Ry(-w') Rz(v') Rx(phi), beam-frame axes: a_w = -e_y, a_v = Ry e_z,
    # a_t = Ry Rz e_x (the tangent: the section's x axis), c1 = Ry Rz e_y
    aw0, aw1, aw2 = 0.0, -1.0, 0.0
    av0, av1, av2 = sp, 0.0, cp
    at0, at1, at2 = cp * ct, st, -sp * ct
    c10, c11, c12 = -cp * st, ct, sp * st
    # relative angular velocity and bias acceleration (beam frame)
    e0, e1, e2 = aw0 * sdw, aw1 * sdw, aw2 * sdw         # a_w dw'
    f0, f1, f2 = av0 * sdv, av1 * sdv, av2 * sdv         # a_v dv'
    h0, h1, h2 = at0 * sphi, at1 * sphi, at2 * sphi      # a_t phi'
    wr0, wr1, wr2 = e0 + f0 + h0, e1 + f1 + h1, e2 + f2 + h2
    # e x f + (e + f) x h
    ar0 = (e1 * f2 - e2 * f1) + ((e1 + f1) * h2 - (e2 + f2) * h1)
    ar1 = (e2 * f0 - e0 * f2) + ((e2 + f2) * h0 - (e0 + f0) * h2)
    ar2 = (e0 * f1 - e1 * f0) + ((e0 + f0) * h1 - (e1 + f1) * h0)
    # plus the second derivatives: a_t phi'' + a_w dw'' + a_v dv''
    ar0 += at0 * aphi + aw0 * adw + av0 * adv
    ar1 += at1 * aphi + aw1 * adw + av1 * adv
    ar2 += at2 * aphi + aw2 * adw + av2 * adv
    # to base axes
    for a in range(3):
        S[0, a] = Rb[a, 0] * wr0 + Rb[a, 1] * wr1 + Rb[a, 2] * wr2
        S[1, a] = Rb[a, 0] * ar0 + Rb[a, 1] * ar1 + Rb[a, 2] * ar2
        S[2, a] = Rb[a, 0] * av0 + Rb[a, 1] * av1 + Rb[a, 2] * av2
        S[3, a] = Rb[a, 1] * aw1
        S[4, a] = Rb[a, 0] * at0 + Rb[a, 1] * at1 + Rb[a, 2] * at2
    # section axes (base): x = a_t, y = cf c1 + sf a_v, z = -sf c1 + cf a_v
    ys0, ys1, ys2 = cf * c10 + sf * av0, cf * c11 + sf * av1, cf * c12 + sf * av2
    zs0, zs1, zs2 = -sf * c10 + cf * av0, -sf * c11 + cf * av1, \
        -sf * c12 + cf * av2
    for a in range(3):
        ek[0, a] = Rb[a, 0] * at0 + Rb[a, 1] * at1 + Rb[a, 2] * at2
        ek[1, a] = Rb[a, 0] * ys0 + Rb[a, 1] * ys1 + Rb[a, 2] * ys2
        ek[2, a] = Rb[a, 0] * zs0 + Rb[a, 1] * zs1 + Rb[a, 2] * zs2


@njit(cache=_CACHE)
def _section_inertia(p, pw, dWv, dWw, Pt, s0, nv, nt, nk, w, al, ek, S, tau, G, C6, M, c, sown,
                     want_m):
    """The section's rotary inertia at Gauss point p, pw[p, k] e_k e_k^T (rhoJ about x;
    with rotary inertia rho I_y, rho I_z about y, z; ek, S of :func:`_section_axes`),
    turning at w_p = w + w_rel, alpha_p = alpha + w x w_rel + (bias): its torque
    tau = sum_k pw_k (e_k (e_k . alpha_p) + (e_k . w_p) w_p x e_k) into G and, along the
    own rotation columns a_v dWv_j, a_w dWw_j, a_t Pt_j, into c, C6 and M."""
    wb0, wb1, wb2 = S[0, 0], S[0, 1], S[0, 2]
    ab0, ab1, ab2 = S[1, 0], S[1, 1], S[1, 2]
    avb0, avb1, avb2 = S[2, 0], S[2, 1], S[2, 2]
    awb0, awb1, awb2 = S[3, 0], S[3, 1], S[3, 2]
    atb0, atb1, atb2 = S[4, 0], S[4, 1], S[4, 2]
    wp0, wp1, wp2 = w[0] + wb0, w[1] + wb1, w[2] + wb2
    lp0 = al[0] + (w[1] * wb2 - w[2] * wb1) + ab0
    lp1 = al[1] + (w[2] * wb0 - w[0] * wb2) + ab1
    lp2 = al[2] + (w[0] * wb1 - w[1] * wb0) + ab2
    tau[0] = 0.0
    tau[1] = 0.0
    tau[2] = 0.0
    n2 = 2 * nv
    nown = n2 + nt
    for k in range(nk):
        pj = pw[p, k]
        x0, x1, x2 = ek[k, 0], ek[k, 1], ek[k, 2]
        xw = x0 * wp0 + x1 * wp1 + x2 * wp2
        xl = x0 * lp0 + x1 * lp1 + x2 * lp2
        # tau += pj (x (x . alpha) + (x . w) w x x)
        tau[0] += pj * (x0 * xl + xw * (wp1 * x2 - wp2 * x1))
        tau[1] += pj * (x1 * xl + xw * (wp2 * x0 - wp0 * x2))
        tau[2] += pj * (x2 * xl + xw * (wp0 * x1 - wp1 * x0))
        for a in range(3):
            for b in range(3):
                G[4 + 3 * a + b] += pj * ek[k, a] * ek[k, b]
        if not want_m:
            continue
        Av = x0 * avb0 + x1 * avb1 + x2 * avb2
        Aw = x0 * awb0 + x1 * awb1 + x2 * awb2
        Ax = x0 * atb0 + x1 * atb1 + x2 * atb2
        for j in range(nv):
            sown[j] = Av * dWv[p, j]
            sown[nv + j] = Aw * dWw[p, j]
        for j in range(nt):
            sown[n2 + j] = Ax * Pt[p, j]
        for j in range(nown):
            sj = pj * sown[j]
            C6[3, s0 + j] += sj * x0
            C6[4, s0 + j] += sj * x1
            C6[5, s0 + j] += sj * x2
            for jj in range(j, nown):
                M[s0 + j, s0 + jj] += sj * sown[jj]
    for a in range(3):
        G[16 + a] += tau[a]
    Tv = avb0 * tau[0] + avb1 * tau[1] + avb2 * tau[2]
    Tw = awb0 * tau[0] + awb1 * tau[1] + awb2 * tau[2]
    Tx = atb0 * tau[0] + atb1 * tau[1] + atb2 * tau[2]
    for j in range(nv):
        c[s0 + j] += Tv * dWv[p, j]
        c[s0 + nv + j] += Tw * dWw[p, j]
    for j in range(nt):
        c[s0 + n2 + j] += Tx * Pt[p, j]


@njit(cache=_CACHE)
def _beam_points(i, Pm, s0, nv, nt, nk, f, Rb, bx, by, bz, w, ao, al, G, C6, M, c, Xn, Pre,
                 xrow, xdir, sva, swa, sown, rv, acc, ek, S, tau, want_m):
    """The Gauss points p of beam i (f = the beam's q, v, qdd slices fv, fw, ft, gv, ...,
    ht): each one's mass into the group G, its own columns (bending, shortening or exact)
    and its section's rotary inertia (torsion or rotary inertia: nt > 0 or nk == 3). One
    call for all points: a call costs a reference count of each array passed."""
    fv, fw, ft, gv, gw, gt, hv, hw, ht = f
    Wv, Ww, dWv, dWw, Pt, mw, g = Pm.Wv, Pm.Ww, Pm.dWv, Pm.dWw, Pm.Pt, Pm.mw, Pm.g
    so, ex = Pm.so, Pm.ex
    for p in range(Pm.pstart[i], Pm.pstart[i + 1]):
        y = _point_shapes(p, Wv, Ww, dWv, dWw, nv, fv, fw, gv, gw, hv, hw)
        mp = mw[p]
        x = _point_offset(p, Pm.zs, Pm.Sv, Pm.Sw, Pm.XR, so, ex, nv, y, fv, fw, gv, gw, hv,
                          hw, Rb, bx, by, bz, Xn, Pre, xrow, xdir, sva, swa)
        _point_acceleration(w, ao, al, g, x, acc)
        rv[0] = x[0]
        rv[1] = x[1]
        rv[2] = x[2]
        _group_point(G, mp, rv, acc)
        if ex:
            _own_columns(xdir, s0, mp, rv, acc, C6, M, c, want_m)
        if so:      # own columns b_y Wv_j - b_x (Sv f_v)_j, b_z Ww_j - b_x (Sw f_w)_j
            _shortening_columns(s0, nv, mp, rv, bx, acc, sva, swa, C6, M, c, want_m)
        if not ex:
            _bending_columns(p, Wv, Ww, s0, nv, mp, rv, by, bz, acc, C6, M, c, want_m)
        if nt or nk == 3:
            _section_axes(p, Pt, nt, ft, gt, ht, y, Rb, ek, S)
            _section_inertia(p, Pm.pw, dWv, dWw, Pt, s0, nv, nt, nk, w, al, ek, S, tau, G, C6,
                             M, c, sown, want_m)


@njit(cache=_CACHE)
def _tip_translation(i, Pm, s0, nv, f, Rb, bx, by, bz, o, Jo, Jw, w, ao, al, Xn, Pre,
                     xrow, sva, swa, rv, xv, tmp, t1, t2, t3, t4):
    """The beam's tip offset r (small deflections: (L, v, w); second_order: (L - u(L), v,
    w); exact: r(L)) moves the frame: o += r, a_o += alpha x r + w x (w x r) + 2 w x rd
    + rdd, Jo += Jw x r (the columns before the beam)."""
    fv, fw, ft, gv, gw, gt, hv, hw, ht = f
    L = Pm.length[i]
    ncols = Pm.koff[i] + 1
    tv, tw = fv[nv - 2], fw[nv - 2]
    sv, sw = gv[nv - 2], gw[nv - 2]
    av_, aw_ = hv[nv - 2], hw[nv - 2]
    ush = 0.0
    dsh = 0.0
    ash = 0.0
    if Pm.so:          # second_order: the tip at (L - u(L), v, w)
        ush, dsh, ash = _shortening(Pm.SL[i, 0], Pm.SL[i, 1], fv, fw, gv, gw, hv, hw, sva,
                                    swa)
    for a in range(3):
        rv[a] = (L - ush) * bx[a] + tv * by[a] + tw * bz[a]
        xv[a] = by[a] * sv + bz[a] * sw - dsh * bx[a]
    if Pm.ex:          # exact: the tip at r(L) (exact.py)
        point_row(Xn, Pre, Pm.xstart[i + 1, 1], 0, 0, xrow)
        rv[0], rv[1], rv[2] = _beam_vector(Rb, xrow, 0)
        xv[0], xv[1], xv[2] = _beam_vector(Rb, xrow, 3)
        tmp[0], tmp[1], tmp[2] = _beam_vector(Rb, xrow, 6)
    _cross(al, rv, t1)
    _cross(w, rv, t2)
    _cross(w, t2, t3)
    _cross(w, xv, t4)
    for a in range(3):
        if Pm.ex:
            ao[a] += t1[a] + t3[a] + 2.0 * t4[a] + tmp[a]
        else:
            ao[a] += t1[a] + t3[a] + 2.0 * t4[a] + av_ * by[a] + aw_ * bz[a] - ash * bx[a]
        o[a] += rv[a]
    for j in range(ncols):
        Jo[0, j] += Jw[1, j] * rv[2] - Jw[2, j] * rv[1]
        Jo[1, j] += Jw[2, j] * rv[0] - Jw[0, j] * rv[2]
        Jo[2, j] += Jw[0, j] * rv[1] - Jw[1, j] * rv[0]


@njit(cache=_CACHE)
def _tip_rotation(Pm, s0, nv, nt, f, Rb, bx, by, bz, R, Jo, Jw, w, al, xrow, xdir, sva, swa,
                  tmp):
    """The tip frame R = R_b Rs (seed 000 Eq. 19, :func:`_section` at the tip's slopes
    and twist) with the own columns of its offset and rotation in Jo, Jw and its
    angular velocity and acceleration: w += R_b w_rel, alpha += w x R_b w_rel +
    R_b alpha_rel."""
    fv, fw, ft, gv, gw, gt, hv, hw, ht = f
    tdv, tdw = fv[nv - 1], fw[nv - 1]
    sdv, sdw = gv[nv - 1], gw[nv - 1]
    adv, adw = hv[nv - 1], hw[nv - 1]
    phi = ft[nt - 2] if nt else 0.0
    sphi = gt[nt - 2] if nt else 0.0
    aphi = ht[nt - 2] if nt else 0.0
    ex = Pm.ex
    Rs, aw, av, at, wrel, arel = _section(phi, tdv, tdw, sphi, sdv, sdw)
    awb = _mv(Rb, aw)
    avb = _mv(Rb, av)
    atb = _mv(Rb, at)
    for j in range(2 * nv if ex else 0):
        xdir[j, 0], xdir[j, 1], xdir[j, 2] = _beam_vector(Rb, xrow, 9 + 3 * j)
        for a in range(3):
            Jo[a, s0 + j] += xdir[j, a]
    for a in range(3):
        if not ex:
            Jo[a, s0 + nv - 2] += by[a]
            Jo[a, s0 + 2 * nv - 2] += bz[a]
        Jw[a, s0 + nv - 1] += avb[a]
        Jw[a, s0 + 2 * nv - 1] += awb[a]
        if nt:
            Jw[a, s0 + 2 * nv + nt - 2] += atb[a]
        if Pm.so:
            for j in range(nv):
                Jo[a, s0 + j] -= sva[j] * bx[a]
                Jo[a, s0 + nv + j] -= swa[j] * bx[a]
    wb = _mv(Rb, wrel)
    _cross(w, wb, tmp)
    for a in range(3):
        arel[a] += at[a] * aphi + aw[a] * adw + av[a] * adv
    ab = _mv(Rb, arel)
    for a in range(3):
        al[a] += tmp[a] + ab[a]
        w[a] += wb[a]
    R[:, :] = _mm(Rb, Rs)


@njit(cache=_CACHE)
def _beam(i, Pm, q, v, qdd, R, o, Jo, Jw, w, ao, al, G, C6, X6, M, c, Rb, ek, S, W, V3,
          want_m):
    """Flexible link i from the frame before its beam: the Gauss points lumped into the
    root group G (flushed at the beam frame), then the tip frame, the end transform and
    the end body. V3 (8, 3): work vectors."""
    nv, nt, s0 = Pm.nv[i], Pm.nt[i], Pm.fstart[i]
    s1 = s0 + 2 * nv + nt
    P, pw, pstart = Pm.P, Pm.pw, Pm.pstart
    C6[:, s0:s1] = 0.0
    for a in range(3):
        for b in range(3):
            Rb[a, b] = R[a, 0] * P[i, 0, b] + R[a, 1] * P[i, 1, b] + R[a, 2] * P[i, 2, b]
    f = (q[s0:s0 + nv], q[s0 + nv:s0 + 2 * nv], q[s0 + 2 * nv:s1],
         v[s0:s0 + nv], v[s0 + nv:s0 + 2 * nv], v[s0 + 2 * nv:s1],
         qdd[s0:s0 + nv], qdd[s0 + nv:s0 + 2 * nv], qdd[s0 + 2 * nv:s1])
    fv, fw, ft, gv, gw, gt, hv, hw, ht = f
    by = np.ascontiguousarray(Rb[:, 1])
    bz = np.ascontiguousarray(Rb[:, 2])
    bx = np.ascontiguousarray(Rb[:, 0])
    # per point, in scalars (no temporaries): the own columns of a point are
    # x_j = b_y Wv_j (v) and b_z Ww_j (w), orthonormal directions, and those of a
    # section's rotation are a_v dWv_j, a_w dWw_j, b_x Pt_j with the rank-one section
    # inertia rhoJ ds a a^T (a the section's x axis; with rotary inertia also
    # rho I_y ds and rho I_z ds about the section's y and z axes)
    sown = np.zeros(2 * nv + nt)
    # section inertia axes per point: 1 (rhoJ about x) or 3 (rotary inertia too)
    nk = 1
    if pstart[i + 1] > pstart[i] and (pw[pstart[i], 1] != 0.0 or pw[pstart[i], 2] != 0.0):
        nk = 3
    sva = np.zeros(nv)
    swa = np.zeros(nv)
    Xn = np.zeros((0, 9 + 6 * nv))
    Pre = np.zeros((1, 9 + 6 * nv))
    if Pm.ex:      # exact: per node the tangent terms and their prefix sums (exact.py)
        xs, xe, XD = Pm.xstart[i, 0], Pm.xstart[i + 1, 0], Pm.XD
        Xn, Pre = link_sums(XD[xs:xe, 0], XD[xs:xe, 1], Pm.XW[xs:xe], Pm.xstart[i + 1, 1],
                            nv, fv, fw, gv, gw, hv, hw)
    xrow = np.zeros(9 + 6 * nv)
    xdir = np.zeros((2 * nv, 3))
    rv, xv, acc, tmp, tau = V3[0], V3[1], V3[2], V3[3], V3[4]
    _beam_points(i, Pm, s0, nv, nt, nk, f, Rb, bx, by, bz, w, ao, al, G, C6, M, c, Xn, Pre,
                 xrow, xdir, sva, swa, sown, rv, acc, ek, S, tau, want_m)
    _flush(G, C6, s0, s1, Jo, Jw, Pm.koff[i] + 1, M, c, X6, want_m)
    _tip_translation(i, Pm, s0, nv, f, Rb, bx, by, bz, o, Jo, Jw, w, ao, al, Xn, Pre, xrow,
                     sva, swa, rv, xv, tmp, V3[5], V3[6], V3[7], tau)
    _tip_rotation(Pm, s0, nv, nt, f, Rb, bx, by, bz, R, Jo, Jw, w, al, xrow, xdir, sva, swa,
                  tmp)
    _fixed(R, o, Jo, Jw, w, ao, al, Pm.T[i, 3], s1, W)
    G[:] = 0.0
    _body_into(G, R, 0.0, 0.0, 0.0, ao, al, w, Pm.bm[i, 1], Pm.bc[i, 1], Pm.bI[i, 1], Pm.g,
               rv, acc, W)
    if _nonzero(G):
        zero = Pm.koff[0] * 0
        _flush(G, C6, zero, zero, Jo, Jw, s1, M, c, X6, want_m)


@njit(cache=_CACHE)
def spatial_eval(Pm, q, v, qdd, want_m):
    """(M(q) or zeros, M(q) qdd + c(q, v)): the recursive Newton-Euler pass with the
    accelerations qdd included (inverse dynamics, O(n) without M when not ``want_m``). The mass
    points and rotors of a link are lumped per frame into a spatial inertia (mass, first
    and second moments) so that M costs one J6^T I6 J6 product per frame group."""
    nq = Pm.nq
    M = np.zeros((nq, nq))
    c = np.zeros(nq)
    R = np.eye(3)
    o = np.zeros(3)
    Jo = np.zeros((3, nq))
    Jw = np.zeros((3, nq))
    w = np.zeros(3)
    ao = np.zeros(3)
    al = np.zeros(3)
    G = np.zeros(19)
    C6 = np.zeros((6, nq))
    X6 = np.zeros((6, nq))
    V3 = np.zeros((8, 3))      # work vectors
    e = np.zeros(3)
    ek = np.zeros((3, 3))
    S = np.zeros((5, 3))
    W = np.zeros((3, 3))
    Rb = np.zeros((3, 3))
    o_root = np.zeros(3)
    ao_root = np.zeros(3)
    Jo_root = np.zeros((3, nq))
    rv, xv, acc = V3[0], V3[1], V3[2]
    for i in range(Pm.jtype.shape[0]):
        _joint(i, Pm, q, v, qdd, R, o, Jo, Jw, w, ao, al, e, rv, xv, V3[5], V3[6], V3[7],
               W, M, c, X6[0], want_m)
        G[:] = 0.0
        _body_into(G, R, 0.0, 0.0, 0.0, ao, al, w, Pm.bm[i, 0], Pm.bc[i, 0], Pm.bI[i, 0],
                   Pm.g, rv, acc, W)
        if Pm.flex[i]:
            _beam(i, Pm, q, v, qdd, R, o, Jo, Jw, w, ao, al, G, C6, X6, M, c, Rb, ek, S, W,
                  V3, want_m)
        else:
            _rigid_end(i, Pm, G, R, o, Jo, Jw, w, ao, al, rv, acc, W, o_root, ao_root,
                       Jo_root, C6, M, c, X6, want_m)
    for a in range(nq):
        if Pm.mdiag[a] != 0.0:      # motor inertias of elastic gears (constant)
            M[a, a] += Pm.mdiag[a]
            c[a] += Pm.mdiag[a] * qdd[a]
    for a in range(nq):
        for b in range(a + 1, nq):
            M[b, a] = M[a, b]
    return M, c


@njit(cache=_CACHE)
def _effects(Q0, fric, v, Q, slope):
    """Q = Q0 + friction torques on their coordinates, slope = their d/dv (effects.friction:
    -F_v w - (F_c + (F_s - F_c) exp(-(w/w_s)^2)) tanh(w/eps)); fric rows: coordinate,
    F_v, F_c, F_s, w_s, eps."""
    Q[:] = Q0
    slope[:] = 0.0
    for r in range(fric.shape[0]):
        a = int(fric[r, 0])
        tau, ds = friction_law_compiled(v[a], fric[r, 1], fric[r, 2], fric[r, 3], fric[r, 4],
                                        fric[r, 5])
        Q[a] += tau
        slope[a] += ds


@njit(cache=_CACHE)
def _motor_torques(motors, cmd, effort, v, Q, slope):
    """DC motors (dynamics.SpatialArmModel.actuator_force; seed 003 Eq. 48, inductance
    neglected): the command of joint j is a voltage, tau = n K_t clip((clip(V, V_max) -
    K_e n w) / R, i_max) clipped to effort[j], added to Q and its d/dv to slope (0 where a
    clip is active); motors rows: joint, actuator coordinate, n, R, K_t, K_e, i_max,
    V_max."""
    for r in range(motors.shape[0]):
        j = int(motors[r, 0])
        a = int(motors[r, 1])
        n, R, kt, ke, imax, vmax = motors[r, 2], motors[r, 3], motors[r, 4], motors[r, 5], \
            motors[r, 6], motors[r, 7]
        cur = (min(max(cmd[j], -vmax), vmax) - ke * n * v[a]) / R
        ds = -n * kt * ke * n / R
        if abs(cur) > imax:
            cur = min(max(cur, -imax), imax)
            ds = 0.0
        tau = n * kt * cur
        if abs(tau) > effort[j]:
            tau = min(max(tau, -effort[j]), effort[j])
            ds = 0.0
        Q[a] += tau
        slope[a] += ds


@njit(cache=_CACHE)
def _backlash(blash, q, v, Q, kt, sl):
    """Backlash corrections of gear springs (dynamics.SpatialArmModel.effect_force):
    x = theta_m - q_i, tau = k (dz(x) - x) + b (dz'(x) - 1) x' on q_i and -tau on the
    motor coordinate; the tangent factors of row r (SpatialArmModel.backlash_tangent):
    kt[r] = max(k dz' + b dz'' x', 0) - k, sl[r] = dz'(x) - 1. blash rows: q_i, motor
    coordinate (-1: locked at the last column), k_t, b_t, half width, smoothing,
    locked_at."""
    for r in range(blash.shape[0]):
        qi = int(blash[r, 0])
        m = int(blash[r, 1])
        k, b, half, sm = blash[r, 2], blash[r, 3], blash[r, 4], blash[r, 5]
        if m >= 0:
            x = q[m] - q[qi]
            xd = v[m] - v[qi]
        else:
            x = blash[r, 6] - q[qi]
            xd = -v[qi]
        dz, s = dead_zone(x, half, sm)
        tau = k * (dz - x) + b * (s - 1.0) * xd
        Q[qi] += tau
        if m >= 0:
            Q[m] -= tau
        rp = np.sqrt((x - half) ** 2 + sm * sm)
        rm = np.sqrt((x + half) ** 2 + sm * sm)
        curv = 0.5 * sm * sm * (1.0 / rp ** 3 - 1.0 / rm ** 3)
        kt[r] = max(k * s + b * curv * xd, 0.0) - k
        sl[r] = s - 1.0


@njit(cache=_CACHE)
def _stops(stops, q, v, Q, kt, ct):
    """End stops at the joint limits (dynamics.SpatialArmModel.stop_load, the law of
    description.JointStops): rows coordinate, lower, upper, k, c, transition s; the
    torque -sigma (k g(d) + c r(d) d') added to Q, the tangent max(k r + c r' d', 0) and
    c r into kt[r], ct[r] (0 inside the range)."""
    for r in range(stops.shape[0]):
        a = int(stops[r, 0])
        lo, hi, k, c, s = stops[r, 1], stops[r, 2], stops[r, 3], stops[r, 4], stops[r, 5]
        kt[r] = 0.0
        ct[r] = 0.0
        sigma = 1.0
        d = q[a] - hi
        if q[a] <= hi:
            sigma = -1.0
            d = lo - q[a]
        if d <= 0.0:
            continue
        dd = sigma * v[a]
        if d < s:
            g = d * d / (2.0 * s)
            rr = d / s
            dr = 1.0 / s
        else:
            g = d - s / 2.0
            rr = 1.0
            dr = 0.0
        Q[a] -= sigma * (k * g + c * rr * dd)
        kt[r] = max(k * rr + c * dr * dd, 0.0)
        ct[r] = c * rr


@njit(cache=_CACHE)
def _pd_clip(pdc, u, q, v, Q, act):
    """The in-loop PD's torque clipped to the effort limit (thesis Eq. 95 with saturation):
    rows joint, actuator coordinate, kp, kd, effort. The PD is stiffness and damping in
    K, D and kp s(t) in the joint torque u, so the actuator torque is T = u_j - kp q_a -
    kd q_a'; beyond +-effort the correction clip(T) - T is added to Q and act[r] = 1 (its
    tangent cancels kp, kd in the Newton matrix)."""
    for r in range(pdc.shape[0]):
        j = int(pdc[r, 0])
        a = int(pdc[r, 1])
        e = pdc[r, 4]
        T = u[j] - pdc[r, 2] * q[a] - pdc[r, 3] * v[a]
        act[r] = 0.0
        if T > e:
            Q[a] += e - T
            act[r] = 1.0
        elif T < -e:
            Q[a] += -e - T
            act[r] = 1.0


@njit(cache=_CACHE)
def _backlash_tangent(blash, kt, sl, cq, cv, S):
    """S += cq kt + cv b_t sl on each gear's [[1, -1], [-1, 1]] block (see _backlash)."""
    for r in range(blash.shape[0]):
        qi = int(blash[r, 0])
        m = int(blash[r, 1])
        g = cq * kt[r] + cv * blash[r, 3] * sl[r]
        S[qi, qi] += g
        if m >= 0:
            S[m, m] += g
            S[qi, m] -= g
            S[m, qi] -= g


@njit(cache=_CACHE)
def tip_point(Pm, q):
    """(o, Jo): the origin of the last link's end frame (base frame, m) and its
    translational Jacobian (3 x nq): the kinematic part of spatial_eval's pass
    (SpatialArmModel.tip_frame), without the rates."""
    (jtype, koff, axis, T, P, flex, nvs, nts, fstart, length, bm, bc, bI, pstart,
     zs, mw, pw, Wv, dWv, Ww, dWw, Pt, g, nq, rot, mdiag, Sv, Sw, SL, so, CF, CW,
     ex, XD, XW, XR, xstart) = Pm
    R = np.eye(3)
    o = np.zeros(3)
    Jo = np.zeros((3, nq))
    Jw = np.zeros((3, nq))
    w = np.zeros(3)          # rates: not needed here (zero)
    ao = np.zeros(3)
    al = np.zeros(3)
    W = np.zeros((3, 3))
    Rb = np.zeros((3, 3))
    e = np.zeros(3)
    rv = np.zeros(3)
    for i in range(jtype.shape[0]):
        k = koff[i]
        ncols = k + 1
        _fixed(R, o, Jo, Jw, w, ao, al, T[i, 0], ncols, W)
        u = axis[i]
        for a in range(3):
            e[a] = R[a, 0] * u[0] + R[a, 1] * u[1] + R[a, 2] * u[2]
        if jtype[i] == 0:
            for a in range(3):
                Jw[a, k] += e[a]
            _rotate_axis(R, u, q[k], W)
        else:
            _slide(Jo, Jw, e, q[k], k, ncols, rv)
            for a in range(3):
                o[a] += rv[a]
        _fixed(R, o, Jo, Jw, w, ao, al, T[i, 1], ncols, W)
        if not flex[i]:
            _fixed(R, o, Jo, Jw, w, ao, al, T[i, 3], ncols, W)
            continue
        _fixed(R, o, Jo, Jw, w, ao, al, T[i, 2], ncols, W)
        nv, nt, s0 = nvs[i], nts[i], fstart[i]
        s1 = s0 + 2 * nv + nt
        for a in range(3):
            for b in range(3):
                Rb[a, b] = R[a, 0] * P[i, 0, b] + R[a, 1] * P[i, 1, b] + R[a, 2] * P[i, 2, b]
        tv, tdv = q[s0 + nv - 2], q[s0 + nv - 1]
        tw, tdw = q[s0 + 2 * nv - 2], q[s0 + 2 * nv - 1]
        phi = q[s1 - 2] if nt else 0.0
        L = length[i]
        if so:          # second_order: the tip at (L - u(L), v, w)
            fv, fw = q[s0:s0 + nv], q[s0 + nv:s0 + 2 * nv]
            sva, swa = np.zeros(nv), np.zeros(nv)
            L -= _shortening(SL[i, 0], SL[i, 1], fv, fw, fv, fw, fv, fw, sva, swa)[0]
            for j in range(nv):
                for a in range(3):
                    Jo[a, s0 + j] -= sva[j] * Rb[a, 0]
                    Jo[a, s0 + nv + j] -= swa[j] * Rb[a, 0]
        for a in range(3):
            rv[a] = L * Rb[a, 0] + tv * Rb[a, 1] + tw * Rb[a, 2]
        if ex:          # exact: the tip at r(L), its own columns (exact.py)
            xs, xe = xstart[i, 0], xstart[i + 1, 0]
            fv, fw, z = q[s0:s0 + nv], q[s0 + nv:s0 + 2 * nv], np.zeros(nv)
            Xn, Pre = link_sums(XD[xs:xe, 0], XD[xs:xe, 1], XW[xs:xe], xstart[i + 1, 1],
                                nv, fv, fw, z, z, z, z)
            xrow = Pre[xstart[i + 1, 1]]
            rv[0], rv[1], rv[2] = _beam_vector(Rb, xrow, 0)
            for j in range(2 * nv):
                d = _beam_vector(Rb, xrow, 9 + 3 * j)
                for a in range(3):
                    Jo[a, s0 + j] += d[a]
        for j in range(ncols):
            Jo[0, j] += Jw[1, j] * rv[2] - Jw[2, j] * rv[1]
            Jo[1, j] += Jw[2, j] * rv[0] - Jw[0, j] * rv[2]
            Jo[2, j] += Jw[0, j] * rv[1] - Jw[1, j] * rv[0]
        Rs, aw, av, at, _, _ = _section(phi, tdv, tdw, 0.0, 0.0, 0.0)
        awb = _mv(Rb, aw)
        avb = _mv(Rb, av)
        atb = _mv(Rb, at)
        for a in range(3):
            o[a] += rv[a]
            if not ex:
                Jo[a, s0 + nv - 2] += Rb[a, 1]
                Jo[a, s0 + 2 * nv - 2] += Rb[a, 2]
            Jw[a, s0 + nv - 1] += avb[a]
            Jw[a, s0 + 2 * nv - 1] += awb[a]
            if nt:
                Jw[a, s1 - 2] += atb[a]
        R[:, :] = _mm(Rb, Rs)
        _fixed(R, o, Jo, Jw, w, ao, al, T[i, 3], s1, W)
    return o, Jo


@njit(cache=_CACHE)
def _tip_force(Pm, F, q, Q):
    """Q += J_tip^T F: a force (N, base frame) at the origin of the last link's end frame
    (tip_point)."""
    if F[0] == 0.0 and F[1] == 0.0 and F[2] == 0.0:
        return
    _, Jo = tip_point(Pm, q)
    for j in range(Q.shape[0]):
        Q[j] += Jo[0, j] * F[0] + Jo[1, j] * F[1] + Jo[2, j] * F[2]


@njit(cache=_CACHE)
def _contact(Pm, ct, q, v, Q, gc):
    """The contact surface at the tip (dynamics.SpatialArmModel.effect_force): ct = p0 (3),
    unit normal n (3), k, c; delta = -n . (p - p0), for delta > 0 the normal force
    fn = max(0, k delta - c n . J v); Q += fn J^T n, gc = J^T n (for the tangent
    (cq k + cv c) gc gc^T while fn > 0). Returns fn (0: no contact)."""
    o, Jo = tip_point(Pm, q)
    nq = q.shape[0]
    delta = -(ct[3] * (o[0] - ct[0]) + ct[4] * (o[1] - ct[1]) + ct[5] * (o[2] - ct[2]))
    if delta <= 0.0:
        return 0.0
    vn = 0.0
    for j in range(nq):
        gc[j] = ct[3] * Jo[0, j] + ct[4] * Jo[1, j] + ct[5] * Jo[2, j]
        vn += gc[j] * v[j]
    fn = max(0.0, ct[6] * delta - ct[7] * vn)
    if fn > 0.0:
        for j in range(nq):
            Q[j] += fn * gc[j]
    return fn


@njit(cache=_CACHE)
def _hold(S, r, held):
    """Held coordinates: identity rows and columns of S and zero entries of r (each if
    not empty)."""
    n = held.shape[0]
    for j in range(n):
        if held[j]:
            if r.shape[0]:
                r[j] = 0.0
            if S.shape[0]:
                for b in range(n):
                    S[j, b] = 0.0
                    S[b, j] = 0.0
                S[j, j] = 1.0


class LoopInputs(NamedTuple):
    """The joint effects and inputs of a :class:`SpatialModel` by name (integrate.
    simulate_fixed_compiled builds them): K, D (nq x nq), Q0 the constant generalized
    force, H (nq x n_joints) the joint torques' matrix, fric (friction, _effects),
    motors (DC motors, _motor_torques), blash (backlash, _backlash), contact (a surface at
    the tip, _contact), stops (end stops, _stops), pdc (an in-loop PD's clipped torque,
    _pd_clip; infinite ``effort`` there), tipf empty or (n_steps, 3) tip forces (N, base
    frame; J_tip^T F at the iterate, no dJ/dq F tangent), held (nq, 0/1: zero
    acceleration), effort (n_joints: the joint torques' clip)."""
    K: np.ndarray
    D: np.ndarray
    Q0: np.ndarray
    fric: np.ndarray
    motors: np.ndarray
    blash: np.ndarray
    contact: np.ndarray
    stops: np.ndarray
    pdc: np.ndarray
    tipf: np.ndarray
    held: np.ndarray
    H: np.ndarray
    effort: np.ndarray


@njit(cache=_CACHE)
def _coupling(Pm, q, g, Hc, want_h):
    """g += dU/dq and (want_h) Hc += d^2U/dq^2 of the second-order curvature energy of
    the twisting links (dynamics.BeamData.curvature_coupling; CF, CW of pack)."""
    flex, nvs, nts, fstart, pstart = Pm.flex, Pm.nv, Pm.nt, Pm.fstart, Pm.pstart
    CF, CW, ex = Pm.CF, Pm.CW, Pm.ex
    x = np.zeros(5)
    du = np.zeros(5)
    h = np.zeros((5, 5))
    for i in range(flex.shape[0]):
        if not flex[i] or (nts[i] == 0 and not ex):
            continue
        n = 2 * nvs[i] + nts[i]
        s0 = fstart[i]
        T = np.zeros((5, n))
        for p in range(pstart[i], pstart[i + 1]):
            for k in range(5):
                x[k] = 0.0
                for j in range(n):
                    x[k] += CF[p, k, j] * q[s0 + j]
            a, b, c, pp, e = x[0], x[1], x[2], x[3], x[4]
            gw, y, z = CW[p, 0], CW[p, 1], CW[p, 2]
            if ex:      # the exact curvatures (exact.py)
                curvature_energy(x, gw, y, z, du, h)
                _coupling_add(CF, p, s0, n, du, h, g, Hc, want_h, T)
                continue
            dz = z - y
            du[0] = -gw * b * c
            du[1] = gw * (-a * c + b * c * c)
            du[2] = gw * (-a * b + b * b * c) + dz * pp * e + z * pp * pp * c
            du[3] = dz * e * c + pp * (y * e * e + z * c * c)
            du[4] = dz * pp * c + y * pp * pp * e
            if not want_h:
                _coupling_add(CF, p, s0, n, du, h, g, Hc, False, T)
                continue
            h[:, :] = 0.0
            h[0, 1], h[0, 2] = -gw * c, -gw * b
            h[1, 1], h[1, 2] = gw * c * c, gw * (2 * b * c - a)
            h[2, 2], h[2, 3], h[2, 4] = gw * b * b + z * pp * pp, dz * e + 2 * z * pp * c, \
                dz * pp
            h[3, 3], h[3, 4] = y * e * e + z * c * c, dz * c + 2 * y * pp * e
            h[4, 4] = y * pp * pp
            for k in range(5):
                for m in range(k):
                    h[k, m] = h[m, k]
            _coupling_add(CF, p, s0, n, du, h, g, Hc, True, T)


@njit(cache=_CACHE)
def _coupling_add(CF, p, s0, n, du, h, g, Hc, want_h, T):
    """g += F^T du and (want_h) Hc += F^T h F at point p (F = CF[p], the link's n
    columns from s0)."""
    for j in range(n):
        for k in range(5):
            g[s0 + j] += CF[p, k, j] * du[k]
    if not want_h:
        return
    for k in range(5):
        for m in range(n):
            T[k, m] = 0.0
            for l_ in range(5):
                T[k, m] += h[k, l_] * CF[p, l_, m]
    for j in range(n):
        for m in range(n):
            acc_ = 0.0
            for k in range(5):
                acc_ += CF[p, k, j] * T[k, m]
            Hc[s0 + j, s0 + m] += acc_


class SpatialWork(NamedTuple):
    """The hooks' work arrays in a run of a :class:`SpatialModel`: the effects' force Qe, slope,
    the clipped torques u, the backlash (kt, sl), stops (skt, sct), PD clip (pact), contact
    (gc, fn) tangent terms; the coupling's tangent Hc, S0 (first iterate), S, its factor L."""
    Qe: np.ndarray
    slope: np.ndarray
    u: np.ndarray
    kt: np.ndarray
    sl: np.ndarray
    skt: np.ndarray
    sct: np.ndarray
    pact: np.ndarray
    gc: np.ndarray
    fn: np.ndarray
    Hc: np.ndarray
    S0: np.ndarray
    S: np.ndarray
    L: np.ndarray


class SpatialModel(NamedTuple):
    """The spatial arm for solvers.loop.fixed_step (the relative Newton, Settings.relative;
    its line search with nonlinear effects only; :func:`spatial_model` builds it): Pm
    (:func:`pack`), inp (:class:`LoopInputs`), tau (n_steps, n_joints): joint
    torques/forces over step k (at t_{k+1}), clipped to +-effort, voltages on motors'
    joints, work
    (:class:`SpatialWork`), has_k (curvature coupling), nonlinear (friction, motors,
    backlash, contact, stops or a clipped PD: their tangents refreshed every iteration)."""
    Pm: tuple
    inp: LoopInputs
    tau: np.ndarray
    work: SpatialWork
    has_k: bool
    nonlinear: bool


@njit(cache=_CACHE)
def spatial_model(Pm, inp, tau):
    """:class:`SpatialModel` with its flags and zeroed work arrays."""
    nq, nb, ns = inp.K.shape[0], inp.blash.shape[0], inp.stops.shape[0]
    z = np.zeros
    work = SpatialWork(z(nq), z(nq), z(tau.shape[1]), z(nb), z(nb), z(ns), z(ns),
                       z(inp.pdc.shape[0]), z(nq), z(1), z((nq, nq)), z((nq, nq)),
                       z((nq, nq)), z((nq, nq)))
    nonlinear = (inp.fric.shape[0] > 0 or inp.motors.shape[0] > 0 or nb > 0 or ns > 0
                 or inp.contact.shape[0] > 0 or inp.pdc.shape[0] > 0)
    has_k = Pm.CW.shape[0] > 0 and np.any(Pm.CW != 0.0)
    return SpatialModel(Pm, inp, tau, work, has_k, nonlinear)


@njit(cache=_CACHE, inline="always")   # numba-inlined: md not passed once more
def _joint_forces(md, k, q, v):
    """The work's u (row k of tau clipped to +-effort; 0 on motor joints: a voltage) and
    Qe: Q0 + the joint effects and the tip force of row k at (q, v), with their slopes
    and tangent terms (:class:`LoopInputs`)."""
    inp, w, Pm = md.inp, md.work, md.Pm
    cmd = md.tau[k]
    for j in range(cmd.shape[0]):
        w.u[j] = min(max(cmd[j], -inp.effort[j]), inp.effort[j])
    for r_ in range(inp.motors.shape[0]):
        w.u[int(inp.motors[r_, 0])] = 0.0     # a voltage: through the motor model
    _effects(inp.Q0, inp.fric, v, w.Qe, w.slope)
    if inp.motors.shape[0] > 0:
        _motor_torques(inp.motors, cmd, inp.effort, v, w.Qe, w.slope)
    if inp.blash.shape[0] > 0:
        _backlash(inp.blash, q, v, w.Qe, w.kt, w.sl)
    if inp.contact.shape[0] > 0:
        w.fn[0] = _contact(Pm, inp.contact, q, v, w.Qe, w.gc)
    if inp.tipf.shape[0] > 0:
        _tip_force(Pm, inp.tipf[k], q, w.Qe)
    if inp.stops.shape[0] > 0:
        _stops(inp.stops, q, v, w.Qe, w.skt, w.sct)
    if inp.pdc.shape[0] > 0:
        _pd_clip(inp.pdc, w.u, q, v, w.Qe, w.pact)


@njit(cache=_CACHE)
def _residual(md, a1, st, c, first):
    """Residual M a1 + c + K q1 + D v1 - H u - Q_e of step st.k at the iterate a1 by the
    inverse dynamics of spatial_eval (M, and the curvature coupling's tangent, at the
    ``first`` iterate only), zero on held coordinates; ctx (M, first, no bristles)."""
    inp, w = md.inp, md.work
    q1, v1, _ = galpha_state(st.q, st.v, st.a, st.abar, a1, c)
    M1, f1 = spatial_eval(md.Pm, q1, v1, a1, first)
    _joint_forces(md, st.k, q1, v1)
    Q, Kq, Dv = _matvec(inp.H, w.u), _matvec(inp.K, q1), _matvec(inp.D, v1)
    if md.has_k:      # its tangent at the first iterate (integrate.simulate_fixed)
        if first:
            w.Hc[:, :] = 0.0
        _coupling(md.Pm, q1, Kq, w.Hc, first)
    for j in range(Kq.shape[0]):     # the residual, in Kq's place; 0 where held
        Kq[j] = 0.0 if inp.held[j] else f1[j] + Kq[j] - Q[j] - w.Qe[j] + Dv[j]
    return Kq, (M1, first, st.z)


@njit(cache=_CACHE)
def _tangent(md, ctx, st, c):
    """Factor of M + beta' (K + H_c) + gamma' D (S0: M, H_c of the step's first iterate)
    with the nonlinear effects' tangents at the current iterate (else kept for the step);
    without friction slopes > 0 (a Stribeck peak) if they make it indefinite."""
    M1, first = ctx[0], ctx[1]
    inp, w = md.inp, md.work
    K, D, contact, stops, pdc = inp.K, inp.D, inp.contact, inp.stops, inp.pdc
    cq, cv = c.bp, c.gp
    nq = K.shape[0]
    S0, S = w.S0, w.S
    if first:
        for j in range(nq):
            for b_ in range(nq):
                S0[j, b_] = M1[j, b_] + cq * (K[j, b_] + w.Hc[j, b_]) + cv * D[j, b_]
    elif not md.nonlinear:
        return w.L
    S[:, :] = S0
    for j in range(nq):
        S[j, j] -= cv * w.slope[j]
    if inp.blash.shape[0] > 0:
        _backlash_tangent(inp.blash, w.kt, w.sl, cq, cv, S)
    if contact.shape[0] > 0 and w.fn[0] > 0.0:   # k g g^T, c g g^T (contact_tangent)
        gk = cq * contact[6] + cv * contact[7]
        for j in range(nq):
            for b_ in range(nq):
                S[j, b_] += gk * w.gc[j] * w.gc[b_]
    for r_ in range(stops.shape[0]):     # the stops' tangent (0: apart)
        a_ = int(stops[r_, 0])
        S[a_, a_] += cq * w.skt[r_] + cv * w.sct[r_]
    for r_ in range(pdc.shape[0]):       # a clipped PD: no kp, kd
        if w.pact[r_] > 0.0:
            a_ = int(pdc[r_, 1])
            S[a_, a_] -= cq * pdc[r_, 2] + cv * pdc[r_, 3]
    _hold(S, w.u[:0], inp.held)
    Lc = cholesky(S)
    if Lc.shape[0] != nq:   # a Stribeck slope's negative damping: drop it
        for j in range(nq):
            if w.slope[j] > 0.0 and not inp.held[j]:
                S[j, j] += cv * w.slope[j]
        Lc = cholesky(S)
    if Lc.shape[0] == nq:
        w.L[:, :] = Lc
    return Lc


implements(residual, SpatialModel, _residual)
implements(tangent, SpatialModel, _tangent)


@njit(cache=_CACHE)
def start_acceleration(md, q, v, h, acc, start, rho_inf):
    """(a, abar, ok) a run of fixed_step on md starts from; ``acc`` (2, nq): (a, abar):
    acc's when ``start`` is 1 (a continued run), else the consistent
    M^-1 (H u + Q_e - c - K q - D v) at (q, v), row 0's inputs (2: solvers.galpha.
    restart_choice from it and acc[0]); ok False when M is not positive definite."""
    if start == 1:
        return acc[0].copy(), acc[1].copy(), True
    inp, w = md.inp, md.work
    nq = q.shape[0]
    M, c = spatial_eval(md.Pm, q, v, np.zeros(nq), nq > 0)
    _joint_forces(md, 0, q, v)
    Hu, Kq, Dv = _matvec(inp.H, w.u), _matvec(inp.K, q), _matvec(inp.D, v)
    if md.has_k:
        _coupling(md.Pm, q, Kq, w.Hc, False)
    r = np.empty(nq)
    for j in range(nq):
        r[j] = Hu[j] + w.Qe[j] - c[j] - Kq[j] - Dv[j]
    _hold(M, r, inp.held)
    Lc = cholesky(M)
    if Lc.shape[0] != nq:   # not positive definite
        return r, r, False
    a = solve_chol(Lc, r)
    if start == 2:
        ga = galpha_coefficients(rho_inf, h)
        S = M + ga.bp * inp.K + ga.gp * inp.D
        _hold(S, r, inp.held)
        a = restart_choice(acc[0].copy(), a, M, S, h, rho_inf)[0]
    return a, a.copy(), True


class CompiledSpatialModel:
    """The compiled kernels of a SpatialArmModel: ``terms(q, v)`` -> (M, c)."""

    def __init__(self, model: SpatialArmModel):
        self.model = model
        self.data = pack(model)

    def terms(self, q, v):
        return spatial_terms(self.data, q, v)

    def mass_matrix(self, q):
        return self.terms(q, np.zeros(self.model.nq))[0]

    def bias(self, q, v):
        return self.terms(q, v)[1]

    def gravity_force(self, q):
        return self.terms(q, np.zeros(self.model.nq))[1]


# numba re-compiles a cached function when its own file changes, not when a compiled
# function it calls from kernels.py or integrators.py does: flush these caches then
def _guard_caches():
    from ..effects import friction
    from ..numba_cache import guard
    from . import exact
    guard([obj for obj in globals().values() if hasattr(obj, "py_func")
           and obj.py_func.__module__ == __name__],
          [kernels.__file__, integrators.__file__, galpha.__file__, newton.__file__,
           loop.__file__, status.__file__, friction.__file__, exact.__file__])


_guard_caches()
