"""Joint elasticity with motor inertia (seed 002 Eqs. 11-14; seed 003 gear stiffness C_xi and
damping B_xi), and gear backlash as a dead zone of that spring."""
from __future__ import annotations

import numpy as np

from .base import Effect, Parameter


class JointElasticity(Effect):
    """The actuator drives a motor coordinate theta_m (link-side units: motor angle / n)
    coupled to the link-side joint angle theta through a torsional spring-damper:

        tau_s = k_t (theta_m - theta) + b_t (theta_m' - theta')      (seed 002 Eq. 11-14)

    ``motor_inertia`` is the motor-side inertia seen from the link side (n^2 J_motor); the
    rotor of a ``gear`` effect on the same joint then spins with the motor coordinate.
    """

    TYPE = "joint_elasticity"
    TARGET = "joint"
    DESCRIPTION = "elastic gear between motor and link with motor inertia"
    PARAMETERS = (
        Parameter("stiffness", "N m/rad", float("inf"), (1e-6, float("inf")), 0.10,
                  "torsional stiffness k_t (inf: rigid joint)"),
        Parameter("damping", "N m s/rad", 0.0, (0.0, 1e9), 0.5, "torsional damping b_t"),
        Parameter("motor_inertia", "kg m^2", 0.0, (0.0, 1e6), 0.05,
                  "motor-side inertia reflected to the link side"),
    )
    EQUIVALENT = ("link bending stiffness (EI) when only motor and tip are measured",
                  "backlash (for small motions)")

    @property
    def is_off(self) -> bool:
        return not np.isfinite(self["stiffness"])

    @classmethod
    def check(cls, f, values) -> None:
        if np.isfinite(values[0]) and values[2] <= 0.0:
            raise f.error("motor_inertia", values[2], "a motor inertia > 0 (kg m^2) for an "
                          "elastic joint (the motor coordinate needs inertia)")


class Backlash(Effect):
    """A dead zone of half-width ``half_width`` (rad) in the joint spring, regularized over
    ``smoothing`` (rad): tau_s = k_t dz(theta_m - theta) with
    dz(x) = x - b tanh-like saturation, C1-smooth (needs ``joint_elasticity``)."""

    TYPE = "backlash"
    TARGET = "joint"
    DESCRIPTION = "gear backlash (dead zone of the joint spring)"
    PARAMETERS = (
        Parameter("half_width", "rad", 0.0, (0.0, 0.5), 0.2, "half the play b"),
        Parameter("smoothing", "rad", 1e-5, (1e-9, 1e-2), 0.0,
                  "width of the regularized corners"),
    )
    EQUIVALENT = ("joint_elasticity (a soft spring near zero load)",
                  "joint encoder quantization")

    @property
    def is_off(self) -> bool:
        return self["half_width"] == 0.0
