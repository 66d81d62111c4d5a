"""The lumped-parameter link of seed 000 (Eqs. 9-16): m masses and springs per link, one
deformation coordinate (the first mode).

Seed 000 keeps the first assumed mode, w(x, t) = F(x) q(t) (Eq. 10; F from Eqs. 7-8, by
default clamped with the tip mass and inertia), and replaces the deformation kinetic
energy of Eq. (9) by that of ``m`` point masses, one at the outer end x_j = j l of each
piece of length l = L / m (Eq. 11), and the elastic energy by ``m`` springs (Eq. 13):

    M_e,j = rho int_{(j-1)l}^{jl} F^2 dx / F(jl)^2                     (seed 000 Eq. 12)
    K_e,j = int_{(j-1)l}^{jl} EI F''^2 dx / w_j^2                      (Eqs. 13, 16)

with y_j = F(jl) q the displacement of mass j and w_j the spring's deflection per unit q.
Eq. (16) writes w_j = l (F'(jl) - F'((j-1)l)) with Eq. (14)'s phi = w / L = w'; the
paper's numbers (Table 2: 0.008634 kg, 96.7425 N/m for one mass on the Table 1 arm, with
8.46 Hz) are those of w_j = l (phi_j - phi_{j-1}), phi_j the chord slope
(F(jl) - F((j-1)l)) / l of piece j (phi_0 = 0): for one mass w_1 = F(L), the tip
deflection. That is what :func:`lumped_parameters` reports.

The link in the model has ONE coordinate, the tip deflection delta = F(L) q (Eq. 10 with
F scaled to F(L) = 1; seed 000 Eq. 44 has one deformation coordinate per link and
direction). The masses then hold sum_j M_e,j F(x_j)^2 = rho int F^2 dx: the modal mass
of Eq. (9), for every m; the springs hold the modal stiffness int EI F''^2 dx for every m.
What m changes is the coupling of the deformation with the rigid motion of the link,
h = sum_j M_e,j F(x_j) and k = sum_j M_e,j x_j F(x_j) (thesis Eqs. 10-11 with the masses
in place of the distributed link), which tends to the first-mode assumed-mode values as
m grows. The rigid-body inertia (mass, first and second moment) is that of the
distributed link (seed 000 Eq. 34: the masses replace the deformation kinetic energy only).
The tip rotation is the slope of the mode, gamma = F'(L) / F(L) delta (Eq. 14: w' = F' q),
given to the model as ``tip_rotation_scale``.
"""
from __future__ import annotations

import numpy as np

from .discretizations import quadrature, basis_from_matrices, link_modes
from .sections import SectionProfile


def lumped_parameters(profile: SectionProfile, masses: int, mode_type: str = "clamped_mass",
                      tip_mass: float = 0.0, tip_inertia: float = 0.0, with_mode=False):
    """Lumped masses M_e,j (kg) and springs K_e,j (N/m) of seed 000 Eqs. (12) and (16)
    (and the mode F used, if ``with_mode``)."""
    shapes = link_modes(profile, 1, mode_type, tip_mass, tip_inertia)
    length = profile.length
    ell = length / masses
    edges = np.linspace(0.0, length, masses + 1)
    _, z, w, ei, m = quadrature(profile, edges)
    phi, _, ddphi = (a[:, 0] for a in shapes.evaluate(z))
    f_e = shapes.evaluate(edges)[0][:, 0]
    piece = np.clip(np.searchsorted(edges, z, side="right") - 1, 0, masses - 1)
    m_e = np.bincount(piece, w * m * phi ** 2, masses) / f_e[1:] ** 2
    chord = np.diff(f_e) / ell
    w_rel = ell * (chord - np.concatenate([[0.0], chord[:-1]]))
    k_e = np.bincount(piece, w * ei * ddphi ** 2, masses) / w_rel ** 2
    return (m_e, k_e, shapes, w_rel) if with_mode else (m_e, k_e)


def lumped_basis(profile: SectionProfile, masses: int, mode_type: str = "clamped_mass",
                 tip_mass: float = 0.0, tip_inertia: float = 0.0):
    """The lumped link as a model basis: one variable, the tip deflection (Eq. 10)."""
    if masses < 1:
        raise ValueError(f"a lumped link needs at least one mass; got {masses}")
    m_e, k_e, mode, w_rel = lumped_parameters(profile, masses, mode_type, tip_mass,
                                              tip_inertia, with_mode=True)
    length = profile.length
    nodes = np.linspace(0.0, length, masses + 1)
    f_tip, df_tip = (a[0, 0] for a in mode.evaluate(np.array([length]))[:2])

    def functions(z):
        return tuple(a / f_tip for a in mode.evaluate(np.atleast_1d(np.asarray(z, float))))
    y = mode.evaluate(nodes[1:])[0][:, 0] / f_tip        # mass displacements per unit delta
    _, z, w, _, m = quadrature(profile, nodes)
    slope = functions(z)[1][:, 0]
    raw = {"Bw": np.array([[m_e @ y ** 2]]), "h": np.array([m_e @ y]),
           "k": np.array([m_e @ (nodes[1:] * y)]),
           "K": np.array([[k_e @ (w_rel / f_tip) ** 2]]), "S1": np.array([[w @ slope ** 2]])}
    rigid = (float(np.sum(w * m)), float(np.sum(w * m * z)), float(np.sum(w * m * z * z)))
    return basis_from_matrices(profile, functions, nodes, raw, rigid, kind="lumped",
                               tip_form=False, tip_rotation_scale=float(df_tip / f_tip),
                               details={"lumped_masses": m_e, "lumped_springs": k_e,
                                        "mode_type": mode_type, "mode": mode})
