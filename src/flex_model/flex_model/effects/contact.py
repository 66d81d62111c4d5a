"""Compliant environment at the tip: a one-sided spring-damper surface (seed 003)."""
from __future__ import annotations

import numpy as np

from ..config import check_number
from .base import Effect, Parameter


class ContactSurface(Effect):
    """A straight surface through ``(x, y)`` with unit normal at ``normal_angle`` pointing
    into the free side. Penetration of the tip p: delta = -n . (p - p0) > 0 gives the force

        F = max(0, k delta - c n . p') n       (never pulls; seed 003's environment force)

    applied at the tip (generalized force J_tip^T F). The contact force is an output.
    """

    TYPE = "contact_surface"
    TARGET = "arm"
    DESCRIPTION = "one-sided spring-damper surface touched by the tip"
    PARAMETERS = (
        Parameter("x", "m", 0.0, (-1e3, 1e3), 0.0, "a point of the surface"),
        Parameter("y", "m", -1e3, (-1e3, 1e3), 0.0, "a point of the surface"),
        Parameter("normal_angle", "rad", np.pi / 2, (-2 * np.pi, 2 * np.pi), 0.0,
                  "direction of the normal into the free side (pi/2: floor)"),
        Parameter("stiffness", "N/m", 0.0, (0.0, 1e12), 0.2, "k"),
        Parameter("damping", "N s/m", 0.0, (0.0, 1e9), 0.5, "c"),
    )
    EQUIVALENT = ("tip load (a constant force while in contact)",)

    def kernel_data(self) -> np.ndarray:
        a = self["normal_angle"]
        return np.array([1.0, self["x"], self["y"], np.cos(a), np.sin(a), self["stiffness"],
                         self["damping"]])

    def force(self, tip, tip_velocity) -> np.ndarray:
        """Contact force vector (N) for a tip position and velocity (base frame)."""
        d = self.kernel_data()
        n = d[3:5]
        pen = -n @ (np.asarray(tip) - d[1:3])
        if pen <= 0:
            return np.zeros(2)
        return max(0.0, d[5] * pen - d[6] * (n @ np.asarray(tip_velocity))) * n

    @classmethod
    def check(cls, f, values) -> None:
        check_number(values[3], f.source, f.sub("stiffness"), positive=True, unit="N/m")
