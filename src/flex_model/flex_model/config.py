"""Validation helpers for declarative YAML files (arm descriptions, scenarios, parameters).

Every error names the file, the field path, the value received and what is allowed.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml


class ConfigError(ValueError):
    """A configuration value is missing, unknown, of the wrong type or out of range."""

    def __init__(self, source: str, path: str, value, allowed: str):
        self.source, self.path, self.value, self.allowed = source, path, value, allowed
        shown = "<missing>" if value is MISSING else repr(value)
        super().__init__(f"{source}: {path}: got {shown}; expected {allowed}")


class _Missing:
    def __repr__(self):
        return "<missing>"


MISSING = _Missing()


def read_yaml(path) -> dict:
    """Read a YAML mapping; errors name the file."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ConfigError(str(path), "<file>", str(path), f"a readable file ({exc.strerror})")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(str(path), "<file>", "<unparsable>", f"valid YAML ({exc})")
    if not isinstance(data, dict):
        raise ConfigError(str(path), "<root>", type(data).__name__, "a mapping of fields")
    return data


class Fields:
    """Reads the fields of one mapping, tracking its path; rejects unknown keys at the end."""

    def __init__(self, data, source: str, path: str):
        if not isinstance(data, dict):
            raise ConfigError(source, path or "<root>", data, "a mapping of fields")
        self.data, self.source, self.path = data, source, path
        self.used: set[str] = set()

    def sub(self, key: str) -> str:
        return f"{self.path}.{key}" if self.path else key

    def error(self, key: str, value, allowed: str) -> ConfigError:
        return ConfigError(self.source, self.sub(key), value, allowed)

    def raw(self, key: str, default=MISSING):
        self.used.add(key)
        if key not in self.data:
            if default is MISSING:
                raise self.error(key, MISSING, "this required field")
            return default
        return self.data[key]

    def has(self, key: str) -> bool:
        return key in self.data

    def number(self, key: str, default=MISSING, *, min_value=None, max_value=None,
               positive=False, nonnegative=False, unit: str = "") -> float:
        value = self.raw(key, default)
        return check_number(value, self.source, self.sub(key), min_value=min_value,
                            max_value=max_value, positive=positive, nonnegative=nonnegative,
                            unit=unit)

    def integer(self, key: str, default=MISSING, *, min_value=None, max_value=None,
                even=False) -> int:
        value = self.raw(key, default)
        what = "an integer"
        if min_value is not None:
            what += f" >= {min_value}"
        if max_value is not None:
            what += f" <= {max_value}"
        if even:
            what = "an even " + what[3:]
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, value, what)
        if ((min_value is not None and value < min_value)
                or (max_value is not None and value > max_value) or (even and value % 2)):
            raise self.error(key, value, what)
        return value

    def string(self, key: str, default=MISSING, *, choices=None) -> str:
        value = self.raw(key, default)
        if not isinstance(value, str):
            raise self.error(key, value, "a string" if not choices else f"one of {choices}")
        if choices is not None and value not in choices:
            raise self.error(key, value, f"one of {', '.join(choices)}")
        return value

    def boolean(self, key: str, default=MISSING) -> bool:
        value = self.raw(key, default)
        if not isinstance(value, bool):
            raise self.error(key, value, "true or false")
        return value

    def vector(self, key: str, length: int | None = None, default=MISSING,
               unit: str = "") -> list[float]:
        value = self.raw(key, default)
        want = f"a list of {length} numbers" if length else "a list of numbers"
        if unit:
            want += f" ({unit})"
        if not isinstance(value, (list, tuple)) or (length is not None and len(value) != length):
            raise self.error(key, value, want)
        return [check_number(v, self.source, f"{self.sub(key)}[{i}]", unit=unit)
                for i, v in enumerate(value)]

    def joint_vector(self, key: str, length: int, default=MISSING, *,
                     all_revolute: bool = True) -> np.ndarray:
        """Joint values in SI (rad, or m on prismatic joints) from ``key``, or in degrees from
        ``key + '_deg'`` (the user's edge; every joint revolute): one convention for set-points
        and initial angles in every scenario format. Both given is refused."""
        deg = key + "_deg"
        self.used.update((key, deg))
        if self.has(key) and self.has(deg):
            raise self.error(deg, self.data[deg], f"'{key}' (rad) or '{deg}', not both")
        if self.has(deg):
            if not all_revolute:
                raise self.error(deg, self.data[deg], f"'{key}' in rad or m (a prismatic "
                                 "joint has no degrees)")
            return np.radians(self.vector(deg, length, unit="deg"))
        return np.array(self.vector(key, length, default, unit="rad or m"), float)

    def mapping(self, key: str, default=MISSING) -> "Fields":
        value = self.raw(key, default)
        return Fields(value, self.source, self.sub(key))

    def items(self, key: str, default=MISSING, *, min_len=0) -> list:
        value = self.raw(key, default)
        if not isinstance(value, list) or len(value) < min_len:
            raise self.error(key, value, f"a list with at least {min_len} entries")
        return value

    def done(self, allowed: list[str] | None = None):
        """Raise on keys that were never read (unknown fields)."""
        for key in self.data:
            if key not in self.used:
                names = ", ".join(sorted(allowed if allowed is not None else self.used))
                raise self.error(str(key), self.data[key], f"no such field (known: {names})")


def check_number(value, source, path, *, min_value=None, max_value=None, positive=False,
                 nonnegative=False, unit="") -> float:
    what = "a finite number"
    if positive:
        what = "a number > 0"
    elif nonnegative:
        what = "a number >= 0"
    if min_value is not None:
        what += f", >= {min_value}"
    if max_value is not None:
        what += f", <= {max_value}"
    if unit:
        what += f" ({unit})"
    if isinstance(value, str):
        # YAML 1.1 reads exponents without a dot or sign ("6.4e10") as strings
        try:
            value = float(value.strip())
        except ValueError:
            raise ConfigError(source, path, value, what) from None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(source, path, value, what)
    value = float(value)
    if (not math.isfinite(value) or (positive and value <= 0) or (nonnegative and value < 0)
            or (min_value is not None and value < min_value)
            or (max_value is not None and value > max_value)):
        raise ConfigError(source, path, value, what)
    return value
