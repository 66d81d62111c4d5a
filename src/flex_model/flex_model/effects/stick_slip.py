"""Stick-slip joint friction: the elasto-plastic model of Dupont, Hayward, Armstrong and
Altpeter, "Single state elastoplastic friction models", IEEE TAC 47(5), 2002.

Why elasto-plastic and not LuGre (Canudas de Wit, Olsson, Astrom, Lischinsky, IEEE TAC
40(3), 1995): both add one bristle (pre-sliding) state z per joint and both hold a joint
at rest under a constant torque below break-away. LuGre's z' = w - |w| z sigma_0 / g(w)
is plastic at every |z| > 0, so an oscillating torque below break-away ratchets the joint
along (drift; Dupont et al. 2002, Sec. II). The joints of a flexible arm always carry the
links' vibration, so the twin would creep where the real hub sticks. The elasto-plastic
model is purely elastic for |z| <= z_ba: no drift there, by construction (in its plastic
part, z_ba < |z| < z_m, a vibrating link does make a held joint creep, as LuGre does
everywhere). For the integrators, what matters is that the bristle law is rate-independent
(z moves with the joint angle; only the level F_ss(w) depends on the speed), so one step
of it is a scalar monotone equation:

- fixed step (generalized-alpha, 1 ms): the bristle state is advanced by backward Euler,
  z1 = z0 + h z'(z1, w1), i.e. y1 = y0 + h |w1| (1 - alpha(y1) y1 / z_m(w0)), with the
  Stribeck level of the step's start speed w0 (a steep drop, -dF_ss/dw above the inertia
  the joint sees over a step, would make the step's equations non-monotone and stall the
  Newton iteration on a flexible link's light hub), and the damping on (z1 - z0) / h: a
  residual
  increasing in y1 with its root bracketed in [z_ba, y0 + h |w1|] (safeguarded Newton,
  a few iterations), solved inside every residual evaluation of the mechanical Newton
  iteration; sigma_0 h dz1/dw1 and the bristle damping enter the iteration matrix. It is
  L-stable: in sliding (sigma_0 |w| h / F_ss = 10 per 1 ms step at 1 rad/s with
  F_ss / sigma_0 = 1e-4 rad, where an explicit or trapezoidal bristle update oscillates)
  and for stiff bristles whose vibration sqrt(sigma_0 / J) the 1 ms step cannot resolve
  (a displacement-driven bristle would ring at the scheme's rho_inf = 0.9 per step and
  could knock a just-stuck joint back into sliding). At rest w1 = 0 gives z1 = z0
  exactly: a held joint cannot creep numerically.
- variable step (Dormand-Prince): z is one more first-order state, z' = w (1 - alpha y /
  z_m), Lipschitz in (z, w); the error control resolves the bristle time constant
  F_ss / (sigma_0 |w|) in sliding and the bristle vibration sqrt(sigma_0 / J) in stick
  (sigma_0 sets the cost: keep F_s / sigma_0 at the measured pre-sliding displacement).

Model (SI units; w rad/s is the speed of the actuator coordinate: the joint angle, or the
motor coordinate of an elastic joint; the effect acts where ``joint_friction`` acts):

    F_ss(w) = F_c + (F_s - F_c) exp(-(w / w_s)^2)        steady sliding level (N m)
    z_m(w) = F_ss(w) / sigma_0,  z_ba = elastic_fraction F_c / sigma_0   (rad)
    y = sgn(w) z;  alpha(y) = 0 for y <= z_ba, 1 for y >= z_m,
        (1 + sin(pi (y - (z_m + z_ba) / 2) / (z_m - z_ba))) / 2 between
    z' = w (1 - alpha(y) y / z_m(w))                       (Dupont et al. 2002, Eq. 11)
    tau_f = -(sigma_0 z + sigma_1 w max(0, 1 - alpha y / z_m) + sigma_2 w)

The bristle damping acts on z' = w (1 - alpha y / z_m) except where z exceeds z_m (the
Stribeck drop shrinks z_m as the speed grows), where it is cut off: the friction then
never delivers power, F w - d/dt (sigma_0 z^2 / 2) = sigma_0 alpha |z| |w| y / z_m
+ sigma_1 w^2 max(0, 1 - alpha y / z_m) + sigma_2 w^2 >= 0 (with a constant sigma_1 the
LuGre and elasto-plastic models can return energy there). At rest under a torque tau the
joint holds while tau < F_s: the displacement tau / sigma_0 for |tau| <= sigma_0 z_ba
(pre-sliding), plus a plastic part while loading between sigma_0 z_ba and F_s; the
quasi-static break-away torque is F_s (z reaches z_m(0)).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from .base import Effect, Parameter

_CACHE = True

#: offset of the effect's columns in FlexArmModel.joint_data: on, then PARAMETERS order
COLUMNS = ("ss_on", "ss_fv", "ss_fc", "ss_fs", "ss_ws", "ss_k", "ss_d", "ss_frac")
#: the columns by name, from inputs.JD_SS on: on, sigma_2, F_c, F_s, w_s, sigma_0, sigma_1,
#: elastic fraction (the kernels' p below)
SS_ON, SS_FV, SS_FC, SS_FS, SS_WS, SS_K, SS_D, SS_FRAC = range(8)


class StickSlipFriction(Effect):
    """Elasto-plastic stick-slip friction on the actuator coordinate (Dupont et al. 2002):
    true sticking below the break-away torque F_s with a pre-sliding displacement, Coulomb
    level F_c in sliding, Stribeck drop between, viscous sigma_2. Adds one state (the
    bristle deflection z, rad) to the integrated state of the arm."""

    TYPE = "stick_slip_friction"
    TARGET = "joint"
    DESCRIPTION = "stick-slip (elasto-plastic, pre-sliding) friction in the joint"
    PARAMETERS = (
        Parameter("viscous", "N m s/rad", 0.0, (0.0, 1e6), 0.3, "sigma_2"),
        Parameter("coulomb", "N m", 0.0, (0.0, 1e6), 0.3, "sliding level F_c"),
        Parameter("static", "N m", 0.0, (0.0, 1e6), 0.3, "break-away torque F_s >= F_c"),
        Parameter("stribeck_velocity", "rad/s", 0.01, (1e-6, 1e3), 0.5, "w_s"),
        Parameter("stiffness", "N m/rad", 1e4, (1e-3, 1e12), 0.5,
                  "pre-sliding (bristle) stiffness sigma_0; F_s / sigma_0 is the "
                  "displacement at break-away"),
        Parameter("damping", "N m s/rad", 0.0, (0.0, 1e9), 0.5,
                  "bristle damping sigma_1 (critical: 2 sqrt(sigma_0 J))"),
        Parameter("elastic_fraction", "-", 0.5, (0.0, 0.99), 0.3,
                  "z_ba sigma_0 / F_c: purely elastic (drift-free) share of the "
                  "pre-sliding range (Dupont's break-away displacement z_ba)"),
    )
    EQUIVALENT = ("joint_friction",
                  "viscous friction and DC-motor back-EMF damping (sliding)")
    LIBRARY = True   # a diagnosis hypothesis (flex_twin.diagnosis.hypotheses): the
    # replay carries the bristle states in x = [q; v; z]

    @property
    def is_off(self) -> bool:
        return self["viscous"] == 0.0 and self["coulomb"] == 0.0 and self["static"] == 0.0

    @classmethod
    def check(cls, f, values) -> None:
        fc, fs = values[1], values[2]
        if fs < fc:
            raise f.error("static", fs, f"a break-away torque >= coulomb ({fc} N m)")
        if fs > 0.0 and fc <= 0.0:
            raise f.error("coulomb", fc, "a sliding level > 0 (N m) with a break-away "
                          "torque (the bristles' sliding deflection F_c / sigma_0 must "
                          "stay > 0)")

    def kernel_data(self) -> np.ndarray:
        """The effect's row of FlexArmModel.joint_data (COLUMNS)."""
        return np.array([0.0 if self.is_off else 1.0, *self.values], float)

    # ------------------------------------------------------------ reference (numpy)
    def torque(self, z, w):
        """Friction torque on the actuator coordinate (N m) at bristle deflection z (rad)
        and speed w (rad/s); opposes the motion."""
        d = self.kernel_data()
        return np.vectorize(lambda zz, ww: -friction_magnitude(zz, ww, d))(z, w)

    def dissipation(self, z, w):
        """Power dissipated (W, >= 0): F w - d/dt (sigma_0 z^2 / 2)."""
        d = self.kernel_data()
        return np.vectorize(lambda zz, ww: dissipation_rate(zz, ww, d))(z, w)


