"""Geometrically exact kinematics of planar links (``kinematics: exact``), inextensible
or, with ``axial_vars``, extensible.

The wavelet variables q_f of a link keep their meaning at small deflections (thesis
Eq. 1: d(z) = W(z) q_f, Eq. 12), but the slope d' = W' q_f is read as the rotation of the
section, phi(s), at arc length s (the rotation-angle parametrization of an inextensible
Euler-Bernoulli beam, the elastica). The centre line in the link's floating frame (root
tangent along e1, alpha the link's absolute angle) is then exact:

    r(s) = int_0^s [cos phi, sin phi] ds,        phi(s) = W'(s) q_f,
    p(s) = o + r_1(s) e1(alpha) + r_2(s) e2(alpha),

and the curvature is exactly phi' = W'' q_f, so the bending energy EI/2 int phi'^2 ds is
the thesis's 1/2 q_f^T K q_f (Eq. 14) with the same constant K, and the tip rotation
variable gamma_n = phi(L) is the tip's angle exactly (so the joint map theta = G q stays
linear). To second order r = (s - 1/2 int d'^2, d): the ``second_order`` kinematics
(kernels.py, mode 1), which this model equals at small deflections; the two differ from
the fourth order of the deflection in the energy (e.g. the sag's effect on the period).

Mass matrix and velocity terms follow from d'Alembert's principle over the mass points of
the links (the Gauss points of ``LinkBasis.runtime_quadrature``, the end masses M- at the
root and M+ at the tip, the end inertias J-, J+ on alpha and alpha + gamma_n), each with
its exact Jacobian J and convective acceleration dJ/dt v:

    B = sum m J^T J + ...,     c = sum m J^T (dJ/dt v - g)

(the d/dt(B v) - 1/2 d/dq(v^T B v) of the Lagrangian, as in flex_model.spatial.dynamics).
r(s) at each mass point is integrated by Gauss-Legendre on the pieces between the
interval ends (``inner`` points per piece, default 8: exact to degree 15); the model is
the Lagrangian of these discrete positions, so it conserves energy exactly. Cost per
evaluation: one compiled sweep (:func:`terms`, ~20 us for 8 variables), linear in the
mass points and quadratic in the variables; flex_model.simulate integrates it in both
modes (:func:`derivative`; solvers.loop.fixed_step on :class:`ExactModel`, full Newton,
no bristle states); the kernels of kernels.py and integrators.py, and so the Stepper, the
control loop and the replays, do not take it.

Axial extensibility (``axial_vars: m``, m variables per link after the arm's and the
motors' coordinates): the axial strain eps(s) = sum_k u_k P_k(2 s / L - 1) (Legendre
polynomials of degree < m, the Ritz field of a clamped-free rod: u(0) = 0, the tip free)
stretches the centre line, r(s) = int_0^s (1 + eps) [cos phi, sin phi] ds, so eps is the
exact axial strain |r'| - 1 (as in Exudyn's ANCF cable) and the axial energy EA/2 int eps^2
ds is 1/2 u^T K_a u with the constant K_a of :func:`axial_stiffness`; the curvature stays
phi' (per undeformed length: the difference is O(eps kappa)). Closed forms in the tests:
the static stretch F L / EA under a tip force and rho g L^2 / (2 E) hanging under its own
weight (exact from m = 1 and 2), the clamped-free rod's first axial frequency c / (4 L).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .effects.contact import CT_ON
from .integrators import joint_passive_forces, joint_tangent, joint_torques
from .solvers.galpha import galpha_coefficients, galpha_state, restart_choice
from .solvers.loop import implements, residual, tangent
from .kernels import cholesky, solve_spd
from .sections import area_and_inertia

_CACHE = True

#: the one line every path that cannot take the exact kinematics raises
REFUSAL = ("kinematics: exact runs only in flex_model.simulate (its own kernels: "
           "flex_model.exact_kinematics); the model's compiled data P (Stepper, in-loop "
           "control, the model node, diagnosis replay) needs kinematics: second_order "
           "(or small_deflection)")


class ExactKinematicsUnsupported(ValueError):
    """A path or an arm feature the exact kinematics does not support."""


def _link_tables(basis, inner: int, na: int = 0):
    """Mass points of one link and their integration rule.

    Returns (s, mw, C, Wd, Ua): arc lengths of the mass points (the distributed Gauss
    points, then the tip s = L with mass 0: the model adds M+), their masses (kg), the
    matrix C (points x inner nodes) with r(s_k) = C[k] @ (1 + eps) [cos phi, sin phi] at the
    inner nodes, the slopes W' (inner nodes x variables) and the axial strain shapes
    (inner nodes x na, :func:`axial_shapes`) there.
    """
    s_out, mw = basis.runtime_quadrature()
    s_out = np.append(s_out, basis.length)
    mw = np.append(mw, 0.0)
    C, Wd, nodes = _rule(basis, s_out, inner)
    return s_out, mw, C, Wd, axial_shapes(nodes, basis.length, na)


def axial_shapes(s, length: float, na: int) -> np.ndarray:
    """The axial strain shapes P_k(2 s / L - 1), k < na (Legendre), at arc lengths s."""
    s = np.asarray(s, float)
    if na == 0:
        return np.zeros((len(s), 0))
    return np.polynomial.legendre.legvander(2.0 * s / length - 1.0, na - 1)


def axial_stiffness(link, profile, na: int) -> np.ndarray:
    """K_a (na x na, N m) of the axial strain variables: int EA P_j P_k ds over the link
    (Gauss-Legendre per segment, exact for the polynomial sections)."""
    length = profile.length
    K = np.zeros((na, na))
    x, w = np.polynomial.legendre.leggauss(na + 8)
    for k, seg in enumerate(profile.segments):
        if seg.shape == "explicit":
            raise ExactKinematicsUnsupported(
                f"axial_vars: link {link.name} has an explicit section (EI, m): its EA is "
                "unknown; give a material and a section shape")
        a, b = profile.breaks[k], profile.breaks[k + 1]
        z = a + 0.5 * (b - a) * (x + 1.0)
        area = area_and_inertia(seg.shape, seg.dims, (z - a) / seg.length)[0]
        P = axial_shapes(z, length, na)
        K += (P * (seg.E * area * 0.5 * (b - a) * w)[:, None]).T @ P
    return K


def _rule(basis, s_out, inner: int):
    """(C, Wd, nodes): r(s_k) = C[k] @ [cos phi, sin phi] at the inner nodes, W' there, the
    nodes; Gauss-Legendre with ``inner`` points on every piece of [0, s_k] between interval
    ends."""
    cuts = np.unique(np.concatenate([basis.nodes, basis.profile.breaks]))
    xi, wxi = np.polynomial.legendre.leggauss(inner)
    nodes, cols = [], []          # inner nodes; per full piece its column range
    for a, b in zip(cuts[:-1], cuts[1:]):
        cols.append(len(nodes))
        nodes.extend(a + 0.5 * (b - a) * (xi + 1.0))
    weights_full = [0.5 * (b - a) * wxi for a, b in zip(cuts[:-1], cuts[1:])]
    partial = []
    tol = 1e-12 * basis.length
    for k, s in enumerate(s_out):
        j = int(np.searchsorted(cuts, s + tol, side="right")) - 1  # piece containing s
        if j < len(cuts) - 1 and s > cuts[j] + tol:
            partial.append((k, len(nodes), cuts[j], s))
            nodes.extend(cuts[j] + 0.5 * (s - cuts[j]) * (xi + 1.0))
    C = np.zeros((len(s_out), len(nodes)))
    for k, s in enumerate(s_out):
        for j in range(len(cuts) - 1):
            if cuts[j + 1] <= s + tol:
                C[k, cols[j]:cols[j] + inner] = weights_full[j]
    for k, c0, a, s in partial:
        C[k, c0:c0 + inner] = 0.5 * (s - a) * wxi
    Wd = basis.slope_matrix(np.array(nodes))
    return np.ascontiguousarray(C), np.ascontiguousarray(Wd), np.array(nodes)


class ExactKinematics:
    """Equations of motion of a FlexArmModel's arm with exact link kinematics."""

    def __init__(self, model, inner: int = 8):
        arm = model.arm
        for lk in arm.links:
            tim = arm.effect("timoshenko", lk.name)
            if lk.discretization != "wavelet" or (tim is not None and not tim.is_off):
                raise ExactKinematicsUnsupported(
                    f"{arm.source}: kinematics: exact needs Euler-Bernoulli wavelet links "
                    f"(discretization: wavelet, no timoshenko effect); {lk.name} has "
                    f"discretization: {lk.discretization}"
                    + (" and a timoshenko effect" if tim is not None and not tim.is_off
                       else ""))
        if arm.effect("contact_surface") is not None or model.contact[CT_ON] > 0:
            raise ExactKinematicsUnsupported(f"{arm.source}: kinematics: exact does not "
                                             "take a contact_surface effect yet")
        self.model = model
        self.inner = inner
        na = model.axial_vars
        self.tables = [_link_tables(b, inner, na) for b in model.bases]
        nl = model.n_links
        # the tables padded into arrays for the compiled sweep (terms)
        npt = np.array([len(t[0]) for t in self.tables], dtype=np.int64)
        nin = np.array([t[2].shape[1] for t in self.tables], dtype=np.int64)
        nfm = int(model.nf.max())
        self._C = np.zeros((nl, npt.max(), nin.max()))
        self._Wd = np.zeros((nl, nin.max(), nfm))
        self._mw = np.zeros((nl, npt.max()))
        self._Ua = np.zeros((nl, nin.max(), max(na, 1)))
        for i, (s_out, mw, C, Wd, Ua) in enumerate(self.tables):
            self._C[i, :npt[i], :nin[i]] = C
            self._Wd[i, :nin[i], :Wd.shape[1]] = Wd
            self._mw[i, :npt[i]] = mw
            self._Ua[i, :nin[i], :na] = Ua
        self._npt, self._nin = npt, nin
        self._na = np.full(nl, na, dtype=np.int64)
        # the columns a point of link i depends on: the arm's up to its own, the axial
        # variables of links 0..i
        cols = [np.concatenate([np.arange(model.off[i] + model.nf[i] + 1),
                                np.arange(model.axial_off[0], model.axial_off[i] + na)])
                for i in range(nl)]
        self._ncols = np.array([len(c) for c in cols], dtype=np.int64)
        self._cols = np.zeros((nl, self._ncols.max()), dtype=np.int64)
        for i, c in enumerate(cols):
            self._cols[i, :len(c)] = c
        self.m_minus = np.array([lk.M_minus for lk in arm.links])
        self.j_minus = np.array([lk.J_minus for lk in arm.links])
        self.m_plus = np.zeros(nl)
        self.j_plus = np.zeros(nl)

    def set_ends(self, m_plus, j_plus) -> None:
        """Tip masses and inertias of the links (payload included), kg and kg m^2."""
        self.m_plus = np.asarray(m_plus, float).copy()
        self.j_plus = np.asarray(j_plus, float).copy()

    # ------------------------------------------------------------------ the sweep
    def _sweep(self, q, v, gx, gy, need_b=True, need_c=True):
        """Forward sweep over the links: per link, the points' positions, Jacobians and
        convective accelerations; accumulates B and c = sum m J^T (xi - g)."""
        mdl = self.model
        nq = mdl.nq
        B = np.zeros((nq, nq)) if need_b else None
        c = np.zeros(nq) if need_c else None
        ox = oy = 0.0
        Jox = np.zeros(nq)
        Joy = np.zeros(nq)
        xox = xoy = 0.0
        origins = [(0.0, 0.0)]
        tipJ = None
        upot = 0.0
        for i, (s_out, mw, C, Wd, Ua) in enumerate(self.tables):
            o = int(mdl.off[i])
            n = int(mdl.nf[i])
            f = slice(o + 1, o + 1 + n)
            u = slice(int(mdl.axial_off[i]), int(mdl.axial_off[i]) + Ua.shape[1])
            qf, vf = q[f], v[f]
            al, om = q[o], v[o]
            ca, sa = np.cos(al), np.sin(al)
            phi = Wd @ qf
            st, sd = 1.0 + Ua @ q[u], Ua @ v[u]    # stretch 1 + eps and its rate
            cp, sp = np.cos(phi), np.sin(phi)
            rx = C @ (st * cp)
            ry = C @ (st * sp)
            Jlx = C @ (-(st * sp)[:, None] * Wd)   # d r_1 / d q_f
            Jly = C @ ((st * cp)[:, None] * Wd)    # d r_2 / d q_f
            Jux = C @ (cp[:, None] * Ua)           # d r_1 / d u
            Juy = C @ (sp[:, None] * Ua)
            # root mass M- and inertia J-, tip inertia J+ (on alpha and alpha + gamma_n)
            mm = self.m_minus[i]
            g = o + n
            if need_b:
                if mm:
                    B += mm * (np.outer(Jox, Jox) + np.outer(Joy, Joy))
                jp = self.j_plus[i]
                B[o, o] += self.j_minus[i] + jp
                B[o, g] += jp
                B[g, o] += jp
                B[g, g] += jp
            if need_c and mm:
                c += mm * (Jox * (xox - gx) + Joy * (xoy - gy))
            upot -= mm * (gx * ox + gy * oy)
            # points: p = o + R(alpha) r
            npt = len(s_out)
            Jx = np.empty((npt, nq))
            Jy = np.empty((npt, nq))
            Jx[:] = Jox
            Jy[:] = Joy
            Jx[:, o] += -rx * sa - ry * ca
            Jy[:, o] += rx * ca - ry * sa
            Jx[:, f] += Jlx * ca - Jly * sa
            Jy[:, f] += Jlx * sa + Jly * ca
            Jx[:, u] += Jux * ca - Juy * sa
            Jy[:, u] += Jux * sa + Juy * ca
            px = ox + rx * ca - ry * sa
            py = oy + rx * sa + ry * ca
            m = mw.copy()
            m[-1] += self.m_plus[i]
            upot -= np.sum(m * (gx * px + gy * py))
            if need_b:
                B += (Jx * m[:, None]).T @ Jx + (Jy * m[:, None]).T @ Jy
            pd = Wd @ vf
            rdx = Jlx @ vf + Jux @ v[u]
            rdy = Jly @ vf + Juy @ v[u]
            kx = -(C @ (st * cp * pd * pd + 2.0 * sd * sp * pd))
            ky = -(C @ (st * sp * pd * pd - 2.0 * sd * cp * pd))
            lx = -om * om * rx - 2.0 * om * rdy + kx
            ly = -om * om * ry + 2.0 * om * rdx + ky
            xix = xox + lx * ca - ly * sa
            xiy = xoy + lx * sa + ly * ca
            if need_c:
                c += Jx.T @ (m * (xix - gx)) + Jy.T @ (m * (xiy - gy))
            # the tip is the next link's origin
            ox, oy = px[-1], py[-1]
            Jox, Joy = Jx[-1].copy(), Jy[-1].copy()
            xox, xoy = xix[-1], xiy[-1]
            origins.append((ox, oy))
            tipJ = (Jx[-1], Jy[-1])
        return B, c, np.array(origins), np.vstack(tipJ), upot

    # ------------------------------------------------------------------ interface
    @property
    def data(self) -> ExactData:
        """The arrays of the compiled sweep :func:`terms` (end masses as set now)."""
        m = self.model
        return ExactData(m.off, m.nf, self._npt, self._nin, self._C, self._Wd, self._mw,
                         self.m_minus, self.j_minus, self.m_plus, self.j_plus, m.B_const,
                         m.axial_off, self._na, self._Ua, self._cols, self._ncols)

    def mass_and_bias(self, q, v, gx, gy):
        """(B(q), c(q, v)) with gravity (gx, gy) entering c; B includes B_const
        (compiled: :func:`terms`; :meth:`mass_and_bias_numpy` is the same in NumPy)."""
        return terms(np.asarray(q, float), np.asarray(v, float), float(gx), float(gy),
                     self.data)[:2]

    def mass_and_bias_numpy(self, q, v, gx, gy):
        """:meth:`mass_and_bias` by the NumPy sweep (the reference of the compiled one)."""
        B, c, _, _, _ = self._sweep(np.asarray(q, float), np.asarray(v, float), gx, gy)
        return B + self.model.B_const, c

    def mass_matrix(self, q) -> np.ndarray:
        q = np.asarray(q, float)
        B = self._sweep(q, np.zeros_like(q), 0.0, 0.0, need_c=False)[0]
        return B + self.model.B_const

    def inverse_dynamics(self, q, v, a, gx, gy) -> np.ndarray:
        """B a + c(q, v) + dU_g/dq (no elastic, damping or applied forces)."""
        B, c = self.mass_and_bias(q, v, gx, gy)
        return B @ np.asarray(a, float) + c

    def link_origins(self, q) -> np.ndarray:
        """Origins of the links and the arm's tip, (n_links + 1, 2), base frame (m)."""
        q = np.asarray(q, float)
        return self._sweep(q, np.zeros_like(q), 0.0, 0.0, need_b=False, need_c=False)[2]

    def tip_jacobian(self, q) -> np.ndarray:
        """d p_tip / d q (2 x nq), exact."""
        q = np.asarray(q, float)
        return self._sweep(q, np.zeros_like(q), 0.0, 0.0, need_b=False, need_c=False)[3]

    def gravity_potential(self, q, gx, gy) -> float:
        """U_g = -g . sum m p over the mass points (J)."""
        q = np.asarray(q, float)
        return float(self._sweep(q, np.zeros_like(q), gx, gy, need_b=False,
                                 need_c=False)[4])

    def shape(self, q, points_per_link: int = 21) -> list:
        """Deflected centre line of every link at equally spaced arc lengths: list of
        (points, 2) arrays, base frame (m)."""
        q = np.asarray(q, float)
        cache = self.__dict__.setdefault("_shape_rules", {})
        if points_per_link not in cache:
            cache[points_per_link] = [
                _rule(b, np.linspace(0.0, b.length, points_per_link), self.inner)
                for b in self.model.bases]
        org = self.link_origins(q)
        out = []
        na = self.model.axial_vars
        for i, (C, Wd, nodes) in enumerate(cache[points_per_link]):
            o, n = int(self.model.off[i]), int(self.model.nf[i])
            phi = Wd @ q[o + 1:o + 1 + n]
            u0 = int(self.model.axial_off[i])
            st = 1.0 + axial_shapes(nodes, self.model.bases[i].length, na) @ q[u0:u0 + na]
            rx, ry = C @ (st * np.cos(phi)), C @ (st * np.sin(phi))
            ca, sa = np.cos(q[o]), np.sin(q[o])
            out.append(np.column_stack([org[i, 0] + rx * ca - ry * sa,
                                        org[i, 1] + rx * sa + ry * ca]))
        return out

    def tip_deflections(self, q) -> np.ndarray:
        """Tip of every link relative to its root, normal to the root tangent (m): the
        exact r_2(L) = int sin(W' q_f) ds (the variable delta_n is int W' q_f ds)."""
        q = np.asarray(q, float)
        org = self.link_origins(q)
        out = np.empty(self.model.n_links)
        for i in range(self.model.n_links):
            a = q[self.model.off[i]]
            d = org[i + 1] - org[i]
            out[i] = -np.sin(a) * d[0] + np.cos(a) * d[1]
        return out


