"""Other discretizations of a flexible link behind the wavelet basis's interface.

Each link basis gives the constant link matrices of thesis Eqs. (8)-(14) (B_f, h, k, K,
the friction matrix S1 and the rigid integrals) for deformation functions ``w(z)``, so
the compiled equations of motion (kernels.py) are reused unchanged:

- ``assumed_modes``: the classic modes of thesis Eqs. (55)-(64), seed 000 Eqs. (7)-(8)
  (flex_model.mode_shapes: clamped_free, hinged_free, clamped_mass);
- ``optimized_modes``: the same modes in the basis of thesis Ch. III.6 Eqs. (80)-(84),
  the last two modal variables replaced by the tip deflection and rotation;
- ``ritz_polynomials``: z^2 .. z^(n+1) (thesis Eqs. 49-52);
- ``fem``: cubic Hermite elements (seed 002 Eqs. 1-10), nodal deflections and rotations,
  integrated with the real EI(z) and m(z).

The kernels need the tip deflection and rotation of every link as coordinates (the
interconnection of thesis Eqs. 20-22), or, for a one-variable link (the lumped link of
seed 000), the tip deflection as its variable and the tip rotation proportional to it
(``tip_rotation_scale``). A basis without them is used in the form of
thesis Eq. (84): ``q_hat = T q_f`` (Eq. 82), ``w_hat = w T^-1``. This is an exact change
of variables of the same function space (thesis Remark 15), so frequencies, statics and
responses are those of the classic assumed-mode model; ``raw_*`` keep the matrices in
the original variables (the condition numbers of thesis Table VI and Remark 8), and
``original_coordinates`` maps q_hat back to them. ``assumed_modes`` and
``optimized_modes`` therefore give the same model here; they differ in the thesis only in
the cost of a symbolic evaluation (Tables XII-XV).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from .basis import LinkBasis
from .mode_shapes import mode_shapes
from .sections import SectionProfile

_XI, _WXI = np.polynomial.legendre.leggauss(12)


@dataclass(frozen=True)
class FunctionBasis(LinkBasis):
    """Link basis of arbitrary deformation functions (values, slopes, curvatures).

    ``functions(z)`` returns the raw functions w, w', w'' (len(z), n); ``tip_transform``
    is T of thesis Eq. (82) (identity when the last two variables are already the tip
    deflection and rotation); the public matrices are in the variables q_hat = T q_f.
    """

    section: SectionProfile = None
    functions: Callable = None
    tip_transform: np.ndarray = None
    raw_Bw: np.ndarray = None
    raw_K: np.ndarray = None
    kind: str = ""
    details: dict = field(default_factory=dict)
    tip_rotation_scale: float = 1.0   # tip rotation per tip deflection of a 1-variable link

    @property
    def profile(self) -> SectionProfile:
        return self.section

    def _evaluate(self, z):
        z = np.atleast_1d(np.asarray(z, float))
        t_inv = np.linalg.inv(self.tip_transform)
        return [f @ t_inv for f in self.functions(z)]

    def _sample(self, z):
        return self._evaluate(z)[:2]

    def curvature_matrix(self, z) -> np.ndarray:
        return self._evaluate(z)[2]


def quadrature(profile: SectionProfile, cuts):
    """Gauss points z, weights and EI(z), m(z) on [0, L] split at ``cuts`` and the breaks."""
    cuts = np.unique(np.concatenate([np.asarray(cuts, float), profile.breaks]))
    z, w = [], []
    for a, b in zip(cuts[:-1], cuts[1:]):
        z.append(a + 0.5 * (b - a) * (_XI + 1.0))
        w.append(0.5 * (b - a) * _WXI)
    z, w = np.concatenate(z), np.concatenate(w)
    mid = np.repeat(0.5 * (cuts[:-1] + cuts[1:]), len(_XI))
    k = np.clip(np.searchsorted(profile.breaks, mid, side="right") - 1, 0,
                len(profile.segments) - 1)
    ei, m = np.zeros_like(z), np.zeros_like(z)
    for piece in np.unique(k):
        sel = k == piece
        props = profile.property_on_piece(int(piece), z[sel])
        ei[sel], m[sel] = props[0], props[1]
    return cuts, z, w, ei, m


def tip_transform(functions, length: float) -> np.ndarray:
    """T of thesis Eq. (82): identity rows for eta_1..eta_{n-2}, then w(L) and w'(L)."""
    w, dw, _ = functions(np.array([float(length)]))
    n = w.shape[1]
    t = np.eye(n)
    t[-2], t[-1] = w[0], dw[0]
    return t


def function_basis(profile: SectionProfile, functions, cuts, *, kind: str,
                   tip_form: bool = True, details: dict | None = None,
                   tip_rotation_scale: float = 1.0) -> FunctionBasis:
    """Integrate the link matrices of thesis Eqs. (8)-(14) for ``functions`` (raw
    variables) and express them in the tip form of thesis Eq. (84) if ``tip_form``."""
    cuts, z, w, ei, m = quadrature(profile, cuts)
    W, dW, ddW = functions(z)
    wm = w * m
    raw = {"Bw": (W * wm[:, None]).T @ W, "K": (ddW * (w * ei)[:, None]).T @ ddW,
           "S1": (dW * w[:, None]).T @ dW, "h": wm @ W, "k": (wm * z) @ W}
    rigid = (float(np.sum(wm)), float(np.sum(wm * z)), float(np.sum(wm * z * z)))
    return basis_from_matrices(profile, functions, cuts, raw, rigid, kind=kind,
                               tip_form=tip_form, details=details,
                               tip_rotation_scale=tip_rotation_scale)


