"""Gear ratio and rotor inertia reflected to the joint (seed 000 Eq. 35)."""
from __future__ import annotations

import numpy as np

from .base import Effect, Parameter


class Gear(Effect):
    """A motor driving joint i through a rigid gear of ratio n: the rotor spins at
    n theta_i relative to its stator, which sits on the tip of link i-1 (or the base).

    Its kinetic energy 1/2 J_r (n theta_i' + Omega_stator)^2 adds the constant matrix
    J_r c c^T to B(q), c = n G_i + e_stator (seed 000 Eq. 35 keeps n^2 J_r, the dominant
    term). The motor-side command of seed 000 Eq. (45) is the motor torque tau_m; the
    joint receives n tau_m (``joint_torque = ratio * motor_torque``).
    """

    TYPE = "gear"
    TARGET = "joint"
    DESCRIPTION = "gear ratio and rotor inertia reflected to the joint"
    PARAMETERS = (
        Parameter("ratio", "-", 1.0, (1e-3, 1e4), 0.0, "gear ratio n (motor / joint speed)"),
        Parameter("rotor_inertia", "kg m^2", 0.0, (0.0, 1e3), 0.05,
                  "rotor inertia J_r on the motor shaft"),
    )
    EQUIVALENT = ("hub inertia J_minus of the driven link",)

    def inertia_matrix(self, model, joint: int) -> np.ndarray:
        """Constant addition to B(q) in the model's coordinates. The rotor turns with the
        actuator coordinate: the joint angle, or the motor coordinate of an elastic joint
        (``joint_elasticity``: then n^2 J_r sits on the motor side of the spring)."""
        c = self["ratio"] * model.Ga[joint].copy()
        if joint > 0:  # stator on the tip of link joint-1: Omega = alpha + gamma_n
            c[model.alpha_index(joint - 1)] += 1.0
            c += model.tip_rotation_matrix()[joint - 1]
        return self["rotor_inertia"] * np.outer(c, c)
