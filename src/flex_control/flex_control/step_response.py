"""Seed 000's simulations (VALIDATION.md section G): the Eq. (45) cascade on a geared
single flexible link, a step of the motor position command from 10 to 30 deg.

Model: the preset arm (``seed000_real_arm``: Table 1; ``seed000_table3``: Table 3) with the
rotor inertia reflected through the gear, ``n^2 I_r`` (seed 000 Eq. 35), as the link's root
end inertia ``J-`` (the rotor turns rigidly with the root of link 1). The arms move in a
horizontal plane: seed 000's ruler droops along its stiff axis (EI_x = 248 N m^2, "almost no
deformation") while the motion and the vibration are about the vertical axis z, so gravity
does not act in the plane of motion (the presets have gravity off). The link's damping
"coefficient xi_1" (0.0005 for Table 1, 0.1 for Table 3) is read as the damping ratio of
its first clamped mode and realized with the internal friction ``k_a`` of thesis Eq. (35).

The joint law is Eq. (45) in continuous time, as in the seed's MATLAB runs: at the joint a
PD with ``kp = n^2 K_pv K_pp``, ``kd = n^2 K_pv`` (:class:`flex_control.laws.PDLikeCascade`
gives the same torques; a test checks it as a sampled policy). Its velocity loop has the
bandwidth ``K_pv / I_r = 25 000 rad/s``, so a digital implementation must run faster than
``2 I_r / K_pv = 80 us`` per cycle (:func:`max_stable_period`).

Reported: rise time (10-90 %) and overshoot of the joint angle and of the tip angle
``atan2(y, x)``, and the residual oscillation of the tip deflection ``w`` (normal to the
root tangent) after the joint has settled: frequency from its zero crossings, amplitude as
half the peak-to-peak over its first period.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from flex_model.arm import ArmDescription, load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from flex_model.simulate import JointPD, simulate

GEAR_RATIO = 50.0       # seed 000, "in all simulations, the gear ratio is set to 50"
ROTOR_INERTIA = 0.002   # kg m^2, I_r1 (seed 000 Section 5 and Table 3)
KPP = 70.0              # 1/s, Eq. (45)
KPV = 50.0              # N m s/rad (motor side), Eq. (45)

#: seed 000's link damping coefficients xi_1 (text of Section 5.1; Table 3)
SEED_DAMPING = {"seed000_real_arm": 0.0005, "seed000_table3": 0.1}
#: seed 000's reported figures (Tables 2 and 4; VALIDATION.md section G)
PAPER = {"seed000_real_arm": {"frequency_hz_simulation": 8.4745, "frequency_hz_measured": 8.24,
                              "frequency_hz_euler_bernoulli": 8.46},
         "seed000_table3": {"frequency_hz_assumed_modes": 0.7937,
                            "frequency_hz_lumped": 0.813, "frequency_hz_exact": 0.824,
                            "amplitude_m_assumed_modes": 0.1462,
                            "amplitude_m_lumped": 0.2032}}


def geared_arm(preset: str | ArmDescription = "seed000_real_arm",
               gear_ratio: float = GEAR_RATIO, rotor_inertia: float = ROTOR_INERTIA,
               vars_per_link: int | None = None) -> ArmDescription:
    """The single-link arm with ``n^2 I_r`` added to link 1's root inertia ``J-``."""
    arm = load_arm(preset, vars_per_link) if isinstance(preset, str) else preset
    if not (gear_ratio > 0 and rotor_inertia >= 0):
        raise ValueError(f"gear_ratio, rotor_inertia: got {gear_ratio!r}, {rotor_inertia!r};"
                         " expected n > 0 and I_r >= 0 kg m^2")
    first = dataclasses.replace(arm.links[0],
                                J_minus=arm.links[0].J_minus + gear_ratio ** 2 * rotor_inertia)
    return dataclasses.replace(arm, links=(first,) + tuple(arm.links[1:]))


def first_mode_damping(arm: ArmDescription) -> float:
    """Damping ratio of the first clamped mode of the arm."""
    return float(natural_modes(FlexArmModel(arm), joints="clamped").damping_ratio[0])


def with_link_damping(arm: ArmDescription, zeta: float) -> ArmDescription:
    """The arm with the internal friction ``k_a`` (equal on all links) that gives its first
    clamped mode the damping ratio ``zeta`` (secant iterations; ``zeta = 0``: none)."""
    if not 0 <= zeta < 1:
        raise ValueError(f"damping_ratio: got {zeta!r}; expected 0 <= zeta < 1")

    def arm_with(k_a):
        links = tuple(dataclasses.replace(lk, internal_friction=k_a) for lk in arm.links)
        return dataclasses.replace(arm, links=links)

    if zeta == 0:
        return arm_with(0.0)
    k1 = 1e-3
    z1 = first_mode_damping(arm_with(k1))
    k = k1 * zeta / z1
    for _ in range(20):
        z = first_mode_damping(arm_with(k))
        if abs(z - zeta) < 1e-6 * zeta:
            break
        k, k1, z1 = k + (zeta - z) * (k - k1) / (z - z1), k, z
    return arm_with(k)


def max_stable_period(kpv: float = KPV, rotor_inertia: float = ROTOR_INERTIA) -> float:
    """Longest sample period (s) of a zero-order-hold Eq. (45) velocity loop on the rotor
    inertia (forward-Euler bound ``K_pv T / I_r < 2``)."""
    return 2.0 * rotor_inertia / kpv


