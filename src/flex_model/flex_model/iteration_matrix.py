"""Newton iteration matrix of the fixed step with second-order kinematics, solved at a cost
linear in the variables (simplified Newton, Hairer-Wanner IV.8: an approximate matrix
converges, the residual stays exact).

The iteration matrix M = B(q) + gamma' (D + C_j) + beta' (K + K_j) of
:mod:`flex_model.integrators` is written as banded plus low rank,

    M ~ A + U C U^T,

A banded (half bandwidth ``bw``: the wavelets' local support, 3 for Hermite wavelets):
the constant inertia sum_k mu_k W_k W_k^T of the deformation (thesis Eq. 9, ``Bp``), the
bands of K, D and of the constant inertia ``Bc``, and each link's own alpha-alpha entry;
U (nq x r, r independent of the variables) with a small core C:
- per link, e_alpha and rho = int (r w + d S q_f) dm (the alpha-deformation row of B),
  core [[0, 1], [1, 0]];
- per link past the first, the x and y rows of the inboard links' tip Jacobians t and
  of the link's own first moment b = int J dm, core [[m I, I], [I, 0]] (the terms
  m t^T t + t^T b + b^T t of the link's particles riding on the inboard links);
- per joint the actuator row Ga_i (PD gains, friction slope, back-EMF), per elastic joint
  Ga_i - G_i (spring), and the eigenvectors of the parts of Bc, D, K outside the band;
- per link, the axial block sum_k mu_k (S_k q_f)(S_k q_f)^T (dense) projected on
  AXIAL_RANK polynomials in z orthonormal in the link's mass: columns
  y_j = sum_k mu_k phi_j(z_k) S_k q_f, core I.
What is left out is the rest of the axial block (of the order of the slopes squared
against the inertia kept; on the hub-less arm of issue 24 the iterations contract by
0.07 per iteration without the block, 0.0035 / 0.0021 / 0.0008 with 2 / 6 / 10
polynomials, 4 taken). Solved by Woodbury: x = y - Z (I + C U^T Z)^-1 C U^T y with
y = A^-1 b and Z = A^-1 U, both by a banded Cholesky factor.

The factor is a tuple (Lb, U, Z, Cap, piv, C, kind): kind 1 this structure, kind 0 a
dense Cholesky factor in Lb (the other arrays empty), an empty Lb when none.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .inputs import (JD_B, JD_EPS, JD_FC, JD_FS, JD_FV, JD_K, JD_KE, JD_KT, JD_MOTOR, JD_R,
                     JD_RATIO)
from .kernels import (P_BAND, P_BC, P_BP, P_DS, P_JPLUS, P_JRIG, P_L, P_LAM, P_LO, P_MU,
                      P_NF, P_OFF, P_V, P_WL, P_WN, P_ZQ, solve_chol)

_CACHE = True
#: polynomials per link on which the axial block sum_k mu_k (S_k q_f)(S_k q_f)^T is
#: projected (its rank in the iteration matrix)
AXIAL_RANK = 4


@njit(cache=_CACHE)
def band_cholesky(Ab):
    """Lower Cholesky factor of the SPD band matrix stored as Ab[i, j] = A[i, i - j],
    j = 0..bw, in the same storage; an empty (0, 0) array when not positive definite."""
    n, w = Ab.shape
    bw = w - 1
    Lb = np.zeros((n, w))
    for i in range(n):
        k0 = max(0, i - bw)
        for j in range(k0, i + 1):
            s = Ab[i, i - j]
            for k in range(max(k0, j - bw), j):
                s -= Lb[i, i - k] * Lb[j, j - k]
            if j == i:
                if s <= 0.0:
                    return np.zeros((0, 0))
                Lb[i, 0] = np.sqrt(s)
            else:
                Lb[i, i - j] = s / Lb[j, 0]
    return Lb


@njit(cache=_CACHE)
def band_solve(Lb, b):
    """Solve L L^T x = b for the band factor of :func:`band_cholesky`."""
    n, w = Lb.shape
    bw = w - 1
    y = np.empty(n)
    for i in range(n):
        t = b[i]
        for k in range(max(0, i - bw), i):
            t -= Lb[i, i - k] * y[k]
        y[i] = t / Lb[i, 0]
    for i in range(n - 1, -1, -1):
        t = y[i]
        for k in range(i + 1, min(n, i + bw + 1)):
            t -= Lb[k, k - i] * y[k]
        y[i] = t / Lb[i, 0]
    return y


@njit(cache=_CACHE)
def _lu(A):
    """LU factor with partial pivoting of a small square matrix (in place), pivots."""
    n = A.shape[0]
    piv = np.arange(n)
    for j in range(n):
        p = j
        for i in range(j + 1, n):
            if abs(A[i, j]) > abs(A[p, j]):
                p = i
        if p != j:
            for k in range(n):
                A[j, k], A[p, k] = A[p, k], A[j, k]
            piv[j], piv[p] = piv[p], piv[j]
        if A[j, j] == 0.0:
            continue
        for i in range(j + 1, n):
            A[i, j] /= A[j, j]
            for k in range(j + 1, n):
                A[i, k] -= A[i, j] * A[j, k]
    return A, piv


@njit(cache=_CACHE)
def _lu_solve(LU, piv, b):
    n = b.shape[0]
    x = np.empty(n)
    for i in range(n):
        x[i] = b[piv[i]]
    for i in range(n):
        for k in range(i):
            x[i] -= LU[i, k] * x[k]
    for i in range(n - 1, -1, -1):
        for k in range(i + 1, n):
            x[i] -= LU[i, k] * x[k]
        x[i] /= LU[i, i]
    return x


@njit(cache=_CACHE)
def empty_factor():
    """The factor tuple holding no factor (its flag an int64: a literal 0 in the tuple's
    type would compile solvers.loop._simplified once more when the flag becomes int64)."""
    z2 = np.zeros((0, 0))
    return z2, z2, z2, z2, np.zeros(0, dtype=np.int64), z2, np.int64(0)


@njit(cache=_CACHE)
def joint_coefficients(v, E):
    """Stiffness and damping of each joint's law along its actuator row Ga_i (PD gains,
    DC motor gain and back-EMF, friction slope), as in integrators.joint_tangent."""
    kp, kd, Ga, jd = E.kp, E.kd, E.Ga, E.joint_data
    nl = jd.shape[0]
    kk = np.zeros(nl)
    cd = np.zeros(nl)
    for i in range(nl):
        gain = 1.0
        c = 0.0
        if jd[i, JD_MOTOR] > 0.0:
            gain = jd[i, JD_RATIO] * jd[i, JD_KT] / jd[i, JD_R]
            c = gain * jd[i, JD_KE] * jd[i, JD_RATIO]
        w = Ga[i] @ v
        if jd[i, JD_FC] > 0.0 or jd[i, JD_FS] > 0.0:
            c += jd[i, JD_FS] / jd[i, JD_EPS] / np.cosh(min(abs(w / jd[i, JD_EPS]), 300.0)) ** 2
        cd[i] = c + jd[i, JD_FV] + gain * kd[i]
        kk[i] = gain * kp[i]
    return kk, cd


@njit(cache=_CACHE)
def _banded_part(gp, bp, bw, P, E):
    """A's bands (module docstring): the deformation inertia Bp (thesis Eq. 9), the
    constant inertia Bc and gamma' D + beta' K, lower bands stored as Ab[i, j] =
    A[i, i - j]."""
    Bp, Bc, K, D = P[P_BP], P[P_BC], E.K, E.D
    nq = Bp.shape[0]
    Ab = np.zeros((nq, bw + 1))
    for i in range(nq):
        for j in range(min(bw, i) + 1):
            c = i - j
            Ab[i, j] = Bp[i, c] + Bc[i, c] + gp * D[i, c] + bp * K[i, c]
    return Ab


@njit(cache=_CACHE)
def _first_moments(i, q, P, e1x, e1y, e2x, e2y, ra, bx, by, U, cA, cB):
    """Link i's points p = (z - u) e1 + d e2 (second-order kinematics, kernels.py):
    the rho column (alpha-deformation row of B) and, past the first link, the own first
    moment columns b = int J dm of U; c_k = mu_k d_k and mu_k into cA, cB. Returns u and
    d at the tip, the alpha-alpha inertia, the mass and the first moment's alpha row."""
    off, zq, mu = P[P_OFF], P[P_ZQ], P[P_MU]
    lo, wn, dS, Wl = P[P_LO], P[P_WN], P[P_DS], P[P_WL]
    o = off[i] + 1
    u = 0.0
    saa = 0.0
    mt = 0.0
    box = 0.0
    boy = 0.0
    d = 0.0
    for k in range(mu.shape[1]):
        b = o + lo[i, k]
        w = wn[i, k]
        d = 0.0
        for j in range(w):
            qj = q[b + j]
            d += Wl[i, k, j] * qj
            sq = 0.0
            for l in range(w):
                sq += dS[i, k, j, l] * q[b + l]
            u += 0.5 * qj * sq
        m = mu[i, k]
        cA[k] = m * d
        cB[k] = m
        if m == 0.0:
            continue
        rr = zq[i, k] - u
        saa += m * (rr * rr + d * d)
        mt += m
        box += m * (rr * e2x - d * e1x)
        boy += m * (rr * e2y - d * e1y)
        for j in range(w):
            mw = m * Wl[i, k, j]
            U[b + j, ra] += rr * mw
            if i > 0:
                U[b + j, bx] += e2x * mw
                U[b + j, by] += e2y * mw
    return u, d, saa, mt, box, boy


