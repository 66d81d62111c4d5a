"""Compiled kernels of the flexible-arm equations of motion (thesis Ch. II, Eqs. 1-30).

Coordinates ``q = [alpha_1, q_f1, alpha_2, q_f2, ...]`` (absolute link angles and the
wavelet deformation variables of each link, thesis Eq. 12 and Eq. 22). Link ``i`` occupies
``q[off[i] : off[i] + 1 + nf[i]]``; its tip deflection ``delta_n`` is at
``off[i] + nf[i] - 1`` and its tip rotation ``gamma_n`` at ``off[i] + nf[i]``. A link
with one variable (the lumped link of seed 000) has its tip deflection as that variable,
``off[i] + 1``, and its tip rotation proportional to it: the model folds the tip inertia's
share into ``jplus`` and ``kt`` (mode 0 only).

A point of link i at abscissa z is (thesis Eq. 1)
    p = o_i + z e1(alpha_i) + d(z) e2(alpha_i),   d = W(z) q_f,
and the next link's origin is its tip (thesis Eqs. 20-21). The equations of motion

    d/dt(B(q) v) - 1/2 d/dq (v^T B(q) v) + K q + D v + dU_g/dq = Q        (thesis Eq. 27)

are evaluated by d'Alembert's principle over the particles of each link: each link's
inertial force is computed in its own (redundant) coordinates (o_i, alpha_i, q_f) and
mapped to q through the interconnection Jacobian of Eqs. (20)-(22), a backward sum of the
outboard links' resultant forces. Gravity enters as a base acceleration -g. The result is
the exact Lagrangian of Eqs. (6)-(7), (15)-(16), with cost linear in the number of
variables for the bias and quadratic (the interconnection coupling) for B.

The model data ``P`` is the tuple built by :class:`flex_model.dynamics.FlexArmModel`:
``(mode, off, nf, L, mtot, ntot, jrot, jplus, Bp, ht, kt, zq, mu, Wq, Sq, jrig, Bc, na, lo,
wn, dS, Wl, (bw, on), V, lam)``, its fields indexed by name (``P[P_OFF]``, the P_ constants
below),
Bc a constant inertia added to B (rotor inertias of geared joints, seed 000 Eq. 35). For the
thesis model (mode 0), per link i, with the end masses M-, M+ and inertias J-, J+
included (thesis Eq. 8 and the tilde quantities of Eq. 18): mtot = M, ntot = N,
jrot = J + M+ L^2, Bp = B_f + M+ e_dn e_dn^T (block of a global nq x nq array),
ht = h~, kt = k~ (global nq arrays, zero at the alpha entries).

Mode 1 adds the second-order (foreshortening) kinematics of an inextensible bent link,
    p = o + (z - u(z)) e1 + d(z) e2,    u(z) = 1/2 q_f^T S(z) q_f,  S = int_0^z w' w'^T,
which the thesis omits (Remark 5 drops the related higher-order terms): it brings the
geometric stiffening of the links under axial load (gravity, centrifugal and the
outboard links' inertia). The integrals are then evaluated at run time by Gauss
quadrature at points zq (per link, padded) with mass weights mu (kg; the end masses are
points at z = 0 and z = L), shape values Wq and matrices Sq = S(zq); jrig = J- + J+;
na (per link and point): W and S vanish past the first na variables (the wavelets' local
support), so the mass matrix's loops stop there. The inverse dynamics (the residual of
the fixed step) costs linear in the variables: lo, wn, dS, Wl give, per
point, the window of variables where the increment dS_k = S(z_k) - S(z_{k-1}) and W_k do
not vanish (at most 6 for the wavelets), and S(z) q_f is accumulated point by point.
(bw, on), V, lam: the band structure of the iteration matrix
(flex_model.iteration_matrix; :func:`band_matvec` for K q, D v, Bc a when on).
The equations stay those of an exact Lagrangian (energy is conserved).
"""
from __future__ import annotations

import numpy as np
from numba import njit

_CACHE = True

#: the fields of the model data P (module docstring), by name: P[P_OFF] is off, ...
(P_MODE, P_OFF, P_NF, P_L, P_MTOT, P_NTOT, P_JROT, P_JPLUS, P_BP, P_HT, P_KT, P_ZQ, P_MU,
 P_WQ, P_SQ, P_JRIG, P_BC, P_NA, P_LO, P_WN, P_DS, P_WL, P_BAND, P_V, P_LAM) = range(25)


