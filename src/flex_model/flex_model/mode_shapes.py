"""Mode shapes of a uniform Euler-Bernoulli link for the assumed-mode method.

Free vibration of ``EI w'''' + rho w_tt = 0`` (thesis Eq. 56) with ``w = phi(z) cos wt``,
``beta^4 = rho w^2 / EI``. On ``x = beta z`` every solution is a combination of the four
bounded functions ``cos x, sin x, e^{-x}, e^{x - beta L}`` (the classic cosh/sinh form
of seed 000 Eq. 8 overflows for high modes); the boundary conditions give a 4 x 4
matrix whose determinant vanishes at the roots ``beta_j L``:

- ``clamped_free``: phi(0) = phi'(0) = 0, phi''(L) = phi'''(L) = 0 (1 + cos cosh = 0);
- ``hinged_free``: phi(0) = phi''(0) = 0, free tip (tan = tanh), rigid mode excluded;
- ``clamped_mass``: clamped root, tip mass M_p and inertia I_p (seed 000 Eqs. 4-6):
  EI phi'''(L) = -M_p w^2 phi(L), EI phi''(L) = I_p w^2 phi'(L); the roots are those of
  the transcendental equation seed 000 Eq. (7).

The model measures deflections from the root tangent (alpha is the root tangent, so a
clamped joint is alpha = const). A hinged-free mode has phi'(0) != 0: it is used as
``phi(z) - z phi'(0)`` with the root rotation moved into alpha, the same first-order
displacement field (thesis Eq. 54 linearized), so the joint angle stays theta = alpha_i -
alpha_{i-1} - gamma_{i-1}.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

MODE_TYPES = ("clamped_free", "hinged_free", "clamped_mass")


def _u(x, big_b, order):
    """d^order/dx^order of (cos x, sin x, e^{-x}, e^{x - B}): shape x.shape + (4,)."""
    x = np.asarray(x, float)
    c, s = np.cos(x), np.sin(x)
    em, ep = np.exp(-x), np.exp(x - big_b)
    trig = [(c, s), (-s, c), (-c, -s), (s, -c)][order % 4]
    return np.stack([trig[0], trig[1], (-1) ** order * em, ep], axis=-1)


def boundary_matrix(big_b: float, mode_type: str, mass_ratio: float = 0.0,
                    inertia_ratio: float = 0.0) -> np.ndarray:
    """4 x 4 boundary-condition matrix at B = beta L (rows: two root, two tip conditions).

    ``mass_ratio`` = M_p / (rho L), ``inertia_ratio`` = I_p / (rho L^3) (clamped_mass).
    """
    root = (_u(0.0, big_b, 0), _u(0.0, big_b, 1 if mode_type != "hinged_free" else 2))
    u0, u1, u2, u3 = (_u(big_b, big_b, k) for k in range(4))
    shear = u3 + mass_ratio * big_b * u0
    moment = u2 - inertia_ratio * big_b ** 3 * u1
    return np.vstack([root[0], root[1], moment, shear])


def seed000_eq7(big_b: float, mass_ratio: float, inertia_ratio: float) -> float:
    """Left side of seed 000 Eq. (7) (the transcendental equation of the clamped link with
    tip mass and inertia) at B = beta L, scaled by e^{-B} so it stays finite."""
    ch, sh = np.cosh(big_b) * np.exp(-big_b), np.sinh(big_b) * np.exp(-big_b)
    c, s = np.cos(big_b), np.sin(big_b)
    return (np.exp(-big_b) + ch * c + mass_ratio * big_b * (sh * c - ch * s)
            - inertia_ratio * big_b ** 3 * (sh * c + ch * s)
            + mass_ratio * inertia_ratio * big_b ** 4 * (np.exp(-big_b) - ch * c))


def mode_roots(count: int, mode_type: str, mass_ratio: float = 0.0,
               inertia_ratio: float = 0.0) -> np.ndarray:
    """The first ``count`` roots beta_j L > 0 (flexible modes) of the boundary determinant."""
    def det(b):
        return np.linalg.det(boundary_matrix(b, mode_type, mass_ratio, inertia_ratio))
    roots = []
    step = 0.02
    b0 = 0.05
    d0 = det(b0)
    while len(roots) < count:
        b1 = b0 + step
        d1 = det(b1)
        if d0 == 0.0 or d0 * d1 < 0:
            roots.append(brentq(det, b0, b1, xtol=1e-14) if d0 != 0.0 else b0)
        b0, d0 = b1, d1
    return np.array(roots)


@dataclass(frozen=True)
class ModeShapes:
    """``count`` mode shapes of a link of length L (normalized: int_0^L phi^2 dz = L)."""

    length: float
    roots: np.ndarray        # beta_j L
    coeffs: np.ndarray       # (4, count) combination of the bounded functions
    mode_type: str

    @property
    def count(self) -> int:
        return len(self.roots)

    def evaluate(self, z):
        """phi, phi', phi'' at points z: three (len(z), count) arrays (root-tangent form)."""
        z = np.atleast_1d(np.asarray(z, float))
        beta = self.roots / self.length
        x = z[:, None] * beta[None, :]
        out = [np.einsum("zmk,km->zm", _u(x, self.roots[None, :], k), self.coeffs)
               * beta ** k for k in range(3)]
        if self.mode_type == "hinged_free":  # move the root rotation into alpha
            slope0 = np.einsum("mk,km->m", _u(np.zeros(self.count), self.roots, 1),
                               self.coeffs) * beta
            out[0] = out[0] - z[:, None] * slope0
            out[1] = out[1] - slope0
        return tuple(out)


def mode_shapes(length: float, count: int, mode_type: str = "clamped_free", *,
                mass_per_length: float = 1.0, tip_mass: float = 0.0,
                tip_inertia: float = 0.0) -> ModeShapes:
    """The first ``count`` flexible modes of a uniform link (thesis Eqs. 55-56, seed 000
    Eqs. 7-8); tip mass and inertia only enter ``clamped_mass``."""
    if mode_type not in MODE_TYPES:
        raise ValueError(f"mode_type {mode_type!r}: expected one of {', '.join(MODE_TYPES)}")
    mr = ir = 0.0
    if mode_type == "clamped_mass":
        mr = tip_mass / (mass_per_length * length)
        ir = tip_inertia / (mass_per_length * length ** 3)
    roots = mode_roots(count, mode_type, mr, ir)
    coeffs = np.zeros((4, count))
    zq, wq = np.polynomial.legendre.leggauss(60)
    for j, b in enumerate(roots):
        c = np.linalg.svd(boundary_matrix(b, mode_type, mr, ir))[2][-1]
        x = 0.5 * b * (zq + 1.0)
        phi = _u(x, b, 0) @ c
        norm = np.sqrt(0.5 * np.sum(wq * phi ** 2))  # sqrt(int phi^2 dz / L)
        sign = np.sign(_u(b, b, 0) @ c) or 1.0
        coeffs[:, j] = sign * c / norm
    return ModeShapes(length=float(length), roots=roots, coeffs=coeffs, mode_type=mode_type)
