"""The lumped-parameter link of seed 000 (Eqs. 9-16): point masses and springs from the
first mode.

The link is cut into ``m`` pieces of length l = L / m. With the first mode F(z) of the
link (seed 000 Eqs. 7-8, by default clamped with the tip mass and inertia), piece j
gets

    M_e,j = int_{(j-1)l}^{jl} rho F^2 dz / F(jl)^2                     (seed 000 Eq. 12)
    K_e,j = int_{(j-1)l}^{jl} EI F''^2 dz / w_j^2                          (Eq. 16)

so that the piece's share of the modal kinetic and elastic energy is 1/2 M_e,j y_j'^2
and 1/2 K_e,j w_j^2 (Eqs. 11, 13). Eq. (16) writes w_j = l (F'(jl) - F'((j-1)l)) with
Eq. (14)'s phi = w / l = w'; the paper's numbers (Table 2: 96.74 N/m for one mass, with
8.46 Hz) are those of w_j = l (phi_j - phi_{j-1}), phi_j the chord slope
(F(jl) - F((j-1)l)) / l of piece j (phi_0 = 0): for one mass w_1 = F(L). That is what is
used here (the relative rotation at the root spring of piece j, times l).

How it sits behind the model interface (our choice; the seed is silent on the kinematics
of more than one mass): a chain of m rigid pieces, piece j rotating by phi_j about the
spring K_e,j l^2 at its root end, with the mass M_e,j at its outer end z = jl. The
deformation variables are the mass deflections y_1..y_m; the deflection between masses
is linear, the tip deflection is y_m and the tip rotation (y_m - y_{m-1}) / l. The
deformation inertia (B_f, h, k of thesis Eqs. 9-11) is that of the lumped masses, the
rigid-body inertia that of the distributed link (seed 000 Eq. 9: the lumped masses
replace the deformation kinetic energy only). The kernels need the tip deflection and
the tip rotation as two coordinates (tip form, thesis Eq. 84), so a model link has
m >= 2 masses; the single-mass numbers of seed 000 Table 2 come from
:func:`lumped_parameters` with m = 1.
"""
from __future__ import annotations

import numpy as np

from .discretizations import _quadrature, basis_from_matrices, link_modes
from .sections import SectionProfile


def lumped_parameters(profile: SectionProfile, masses: int, mode_type: str = "clamped_mass",
                      tip_mass: float = 0.0, tip_inertia: float = 0.0, with_mode=False):
    """Lumped masses M_e,j (kg) and springs K_e,j (N/m) of seed 000 Eqs. (12) and (16)
    (and the mode F used, if ``with_mode``)."""
    shapes = link_modes(profile, 1, mode_type, tip_mass, tip_inertia)
    length = profile.length
    ell = length / masses
    edges = np.linspace(0.0, length, masses + 1)
    _, z, w, ei, m = _quadrature(profile, edges)
    phi, _, ddphi = (a[:, 0] for a in shapes.evaluate(z))
    f_e = shapes.evaluate(edges)[0][:, 0]
    piece = np.clip(np.searchsorted(edges, z, side="right") - 1, 0, masses - 1)
    m_e = np.bincount(piece, w * m * phi ** 2, masses) / f_e[1:] ** 2
    chord = np.diff(f_e) / ell
    w_rel = ell * (chord - np.concatenate([[0.0], chord[:-1]]))
    k_e = np.bincount(piece, w * ei * ddphi ** 2, masses) / w_rel ** 2
    return (m_e, k_e, shapes) if with_mode else (m_e, k_e)


def lumped_basis(profile: SectionProfile, masses: int, mode_type: str = "clamped_mass",
                 tip_mass: float = 0.0, tip_inertia: float = 0.0):
    """The lumped link as a model basis (variables: mass deflections, in tip form)."""
    if masses < 2:
        raise ValueError("a lumped link in the model needs variables >= 2 masses (the tip "
                         f"deflection and rotation are two coordinates); got {masses}")
    m_e, k_e, mode = lumped_parameters(profile, masses, mode_type, tip_mass, tip_inertia,
                                       with_mode=True)
    length = profile.length
    ell = length / masses
    nodes = np.linspace(0.0, length, masses + 1)

    def functions(z):
        z = np.atleast_1d(np.asarray(z, float))
        j = np.clip(np.searchsorted(nodes, z, side="right") - 1, 0, masses - 1)
        s = (z - nodes[j]) / ell
        w, dw = np.zeros((len(z), masses)), np.zeros((len(z), masses))
        rows = np.arange(len(z))
        w[rows, j] += s
        dw[rows, j] += 1.0 / ell
        inner = j >= 1
        w[rows[inner], j[inner] - 1] += 1.0 - s[inner]
        dw[rows[inner], j[inner] - 1] -= 1.0 / ell
        return w, dw, np.zeros_like(w)
    # piece rotations phi = R y, relative rotations at the springs D phi
    r = (np.eye(masses) - np.eye(masses, k=-1)) / ell
    d = np.eye(masses) - np.eye(masses, k=-1)
    rel = d @ r
    raw = {"Bw": np.diag(m_e), "h": m_e.copy(), "k": m_e * nodes[1:],
           "K": rel.T @ np.diag(k_e * ell ** 2) @ rel, "S1": ell * r.T @ r}
    _, z, w, _, m = _quadrature(profile, nodes)
    rigid = (float(np.sum(w * m)), float(np.sum(w * m * z)), float(np.sum(w * m * z * z)))
    return basis_from_matrices(profile, functions, nodes, raw, rigid, kind="lumped",
                               details={"lumped_masses": m_e, "lumped_springs": k_e,
                                        "mode_type": mode_type, "mode": mode})