@njit(cache=_CACHE)
def _tip_index(o, n):
    """Index of the tip deflection of the link at offset o with n variables."""
    return o + n - 1 if n > 1 else o + 1


@njit(cache=_CACHE)
def inverse_dynamics(q, v, a, gx, gy, P):
    """Generalized inertial + Coriolis/centrifugal + gravity force B a + c(q, v) + dU_g/dq.

    Elastic and damping forces are not included (they are K q and D v).
    """
    if P[P_MODE] == 1:
        f = _inverse_dynamics_2(q, v, a, gx, gy, P)
        if P[P_BAND][1] == 1:  # banded model (dynamics._band_structure): Bc a linear in nq
            f += band_matvec(P[P_BC], a, P[P_BAND][0], P[P_V], P[P_LAM][0])
            return f
        return _add_matvec(f, P[P_BC], a)
    return _add_matvec(_inverse_dynamics_1(q, v, a, gx, gy, P), P[P_BC], a)


@njit(cache=_CACHE)
def _add_matvec(f, M, x):
    """f += M x by loops (a BLAS call's overhead exceeds the product at these sizes)."""
    for i in range(f.shape[0]):
        s = 0.0
        for j in range(x.shape[0]):
            s += M[i, j] * x[j]
        f[i] += s
    return f


@njit(cache=_CACHE)
def band_matvec(M, x, bw, V, lam):
    """M x for M = (M within bw of its diagonal) + V diag(lam) V^T (the rest of M as its
    eigenvectors: dynamics._band_structure), at a cost linear in the size."""
    n = x.shape[0]
    y = np.zeros(n)
    for i in range(n):
        t = 0.0
        for j in range(max(0, i - bw), min(n, i + bw + 1)):
            t += M[i, j] * x[j]
        y[i] = t
    for m in range(V.shape[1]):
        if lam[m] != 0.0:
            t = 0.0
            for i in range(n):
                t += V[i, m] * x[i]
            t *= lam[m]
            for i in range(n):
                y[i] += V[i, m] * t
    return y


@njit(cache=_CACHE)
def _inverse_dynamics_1(q, v, a, gx, gy, P):
    """Mode 0 (thesis kinematics) of :func:`inverse_dynamics`."""
    off, nf, L, mtot, ntot, jrot, jplus, Bp, ht, kt = P[1:11]
    nl = L.shape[0]
    nq = q.shape[0]
    f = np.zeros(nq)
    # forward pass: accelerations of the link origins; base accelerates with -g
    aox = -gx
    aoy = -gy
    fox = np.zeros(nl)
    foy = np.zeros(nl)
    for i in range(nl):
        o = off[i]
        n = nf[i]
        al = q[o]
        wd = v[o]
        ad = a[o]
        c = np.cos(al)
        s = np.sin(al)
        e1x, e1y, e2x, e2y = c, s, -s, c
        S = 0.0
        Sd = 0.0
        Sdd = 0.0
        qBq = 0.0
        qBv = 0.0
        ka = 0.0
        for j in range(n):
            r = o + 1 + j
            S += ht[r] * q[r]
            Sd += ht[r] * v[r]
            Sdd += ht[r] * a[r]
            ka += kt[r] * a[r]
            bq = 0.0
            bv = 0.0
            for l in range(n):
                cidx = o + 1 + l
                bq += Bp[r, cidx] * q[cidx]
                bv += Bp[r, cidx] * v[cidx]
            qBq += q[r] * bq
            qBv += q[r] * bv
        N = ntot[i]
        e2a = e2x * aox + e2y * aoy
        e1a = e1x * aox + e1y * aoy
        # link resultant force (particles): F_o = int p'' dm
        fox[i] = (mtot[i] * aox + ad * (N * e2x - S * e1x) - wd * wd * (N * e1x + S * e2x)
                  - 2.0 * wd * Sd * e1x + Sdd * e2x)
        foy[i] = (mtot[i] * aoy + ad * (N * e2y - S * e1y) - wd * wd * (N * e1y + S * e2y)
                  - 2.0 * wd * Sd * e1y + Sdd * e2y)
        # alpha equation
        f[o] = N * e2a - S * e1a + ad * (jrot[i] + qBq) + 2.0 * wd * qBv + ka
        # deformation equations
        for j in range(n):
            r = o + 1 + j
            bq = 0.0
            ba = 0.0
            for l in range(n):
                cidx = o + 1 + l
                bq += Bp[r, cidx] * q[cidx]
                ba += Bp[r, cidx] * a[cidx]
            f[r] = ht[r] * e2a + kt[r] * ad - wd * wd * bq + ba
        g = o + n
        f[g] += jplus[i] * a[g]
        # acceleration of the tip = origin of the next link (thesis Eq. 20 differentiated)
        dl = _tip_index(o, n)
        de = q[dl]
        dd = v[dl]
        da = a[dl]
        Li = L[i]
        aox = (aox + ad * (Li * e2x - de * e1x) - wd * wd * (Li * e1x + de * e2x)
               - 2.0 * wd * dd * e1x + da * e2x)
        aoy = (aoy + ad * (Li * e2y - de * e1y) - wd * wd * (Li * e1y + de * e2y)
               - 2.0 * wd * dd * e1y + da * e2y)
    # backward pass: outboard resultant forces acting through each link's tip
    rx = 0.0
    ry = 0.0
    for i in range(nl - 1, -1, -1):
        o = off[i]
        n = nf[i]
        al = q[o]
        c = np.cos(al)
        s = np.sin(al)
        de = q[_tip_index(o, n)]
        f[o] += (L[i] * (-s) - de * c) * rx + (L[i] * c - de * s) * ry
        f[_tip_index(o, n)] += -s * rx + c * ry
        rx += fox[i]
        ry += foy[i]
    return f