class ExactData(NamedTuple):
    """The arrays of the compiled sweep :func:`terms` (:meth:`ExactKinematics.data`), per
    link i (padded): its offset and bending variables in q, its mass points and inner
    nodes, the quadrature r_k = sum_j C[i, k, j] t_j of r = int t ds, W' at the nodes
    (Wd), the points' masses (mw), the end masses and inertias, the constant inertia Bc,
    its first axial variable (axo) and count (na), the axial shapes at the nodes (Ua) and
    the columns of q its points depend on (cols[i, :ncols[i]])."""
    off: np.ndarray
    nf: np.ndarray
    npt: np.ndarray
    nin: np.ndarray
    C: np.ndarray
    Wd: np.ndarray
    mw: np.ndarray
    m_minus: np.ndarray
    j_minus: np.ndarray
    m_plus: np.ndarray
    j_plus: np.ndarray
    Bc: np.ndarray
    axo: np.ndarray
    na: np.ndarray
    Ua: np.ndarray
    cols: np.ndarray
    ncols: np.ndarray


@njit(cache=_CACHE)
def _node_values(i, q, v, X, cp, sp, pd, st, sd):
    """At link i's inner nodes j: cos and sin of the tangent angle phi = W' q_f, its rate,
    the stretch 1 + eps (eps = U_a u, the axial shapes) and its rate, into cp, sp, pd, st,
    sd (the tangent t = (1 + eps)(cos phi, sin phi) integrated by ExactKinematics._sweep)."""
    o, n, u0, nu = X.off[i], X.nf[i], X.axo[i], X.na[i]
    Wd, Ua = X.Wd, X.Ua
    for j in range(X.nin[i]):
        ph = 0.0
        pv = 0.0
        for l in range(n):
            ph += Wd[i, j, l] * q[o + 1 + l]
            pv += Wd[i, j, l] * v[o + 1 + l]
        e = 0.0
        ed = 0.0
        for l in range(nu):
            e += Ua[i, j, l] * q[u0 + l]
            ed += Ua[i, j, l] * v[u0 + l]
        cp[j] = np.cos(ph)
        sp[j] = np.sin(ph)
        pd[j] = pv
        st[j] = 1.0 + e
        sd[j] = ed


