"""DC motor electrical model (seed 003 Eqs. 43, 48) and cogging torque."""
from __future__ import annotations

import numpy as np

from .base import Effect, Parameter


class DCMotor(Effect):
    """The joint's command is a voltage V; with the armature inductance neglected (its time
    constant L/R is far below the mechanical ones), the current and torque are

        i = clip((V - K_e n w) / R, -i_max, i_max),   tau_joint = n K_t i  (seed 003 Eq. 48)

    with w the joint-side speed of the actuator coordinate and n the ratio of a ``gear``
    effect on the same joint (1 without one). ``voltage_limit`` clips V first.
    """

    TYPE = "dc_motor"
    TARGET = "joint"
    DESCRIPTION = "voltage-driven DC motor with back-EMF and current limit"
    PARAMETERS = (
        Parameter("resistance", "ohm", 1.0, (1e-6, 1e6), 0.05, "armature resistance R"),
        Parameter("torque_constant", "N m/A", 1.0, (1e-9, 1e3), 0.05, "K_t"),
        Parameter("back_emf_constant", "V s/rad", 0.0, (0.0, 1e3), 0.05, "K_e"),
        Parameter("current_limit", "A", float("inf"), (0.0, float("inf")), 0.05, "i_max"),
        Parameter("voltage_limit", "V", float("inf"), (0.0, float("inf")), 0.02, "V_max"),
    )
    EQUIVALENT = ("viscous joint friction (back-EMF damping n^2 K_t K_e / R)",
                  "torque_saturation (current limit)")


class Cogging(Effect):
    """Cogging torque periodic in the motor angle n theta_a:
    tau = A sin(N n theta_a + phase), N periods per motor revolution."""

    TYPE = "cogging"
    TARGET = "joint"
    DESCRIPTION = "cogging torque of the motor, periodic in the motor angle"
    PARAMETERS = (
        Parameter("amplitude", "N m", 0.0, (0.0, 1e4), 0.3, "A (joint side)"),
        Parameter("periods", "-", 24.0, (1.0, 1e4), 0.0, "N per motor revolution"),
        Parameter("phase", "rad", 0.0, (-np.pi, np.pi), 0.0, "phase"),
    )
    EQUIVALENT = ("none: periodic in the motor angle, unlike every other effect",)
    LIBRARY = False  # kept out of the diagnosis library: the out-of-library test case

    @property
    def is_off(self) -> bool:
        return self["amplitude"] == 0.0
