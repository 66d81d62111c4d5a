"""Geometrically exact kinematics of spatial links (``kinematics: exact``, issues 43, 47).

The planar ``exact`` model (flex_model.exact_kinematics) in 3D: the link variables keep
their meaning at small deflections, but the slopes b = v'(s) = W_v' f_v, a = w'(s) =
W_w' f_w and the twist c = phi(s) = P_t f_t are read as the angles of the section
rotation (the small-deflection model's own section rotation, seed 000 Eq. 19 with the
twist about the tangent)

    R_s(s) = Ry(-a) Rz(b) Rx(c),

an inextensible, shear-free (Kirchhoff) rod whose centre line is the integral of the
section's x axis (the tangent):

    r(s) = int_0^s t ds,    t = R_s e_x = (cos a cos b, sin b, sin a cos b),

by Gauss-Legendre (``inner`` points) on the pieces between the interval ends of both
bending bases and the section breaks (:func:`tangent_rule`). The curvatures are those of
R_s exactly, R_s^T R_s' = [k]x:

    k_x = c' - a' sin b,   k_y = -a' cos b cos c + b' sin c,   k_z = a' cos b sin c + b' cos c,

and the strain energy 1/2 int (GJ k_x^2 + EI_y k_y^2 + EI_z k_z^2) ds is the model's
quadratic 1/2 f^T K f plus :func:`curvature_energy` (the ``second_order`` model's
curvature coupling is this to second order). In the plane (a = c = 0) it is the planar
elastica: r = int (cos b, sin b), energy EI_z/2 int b'^2. Mass matrix and velocity terms
follow from the positions and their exact Jacobians and bias accelerations dJ/dt v
(:func:`link_sums`), the tip frame is (R_s(L), r(L)); dynamics.py (Python, complex step)
and compiled.py (Newton-Euler) use them. Singular at b = +-90 deg (Euler angles).
"""
from __future__ import annotations

import numpy as np
from numba import njit

_CACHE = True


def tangent_rule(cuts, s_out, inner: int = 8):
    """The quadrature of r(s_k) = int_0^{s_k} t ds at the points ``s_out``.

    Returns (nodes, weights, nfull, rows): the integration nodes (the ``inner`` Gauss
    points of every full piece between ``cuts``, then those of the partial piece of each
    point), their weights, the number of full-piece nodes, and per point (pfull, pa, pb):
    r(s_k) = sum of the first pfull nodes' terms + those of nodes pa..pb-1."""
    xi, wxi = np.polynomial.legendre.leggauss(inner)
    nodes, weights = [], []
    for a, b in zip(cuts[:-1], cuts[1:]):
        nodes.extend(a + 0.5 * (b - a) * (xi + 1.0))
        weights.extend(0.5 * (b - a) * wxi)
    nfull = len(nodes)
    npiece = len(cuts) - 1
    tol = 1e-12 * cuts[-1]
    rows = np.zeros((len(s_out), 3), dtype=np.int64)
    for k, s in enumerate(s_out):
        j = min(int(np.searchsorted(cuts, s + tol, side="right")) - 1, npiece)
        rows[k] = (j * inner, len(nodes), len(nodes))
        if j < npiece and s > cuts[j] + tol:
            nodes.extend(cuts[j] + 0.5 * (s - cuts[j]) * (xi + 1.0))
            weights.extend(0.5 * (s - cuts[j]) * wxi)
            rows[k, 2] = len(nodes)
    return np.array(nodes), np.array(weights), nfull, rows


def dense_rule(weights, nfull: int, rows) -> np.ndarray:
    """C (points x nodes) with r(s_k) = C[k] @ t(nodes) (the rule of :func:`tangent_rule`)."""
    C = np.zeros((len(rows), len(weights)))
    for k, (pf, pa, pb) in enumerate(rows):
        C[k, :pf] = weights[:pf]
        C[k, pa:pb] = weights[pa:pb]
    return C


def tangents(a, b):
    """t, dt/db, dt/da (each (..., 3)) of t = (cos a cos b, sin b, sin a cos b)
    (analytic: complex steps pass)."""
    ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
    zero = 0.0 * a
    t = np.stack([ca * cb, sb, sa * cb], axis=-1)
    tb = np.stack([-ca * sb, cb, -sa * sb], axis=-1)
    ta = np.stack([-sa * cb, zero, ca * cb], axis=-1)
    return t, tb, ta


@njit(cache=_CACHE)
def shape_sums(W, k, nv, f, g, h):
    """(W[k] f, W[k] g, W[k] h): a shape's value, rate and acceleration at row k (point or
    node) from the beam's coordinates f, their rates g and accelerations h."""
    x = 0.0
    xd = 0.0
    xdd = 0.0
    for j in range(nv):
        x += W[k, j] * f[j]
        xd += W[k, j] * g[j]
        xdd += W[k, j] * h[j]
    return x, xd, xdd