@njit(cache=_CACHE)
def _point_in_link(i, k, X, cp, sp, pd, st, sd, jlx, jly, jux, juy):
    """Mass point k of link i in the link frame: r = sum_j C_kj t_j (the quadrature of
    r = int t ds), the curvature part (kx, ky) of its acceleration and its Jacobians
    (jlx, jly) on the bending and (jux, juy) on the axial variables. Returns rx, ry, kx,
    ky."""
    n, nu = X.nf[i], X.na[i]
    C, Wd, Ua = X.C, X.Wd, X.Ua
    rx = 0.0
    ry = 0.0
    kx = 0.0
    ky = 0.0
    for l in range(n):
        jlx[l] = 0.0
        jly[l] = 0.0
    for l in range(nu):
        jux[l] = 0.0
        juy[l] = 0.0
    for j in range(X.nin[i]):
        w = C[i, k, j]
        if w == 0.0:
            continue
        wc = w * cp[j]
        ws = w * sp[j]
        tc = st[j] * wc
        ts = st[j] * ws
        rx += tc
        ry += ts
        p2 = pd[j] * pd[j]
        kx -= tc * p2 + 2.0 * sd[j] * ws * pd[j]
        ky -= ts * p2 - 2.0 * sd[j] * wc * pd[j]
        for l in range(n):
            jlx[l] -= ts * Wd[i, j, l]
            jly[l] += tc * Wd[i, j, l]
        for l in range(nu):
            jux[l] += wc * Ua[i, j, l]
            juy[l] += ws * Ua[i, j, l]
    return rx, ry, kx, ky