@njit(cache=_CACHE)
def mass_matrix(q, P):
    """Inertia matrix B(q) of thesis Eqs. (18)-(23), assembled link by link."""
    if P[0] == 1:
        return _mass_matrix_2(q, P) + P[16]
    return _mass_matrix_1(q, P) + P[16]


@njit(cache=_CACHE)
def _mass_matrix_1(q, P):
    """Mode 0 (thesis kinematics) of :func:`mass_matrix`."""
    off, nf, L, mtot, ntot, jrot, jplus, Bp, ht, kt = P[1:11]
    nl = L.shape[0]
    nq = q.shape[0]
    B = np.zeros((nq, nq))
    # interface columns (alpha_k, delta_n,k) and their 2-vectors phi = d o_{k+1} / d q_c
    cols = np.zeros(2 * nl, dtype=np.int64)
    phx = np.zeros(2 * nl)
    phy = np.zeros(2 * nl)
    for i in range(nl):
        o = off[i]
        n = nf[i]
        c = np.cos(q[o])
        s = np.sin(q[o])
        e1x, e1y, e2x, e2y = c, s, -s, c
        S = 0.0
        qBq = 0.0
        for j in range(n):
            r = o + 1 + j
            S += ht[r] * q[r]
            bq = 0.0
            for l in range(n):
                bq += Bp[r, o + 1 + l] * q[o + 1 + l]
            qBq += q[r] * bq
        # own block
        B[o, o] += jrot[i] + qBq
        for j in range(n):
            r = o + 1 + j
            B[o, r] += kt[r]
            B[r, o] += kt[r]
            for l in range(n):
                B[r, o + 1 + l] += Bp[r, o + 1 + l]
        B[o + n, o + n] += jplus[i]
        # coupling with the interface columns of the inboard links
        N = ntot[i]
        bax = N * e2x - S * e1x
        bay = N * e2y - S * e1y
        nc = 2 * i
        for m in range(nc):
            cm = cols[m]
            val = bax * phx[m] + bay * phy[m]
            B[o, cm] += val
            B[cm, o] += val
            e2p = e2x * phx[m] + e2y * phy[m]
            for j in range(n):
                r = o + 1 + j
                B[r, cm] += ht[r] * e2p
                B[cm, r] += ht[r] * e2p
            for m2 in range(nc):
                B[cm, cols[m2]] += mtot[i] * (phx[m] * phx[m2] + phy[m] * phy[m2])
        # this link's interface columns for the links outboard of it
        de = q[_tip_index(o, n)]
        cols[nc] = o
        phx[nc] = L[i] * e2x - de * e1x
        phy[nc] = L[i] * e2y - de * e1y
        cols[nc + 1] = _tip_index(o, n)
        phx[nc + 1] = e2x
        phy[nc + 1] = e2y
    return B


