"""Effects: named, switchable components of a model ("nominal arm + a list of effects").

Each effect type declares its parameters (unit, "off" value, physical bounds, typical
manufacturing tolerance), what it attaches to (a joint, a link or the whole arm) and its
equivalence class: the effects it cannot be told apart from with common sensors (motor
encoder, link encoder, tip sensor). The diagnosis workflow uses the same declarations as
its hypotheses.
"""
from __future__ import annotations

from dataclasses import dataclass

from ..config import Fields


@dataclass(frozen=True)
class Parameter:
    """A parameter of an effect, SI units; ``tolerance`` is relative (0.05 = 5 %)."""

    name: str
    unit: str
    off: float
    bounds: tuple
    tolerance: float
    description: str = ""


#: Typical manufacturing tolerances (relative) of the nominal arm's parameters.
NOMINAL_TOLERANCES = {
    "E": 0.05,            # Young's modulus of structural metals
    "rho": 0.02,          # density
    "section": 0.03,      # cross-section dimensions (thin walls: a few %)
    "end_masses": 0.02,   # M-, M+, J-, J+
    "payload": 0.01,
    "internal_friction": 0.5,
}


@dataclass(frozen=True)
class Effect:
    """Base of all effects; subclasses set the class attributes below."""

    TYPE = ""
    TARGET = "arm"            # "joint", "link" or "arm"
    PARAMETERS = ()
    EQUIVALENT = ()           # effect types (or nominal parameters) it is confused with
    DESCRIPTION = ""
    LIBRARY = True            # a hypothesis of the diagnosis library

    target: str               # joint or link name ("" for the arm)
    values: tuple             # parameter values in PARAMETERS order

    def __getitem__(self, name: str) -> float:
        for p, v in zip(self.PARAMETERS, self.values):
            if p.name == name:
                return v
        raise KeyError(name)

    @property
    def is_off(self) -> bool:
        return all(v == p.off for p, v in zip(self.PARAMETERS, self.values))

    @classmethod
    def parse(cls, f: Fields, joint_names, link_names) -> "Effect":
        """Read the parameters (defaults: the "off" values) from a YAML mapping."""
        f.raw("type")
        target = ""
        if cls.TARGET in ("joint", "link"):
            names = joint_names if cls.TARGET == "joint" else link_names
            target = f.string(cls.TARGET, choices=list(names))
        values = []
        for p in cls.PARAMETERS:
            lo, hi = p.bounds
            if not f.has(p.name):  # the "off" value (may be infinite, e.g. a rigid joint)
                values.append(p.off)
                continue
            values.append(f.number(p.name, min_value=lo, max_value=hi, unit=p.unit))
        cls.check(f, values)
        f.done()
        return cls(target=target, values=tuple(values))

    @classmethod
    def check(cls, f: Fields, values) -> None:
        """Extra validation of a combination of values (override)."""

    @classmethod
    def describe(cls) -> dict:
        return {"type": cls.TYPE, "target": cls.TARGET, "description": cls.DESCRIPTION,
                "equivalent": list(cls.EQUIVALENT),
                "parameters": [{"name": p.name, "unit": p.unit, "off": p.off,
                                "bounds": list(p.bounds), "tolerance": p.tolerance,
                                "description": p.description} for p in cls.PARAMETERS]}