@njit(cache=_CACHE)
def _point_jacobian(i, v, X, rx, ry, ca, sa, jlx, jly, jux, juy, Jox, Joy, Jx, Jy):
    """The point's base-frame Jacobian J = J_o + the link's rotation of (r, jl, ju) into
    (Jx, Jy) (link i's columns) and its velocity in the link frame (rdx, rdy)."""
    o, n, u0, nu = X.off[i], X.nf[i], X.axo[i], X.na[i]
    ci = X.cols[i]
    rdx = 0.0
    rdy = 0.0
    for l in range(n):
        rdx += jlx[l] * v[o + 1 + l]
        rdy += jly[l] * v[o + 1 + l]
    for l in range(nu):
        rdx += jux[l] * v[u0 + l]
        rdy += juy[l] * v[u0 + l]
    for ia in range(X.ncols[i]):
        a = ci[ia]
        Jx[a] = Jox[a]
        Jy[a] = Joy[a]
    Jx[o] += -rx * sa - ry * ca
    Jy[o] += rx * ca - ry * sa
    for l in range(n):
        Jx[o + 1 + l] += jlx[l] * ca - jly[l] * sa
        Jy[o + 1 + l] += jlx[l] * sa + jly[l] * ca
    for l in range(nu):
        Jx[u0 + l] += jux[l] * ca - juy[l] * sa
        Jy[u0 + l] += jux[l] * sa + juy[l] * ca
    return rdx, rdy