@njit(cache=_CACHE)
def _mass_orthonormal_polynomials(i, P, mt, phi):
    """phi[j] = the polynomials (z / L)^j at link i's points, orthonormal in the points'
    masses mu_k (Gram-Schmidt; zero where mu_k = 0), onto which the axial block is
    projected (module docstring)."""
    L, zq, mu = P[P_L], P[P_ZQ], P[P_MU]
    npt = mu.shape[1]
    for j in range(AXIAL_RANK):
        for k in range(npt):
            phi[j, k] = (zq[i, k] / L[i]) ** j if mu[i, k] != 0.0 else 0.0
        for jj in range(j):
            dot = 0.0
            for k in range(npt):
                dot += mu[i, k] * phi[j, k] * phi[jj, k]
            for k in range(npt):
                phi[j, k] -= dot * phi[jj, k]
        nrm = 0.0
        for k in range(npt):
            nrm += mu[i, k] * phi[j, k] * phi[j, k]
        for k in range(npt):
            phi[j, k] = phi[j, k] / np.sqrt(nrm) if nrm > 1e-12 * mt else 0.0


@njit(cache=_CACHE)
def _shortening_columns(i, q, P, e1x, e1y, ra, bx, by, ax, U, cA, cB, phi, sp):
    """The shortening's share of link i's columns of U by suffix sums,
    sum_k c_k S_k q_f = sum_k dS_k q_f sum_{k' >= k} c_k': rho, the first moment (past the
    first link) and the projected axial block y_j = sum_k mu_k phi_j(z_k) S_k q_f;
    returns S(L) q_f (the tip's)."""
    off, nf, mu = P[P_OFF], P[P_NF], P[P_MU]
    lo, wn, dS = P[P_LO], P[P_WN], P[P_DS]
    o = off[i] + 1
    sa = 0.0
    sb = 0.0
    sp[:] = 0.0
    svl = np.zeros(nf[i])
    for k in range(mu.shape[1] - 1, -1, -1):
        sa += cA[k]
        sb += cB[k]
        for j in range(AXIAL_RANK):
            sp[j] += mu[i, k] * phi[j, k]
        b = lo[i, k]
        w = wn[i, k]
        for j in range(w):
            sq = 0.0
            for l in range(w):
                sq += dS[i, k, j, l] * q[o + b + l]
            U[o + b + j, ra] += sa * sq
            if i > 0:
                U[o + b + j, bx] -= e1x * sb * sq
                U[o + b + j, by] -= e1y * sb * sq
            for jj in range(AXIAL_RANK):
                U[o + b + j, ax + jj] += sp[jj] * sq
            svl[b + j] += sq
    return svl