# ---------------------------------------------------------------- compiled kernels
# p: a joint_data row slice in COLUMNS order: p[0] on, p[1] sigma_2, p[2] F_c, p[3] F_s,
# p[4] w_s, p[5] sigma_0, p[6] sigma_1, p[7] elastic fraction

@njit(cache=_CACHE)
def bristle_limits(w, p):
    """(z_m(w), z_ba): steady sliding deflection F_ss(w) / sigma_0 and the elastic limit."""
    g = p[2] + (p[3] - p[2]) * np.exp(-(w / p[4]) ** 2)
    return g / p[5], p[7] * p[2] / p[5]


@njit(cache=_CACHE)
def plastic_share(y, zm, zba):
    """alpha(y) y / z_m and alpha (Dupont et al. 2002, Eq. 12), y = sgn(w) z."""
    if y <= zba:
        return 0.0, 0.0
    if y >= zm:
        return y / zm, 1.0
    a = 0.5 + 0.5 * np.sin(np.pi * (y - 0.5 * (zm + zba)) / (zm - zba))
    return a * y / zm, a


@njit(cache=_CACHE)
def bristle_rate(z, w, p):
    """(z', r) with r = alpha y / z_m: z' = w (1 - r)."""
    if w == 0.0 or p[3] <= 0.0:
        return 0.0, 0.0
    zm, zba = bristle_limits(w, p)
    r, _ = plastic_share(z if w > 0.0 else -z, zm, zba)
    return w * (1.0 - r), r


