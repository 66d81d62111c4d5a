"""The two-mass bench as a twin: its parameters and the arm description (the FRF
identification is studies/two_mass_data.py's).

Two-inertia model (seed 002 Eqs. 11-14 with a rigid link; Pintelon & Schoukens' 4th-order
continuous-time model of the FdiTools example), torque tau = K_t i on the motor:

    J_m th_m'' = K_t i - k (th_m - th_l) - c (th_m' - th_l') - b_m th_m'
    J_l th_l'' =         k (th_m - th_l) + c (th_m' - th_l')

Anti-resonance (motor side) sqrt(k / J_l), resonance sqrt(k (J_m + J_l) / (J_m J_l)); the
mass lines give K_t / (J_m + J_l) (low) and K_t / J_m (high). K_t is not observable from
the angles: it is FIXED at 1 N m/A (``TORQUE_CONSTANT``), so every inertia, stiffness and
damping here is "per N m/A of K_t" (all scale with the true K_t). Friction sits on the motor
side only (``joint_friction`` acts on the motor coordinate of an elastic joint); the fit
with a load-side viscous term as well is reported as what the twin lacks.

In the library: ``joint_elasticity`` (k, c, motor_inertia J_m) on a short, very stiff link
with root inertia ``J_minus`` = J_l (first bending mode above 5 kHz, as the
``quanser_cuboulder_rigid`` preset's bar); the rigid nominal twin has the coupling rigid and
J_m as a ``gear`` rotor (ratio 1), the inertias summed on one coordinate.
"""
from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

#: N m/A, fixed (not observable from speed): every fitted value scales with it
TORQUE_CONSTANT = 1.0
#: the rigid end body: a short, very stiff, light link (first bending mode ~5.6 kHz)
LINK_LENGTH, LINK_EI, LINK_MASS_PER_LENGTH = 0.1, 100.0, 0.01
LINK_OWN_INERTIA = LINK_MASS_PER_LENGTH * LINK_LENGTH ** 3 / 3.0


@dataclass(frozen=True)
class TwoMassParameters:
    """SI: inertias kg m^2, k N m/rad, c and b N m s/rad, delay s (K_t = TORQUE_CONSTANT)."""

    J_m: float
    J_l: float
    k: float
    c: float
    b_m: float
    b_l: float = 0.0
    delay: float = 0.0

    @property
    def anti_resonance_hz(self) -> float:
        return float(np.sqrt(self.k / self.J_l) / (2 * np.pi))

    @property
    def resonance_hz(self) -> float:
        return float(np.sqrt(self.k * (self.J_m + self.J_l) / (self.J_m * self.J_l))
                     / (2 * np.pi))

    @property
    def damping_ratio(self) -> float:
        """Coupling damping ratio of the resonance, c / (2 sqrt(k J_m J_l / (J_m + J_l)))."""
        return float(self.c / (2 * np.sqrt(self.k * self.J_m * self.J_l / (self.J_m + self.J_l))))

    def as_dict(self) -> dict:
        return {**asdict(self), "K_t": TORQUE_CONSTANT, "anti_resonance_hz":
                self.anti_resonance_hz, "resonance_hz": self.resonance_hz,
                "damping_ratio": self.damping_ratio}


def arm_dict(p: TwoMassParameters, elastic: bool = True, name: str = "two_mass_bench") -> dict:
    """The arm description (``flex_model.arm.arm_from_dict``) of the twin: elastic (the
    coupling as ``joint_elasticity``) or the rigid nominal (coupling rigid, J_m a ``gear``
    rotor of ratio 1); viscous friction ``b_m`` on the motor coordinate."""
    effects = []
    if elastic:
        effects.append({"type": "joint_elasticity", "joint": "coupling",
                        "stiffness": float(p.k), "damping": float(p.c),
                        "motor_inertia": float(p.J_m)})
    else:
        effects.append({"type": "gear", "joint": "coupling", "ratio": 1.0,
                        "rotor_inertia": float(p.J_m)})
    if p.b_m > 0:
        # every field written: the diagnosis rescales the nominal effects' fields by name
        effects.append({"type": "joint_friction", "joint": "coupling", "viscous": float(p.b_m),
                        "coulomb": 0.0, "static": 0.0, "stribeck_velocity": 0.01,
                        "regularization": 1e-6})
    return {"name": name if elastic else f"{name}_rigid",
            "description": "FdiTools two-mass motor bench, K_t fixed at 1 N m/A" +
                           ("" if elastic else ", coupling rigid (nominal)"),
            "gravity": [0.0, 0.0],
            "links": [{"name": "load", "length": LINK_LENGTH,
                       "section": {"shape": "explicit", "EI": LINK_EI,
                                   "m": LINK_MASS_PER_LENGTH},
                       "variables": 2,
                       "end_masses": {"J_minus": float(p.J_l - LINK_OWN_INERTIA)}}],
            "joints": [{"name": "coupling"}],
            "effects": effects}


def parameters_from_arm(arm) -> TwoMassParameters:
    """Read (J_m, J_l, k, c, b_m) back from a two-mass arm (preset or diagnosed)."""
    j = arm.joint_names[0]
    el, gear, fr = (arm.effect(k, j) for k in ("joint_elasticity", "gear", "joint_friction"))
    jm = (gear["ratio"] ** 2 * gear["rotor_inertia"] if gear else 0.0)
    k, c = float("inf"), 0.0
    if el is not None and not el.is_off:
        jm += el["motor_inertia"]
        k, c = el["stiffness"], el["damping"]
    return TwoMassParameters(J_m=float(jm), J_l=float(arm.links[0].J_minus + LINK_OWN_INERTIA),
                             k=float(k), c=float(c), b_m=float(fr["viscous"]) if fr else 0.0)