@njit(cache=_CACHE)
def cholesky(A):
    """Lower Cholesky factor of the symmetric positive definite A (A is not modified); an
    empty (0, 0) array when A is not positive definite."""
    n = A.shape[0]
    Lc = np.zeros((n, n))
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= Lc[j, k] * Lc[j, k]
        if s <= 0.0:
            return np.zeros((0, 0))
        d = np.sqrt(s)
        Lc[j, j] = d
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= Lc[i, k] * Lc[j, k]
            Lc[i, j] = t / d
    return Lc


@njit(cache=_CACHE)
def solve_chol(Lc, b):
    """Solve L L^T x = b for the factor L of :func:`cholesky`."""
    n = b.shape[0]
    y = np.zeros(n)
    for i in range(n):
        t = b[i]
        for k in range(i):
            t -= Lc[i, k] * y[k]
        y[i] = t / Lc[i, i]
    x = np.zeros(n)
    for i in range(n - 1, -1, -1):
        t = y[i]
        for k in range(i + 1, n):
            t -= Lc[k, i] * x[k]
        x[i] = t / Lc[i, i]
    return x


@njit(cache=_CACHE)
def solve_spd(A, b):
    """Solve A x = b for symmetric positive definite A by Cholesky (A is not modified;
    NaN when A is not positive definite)."""
    Lc = cholesky(A)
    if Lc.shape[0] != b.shape[0]:
        return np.full(b.shape[0], np.nan)
    return solve_chol(Lc, b)


@njit(cache=_CACHE)
def _tip_point(q, i, P):
    """Local tip quantities of link i: (u_L, s_L = S(L) q_f) (zero in mode 0)."""
    off, nf = P[1], P[2]
    n = nf[i]
    o = off[i]
    sL = np.zeros(n)
    uL = 0.0
    if P[0] == 1:
        Sq, npt = P[14], P[12].shape[1]
        k = npt - 1  # the last point of every link is its tip (z = L)
        for j in range(n):
            acc = 0.0
            for l in range(n):
                acc += Sq[i, k, j, l] * q[o + 1 + l]
            sL[j] = acc
            uL += 0.5 * q[o + 1 + j] * acc
    return uL, sL


@njit(cache=_CACHE)
def link_origins(q, P):
    """Origins o_1..o_{nl+1} (the last is the arm's tip) in the base frame: (nl+1, 2)."""
    off, nf, L = P[1], P[2], P[3]
    nl = L.shape[0]
    out = np.zeros((nl + 1, 2))
    for i in range(nl):
        o = off[i]
        c = np.cos(q[o])
        s = np.sin(q[o])
        de = q[_tip_index(o, nf[i])]
        uL, sL = _tip_point(q, i, P)
        out[i + 1, 0] = out[i, 0] + (L[i] - uL) * c - de * s
        out[i + 1, 1] = out[i, 1] + (L[i] - uL) * s + de * c
    return out


@njit(cache=_CACHE)
def tip_jacobian(q, P):
    """d p_tip / d q (2, nq): Jacobian of the arm's end point (thesis Eqs. 20-21, 30)."""
    off, nf, L = P[1], P[2], P[3]
    nl = L.shape[0]
    Jt = np.zeros((2, q.shape[0]))
    for i in range(nl):
        o = off[i]
        c = np.cos(q[o])
        s = np.sin(q[o])
        de = q[_tip_index(o, nf[i])]
        uL, sL = _tip_point(q, i, P)
        Jt[0, o] = -(L[i] - uL) * s - de * c
        Jt[1, o] = (L[i] - uL) * c - de * s
        for j in range(nf[i]):
            Jt[0, o + 1 + j] -= sL[j] * c
            Jt[1, o + 1 + j] -= sL[j] * s
        Jt[0, _tip_index(o, nf[i])] += -s
        Jt[1, _tip_index(o, nf[i])] += c
    return Jt