@njit(cache=_CACHE)
def _tip_rows(i, P, u, d, e1x, e1y, e2x, e2y, svl, TX, TY):
    """Link i's part of the x and y rows of its tip Jacobian (the last point, z = L):
    alpha column r e2 - d e1 and the deformation columns W(L) e2 - S(L) q_f e1."""
    off, nf, zq, mu = P[P_OFF], P[P_NF], P[P_ZQ], P[P_MU]
    lo, wn, Wl = P[P_LO], P[P_WN], P[P_WL]
    o = off[i] + 1
    kt = mu.shape[1] - 1
    rl = zq[i, kt] - u
    TX[o - 1] = rl * e2x - d * e1x
    TY[o - 1] = rl * e2y - d * e1y
    for j in range(nf[i]):
        TX[o + j] = -svl[j] * e1x
        TY[o + j] = -svl[j] * e1y
    for j in range(wn[i, kt]):
        TX[o + lo[i, kt] + j] += Wl[i, kt, j] * e2x
        TY[o + lo[i, kt] + j] += Wl[i, kt, j] * e2y


@njit(cache=_CACHE)
def _link_columns(i, q, P, col, Ab, U, C, TX, TY, cA, cB, phi, sp):
    """Link i's columns of U from ``col`` with their core C (module docstring: e_alpha and
    rho; past the first link the inboard tip rows t and the own first moment b; the
    projected axial block) and its alpha-alpha entry of A; TX, TY: the inboard links'
    tip rows, on return this link's. Returns the next free column."""
    off, nf, jplus, jrig = P[P_OFF], P[P_NF], P[P_JPLUS], P[P_JRIG]
    o = off[i] + 1
    c = np.cos(q[o - 1])
    s = np.sin(q[o - 1])
    e1x, e1y, e2x, e2y = c, s, -s, c
    ra = col + 1            # rho
    bx = col + 4            # own first moment, x and y (after tx, ty)
    by = col + 5
    u, d, saa, mt, box, boy = _first_moments(i, q, P, e1x, e1y, e2x, e2y, ra, bx, by, U,
                                             cA, cB)
    _mass_orthonormal_polynomials(i, P, mt, phi)
    ax = col + 2 + (4 if i > 0 else 0)
    svl = _shortening_columns(i, q, P, e1x, e1y, ra, bx, by, ax, U, cA, cB, phi, sp)
    for jj in range(AXIAL_RANK):
        C[ax + jj, ax + jj] = 1.0
    g = o - 1 + nf[i]
    Ab[o - 1, 0] += saa + jrig[i]
    Ab[g, 0] += jplus[i]
    U[g, ra] += jplus[i]
    U[o - 1, col] = 1.0
    C[col, ra] = 1.0
    C[ra, col] = 1.0
    col += 2
    if i > 0:
        U[:, col] = TX
        U[:, col + 1] = TY
        U[o - 1, bx] = box
        U[o - 1, by] = boy
        C[col, col] = mt
        C[col + 1, col + 1] = mt
        C[col, bx] = C[bx, col] = 1.0
        C[col + 1, by] = C[by, col + 1] = 1.0
        col += 4
    col += AXIAL_RANK
    _tip_rows(i, P, u, d, e1x, e1y, e2x, e2y, svl, TX, TY)
    return col


