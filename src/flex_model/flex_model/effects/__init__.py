"""Effect registry: parse the ``effects:`` list of an arm description."""
from __future__ import annotations

from ..config import Fields
from .base import NOMINAL_TOLERANCES, Effect, Parameter
from .base_tilt import BaseTilt
from .contact import ContactSurface
from .delay import ActuatorDelay
from .friction import JointFriction
from .gear import Gear
from .joint_elasticity import Backlash, JointElasticity
from .motor import Cogging, DCMotor
from .saturation import TorqueSaturation
from .stick_slip import StickSlipFriction
from .structural_damping import StructuralDamping
from .timoshenko import Timoshenko, slenderness

EFFECT_TYPES = {cls.TYPE: cls for cls in (Gear, JointElasticity, Backlash, JointFriction,
                                          DCMotor, Cogging, StructuralDamping, BaseTilt,
                                          TorqueSaturation, ContactSurface, ActuatorDelay,
                                          Timoshenko, StickSlipFriction)}

__all__ = ["EFFECT_TYPES", "NOMINAL_TOLERANCES", "Effect", "Parameter", "parse_effects",
           "ActuatorDelay", "Backlash", "BaseTilt", "Cogging", "ContactSurface", "DCMotor", "Gear",
           "JointElasticity", "JointFriction", "StickSlipFriction", "StructuralDamping",
           "Timoshenko", "TorqueSaturation", "slenderness"]


def parse_effects(items: list, source: str, joint_names, link_names) -> tuple:
    """Validate the effects of an arm description; one effect per type and target."""
    effects = []
    seen = set()
    for k, raw in enumerate(items):
        f = Fields(raw, source, f"effects[{k}]")
        kind = f.string("type", choices=sorted(EFFECT_TYPES))
        eff = EFFECT_TYPES[kind].parse(f, joint_names, link_names)
        key = (kind, eff.target)
        if key in seen:
            raise f.error("type", kind, f"at most one {kind} effect per "
                          f"{EFFECT_TYPES[kind].TARGET}")
        seen.add(key)
        effects.append(eff)
    for k, eff in enumerate(effects):
        if eff.TYPE == "backlash" and ("joint_elasticity", eff.target) not in seen:
            raise Fields(items[k], source, f"effects[{k}]").error(
                "type", "backlash", f"a joint_elasticity effect on {eff.target} as well "
                "(backlash is a dead zone of the joint spring)")
        if eff.TYPE == "stick_slip_friction" and ("joint_friction", eff.target) in seen:
            raise Fields(items[k], source, f"effects[{k}]").error(
                "type", "stick_slip_friction", f"no joint_friction effect on {eff.target} "
                "as well (two friction models of one joint; stick_slip_friction has its "
                "own viscous, Coulomb and Stribeck terms)")
    return tuple(effects)