@njit(cache=_CACHE)
def _link_root(i, gx, gy, X, B, c, Jox, Joy, xox, xoy):
    """Link i's root: the end mass M- at its origin (Jacobian Jo, acceleration xo) into B
    and c, and the joint inertias J-, J+ (thesis Eq. 8) into B."""
    o, g = X.off[i], X.off[i] + X.nf[i]
    ci = X.cols[i]
    mm = X.m_minus[i]
    if mm != 0.0:
        for ia in range(X.ncols[i]):
            a = ci[ia]
            c[a] += mm * (Jox[a] * (xox - gx) + Joy[a] * (xoy - gy))
            for ib in range(X.ncols[i]):
                b = ci[ib]
                B[a, b] += mm * (Jox[a] * Jox[b] + Joy[a] * Joy[b])
    B[o, o] += X.j_minus[i] + X.j_plus[i]
    B[o, g] += X.j_plus[i]
    B[g, o] += X.j_plus[i]
    B[g, g] += X.j_plus[i]


@njit(cache=_CACHE)
def _add_point_mass(m, fx, fy, ci, nc, Jx, Jy, B, c):
    """c += J^T f and B += m J^T J of a point mass m with inertial force (fx, fy) =
    m (p'' - g) on the columns ci[:nc]."""
    for ia in range(nc):
        a = ci[ia]
        c[a] += Jx[a] * fx + Jy[a] * fy
        ma = m * Jx[a]
        mb = m * Jy[a]
        for ib in range(nc):
            b = ci[ib]
            B[a, b] += ma * Jx[b] + mb * Jy[b]


