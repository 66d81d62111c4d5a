"""Actuator torque saturation at a joint."""
from __future__ import annotations

from .base import Effect, Parameter


class TorqueSaturation(Effect):
    """The joint torque of the actuator is clipped to [-limit, limit] (N m): PD, policy and
    pulse torques are summed first, then clipped."""

    TYPE = "torque_saturation"
    TARGET = "joint"
    DESCRIPTION = "actuator torque limit"
    PARAMETERS = (Parameter("limit", "N m", float("inf"), (0.0, float("inf")), 0.05,
                            "largest torque the actuator delivers"),)
    EQUIVALENT = ("current limit of a DC motor",)