@njit(cache=_CACHE)
def gravity_potential(q, gx, gy, P):
    """U_g = -g . sum_i int p dm (thesis Eqs. 15-16, 26)."""
    org = link_origins(q, P)
    u = 0.0
    if P[0] == 1:
        off, nf, L, zq, mu, Wq, Sq = P[1], P[2], P[3], P[11], P[12], P[13], P[14]
        for i in range(L.shape[0]):
            o = off[i]
            c = np.cos(q[o])
            s = np.sin(q[o])
            for k in range(mu.shape[1]):
                d, uu = _point_dq(q, o, nf[i], Wq[i, k], Sq[i, k])
                r = zq[i, k] - uu
                u -= mu[i, k] * (gx * (org[i, 0] + r * c - d * s)
                                 + gy * (org[i, 1] + r * s + d * c))
        return u
    off, nf, L, mtot, ntot = P[1], P[2], P[3], P[4], P[5]
    ht = P[9]
    for i in range(L.shape[0]):
        o = off[i]
        c = np.cos(q[o])
        s = np.sin(q[o])
        S = 0.0
        for j in range(nf[i]):
            S += ht[o + 1 + j] * q[o + 1 + j]
        px = mtot[i] * org[i, 0] + ntot[i] * c - S * s
        py = mtot[i] * org[i, 1] + ntot[i] * s + S * c
        u -= gx * px + gy * py
    return u


@njit(cache=_CACHE)
def _point_dq(q, o, n, W, S):
    """Deflection d = W q_f and shortening u = 1/2 q_f^T S q_f at one point."""
    d = 0.0
    u = 0.0
    for j in range(n):
        d += W[j] * q[o + 1 + j]
        acc = 0.0
        for l in range(n):
            acc += S[j, l] * q[o + 1 + l]
        u += 0.5 * q[o + 1 + j] * acc
    return d, u


@njit(cache=_CACHE)
def _point_kinematics(q, v, o, n, W, S, z, c, s, wd, sv, Jfx, Jfy):
    """Point of a link with second-order kinematics (mode 1).

    Fills the columns Jf (d p / d q_f) and ``sv`` = S q_f for the first n variables (W
    and S vanish past them: P[17]); returns the alpha column (Jax, Jay) and the
    velocity-product acceleration (xix, xiy) for alpha' = wd.
    """
    d = 0.0
    dd = 0.0
    u = 0.0
    ud = 0.0
    vSv = 0.0
    for j in range(n):
        qj = q[o + 1 + j]
        d += W[j] * qj
        dd += W[j] * v[o + 1 + j]
        acc = 0.0
        accv = 0.0
        for l in range(n):
            acc += S[j, l] * q[o + 1 + l]
            accv += S[j, l] * v[o + 1 + l]
        sv[j] = acc
        u += 0.5 * qj * acc
        ud += acc * v[o + 1 + j]
        vSv += v[o + 1 + j] * accv
    e1x, e1y, e2x, e2y = c, s, -s, c
    r = z - u
    for j in range(n):
        Jfx[j] = W[j] * e2x - sv[j] * e1x
        Jfy[j] = W[j] * e2y - sv[j] * e1y
    Jax = r * e2x - d * e1x
    Jay = r * e2y - d * e1y
    xix = -(vSv + r * wd * wd + 2.0 * dd * wd) * e1x - (2.0 * ud * wd + d * wd * wd) * e2x
    xiy = -(vSv + r * wd * wd + 2.0 * dd * wd) * e1y - (2.0 * ud * wd + d * wd * wd) * e2y
    return Jax, Jay, xix, xiy


@njit(cache=_CACHE)
def _window_sums(q, v, a, Wl, dS, i, k, b, w, u, ud, vSv, qSa):
    """Mode 1, point k of link i (its variables' window [b, b + w)): the deflection
    d = W q_f with its rate and acceleration (thesis Eq. 1), and the shortening sums
    u = 1/2 q_f^T S q_f, u' = v^T S q_f, v^T S v and q_f^T S a carried on from the points
    before (S(z_k) = S(z_{k-1}) + dS_k, module docstring)."""
    d = 0.0
    dd = 0.0
    da = 0.0
    for j in range(w):
        Wj = Wl[i, k, j]
        qj = q[b + j]
        vj = v[b + j]
        d += Wj * qj
        dd += Wj * vj
        da += Wj * a[b + j]
        sq = 0.0
        sv = 0.0
        sa = 0.0
        for l in range(w):
            m = dS[i, k, j, l]
            sq += m * q[b + l]
            sv += m * v[b + l]
            sa += m * a[b + l]
        u += 0.5 * qj * sq
        ud += vj * sq
        vSv += vj * sv
        qSa += qj * sa
    return d, dd, da, u, ud, vSv, qSa


