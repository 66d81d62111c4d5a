"""Parameters of the controller node: one frozen dataclass, validated on construction.

The node declares one ROS parameter per field (name, default, description and range from
the field's metadata) and builds the controller with :func:`build_controller`; nothing here
imports ROS, so the same parameters can be checked and used from Python and tests.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

from flex_model.trajectory import JointTrajectoryData

from .gain_schedule import GainSchedule
from .laws import DecentralizedPD, PDLikeCascade, hold_reference, torque_limit_vector

LAWS = ("eq95", "eq45")
STALE_ACTIONS = ("zero", "hold")


def _doc(text: str, low: float | None = None, high: float | None = None) -> dict:
    return {"doc": text, "range": None if low is None else (low, high)}


@dataclass(frozen=True)
class ControllerParams:
    """Controller node parameters (SI units)."""

    joint_names: tuple = field(default=("joint1", "joint2"), metadata=_doc(
        "joints in command order (the effort controller's order)"))
    law: str = field(default="eq95", metadata=_doc(
        "eq95: thesis PD h(a^2 e + sqrt(2) a e_dot) + nominal torque; eq45: seed 000 cascade"))
    h: tuple = field(default=(25.0,), metadata=_doc(
        "Eq. (95) h per joint (or one value), kg m^2; ignored with schedule_file"))
    a: tuple = field(default=(5.0,), metadata=_doc(
        "Eq. (95) a per joint (or one value), rad/s; ignored with schedule_file"))
    schedule_file: str = field(default="", metadata=_doc(
        "gain schedule YAML (flex-twin control design); empty: constant h, a"))
    feedforward: bool = field(default=True, metadata=_doc(
        "Eq. (95): add the trajectory's effort (nominal torque)"))
    kpp: float = field(default=70.0, metadata=_doc("Eq. (45) K_pp, 1/s", 1e-6, 1e6))
    kpv: float = field(default=50.0, metadata=_doc("Eq. (45) K_pv, N m s/rad", 1e-9, 1e9))
    gear_ratio: float = field(default=50.0, metadata=_doc("Eq. (45) gear ratio n", 1e-3, 1e4))
    torque_limits: tuple = field(default=(100.0,), metadata=_doc(
        "|tau| limit per joint (or one value), N m; commands are clamped to it"))
    rate_hz: float = field(default=500.0, metadata=_doc("control rate, Hz", 1.0, 20000.0))
    state_timeout: float = field(default=0.1, metadata=_doc(
        "joint states older than this (s) are stale", 1e-3, 60.0))
    stale_action: str = field(default="zero", metadata=_doc(
        "on stale joint states: zero torques, or hold the last command"))
    use_deflections: bool = field(default=False, metadata=_doc(
        "subscribe flex/deflections (link tip deflections, m) for the gain schedule"))

    def __post_init__(self):
        names = tuple(str(n) for n in self.joint_names)
        if not names or len(set(names)) != len(names) or not all(names):
            raise ValueError(f"joint_names: got {list(self.joint_names)}; expected unique, "
                             "non-empty joint names")
        object.__setattr__(self, "joint_names", names)
        if self.law not in LAWS:
            raise ValueError(f"law: got {self.law!r}; expected one of {', '.join(LAWS)}")
        if self.stale_action not in STALE_ACTIONS:
            raise ValueError(f"stale_action: got {self.stale_action!r}; expected one of "
                             f"{', '.join(STALE_ACTIONS)}")
        n = len(names)
        for name in ("h", "a"):
            v = tuple(float(x) for x in getattr(self, name))
            if len(v) not in (1, n) or not all(math.isfinite(x) and x > 0 for x in v):
                raise ValueError(f"{name}: got {list(v)}; expected 1 or {n} finite gains > 0")
            object.__setattr__(self, name, v)
        lim = tuple(float(x) for x in self.torque_limits)
        torque_limit_vector(lim, n)   # raises with the field name
        object.__setattr__(self, "torque_limits", lim)
        for f in fields(self):
            rng = f.metadata.get("range")
            value = getattr(self, f.name)
            if rng is not None and not (math.isfinite(value) and rng[0] <= value <= rng[1]):
                raise ValueError(f"{f.name}: got {value!r}; expected a number in "
                                 f"[{rng[0]:g}, {rng[1]:g}]")

    @classmethod
    def from_mapping(cls, values: dict) -> "ControllerParams":
        """From a mapping of field names to values; unknown names are an error."""
        known = {f.name for f in fields(cls)}
        for key in values:
            if key not in known:
                raise ValueError(f"{key}: got an unknown parameter; expected one of "
                                 f"{', '.join(sorted(known))}")
        return cls(**values)


def build_controller(params: ControllerParams, reference: JointTrajectoryData | None = None,
                     hold_positions=None):
    """The controller of ``params`` tracking ``reference`` (default: hold
    ``hold_positions``, zero if not given)."""
    names = list(params.joint_names)
    if reference is None:
        reference = hold_reference(names, hold_positions if hold_positions is not None
                                   else [0.0] * len(names))
    if params.law == "eq45":
        return PDLikeCascade(reference, kpp=params.kpp, kpv=params.kpv,
                             gear_ratio=params.gear_ratio, torque_limits=params.torque_limits)
    schedule = GainSchedule.load(params.schedule_file) if params.schedule_file else None
    return DecentralizedPD(reference, h=params.h, a=params.a, schedule=schedule,
                           feedforward=params.feedforward, torque_limits=params.torque_limits)
