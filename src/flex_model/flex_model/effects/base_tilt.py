"""Base tilt: the gravity direction off by a small angle in the plane of motion."""
from __future__ import annotations

import numpy as np

from .base import Effect, Parameter


class BaseTilt(Effect):
    """The base frame is rotated by ``angle`` (rad, counter-clockwise): gravity, given in
    the nominal base frame, appears rotated by -angle in the tilted base frame."""

    TYPE = "base_tilt"
    TARGET = "arm"
    DESCRIPTION = "base mounted with a small tilt in the plane of motion"
    PARAMETERS = (Parameter("angle", "rad", 0.0, (-np.pi / 2, np.pi / 2), 0.0,
                            "tilt of the base, counter-clockwise"),)
    EQUIVALENT = ("joint encoder bias of joint 1 (under gravity only)",)

    def gravity(self, g) -> np.ndarray:
        a = -self["angle"]
        c, s = np.cos(a), np.sin(a)
        return np.array([c * g[0] - s * g[1], s * g[0] + c * g[1]])