@njit(cache=_CACHE)
def link_sums(dWv, dWw, wts, nfull, nv, fv, fw, gv, gw, hv, hw):
    """Per node k (weighted by its quadrature weight) the row [t, t', t'', dt/df_v (3 nv),
    dt/df_w (3 nv)] (t' = dt/dt at the rates g, t'' at the accelerations h: the bias and
    acceleration terms), and the prefix sums of the first ``nfull`` rows: (X, Pre).
    A point's row is Pre[pfull] + sum X[pa:pb] (:func:`point_row`): its position r,
    velocity, acceleration and Jacobian in the beam frame."""
    nn = wts.shape[0]
    width = 9 + 6 * nv
    X = np.zeros((nn, width))
    for k in range(nn):
        b, bd, bdd = shape_sums(dWv, k, nv, fv, gv, hv)
        a, ad, add = shape_sums(dWw, k, nv, fw, gw, hw)
        ca, sa, cb, sb = np.cos(a), np.sin(a), np.cos(b), np.sin(b)
        wk = wts[k]
        t = (ca * cb, sb, sa * cb)
        tb = (-ca * sb, cb, -sa * sb)
        ta = (-sa * cb, 0.0, ca * cb)
        taa = (-ca * cb, 0.0, -sa * cb)
        tab = (sa * sb, 0.0, -ca * sb)
        for x in range(3):
            X[k, x] = wk * t[x]
            X[k, 3 + x] = wk * (tb[x] * bd + ta[x] * ad)
            X[k, 6 + x] = wk * (tb[x] * bdd + ta[x] * add - t[x] * bd * bd
                                + 2.0 * tab[x] * ad * bd + taa[x] * ad * ad)
            for j in range(nv):
                X[k, 9 + 3 * j + x] = wk * tb[x] * dWv[k, j]
                X[k, 9 + 3 * (nv + j) + x] = wk * ta[x] * dWw[k, j]
    Pre = np.zeros((nfull + 1, width))
    for k in range(nfull):
        for x in range(width):
            Pre[k + 1, x] = Pre[k, x] + X[k, x]
    return X, Pre


@njit(cache=_CACHE)
def point_row(X, Pre, pf, pa, pb, out):
    """out = Pre[pf] + sum X[pa:pb] (:func:`link_sums`)."""
    for x in range(out.shape[0]):
        s = Pre[pf, x]
        for k in range(pa, pb):
            s += X[k, x]
        out[x] = s


@njit(cache=_CACHE)
def curvature_energy(x, gj, eiy, eiz, du, h):
    """The exact strain energy density beyond the quadratic one (module docstring) at one
    point, x = (phi', v', w'', phi, v'') = (c', b, a', c, b') and the weights GJ ds,
    EI_y ds, EI_z ds: returns u, writes du/dx (5) and d^2u/dx^2 (5 x 5) into du, h."""
    c1, b, a1, c, b1 = x[0], x[1], x[2], x[3], x[4]
    sb, cb, sc, cc = np.sin(b), np.cos(b), np.sin(c), np.cos(c)
    kx = c1 - a1 * sb
    ky = -a1 * cb * cc + b1 * sc
    kz = a1 * cb * sc + b1 * cc
    dk = np.zeros((3, 5))
    dk[0, 0], dk[0, 1], dk[0, 2] = 1.0, -a1 * cb, -sb
    dk[1, 1], dk[1, 2], dk[1, 3], dk[1, 4] = a1 * sb * cc, -cb * cc, kz, sc
    dk[2, 1], dk[2, 2], dk[2, 3], dk[2, 4] = -a1 * sb * sc, cb * sc, -ky, cc
    k = (kx, ky, kz)
    wt = (gj, eiy, eiz)
    u = 0.5 * (gj * (kx * kx - c1 * c1) + eiy * (ky * ky - a1 * a1) + eiz * (kz * kz - b1 * b1))
    for m in range(5):
        du[m] = wt[0] * kx * dk[0, m] + wt[1] * ky * dk[1, m] + wt[2] * kz * dk[2, m]
    du[0] -= gj * c1
    du[2] -= eiy * a1
    du[4] -= eiz * b1
    for m in range(5):
        for n in range(5):
            h[m, n] = (wt[0] * dk[0, m] * dk[0, n] + wt[1] * dk[1, m] * dk[1, n]
                       + wt[2] * dk[2, m] * dk[2, n])
    h[0, 0] -= gj
    h[2, 2] -= eiy
    h[4, 4] -= eiz
    # second derivatives of the curvatures (upper triangle, symmetric)
    d2 = np.zeros((3, 5, 5))
    d2[0, 1, 1], d2[0, 1, 2] = a1 * sb, -cb
    d2[1, 1, 1], d2[1, 1, 2], d2[1, 1, 3] = a1 * cb * cc, sb * cc, -a1 * sb * sc
    d2[1, 2, 3], d2[1, 3, 3], d2[1, 3, 4] = cb * sc, -ky, cc
    d2[2, 1, 1], d2[2, 1, 2], d2[2, 1, 3] = -a1 * cb * sc, -sb * sc, -a1 * sb * cc
    d2[2, 2, 3], d2[2, 3, 3], d2[2, 3, 4] = cb * cc, -kz, -sc
    for i in range(3):
        f = wt[i] * k[i]
        for m in range(5):
            for n in range(m, 5):
                h[m, n] += f * d2[i, m, n]
                if n > m:
                    h[n, m] += f * d2[i, m, n]
    return u


@njit(cache=_CACHE)
def curvature_energies(X, gj, eiy, eiz, DU, H):
    """:func:`curvature_energy` at every point (rows of X); returns the sum."""
    U = 0.0
    for p in range(X.shape[0]):
        U += curvature_energy(X[p], gj[p], eiy[p], eiz[p], DU[p], H[p])
    return U