@njit(cache=_CACHE)
def friction_magnitude(z, w, p):
    """F = sigma_0 z + sigma_1 w max(0, 1 - r) + sigma_2 w: the friction torque is -F."""
    _, r = bristle_rate(z, w, p)
    return p[5] * z + p[6] * w * max(0.0, 1.0 - r) + p[1] * w


@njit(cache=_CACHE)
def dissipation_rate(z, w, p):
    """F w - z' sigma_0 z (W): >= 0 for every (z, w)."""
    zd, r = bristle_rate(z, w, p)
    return friction_magnitude(z, w, p) * w - p[5] * z * zd


@njit(cache=_CACHE)
def bristle_step(z0, d, w1, p):
    """Backward Euler over a fixed step h: the bristle deflection z1 for the increment
    d = h w (rad), z_m at the speed w1 (the integrators pass the step's start speed),
    and dz1/dd in [0, 1].

    With s = sgn(d), y = s z: y1 = y0 + |d| (1 - alpha(y1) y1 / z_m(w1)); the residual is
    increasing in y1 on [z_ba, y0 + |d|], where its root lies (elastic below z_ba)."""
    if p[3] <= 0.0:
        return z0, 0.0
    if d == 0.0:
        return z0, 1.0
    s = 1.0 if d > 0.0 else -1.0
    dd = abs(d)
    y0 = s * z0
    hi = y0 + dd
    zm, zba = bristle_limits(w1, p)
    if hi <= zba:
        return z0 + d, 1.0
    lo = zba
    y = hi
    if hi >= zm:  # start from the root of the fully plastic branch when it is in range
        y = max(lo, min(hi, hi / (1.0 + dd / zm)))
    fp = 1.0
    r = 0.0
    for _ in range(100):
        r, a = plastic_share(y, zm, zba)
        f = y - y0 - dd * (1.0 - r)
        da = 0.0
        if zba < y < zm:
            c = np.pi / (zm - zba)
            da = 0.5 * c * np.cos(c * (y - 0.5 * (zm + zba)))
        fp = 1.0 + dd * (a + da * y) / zm
        if f > 0.0:
            hi = y
        else:
            lo = y
        y_new = y - f / fp
        if not lo <= y_new <= hi:
            y_new = 0.5 * (lo + hi)
        if abs(y_new - y) <= 1e-15 * zm or hi - lo <= 1e-15 * zm:
            y = y_new
            break
        y = y_new
    r, a = plastic_share(y, zm, zba)
    g = (1.0 - r) / fp
    return s * y, min(max(g, 0.0), 1.0)