@njit(cache=_CACHE)
def _joint_columns(v, gp, bp, E, col, U, C):
    """The joints' columns of U from ``col``: per joint its actuator row Ga_i with core
    beta' k + gamma' c (joint_coefficients), per elastic joint Ga_i - G_i with its spring
    and damper. Returns the next free column."""
    G, Ga, jd = E.G, E.Ga, E.joint_data
    kk, cd = joint_coefficients(v, E)
    for i in range(jd.shape[0]):
        U[:, col] = Ga[i]
        C[col, col] = bp * kk[i] + gp * cd[i]
        col += 1
        if np.isfinite(jd[i, JD_K]):
            for j in range(U.shape[0]):
                U[j, col] = Ga[i, j] - G[i, j]
            C[col, col] = bp * jd[i, JD_K] + gp * jd[i, JD_B]
            col += 1
    return col


@njit(cache=_CACHE)
def _woodbury_factor(Ab, U, C):
    """The factor tuple of A + U C U^T (Woodbury, module docstring): A's band Cholesky
    factor Lb, Z = A^-1 U and the LU factor of I + C U^T Z; empty when A is not positive
    definite."""
    Lb = band_cholesky(Ab)
    if Lb.shape[0] == 0:
        return empty_factor()
    nq, r = U.shape
    Z = np.empty((nq, r))
    for m in range(r):
        Z[:, m] = band_solve(Lb, U[:, m])
    Cap = C @ (U.T @ Z)
    for m in range(r):
        Cap[m, m] += 1.0
    Cap, piv = _lu(Cap)
    return Lb, U, Z, Cap, piv, C, 1


@njit(cache=_CACHE)
def structured_factor(q, v, gp, bp, P, E):
    """The factor of M = A + U C U^T (module docstring) at (q, v); an empty factor when A
    is not positive definite."""
    L, V, lam = P[P_L], P[P_V], P[P_LAM]
    jd = E.joint_data
    nl = L.shape[0]
    nq = q.shape[0]
    npt = P[P_MU].shape[1]
    ne = 0
    for i in range(nl):
        if np.isfinite(jd[i, JD_K]):
            ne += 1
    r = (2 + AXIAL_RANK) * nl + 4 * (nl - 1) + nl + ne + V.shape[1]
    Ab = _banded_part(gp, bp, P[P_BAND][0], P, E)
    U = np.zeros((nq, r))
    C = np.zeros((r, r))
    TX = np.zeros(nq)  # rows of the inboard links' tip Jacobians
    TY = np.zeros(nq)
    cA = np.zeros(npt)
    cB = np.zeros(npt)
    phi = np.zeros((AXIAL_RANK, npt))
    sp = np.zeros(AXIAL_RANK)
    col = 0
    for i in range(nl):
        col = _link_columns(i, q, P, col, Ab, U, C, TX, TY, cA, cB, phi, sp)
    col = _joint_columns(v, gp, bp, E, col, U, C)
    for m in range(V.shape[1]):
        U[:, col] = V[:, m]
        C[col, col] = lam[0, m] + gp * lam[1, m] + bp * lam[2, m]
        col += 1
    return _woodbury_factor(Ab, U, C)


@njit(cache=_CACHE)
def factor_solve(F, b):
    """Solve M x = b with a factor tuple (module docstring)."""
    Lb, U, Z, Cap, piv, C, kind = F
    if kind == 0:
        return solve_chol(Lb, b)
    y = band_solve(Lb, b)
    w = U.T @ y
    t = _lu_solve(Cap, piv, C @ w)
    return y - Z @ t


# the compiled caches of this module are guarded against changes of kernels.py by
# integrators._guard_caches (it imports the dispatchers that call into kernels)