@njit(cache=_CACHE)
def _link_forces_2(i, q, v, a, aox, aoy, off, zq, mu, lo, wn, Wl, dS, f, cpt, tja):
    """Mode 1, the forward sweep over link i's points (d'Alembert, thesis Eq. 27): the
    point accelerations p'' = a_o + J_alpha alpha'' - t1 e1 - t2 e2 from the origin's
    (aox, aoy), the deformation forces W^T mu e2 . p'' into f, c_k = mu_k e1 . p'' into
    cpt, the tip's alpha column into tja; returns the link's resultant (Fx, Fy), its
    alpha force Fa and the tip's acceleration (the next origin's). P's arrays passed one by
    one: a call reference-counts each array of a tuple passed."""
    npt = mu.shape[1]
    o = off[i] + 1  # first deformation variable
    c = np.cos(q[o - 1])
    s = np.sin(q[o - 1])
    e1x, e1y, e2x, e2y = c, s, -s, c
    wd = v[o - 1]
    ad = a[o - 1]
    Fx = 0.0
    Fy = 0.0
    Fa = 0.0
    u = 0.0
    ud = 0.0
    vSv = 0.0
    qSa = 0.0
    for k in range(npt):
        b = o + lo[i, k]
        w = wn[i, k]
        d, dd, da, u, ud, vSv, qSa = _window_sums(q, v, a, Wl, dS, i, k, b, w,
                                                  u, ud, vSv, qSa)
        m = mu[i, k]
        tip = k == npt - 1
        if m == 0.0 and not tip:
            continue
        r = zq[i, k] - u
        Jax = r * e2x - d * e1x
        Jay = r * e2y - d * e1y
        t1 = vSv + r * wd * wd + 2.0 * dd * wd + qSa
        t2 = 2.0 * ud * wd + d * wd * wd - da
        px = aox + Jax * ad - t1 * e1x - t2 * e2x
        py = aoy + Jay * ad - t1 * e1y - t2 * e2y
        if tip:  # the next origin's acceleration and the tip's alpha column
            tja[i, 0] = Jax
            tja[i, 1] = Jay
        if m == 0.0:
            if tip:
                aox = px
                aoy = py
            continue
        Fx += m * px
        Fy += m * py
        Fa += m * (Jax * px + Jay * py)
        e2p = m * (e2x * px + e2y * py)
        for j in range(w):
            f[b + j] += Wl[i, k, j] * e2p
        cpt[i, k] = m * (e1x * px + e1y * py)
        if tip:
            aox = px
            aoy = py
    return Fx, Fy, Fa, aox, aoy


@njit(cache=_CACHE)
def _outboard_forces_2(i, q, rx, ry, off, lo, wn, dS, Wl, npt, f, cpt, tja):
    """Mode 1, link i in the backward sweep: the outboard links' resultant (rx, ry)
    through the tip (alpha column, W(L) e2 - S(L) q_f e1; thesis Eqs. 20-22) and the
    shortening's generalized force -sum_k dS_k q_f (suffix sum of c_k) into f."""
    o = off[i] + 1
    c = np.cos(q[o - 1])
    s = np.sin(q[o - 1])
    f[o - 1] += tja[i, 0] * rx + tja[i, 1] * ry
    k = npt - 1
    e2r = -s * rx + c * ry
    for j in range(wn[i, k]):
        f[o + lo[i, k] + j] += Wl[i, k, j] * e2r
    cpt[i, k] += c * rx + s * ry
    acc = 0.0
    for k in range(npt - 1, -1, -1):
        acc += cpt[i, k]
        b = o + lo[i, k]
        w = wn[i, k]
        for j in range(w):
            sq = 0.0
            for l in range(w):
                sq += dS[i, k, j, l] * q[b + l]
            f[b + j] -= acc * sq


