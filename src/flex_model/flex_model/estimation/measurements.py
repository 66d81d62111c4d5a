"""What the filter measures: one scalar reading per Measurement, with its noise, delay and
quantization (the sensor model of flex_model.sensors, y = Q(h(x(t - delay)) + noise)).

Kinds and ``index``: ``joint_angle``, ``joint_rate``, ``motor_angle`` (joint index; motor
angle = gear ratio x actuator coordinate), ``tip_deflection`` (link index; planar: the
deflection delta_n, spatial: ``component`` 0 = v, 1 = w, 2 = twist), ``strain`` (link index,
``position`` m from the root, ``surface_distance`` m; planar), ``tip_acceleration``
(``component`` 0/1 of the tip-frame specific force; planar), ``tip_position`` (``component``
0/1/2 = x/y/z, base frame).
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

KINDS = ("joint_angle", "joint_rate", "motor_angle", "tip_deflection", "strain",
         "tip_acceleration", "tip_position")
#: the default reading std of each kind (SI: rad, rad/s, m, m/s^2) where neither the user
#: nor the arm file's sensor gives one: ``flex-twin estimate`` and the observer node alike
#: (one table; the joint angle's 1 mrad is the observer's, whose test feeds 1 mrad noise)
DEFAULT_STD = {"joint_angle": 1e-3, "joint_rate": 1e-2, "motor_angle": 1e-3,
               "tip_deflection": 5e-4, "strain": 1e-5, "tip_acceleration": 0.1,
               "tip_position": 1e-3}
#: kinds read by the planar / spatial plant
PLANAR_KINDS = KINDS
SPATIAL_KINDS = ("joint_angle", "joint_rate", "motor_angle", "tip_deflection",
                 "tip_position")
#: the name of an indexed measurement (recording channels, ``flex-twin estimate --measure``,
#: the observer node): q<i>, v<i>, m<i> joint i's angle, rate, motor angle, w<i> link i's
#: tip deflection (spatial: w<i>y, w<i>z, w<i>t); groups prefix, index (1-based; empty:
#: every joint), suffix
NAME_PATTERN = re.compile(r"([qvmw])(\d*)([yzt]?)$")


@dataclass(frozen=True)
class Measurement:
    """One scalar sensor reading: std (its unit), delay (s), quantum (the resolution:
    adds quantum^2 / 12 to the variance)."""

    name: str
    kind: str
    index: int = 0
    std: float = 1e-3
    delay: float = 0.0
    quantum: float = 0.0
    component: int = 0
    position: float = 0.0
    surface_distance: float = 0.0

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f"measurement {self.name}: kind {self.kind!r}; expected one "
                             f"of {', '.join(KINDS)}")
        if not (self.std >= 0 and self.delay >= 0 and self.quantum >= 0):
            raise ValueError(f"measurement {self.name}: std, delay and quantum must be "
                             f">= 0 (got {self.std}, {self.delay}, {self.quantum})")
        if self.variance <= 0:
            raise ValueError(f"measurement {self.name}: std or quantum must be > 0 (a "
                             "perfect sensor makes the innovation covariance singular)")

    @property
    def variance(self) -> float:
        """std^2 + quantum^2 / 12 (uniform rounding error)."""
        return self.std ** 2 + self.quantum ** 2 / 12.0


def check(measurements, plant) -> None:
    """One-line errors for measurements the plant cannot read."""
    kinds = SPATIAL_KINDS if plant.spatial else PLANAR_KINDS
    for m in measurements:
        if m.kind not in kinds:
            raise ValueError(f"measurement {m.name}: kind {m.kind} is not read on a "
                             f"{'spatial' if plant.spatial else 'planar'} arm; expected "
                             f"one of {', '.join(kinds)}")
        n = plant.n_links if m.kind in ("tip_deflection", "strain") else plant.n_joints
        if m.kind not in ("tip_acceleration", "tip_position") and not 0 <= m.index < n:
            raise ValueError(f"measurement {m.name}: index {m.index} out of range 0..{n - 1}")


def outputs(measurements, plant, x, u) -> np.ndarray:
    """h(x): the noiseless readings of the measurements at state x (undelayed)."""
    nq = plant.nq
    q, v = x[:nq], x[nq:2 * nq]
    cache = {}
    out = np.empty(len(measurements))
    for k, m in enumerate(measurements):
        out[k] = _reading(m, plant, q, v, x, u, cache)
    return out


def _reading(m, plant, q, v, x, u, cache) -> float:
    if m.kind == "joint_angle":
        return float(plant.joint_angles(q)[m.index])
    if m.kind == "joint_rate":
        return float(plant.joint_rates(v)[m.index])
    if m.kind == "motor_angle":
        return plant.motor_angle(q, m.index)
    if m.kind == "tip_deflection":
        if "defl" not in cache:
            cache["defl"] = plant.tip_deflections(q)
        d = cache["defl"]
        return float(d[m.index] if d.ndim == 1 else d[m.index, m.component])
    if m.kind == "strain":
        return plant.strain(q, m.index, m.position, m.surface_distance)
    if m.kind == "tip_position":
        if "tip" not in cache:
            cache["tip"] = plant.tip_position(q)
        return float(cache["tip"][m.component])
    if "acc" not in cache:
        cache["acc"] = plant.tip_acceleration(x, u)
    return float(cache["acc"][m.component])