def basis_from_matrices(profile: SectionProfile, functions, cuts, raw: dict, rigid,
                        *, kind: str, tip_form: bool = True, details: dict | None = None,
                        tip_rotation_scale: float = 1.0) -> FunctionBasis:
    """A FunctionBasis from its link matrices in the raw variables (``raw``: Bw, K, S1,
    h, k) and the rigid integrals (mass, first and second moment), in tip form (Eq. 84)
    if ``tip_form``; a one-variable link (its variable the tip deflection) gives its tip
    rotation per tip deflection as ``tip_rotation_scale``."""
    n = raw["Bw"].shape[0]
    t = tip_transform(functions, profile.length) if tip_form else np.eye(n)
    t_inv = np.linalg.inv(t)
    sym = lambda a: 0.5 * (a + a.T)  # noqa: E731
    cong = lambda a: sym(t_inv.T @ a @ t_inv)  # noqa: E731
    return FunctionBasis(
        length=profile.length, nodes=np.asarray(cuts, float), mass=rigid[0],
        first_moment=rigid[1], second_moment=rigid[2], Bw=cong(raw["Bw"]),
        h=raw["h"] @ t_inv, k=raw["k"] @ t_inv, K=cong(raw["K"]), S1=cong(raw["S1"]),
        elements=(), coeffs=(), section=profile, functions=functions, tip_transform=t,
        raw_Bw=sym(raw["Bw"]), raw_K=sym(raw["K"]), kind=kind, details=details or {},
        tip_rotation_scale=tip_rotation_scale)


def assumed_modes_basis(profile: SectionProfile, count: int, mode_type: str = "clamped_free",
                        tip_mass: float = 0.0, tip_inertia: float = 0.0,
                        kind: str = "assumed_modes") -> FunctionBasis:
    """``count`` modes of the uniform link of the same length and mean mass per length
    (thesis Eqs. 55-56; for a variable section the shapes are those of the mean link and
    the integrals use the real EI(z), m(z)). One mode is scaled to a unit tip deflection,
    its variable (the limit of seed 000's lumped link for many masses, flex_model.lumped)."""
    length = profile.length
    shapes = link_modes(profile, count, mode_type, tip_mass, tip_inertia)
    cuts = np.linspace(0.0, length, max(8, count) + 1)
    details = {"mode_type": mode_type, "beta_L": shapes.roots}
    if count > 1:
        return function_basis(profile, shapes.evaluate, cuts, kind=kind, details=details)
    f_tip, df_tip = (a[0, 0] for a in shapes.evaluate(np.array([length]))[:2])

    def functions(z):
        return tuple(a / f_tip for a in shapes.evaluate(z))
    return function_basis(profile, functions, cuts, kind=kind, tip_form=False,
                          details=details, tip_rotation_scale=float(df_tip / f_tip))


def link_modes(profile: SectionProfile, count: int, mode_type: str, tip_mass: float = 0.0,
               tip_inertia: float = 0.0):
    """Mode shapes of the uniform link with the link's length and mean mass per length."""
    q = quadrature(profile, [0.0, profile.length])
    m_mean = float(np.sum(q[2] * q[4])) / profile.length
    return mode_shapes(profile.length, count, mode_type, mass_per_length=m_mean,
                       tip_mass=tip_mass, tip_inertia=tip_inertia)


def ritz_basis(profile: SectionProfile, count: int) -> FunctionBasis:
    """Ritz-Kantorovich polynomials z^2 .. z^(count+1) in metres (thesis Eqs. 49-52)."""
    powers = np.arange(2, count + 2, dtype=float)

    def functions(z):
        zz = z[:, None]
        return (zz ** powers, powers * zz ** (powers - 1),
                powers * (powers - 1) * zz ** (powers - 2))
    return function_basis(profile, functions, np.linspace(0.0, profile.length, 9),
                          kind="ritz_polynomials")


def fem_basis(profile: SectionProfile, n_elements: int) -> FunctionBasis:
    """Cubic Hermite beam elements (seed 002 Eqs. 1-10) on a uniform mesh; variables are
    the nodal deflection and rotation of nodes 1..n (node 0 is the clamped root)."""
    nodes = np.linspace(0.0, profile.length, n_elements + 1)
    h = nodes[1] - nodes[0]

    def functions(z):
        e = np.clip(np.searchsorted(nodes, z, side="right") - 1, 0, n_elements - 1)
        s = (z - nodes[e]) / h
        local = [np.stack([1 - 3 * s**2 + 2 * s**3, h * (s - 2 * s**2 + s**3),
                           3 * s**2 - 2 * s**3, h * (-s**2 + s**3)], axis=1),
                 np.stack([-6 * s + 6 * s**2, h * (1 - 4 * s + 3 * s**2),
                           6 * s - 6 * s**2, h * (-2 * s + 3 * s**2)], axis=1) / h,
                 np.stack([-6 + 12 * s, h * (-4 + 6 * s), 6 - 12 * s,
                           h * (-2 + 6 * s)], axis=1) / h**2]
        out = [np.zeros((len(z), 2 * n_elements)) for _ in local]
        for k in range(4):
            col = 2 * (e - 1) + k  # global index of local end value k of element e
            ok = col >= 0
            for o, loc in zip(out, local):
                o[np.flatnonzero(ok), col[ok]] += loc[ok, k]
        return tuple(out)
    return function_basis(profile, functions, nodes, kind="fem", tip_form=False)
