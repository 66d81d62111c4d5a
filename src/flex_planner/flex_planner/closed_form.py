"""The thesis's closed-form static model of the two-link arm (Ch. IV.3, Eqs. 85-94).

Small-deflection Euler-Bernoulli cantilevers under their own weight, with superposition
(Eq. 34 for the elementary cases). With absolute link angles alpha_1, alpha_2 (rad), link
masses per length m_i (kg/m), bending stiffnesses EI_i (N m^2) and gravity g (m/s^2):

    x = L1 cos a1 - d1 sin a1 + L2 cos a2 - d2 sin a2                       (Eq. 85)
    y = L1 sin a1 + d1 cos a1 + L2 sin a2 + d2 cos a2
    d2 = -m2 g cos(a2) L2^4 / (8 EI2)                          (Eqs. 86-87 with Eq. 34)
    d1 = d1g + d1T + d1M                                                    (Eq. 91)
    d1g = -m1 g cos(a1) L1^4 / (8 EI1)                                      (Eq. 92)
    d1T = -m2 L2 g cos(a1) L1^3 / (3 EI1)      (weight of link 2, T21 = -m2 L2 g, Eq. 89/93)
    d1M = -m2 L2^2 g cos(a2) L1^2 / (4 EI1)    (its moment M21 = -m2 g L2^2 cos a2 / 2, Eq. 90)

and Eq. (94) x = f1(a1, a2), y = f2(a1, a2) is inverted numerically ("the powerful Matlab
algorithms": here scipy's MINPACK hybrid method). The joint (encoder) angles follow with
the tip rotation of link 1 from Eq. (34): theta_1 = a1, theta_2 = a2 - a1 - g1,

    g1 = -m1 g cos(a1) L1^3 / (6 EI1) - m2 L2 g cos(a1) L1^2 / (2 EI1)
         - m2 g L2^2 cos(a2) L1 / (2 EI1).

It is an independent check of the general inversion of :mod:`flex_planner.inverse_statics`,
with which it agrees to first order in the deflections.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from .rigid_kinematics import two_link_ik


@dataclass(frozen=True)
class TwoLinkBeams:
    """Lengths L (m), bending stiffness EI (N m^2), mass per length m (kg/m), g (m/s^2)."""

    L1: float
    L2: float
    EI1: float
    EI2: float
    m1: float
    m2: float
    g: float = 9.81

    @staticmethod
    def from_model(model) -> "TwoLinkBeams":
        """The constant-section two-link arm of a FlexArmModel (no end masses, no payload)."""
        if model.n_links != 2:
            raise ValueError(f"model: got {model.n_links} links; the closed form of thesis "
                             "Eqs. 85-94 is for two links")
        props = [lk.profile.properties(np.array([0.0]))[:2] for lk in model.arm.links]
        g = float(-model.gravity[1])
        return TwoLinkBeams(model.arm.links[0].length, model.arm.links[1].length,
                            float(props[0][0][0]), float(props[1][0][0]),
                            float(props[0][1][0]), float(props[1][1][0]), g)


def deflections(b: TwoLinkBeams, a1: float, a2: float) -> tuple[float, float, float]:
    """Tip deflections d1, d2 (m) and tip rotation g1 of link 1 (rad): Eqs. 86-93, 34."""
    w1, w2 = b.m1 * b.g, b.m2 * b.g
    c1, c2 = np.cos(a1), np.cos(a2)
    d2 = -w2 * c2 * b.L2 ** 4 / (8.0 * b.EI2)
    d1 = (-w1 * c1 * b.L1 ** 4 / (8.0 * b.EI1)
          - w2 * b.L2 * c1 * b.L1 ** 3 / (3.0 * b.EI1)
          - w2 * b.L2 ** 2 * c2 * b.L1 ** 2 / (4.0 * b.EI1))
    g1 = (-w1 * c1 * b.L1 ** 3 / (6.0 * b.EI1)
          - w2 * b.L2 * c1 * b.L1 ** 2 / (2.0 * b.EI1)
          - w2 * b.L2 ** 2 * c2 * b.L1 / (2.0 * b.EI1))
    return d1, d2, g1


def tip_position(b: TwoLinkBeams, a1: float, a2: float) -> np.ndarray:
    """Eq. (85) with the deflections of Eqs. (86)-(93): the static tip (m)."""
    d1, d2, _ = deflections(b, a1, a2)
    return np.array([b.L1 * np.cos(a1) - d1 * np.sin(a1) + b.L2 * np.cos(a2) - d2 * np.sin(a2),
                     b.L1 * np.sin(a1) + d1 * np.cos(a1) + b.L2 * np.sin(a2) + d2 * np.cos(a2)])


@dataclass
class ClosedFormInverse:
    """Absolute link angles alpha (rad), joint angles theta (rad), deflections d1, d2 (m)."""

    alpha: np.ndarray
    joint_angles: np.ndarray
    tip_deflections: np.ndarray


def invert(b: TwoLinkBeams, target, bend: int) -> ClosedFormInverse:
    """Solve Eq. (94) for (alpha_1, alpha_2) from the rigid inverse kinematics (branch
    ``bend`` = sign of theta_2); raises ``ValueError`` when the solver fails."""
    target = np.asarray(target, float)
    t1, t2 = two_link_ik(b.L1, b.L2, target, bend)
    sol = root(lambda a: tip_position(b, a[0], a[1]) - target, [t1, t1 + t2],
               method="hybr", options={"xtol": 1e-12})
    if not sol.success or np.max(np.abs(tip_position(b, *sol.x) - target)) > 1e-9:
        raise ValueError(f"target: the closed form of Eq. (94) has no solution near the "
                         f"rigid pose for {target.tolist()} m ({sol.message})")
    a1, a2 = sol.x
    d1, d2, g1 = deflections(b, a1, a2)
    return ClosedFormInverse(alpha=np.array([a1, a2]),
                             joint_angles=np.array([a1, a2 - a1 - g1]),
                             tip_deflections=np.array([d1, d2]))
