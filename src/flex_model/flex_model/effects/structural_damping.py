"""Structural damping of a link: internal friction (thesis Eqs. 35-36) and Rayleigh."""
from __future__ import annotations

import numpy as np

from .base import Effect, Parameter


class StructuralDamping(Effect):
    """D_link += k_a int w' w'^T dz + a M_ff + b K_ff on the link's deformation block.

    M_ff is the link's clamped deformation inertia (int w w^T m dz with the link's end
    body; an arm's payload is not in it), so with joints clamped and no payload the modal
    damping ratios are zeta_k = a / (2 w_k) + b w_k / 2.
    """

    TYPE = "structural_damping"
    TARGET = "link"
    DESCRIPTION = "internal friction (thesis Eq. 35) and Rayleigh damping of a link"
    PARAMETERS = (
        Parameter("internal_friction", "N s", 0.0, (0.0, 1e9), 0.5,
                  "k_a of thesis Eq. (35), added to the link's own"),
        Parameter("rayleigh_mass", "1/s", 0.0, (0.0, 1e6), 0.5, "a of D = a M + b K"),
        Parameter("rayleigh_stiffness", "s", 0.0, (0.0, 1.0), 0.5, "b of D = a M + b K"),
    )
    EQUIVALENT = ("structural_damping (internal friction and Rayleigh are one class)",)

    def damping_block(self, basis, m_ff: np.ndarray) -> np.ndarray:
        return (self["internal_friction"] * basis.S1 + self["rayleigh_mass"] * m_ff
                + self["rayleigh_stiffness"] * basis.K)
