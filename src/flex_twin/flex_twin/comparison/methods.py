"""The discretizations compared, and the arm with every link discretized one way."""
from __future__ import annotations

import dataclasses
from fractions import Fraction

import numpy as np

from flex_model.arm import ArmDescription

#: (label, discretization, options) of the methods the report compares
METHODS = (
    ("wavelet", "wavelet", {}),
    ("clamped-free modes", "assumed_modes", {"mode_type": "clamped_free"}),
    ("hinged-free modes", "assumed_modes", {"mode_type": "hinged_free"}),
    ("optimized modes", "optimized_modes", {"mode_type": "clamped_free"}),
    ("Ritz polynomials", "ritz_polynomials", {}),
    ("FEM", "fem", {}),
    ("lumped", "lumped", {"mode_type": "clamped_free"}),
)


def with_discretization(arm: ArmDescription, discretization: str, n_vars: int | None = None,
                        **options) -> ArmDescription:
    """The arm with every link discretized by ``discretization`` (and ``n_vars``)."""
    links = []
    for lk in arm.links:
        lk = dataclasses.replace(lk, discretization=discretization, **options)
        if n_vars is not None:
            lk = dataclasses.replace(lk, n_vars=n_vars)
        links.append(lk)
    return dataclasses.replace(arm, links=tuple(links))


def original_coordinates_matrix(model) -> np.ndarray:
    """T_q with q_hat = T_q q_orig: the tip form (thesis Eq. 82) of every link, identity
    elsewhere; B in the original variables is T_q^T B T_q (thesis Table VI)."""
    t = np.eye(model.nq)
    for i, b in enumerate(model.bases):
        if getattr(b, "tip_transform", None) is not None:
            s = model.flex_slice(i)
            t[s, s] = b.tip_transform
    return t


def exact_condition_number(matrix_fractions) -> float:
    """2-norm condition number of a matrix given exactly (lists of Fractions): the inverse
    is computed in rational arithmetic, so a cond above 1/eps is still meaningful."""
    a = [[Fraction(x) for x in row] for row in matrix_fractions]
    n = len(a)
    inv = [[Fraction(int(i == j)) for j in range(n)] for i in range(n)]
    for c in range(n):
        p = next(r for r in range(c, n) if a[r][c] != 0)
        a[c], a[p], inv[c], inv[p] = a[p], a[c], inv[p], inv[c]
        piv = a[c][c]
        a[c] = [x / piv for x in a[c]]
        inv[c] = [x / piv for x in inv[c]]
        for r in range(n):
            if r != c and a[r][c] != 0:
                f = a[r][c]
                a[r] = [x - f * y for x, y in zip(a[r], a[c])]
                inv[r] = [x - f * y for x, y in zip(inv[r], inv[c])]
    dense = np.array([[float(x) for x in row] for row in matrix_fractions])
    return float(np.linalg.norm(dense, 2)
                 * np.linalg.norm(np.array([[float(x) for x in r] for r in inv]), 2))
