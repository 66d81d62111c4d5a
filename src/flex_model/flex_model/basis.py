"""Wavelet deformation functions of a link and the link matrices they give (thesis Ch. II).

The link ``[0, L]`` is partitioned into ``n`` intervals. On each interval the wavelet
functions ``w_delta_k``, ``w_gamma_k`` are the exact solutions of the static beam equation
``(EI w'')'' = 0`` (thesis Eq. 3) with unit displacement or unit rotation at one end of
the interval and zero at the other: for constant EI they are cubic Hermite polynomials,
for variable EI they are built from the moments ``G_p(s) = int_0^s t^p / EI dt``:

    w(s) = c0 + c1 s + c2 F1(s) + c3 F2(s),   F1 = s G0 - G1,   F2 = s G1 - G2,
    w''(s) = (c2 + c3 s) / EI(s).

For a Timoshenko link (thesis Eq. 4) the section rotation psi = c1 + c2 G0 + c3 G1 is the
nodal variable and the shear force V = -c3 adds w' = psi - c3 chi/GA, so F2 gains
-H(s) = -int_0^s chi/GA dt and K the shear energy c3^2 H(h).

The root of the link is clamped to its rigid frame (d(0) = d'(0) = 0: alpha is the root
tangent), so the deformation variables are ``q_f = [delta_1, gamma_1, ..., delta_n,
gamma_n]`` (thesis Eq. 12): deflection and rotation at the interval end points.

From them the link's constant matrices are integrated once (thesis Remark 4):
``B_f`` (Eq. 9), ``h`` (Eq. 10), ``k`` (Eq. 11), ``K`` (Eqs. 13-14), the internal
friction matrix (Eqs. 35-36) and the rigid-body integrals of Eq. (8).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .sections import SectionProfile

_GAUSS_N = 12
_XI, _WXI = np.polynomial.legendre.leggauss(_GAUSS_N)
_SUBDIVISIONS = 8


def _gauss(a, b):
    """Gauss nodes and weights on [a, b] (a, b broadcastable arrays, nodes on last axis)."""
    a = np.asarray(a, dtype=float)[..., None]
    b = np.asarray(b, dtype=float)[..., None]
    half = 0.5 * (b - a)
    return a + half * (_XI + 1.0), half * _WXI


class _Element:
    """One interval [a, b] of a link: quadrature grid and the moments of 1/EI.

    With ``shear`` (Timoshenko, thesis Eq. 4) the shear compliance chi/GA of the profile (or
    1/``shear_stiffness`` when given) enters the static solution as a fourth moment
    H(s) = int_0^s chi/GA dt.
    """

    def __init__(self, profile: SectionProfile, a: float, b: float, shear: bool = False,
                 shear_stiffness: float | None = None):
        self.profile, self.a, self.b = profile, a, b
        self.shear, self.shear_stiffness = shear, shear_stiffness
        self.h = b - a
        # smooth pieces of [a, b], each cut into equal sub-intervals
        cuts = [a] + [z for z in profile.breaks[1:-1] if a < z < b] + [b]
        sub = []
        for c0, c1 in zip(cuts[:-1], cuts[1:]):
            k = self._piece(0.5 * (c0 + c1))
            edges = np.linspace(c0, c1, _SUBDIVISIONS + 1)
            sub += [(e0, e1, k) for e0, e1 in zip(edges[:-1], edges[1:])]
        self.sub = sub
        self.sub_lo = np.array([s[0] for s in sub])
        self.sub_hi = np.array([s[1] for s in sub])
        # full integrals of s^p / EI over each sub-interval, cumulated
        full = np.array([self._moments_on(e0, e1, k) for e0, e1, k in sub])  # (nsub, 4)
        self.cum = np.vstack([np.zeros(4), np.cumsum(full, axis=0)])
        # quadrature grid for the element integrals
        zq, wq, props = [], [], []
        for e0, e1, k in sub:
            z, w = _gauss(e0, e1)
            ei, m, ga = profile.property_on_piece(k, z)
            zq.append(z)
            wq.append(w)
            props.append((ei, m, ga))
        self.zq = np.concatenate(zq)
        self.wq = np.concatenate(wq)
        self.ei_q = np.concatenate([p[0] for p in props])
        self.m_q = np.concatenate([p[1] for p in props])
        self.ga_q = np.concatenate([p[2] for p in props])
        self.mu = self.cum[-1]  # moments over the whole element: G_p(h)

    def _piece(self, z):
        return int(np.clip(np.searchsorted(self.profile.breaks, z, side="right") - 1, 0,
                           len(self.profile.segments) - 1))

    def _compliance(self, ei, ga):
        if not self.shear:
            return np.zeros_like(ei)
        if self.shear_stiffness is not None:
            return np.full_like(ei, 1.0 / self.shear_stiffness)
        return 1.0 / ga

    def _moments_on(self, z0, z1, k):
        """int_{z0}^{z1} (z - a)^p / EI(z) dz for p = 0, 1, 2 and int chi/GA dz."""
        z, w = _gauss(z0, z1)
        ei, _, ga = self.profile.property_on_piece(k, z)
        s = z - self.a
        return np.array([np.sum(w / ei), np.sum(w * s / ei), np.sum(w * s * s / ei),
                         np.sum(w * self._compliance(ei, ga))])

    def moments(self, z):
        """G_p(z - a), p = 0, 1, 2, and H(z - a) at points z in [a, b]: (len(z), 4)."""
        z = np.clip(np.atleast_1d(np.asarray(z, dtype=float)), self.a, self.b)
        j = np.clip(np.searchsorted(self.sub_hi, z, side="left"), 0, len(self.sub) - 1)
        out = self.cum[j].copy()
        lo = self.sub_lo[j]
        nodes, weights = _gauss(lo, z)  # (len(z), ng)
        for i in range(len(z)):
            k = self.sub[j[i]][2]
            ei, _, ga = self.profile.property_on_piece(k, nodes[i])
            s = nodes[i] - self.a
            out[i] += [np.sum(weights[i] / ei), np.sum(weights[i] * s / ei),
                       np.sum(weights[i] * s * s / ei),
                       np.sum(weights[i] * self._compliance(ei, ga))]
        return out

    def coefficients(self):
        """c (4 x 4): column j gives c0..c3 of the shape function with unit end value j.

        End values ordered (w(a), psi(a), w(b), psi(b)), psi the rotation of the section
        (= w' without shear).
        """
        g0, g1, g2, hh = self.mu
        h = self.h
        f1, f2 = h * g0 - g1, h * g1 - g2 - hh
        mat = np.array([[f1, f2], [g0, g1]])
        c = np.zeros((4, 4))
        for j in range(4):
            e = np.zeros(4)
            e[j] = 1.0
            c[0, j], c[1, j] = e[0], e[1]
            rhs = np.array([e[2] - e[0] - e[1] * h, e[3] - e[1]])
            c[2:, j] = np.linalg.solve(mat, rhs)
        return c

    def shape(self, z, c, rotation: bool = False):
        """Values and slopes w' of the 4 shape functions at points z: (len(z), 4) each; with
        ``rotation`` the section rotations psi = w' + c3 chi/GA instead of the slopes."""
        z = np.atleast_1d(np.asarray(z, dtype=float))
        g = self.moments(z)
        s = z - self.a
        f1 = s * g[:, 0] - g[:, 1]
        f2 = s * g[:, 1] - g[:, 2] - g[:, 3]
        basis = np.stack([np.ones_like(s), s, f1, f2], axis=1)
        dbasis = np.stack([np.zeros_like(s), np.ones_like(s), g[:, 0], g[:, 1]], axis=1)
        if not rotation and self.shear:  # w' = psi + V chi/GA, shear force V = -c3
            ei, _, ga = self.profile.properties(z)
            dbasis[:, 3] -= self._compliance(ei, ga)
        return basis @ c, dbasis @ c


@dataclass(frozen=True)
class LinkBasis:
    """Integrated quantities of one link for its wavelet basis (distributed part only).

    The rigid end masses are added by the model (they may change at run time).
    Attributes are SI: ``mass`` = int m dz (kg), ``first_moment`` = int z m dz (kg m),
    ``second_moment`` = int z^2 m dz (kg m^2); ``Bw`` = int w w^T m dz (Eq. 9),
    ``h`` = int w m dz (Eq. 10), ``k`` = int z w m dz (Eq. 11), ``K`` = int w'' w''^T EI dz
    (Eq. 14), ``S1`` = int w' w'^T dz (internal friction, Eqs. 35-36).
    """

    length: float
    nodes: np.ndarray
    mass: float
    first_moment: float
    second_moment: float
    Bw: np.ndarray
    h: np.ndarray
    k: np.ndarray
    K: np.ndarray
    S1: np.ndarray
    elements: tuple
    coeffs: tuple
    rot_inertia: float = 0.0          # int rho I dz (kg m), Timoshenko rotary inertia
    rot_coupling: np.ndarray = None   # int rho I psi dz
    rot_matrix: np.ndarray = None     # int rho I psi psi^T dz

    @property
    def n_vars(self) -> int:
        return self.Bw.shape[0]

    @property
    def profile(self) -> SectionProfile:
        return self.elements[0].profile

    def shape_matrix(self, z) -> np.ndarray:
        """W (len(z), n_vars): deflection d(z) = W q_f at points z along the link."""
        return self._sample(z)[0]

    def slope_matrix(self, z) -> np.ndarray:
        """W' (len(z), n_vars): slope d'(z) = W' q_f."""
        return self._sample(z)[1]

    def curvature_matrix(self, z) -> np.ndarray:
        """W'' (len(z), n_vars): curvature d''(z) = W'' q_f = M(z) / EI(z) (exact for the
        wavelets: (c2 + c3 s) / EI on each interval)."""
        def curvature(el, c, zs):
            ei = el.profile.properties(zs)[0]
            return ((c[2][None, :] + (zs - el.a)[:, None] * c[3][None, :]) / ei[:, None],)
        return self._per_element(z, curvature)[0]

    def shortening_matrix(self, z) -> np.ndarray:
        """S(z) = int_0^z w' w'^T ds (len(z), n, n): axial shortening u(z) = 1/2 q_f^T S q_f.

        Second-order (foreshortening) kinematics of a bent inextensible link: the point
        at arc length z lies at z - u(z) along the root tangent.
        """
        z = np.atleast_1d(np.asarray(z, dtype=float))
        n = self.n_vars
        out = np.zeros((len(z), n, n))
        cuts = np.unique(np.concatenate([self.nodes, self.profile.breaks]))
        for m, zz in enumerate(z):
            edges = np.concatenate([cuts[cuts < zz], [zz]])
            for a, b in zip(edges[:-1], edges[1:]):
                pts, w = _gauss(a, b)
                d = self.slope_matrix(pts)
                out[m] += (d * w[:, None]).T @ d
        return out

    def runtime_quadrature(self, points_per_piece: int = 6):
        """Gauss points z (m), weights times m(z) (kg) over the link, split at the interval
        ends and the section breaks. Six points are exact to degree 11: the mass-matrix
        integrand of Hermite wavelets with the shortening (S S, degree 10) times a linearly
        varying mass per length."""
        xi, wxi = np.polynomial.legendre.leggauss(points_per_piece)
        cuts = np.unique(np.concatenate([self.nodes, self.profile.breaks]))
        z, mw = [], []
        profile = self.profile
        for a, b in zip(cuts[:-1], cuts[1:]):
            zz = a + 0.5 * (b - a) * (xi + 1.0)
            k = int(np.clip(np.searchsorted(profile.breaks, 0.5 * (a + b), side="right") - 1,
                            0, len(profile.segments) - 1))
            m = profile.property_on_piece(k, zz)[1]
            z.append(zz)
            mw.append(0.5 * (b - a) * wxi * m)
        return np.concatenate(z), np.concatenate(mw)

    def _sample(self, z):
        return self._per_element(z, lambda el, c, zs: el.shape(zs, c))

    def _per_element(self, z, evaluate):
        """Assemble per-element arrays (len(z), 4) returned by ``evaluate(el, c, z_in_el)``
        into (len(z), n_vars) arrays of the link's variables."""
        z = np.atleast_1d(np.asarray(z, dtype=float))
        e_idx = np.clip(np.searchsorted(self.nodes, z, side="right") - 1, 0,
                        len(self.elements) - 1)
        out = None
        for e, (el, c) in enumerate(zip(self.elements, self.coeffs)):
            sel = e_idx == e
            if not np.any(sel):
                continue
            parts = evaluate(el, c, z[sel])
            if out is None:
                out = [np.zeros((len(z), self.n_vars)) for _ in parts]
            cols, keep = _element_dofs(e)
            for o, part in zip(out, parts):
                o[np.ix_(sel, cols)] = part[:, keep]
        return out if out is not None else [np.zeros((len(z), self.n_vars))] * 2


def _element_dofs(e: int):
    """Global q_f indices of element e's end values and which of its 4 locals they are.

    Node 0 (the link root) is clamped, so element 0 has only its right-end variables.
    """
    if e == 0:
        return [0, 1], [2, 3]
    base = 2 * (e - 1)
    return [base, base + 1, base + 2, base + 3], [0, 1, 2, 3]


def link_basis(profile: SectionProfile, n_intervals: int, nodes=None, shear: bool = False,
               shear_stiffness: float | None = None, rho_over_e: float = 0.0) -> LinkBasis:
    """Build the wavelet basis of a link with ``n_intervals`` intervals (2 n variables).

    ``nodes`` optionally gives the partition points (0 = z_0 < ... < z_n = L); by default
    the partition is uniform (thesis Eq. 5). ``shear`` builds the Timoshenko wavelets
    (static solutions of thesis Eq. 4, shear energy of Remark 3 in K, rotary inertia
    rho I = (rho/E) EI in rot_*); the deformation variables are then the deflection and
    the section rotation at the interval ends.
    """
    length = profile.length
    if nodes is None:
        nodes = np.linspace(0.0, length, n_intervals + 1)
    nodes = np.asarray(nodes, dtype=float)
    n = 2 * n_intervals
    Bw = np.zeros((n, n))
    K = np.zeros((n, n))
    S1 = np.zeros((n, n))
    h = np.zeros(n)
    k = np.zeros(n)
    mass = first = second = 0.0
    elements, coeffs = [], []
    r_in = 0.0
    r_c = np.zeros(n)
    r_m = np.zeros((n, n))
    for e in range(n_intervals):
        el = _Element(profile, nodes[e], nodes[e + 1], shear, shear_stiffness)
        c = el.coefficients()
        zq, wq, mq = el.zq, el.wq, el.m_q
        vals, slopes = el.shape(zq, c)
        cols, keep = _element_dofs(e)
        v = vals[:, keep]
        s = slopes[:, keep]
        ix = np.ix_(cols, cols)
        Bw[ix] += (v * (wq * mq)[:, None]).T @ v
        S1[ix] += (s * wq[:, None]).T @ s
        h[cols] += (wq * mq) @ v
        k[cols] += (wq * mq * zq) @ v
        # stiffness from the moments of 1/EI: EI psi' = c2 + c3 s; shear force V = c3
        g0, g1, g2, hh = el.mu
        c2, c3 = c[2, keep], c[3, keep]
        K[ix] += (np.outer(c2, c2) * g0 + (np.outer(c2, c3) + np.outer(c3, c2)) * g1
                  + np.outer(c3, c3) * (g2 + hh))
        if shear and rho_over_e > 0:
            rho_i = rho_over_e * el.ei_q * wq
            psi = el.shape(zq, c, rotation=True)[1][:, keep]
            r_in += np.sum(rho_i)
            r_c[cols] += rho_i @ psi
            r_m[ix] += (psi * rho_i[:, None]).T @ psi
        mass += np.sum(wq * mq)
        first += np.sum(wq * mq * zq)
        second += np.sum(wq * mq * zq * zq)
        elements.append(el)
        coeffs.append(c)
    sym = lambda a: 0.5 * (a + a.T)  # noqa: E731
    return LinkBasis(length=length, nodes=nodes, mass=mass, first_moment=first,
                     second_moment=second, Bw=sym(Bw), h=h, k=k, K=sym(K), S1=sym(S1),
                     elements=tuple(elements), coeffs=tuple(coeffs), rot_inertia=r_in,
                     rot_coupling=r_c, rot_matrix=sym(r_m))