def rise_and_overshoot(t, y, y0: float, y1: float) -> tuple[float, float]:
    """10-90 % rise time (s, linear interpolation) and overshoot (% of the step)."""
    t = np.asarray(t, float)
    s = (np.asarray(y, float) - y0) / (y1 - y0)

    def crossing(level):
        k = int(np.argmax(s >= level))
        if s[k] < level:
            return np.nan
        if k == 0:
            return float(t[0])
        return float(t[k - 1] + (level - s[k - 1]) * (t[k] - t[k - 1]) / (s[k] - s[k - 1]))

    return crossing(0.9) - crossing(0.1), float(100.0 * max(0.0, np.max(s) - 1.0))


def residual_oscillation(t, w, t_from: float) -> tuple[float, float]:
    """Frequency (Hz, mean spacing of upward zero crossings of ``w`` after ``t_from``) and
    amplitude (half peak-to-peak over the first period after ``t_from``)."""
    t = np.asarray(t, float)
    w = np.asarray(w, float)
    sel = t >= t_from
    ts, ws = t[sel], w[sel]
    up = np.flatnonzero((ws[:-1] < 0) & (ws[1:] >= 0))
    if len(up) < 2:
        return float("nan"), float("nan")
    tc = ts[up] - ws[up] * (ts[up + 1] - ts[up]) / (ws[up + 1] - ws[up])
    freq = (len(tc) - 1) / (tc[-1] - tc[0])
    first = (ts >= tc[0]) & (ts <= tc[1])
    return float(freq), float(0.5 * (ws[first].max() - ws[first].min()))


@dataclass
class StepResponse:
    """A simulated step of Eq. (45) and its figures (SI units)."""

    arm: str
    t: np.ndarray
    joint_angle: np.ndarray
    tip_angle: np.ndarray
    tip_deflection: np.ndarray
    torque: np.ndarray
    start: float
    end: float
    damping_ratio: float
    joint_rise_time: float
    joint_overshoot_pct: float
    tip_rise_time: float
    tip_overshoot_pct: float
    settle_time: float
    tip_frequency_hz: float
    tip_amplitude_m: float
    clamped_frequency_hz: float

    def as_dict(self) -> dict:
        out = {"arm": self.arm, "step_deg": [float(np.degrees(self.start)),
                                             float(np.degrees(self.end))],
               "link_damping_ratio": self.damping_ratio,
               "joint_rise_time_s": self.joint_rise_time,
               "joint_overshoot_pct": self.joint_overshoot_pct,
               "tip_rise_time_s": self.tip_rise_time,
               "tip_overshoot_pct": self.tip_overshoot_pct,
               "joint_settled_at_s": self.settle_time,
               "tip_frequency_hz": self.tip_frequency_hz,
               "tip_amplitude_m": self.tip_amplitude_m,
               "clamped_first_frequency_hz": self.clamped_frequency_hz,
               "max_joint_torque_n_m": float(np.max(np.abs(self.torque)))}
        out["paper"] = PAPER.get(self.arm, {})
        return out


def step_response(preset: str | ArmDescription = "seed000_real_arm", *,
                  start_deg: float = 10.0,
                  end_deg: float = 30.0, kpp: float = KPP, kpv: float = KPV,
                  gear_ratio: float = GEAR_RATIO, rotor_inertia: float = ROTOR_INERTIA,
                  damping_ratio: float | None = None, t_final: float | None = None,
                  step: float = 1e-4, sample_period: float = 5e-4) -> StepResponse:
    """Simulate the step ``start_deg -> end_deg`` of the joint (motor command / n) under
    Eq. (45) from rest, undeformed (seed 000 Section 5); ``damping_ratio`` defaults to the
    seed's value for the preset (0 for others). ``preset`` may be an arm description (e.g.
    the preset with another link discretization); its name selects the seed's values."""
    name = preset if isinstance(preset, str) else preset.name
    zeta = SEED_DAMPING.get(name, 0.0) if damping_ratio is None else damping_ratio
    arm = with_link_damping(geared_arm(preset, gear_ratio, rotor_inertia), zeta)
    model = FlexArmModel(arm)
    f_clamped = float(natural_modes(model, joints="clamped").frequencies_hz[0])
    if t_final is None:
        t_final = max(1.0, 6.0 / f_clamped)
    th0, th1 = np.radians(start_deg), np.radians(end_deg)
    n2 = gear_ratio ** 2
    pd = JointPD(kp=np.array([n2 * kpv * kpp]), kd=np.array([n2 * kpv]),
                 setpoints=np.array([th1]))
    res = simulate(model, model.q_from_joint_angles([th0]), t_final=t_final,
                   sample_period=sample_period, pd=pd, method="fixed", dt=step)
    theta = res.joint_angles[:, 0]
    tip = res.tip_positions
    tip_angle = np.unwrap(np.arctan2(tip[:, 1], tip[:, 0]))
    w = res.tip_deflections[:, 0]
    rise_j, over_j = rise_and_overshoot(res.t, theta, th0, th1)
    rise_t, over_t = rise_and_overshoot(res.t, tip_angle, th0, th1)
    off = np.abs(theta - th1) > 0.02 * abs(th1 - th0)
    settle = float(res.t[np.flatnonzero(off)[-1] + 1]) if off.any() and not off[-1] \
        else float(res.t[-1])
    freq, amp = residual_oscillation(res.t, w, settle)
    return StepResponse(arm=name, t=res.t, joint_angle=theta, tip_angle=tip_angle,
                        tip_deflection=w, torque=res.tau[:, 0], start=th0, end=th1,
                        damping_ratio=zeta, joint_rise_time=rise_j, joint_overshoot_pct=over_j,
                        tip_rise_time=rise_t, tip_overshoot_pct=over_t, settle_time=settle,
                        tip_frequency_hz=freq, tip_amplitude_m=amp,
                        clamped_frequency_hz=f_clamped)