@njit(cache=_CACHE)
def terms(q, v, gx, gy, X):
    """(B(q), c(q, v), J_tip) of the exact kinematics, compiled: the sweep of
    ExactKinematics._sweep over the links' mass points, X = ExactKinematics.data; J_tip
    (2 x nq) is the Jacobian of the arm's end. A point's acceleration is the origin's
    plus the link's rotation of l = -om^2 r - 2 om k x r' + (kx, ky)."""
    nq = q.shape[0]
    B = X.Bc.copy()
    c = np.zeros(nq)
    Jox = np.zeros(nq)
    Joy = np.zeros(nq)
    xox = 0.0
    xoy = 0.0
    Jx = np.zeros(nq)
    Jy = np.zeros(nq)
    jlx = np.zeros(X.Wd.shape[2])
    jly = np.zeros(X.Wd.shape[2])
    jux = np.zeros(X.Ua.shape[2])
    juy = np.zeros(X.Ua.shape[2])
    cp = np.zeros(X.Wd.shape[1])
    sp = np.zeros(X.Wd.shape[1])
    pd = np.zeros(X.Wd.shape[1])
    st = np.zeros(X.Wd.shape[1])
    sd = np.zeros(X.Wd.shape[1])
    for i in range(X.off.shape[0]):
        o = X.off[i]
        ca = np.cos(q[o])
        sa = np.sin(q[o])
        om = v[o]
        _node_values(i, q, v, X, cp, sp, pd, st, sd)
        _link_root(i, gx, gy, X, B, c, Jox, Joy, xox, xoy)
        for k in range(X.npt[i]):
            rx, ry, kx, ky = _point_in_link(i, k, X, cp, sp, pd, st, sd, jlx, jly, jux, juy)
            rdx, rdy = _point_jacobian(i, v, X, rx, ry, ca, sa, jlx, jly, jux, juy, Jox,
                                       Joy, Jx, Jy)
            lx = -om * om * rx - 2.0 * om * rdy + kx
            ly = -om * om * ry + 2.0 * om * rdx + ky
            xix = xox + lx * ca - ly * sa
            xiy = xoy + lx * sa + ly * ca
            tip = k == X.npt[i] - 1
            m = X.mw[i, k] + (X.m_plus[i] if tip else 0.0)
            if m != 0.0:
                _add_point_mass(m, m * (xix - gx), m * (xiy - gy), X.cols[i], X.ncols[i], Jx,
                                Jy, B, c)
            if tip:
                for ia in range(X.ncols[i]):
                    a = X.cols[i][ia]
                    Jox[a] = Jx[a]
                    Joy[a] = Jy[a]
                xox = xix
                xoy = xiy
    Jt = np.zeros((2, nq))
    Jt[0] = Jox
    Jt[1] = Joy
    return B, c, Jt


