"""Joint friction: viscous, Coulomb and Stribeck, regularized."""
from __future__ import annotations

import numpy as np
from numba import njit

from .base import Effect, Parameter


def friction_law(w, fv, fc, fs, ws, eps):
    """The friction torque tau_f(w) of :class:`JointFriction` and its slope d tau_f / dw
    (NumPy arrays or floats). The one place of the law: the Python models call it, the
    compiled kernels call :data:`friction_law_compiled`."""
    ex = np.exp(-(w / ws) ** 2)
    th = np.tanh(w / eps)
    level = fc + (fs - fc) * ex
    return (-fv * w - level * th,
            -fv + (fs - fc) * ex * 2.0 * w / ws ** 2 * th - level * (1.0 - th * th) / eps)


#: :func:`friction_law` compiled, for the integrators' kernels (numba)
friction_law_compiled = njit(cache=True)(friction_law)


class JointFriction(Effect):
    """Friction torque on the actuator coordinate (the joint, or the motor side of an elastic
    joint):

        tau_f = -F_v w - (F_c + (F_s - F_c) exp(-(w / w_s)^2)) tanh(w / eps)

    The tanh regularization keeps the equations smooth; the implicit fixed-step scheme
    takes its steep slope into its Newton matrix. A joint under a torque tau < F_s then
    holds with a creep of eps * atanh(tau / F_s) rad/s (eps = 1e-6 rad/s by default).
    """

    TYPE = "joint_friction"
    TARGET = "joint"
    DESCRIPTION = "viscous, Coulomb and Stribeck friction in the joint"
    PARAMETERS = (
        Parameter("viscous", "N m s/rad", 0.0, (0.0, 1e6), 0.3, "F_v"),
        Parameter("coulomb", "N m", 0.0, (0.0, 1e6), 0.3, "F_c"),
        Parameter("static", "N m", 0.0, (0.0, 1e6), 0.3, "break-away torque F_s >= F_c"),
        Parameter("stribeck_velocity", "rad/s", 0.01, (1e-6, 1e3), 0.5, "w_s"),
        Parameter("regularization", "rad/s", 1e-6, (1e-9, 1.0), 0.0, "eps"),
    )
    EQUIVALENT = ("Coulomb within Stribeck", "viscous friction and DC-motor back-EMF damping")

    @classmethod
    def check(cls, f, values) -> None:
        if values[2] < values[1]:
            raise f.error("static", values[2], f"a break-away torque >= coulomb ({values[1]})")

    def torque(self, w):
        return friction_law(np.asarray(w, float), *self.values)[0]