@njit(cache=_CACHE)
def _inverse_dynamics_2(q, v, a, gx, gy, P):
    """Mode 1 of :func:`inverse_dynamics`: d'Alembert over quadrature points, with cost
    linear in the variables. Along a link the shortening matrix is accumulated interval by
    interval, S(z_k) = S(z_{k-1}) + dS_k (dS_k local: P[P_DS] on the window P[P_LO],
    P[P_WN]), so u = 1/2 q_f^T S q_f, its rates and q_f^T S a are running sums; the
    generalized force of the shortening, -sum_k c_k S(z_k) q_f with c_k = mu_k e1 . p''_k
    (and the outboard resultant at the tip), is sum_k dS_k q_f times the suffix sums of
    c_k."""
    off, nf, L = P[P_OFF], P[P_NF], P[P_L]
    jplus, jrig = P[P_JPLUS], P[P_JRIG]
    zq, mu, lo, wn, Wl, dS = P[P_ZQ], P[P_MU], P[P_LO], P[P_WN], P[P_WL], P[P_DS]
    nl = L.shape[0]
    npt = mu.shape[1]
    f = np.zeros(q.shape[0])
    aox = -gx
    aoy = -gy
    fox = np.zeros(nl)
    foy = np.zeros(nl)
    cpt = np.zeros((nl, npt))  # c_k = mu_k e1 . p''_k
    tja = np.zeros((nl, 2))    # tip alpha column
    for i in range(nl):
        o = off[i] + 1
        ad = a[o - 1]
        Fx, Fy, Fa, aox, aoy = _link_forces_2(i, q, v, a, aox, aoy, off, zq, mu, lo, wn, Wl,
                                              dS, f, cpt, tja)
        g = o - 1 + nf[i]
        f[o - 1] += Fa + jrig[i] * ad + jplus[i] * a[g]
        f[g] += jplus[i] * (ad + a[g])
        fox[i] = Fx
        foy[i] = Fy
    rx = 0.0
    ry = 0.0
    for i in range(nl - 1, -1, -1):
        _outboard_forces_2(i, q, rx, ry, off, lo, wn, dS, Wl, npt, f, cpt, tja)
        rx += fox[i]
        ry += foy[i]
    return f


@njit(cache=_CACHE)
def _mass_matrix_2(q, P):
    """Mode 1 of :func:`mass_matrix`: sum of mu J^T J over the quadrature points."""
    off, nf, L = P[1], P[2], P[3]
    jplus = P[7]
    zq, mu, Wq, Sq, jrig, na = P[11], P[12], P[13], P[14], P[15], P[17]
    nl = L.shape[0]
    nq = q.shape[0]
    npt = mu.shape[1]
    nfm = Wq.shape[2]
    B = np.zeros((nq, nq))
    v0 = np.zeros(nq)
    cols = np.zeros(nq, dtype=np.int64)
    phx = np.zeros(nq)
    phy = np.zeros(nq)
    nc = 0
    sv = np.zeros(nfm)
    Jfx = np.zeros(nfm)
    Jfy = np.zeros(nfm)
    Jx = np.zeros(nfm + 1)
    Jy = np.zeros(nfm + 1)
    for i in range(nl):
        o = off[i]
        n = nf[i]
        c = np.cos(q[o])
        s = np.sin(q[o])
        # local blocks: oo (scalar mass), o-(alpha, f) (2 x (n+1)), (alpha, f)^2
        mt = 0.0
        box = np.zeros(n + 1)
        boy = np.zeros(n + 1)
        for k in range(npt):
            nk = na[i, k]
            Jax, Jay, xix, xiy = _point_kinematics(q, v0, o, nk, Wq[i, k], Sq[i, k],
                                                   zq[i, k], c, s, 0.0, sv, Jfx, Jfy)
            Jx[0] = Jax
            Jy[0] = Jay
            for j in range(nk):
                Jx[1 + j] = Jfx[j]
                Jy[1 + j] = Jfy[j]
            for j in range(nk, n):
                Jx[1 + j] = 0.0
                Jy[1 + j] = 0.0
            m = mu[i, k]
            if m != 0.0:
                mt += m
                for j in range(nk + 1):
                    box[j] += m * Jx[j]
                    boy[j] += m * Jy[j]
                    for l in range(nk + 1):
                        B[o + j, o + l] += m * (Jx[j] * Jx[l] + Jy[j] * Jy[l])
        g = o + n
        B[o, o] += jrig[i]
        B[o, g] += jplus[i]
        B[g, o] += jplus[i]
        B[g, g] += jplus[i]
        for mm in range(nc):
            cm = cols[mm]
            for j in range(n + 1):
                val = box[j] * phx[mm] + boy[j] * phy[mm]
                B[o + j, cm] += val
                B[cm, o + j] += val
            for m2 in range(nc):
                B[cm, cols[m2]] += mt * (phx[mm] * phx[m2] + phy[mm] * phy[m2])
        # this link's tip Jacobian columns (the last point is z = L)
        for j in range(n + 1):
            cols[nc + j] = o + j
            phx[nc + j] = Jx[j]
            phy[nc + j] = Jy[j]
        nc += n + 1
    return B