@njit(cache=_CACHE)
def balance(t, q, v, X, E):
    """B(q) and Q - c(q, v) with exact kinematics: the forces of
    integrators.applied_force (joint torques and effects, K q, D v, tip pulses; no
    contact, no stick-slip: refused) with the exact tip Jacobian. E: inputs.input_data."""
    B, c, Jt = terms(q, v, E.gx, E.gy, X)
    K, D, pt0, pt1, pF, pC = E.K, E.D, E.pulse_t0, E.pulse_t1, E.pulse_force, E.pulse_torque
    Ga = E.Ga
    Q = Ga.T @ joint_torques(t, q, v, E) - K @ q - D @ v + joint_passive_forces(q, v, E) - c
    fx = 0.0
    fy = 0.0
    cm = 0.0
    for p in range(pt0.shape[0]):
        if pt0[p] <= t < pt1[p]:
            fx += pF[p, 0]
            fy += pF[p, 1]
            cm += pC[p]
    if fx != 0.0 or fy != 0.0:
        Q += Jt[0] * fx + Jt[1] * fy
    if cm != 0.0:
        off, nf = X.off, X.nf
        last = off.shape[0] - 1
        Q[off[last]] += cm
        Q[off[last] + nf[last]] += cm
    return B, Q


@njit(cache=_CACHE)
def derivative(t, x, X, E):
    """dx/dt = [v; B(q)^-1 (Q - c)] for x = [q; v] with exact kinematics."""
    n = E.K.shape[0]
    B, rhs = balance(t, x[:n], x[n:2 * n], X, E)
    out = np.empty(2 * n)
    out[:n] = x[n:2 * n]
    out[n:] = solve_spd(B, rhs)
    return out


