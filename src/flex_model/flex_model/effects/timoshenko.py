"""Timoshenko shear flexibility and rotary inertia of a thick link (thesis Eq. 4, Remark 3)."""
from __future__ import annotations

import numpy as np

from .base import Effect, Parameter


class Timoshenko(Effect):
    """The link's wavelets become the static solutions of the Timoshenko beam (thesis Eq. 4):
    shear compliance chi/GA in the deflection, shear energy 1/2 int GA/chi (d' - psi)^2 and
    rotary inertia 1/2 int rho I psi'^2 (Remark 3) in the model.

    ``shear_stiffness`` GA/chi (N); left out, it comes from the link's material (G, shear
    factor) and section. Thesis Remark 6: beta = G A L^2 / (chi E I) > 100 makes it
    practically Euler-Bernoulli; the model warns when a link below that is modelled without
    this effect.
    """

    TYPE = "timoshenko"
    TARGET = "link"
    DESCRIPTION = "shear flexibility and rotary inertia of a thick link"
    PARAMETERS = (Parameter("shear_stiffness", "N", float("inf"), (1e-3, float("inf")), 0.1,
                            "GA / chi (inf: Euler-Bernoulli)"),)
    EQUIVALENT = ("link bending stiffness EI (the first mode alone cannot tell them apart)",)

    @classmethod
    def parse(cls, f, joint_names, link_names):
        eff = super().parse(f, joint_names, link_names)
        if not f.has("shear_stiffness"):
            return cls(target=eff.target, values=(float("nan"),))  # from the material
        return eff

    @property
    def is_off(self) -> bool:
        return self["shear_stiffness"] == float("inf")


def slenderness(link) -> float:
    """beta = G A L^2 / (chi E I) at the link root (thesis Eq. 17); inf without G."""
    seg = link.segments[0]
    ei, _, ga = seg.properties(0.0)
    return float(np.asarray(ga) * link.length**2 / np.asarray(ei))