@njit(cache=_CACHE)
def iteration_matrix(x, h, rho_inf, X, E):
    """(S, G): the fixed step's iteration matrix S = B + gamma' (D + C_j) + beta' (K + K_j)
    at state x and its damping part G = gamma' (D + C_j) (Arnold-Bruls form)."""
    n = E.K.shape[0]
    B = terms(x[:n], x[n:2 * n], 0.0, 0.0, X)[0]
    c = galpha_coefficients(rho_inf, h)
    Kj, Cj = joint_tangent(x[n:2 * n], E)
    G = c.gp * (E.D + Cj)
    return B + G + c.bp * (E.K + Kj), G


@njit(cache=_CACHE)
def restart_acceleration(t, x, a, h, rho_inf, X, E):
    """(a1, filtered): the start acceleration (a = abar = a1) of the fixed step after a
    jump of the applied forces with exact kinematics, a the step's before it:
    solvers.galpha.restart_choice between the consistent B^-1 (Q - c) and the part
    a + S^-1 B dA of the jump the step follows (filtered True), S = iteration_matrix.
    Filtered wherever the step misses most of the jump (share > RESTART_SHARE), whatever
    the overshoot: with the position of the damper-held root modes completed
    (simulate._exact_jump_step) the filtered restart is the closer at every step; the
    consistent one converges (as h^2) to the same limit but with a constant ~ kd / J_root
    (issue 47, hub-less arm, 16 variables, 0.3 s: 0.110 / 0.028 mm at the end of link 2
    at 1/32 / 1/64 ms, filtered 0.006 / 0.003 mm; bench_hubless_floor --own-convergence)."""
    n = E.K.shape[0]
    B, rhs = balance(t, x[:n], x[n:2 * n], X, E)
    ac = solve_spd(B, rhs)
    S = iteration_matrix(x, h, rho_inf, X, E)[0]
    a1 = restart_choice(a, ac, B, S, h, rho_inf, 0.0)[0]
    return a1, not np.array_equal(a1, ac)


class ExactModel(NamedTuple):
    """The exact kinematics' compiled data for solvers.loop: X (:meth:`ExactKinematics.data`)
    and E (inputs.input_data)."""
    X: ExactData
    E: tuple


@njit(cache=_CACHE)
def _residual(md, a1, st, c, first):
    """Residual B(q1) a1 - (Q - c) of a generalized-alpha step (solvers.galpha.Step st,
    coefficients c; ``first`` unused) with :func:`balance`, and (B, v1, no bristle states)."""
    q1, v1, _ = galpha_state(st.q, st.v, st.a, st.abar, a1, c)
    B, rhs = balance(st.t, q1, v1, md.X, md.E)
    return B @ a1 - rhs, (B, v1, st.z)


@njit(cache=_CACHE)
def _tangent(md, ctx, st, c):
    """Cholesky factor of B(q1) + gamma' (D + C_joints) + beta' (K + K_joints)."""
    B, v1 = ctx[0], ctx[1]
    Kj, Cj = joint_tangent(v1, md.E)
    return cholesky(B + c.gp * (md.E.D + Cj) + c.bp * (md.E.K + Kj))


implements(residual, ExactModel, _residual)
implements(tangent, ExactModel, _tangent)


# numba re-compiles a cached function when its own file changes, not when a compiled
# function it calls (integrators.py, kernels.py and theirs) does: flush these caches then
def _guard_caches():
    from . import integrators, iteration_matrix, kernels
    from .effects import friction, stick_slip
    from .numba_cache import guard
    from .solvers import galpha, loop, newton
    guard([obj for obj in globals().values() if hasattr(obj, "py_func")
           and obj.py_func.__module__ == __name__],
          [integrators.__file__, kernels.__file__, stick_slip.__file__, friction.__file__,
           iteration_matrix.__file__, galpha.__file__, newton.__file__, loop.__file__])


_guard_caches()
