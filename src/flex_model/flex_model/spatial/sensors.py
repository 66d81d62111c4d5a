"""Sensors of a spatial arm (issue 25): the planar sensor model (flex_model.sensors) on the
readings of a spatial run,

    y(t) = Q( x(t - delay) + bias + noise ),   Q = rounding to the resolution,

for the kinds that have a spatial meaning so far: ``joint_encoder`` (rad or m: the
link-side joint variable), ``motor_encoder`` (rad: the gear ratio n times the actuator
coordinate -- the motor coordinate of an elastic gear, the joint of a rigid one; a locked
motor reads n locked_at), ``joint_torque`` (N m or N: the spring torque k_t (theta_m -
theta) + b_t (theta_m' - theta') of an elastic gear, seed 002 Eqs. 11-14; the joint
torque of the run for a rigid one) and ``tip_position`` (m: x, y, z of the arm's end
frame, base frame). The arm file lists them under ``sensors:`` with the planar fields
(flex_model.sensors.Sensor).
"""
from __future__ import annotations

import numpy as np

from ..config import ConfigError, Fields
from ..sensors import Sensor, quantise

KINDS = ("joint_encoder", "motor_encoder", "joint_torque", "tip_position")


def parse_sensors(items: list, source: str, joint_names, link_names) -> tuple:
    """The ``sensors:`` list of a spatial arm file (planar fields, KINDS only)."""
    out = []
    for k, raw in enumerate(items):
        if isinstance(raw, dict) and isinstance(raw.get("kind"), str) and \
                raw["kind"] not in KINDS:
            raise ConfigError(source, f"sensors[{k}].kind", raw["kind"],
                              f"one of {', '.join(KINDS)} (the sensors of spatial arms "
                              "so far)")
        out.append(Sensor.parse(Fields(raw, source, f"sensors[{k}]"), joint_names,
                                link_names))
    names = [s.name for s in out]
    if len(set(names)) != len(names):
        raise ConfigError(source, "sensors", names, "unique sensor names")
    return tuple(out)


def true_signal(sensor: Sensor, model, q, v, tau=None) -> np.ndarray:
    """The noiseless, undelayed signal (N, k) along the states q, v (N, nq) of a run of
    ``model`` (a SpatialArmModel); ``tau`` (N, n_joints): the run's joint torques (needed
    by ``joint_torque`` on a rigid gear)."""
    q, v = np.atleast_2d(q), np.atleast_2d(v)
    if sensor.kind == "tip_position":
        return np.array([model.tip_position(x) for x in q])
    i = model.arm.joint_names.index(sensor.target)
    lk = model.arm.links[i]
    k = model.off[i]
    if sensor.kind == "joint_encoder":
        return q[:, [k]]
    elastic = model.arm.effect("joint_elasticity", lk.joint.name)
    elastic = elastic if lk.joint.gear == "elastic" else None
    m = model.motor_index[i]
    if m >= 0:
        theta_m, rate_m = q[:, m], v[:, m]
    elif elastic is not None:          # a locked motor behind an elastic gear
        theta_m, rate_m = np.full(len(q), lk.joint.locked_at), np.zeros(len(q))
    else:
        theta_m, rate_m = q[:, k], v[:, k]
    if sensor.kind == "motor_encoder":
        g = model.arm.effect("gear", lk.joint.name)
        return ((1.0 if g is None else g["ratio"]) * theta_m)[:, None]
    if sensor.kind == "joint_torque":
        if elastic is not None:
            return (elastic["stiffness"] * (theta_m - q[:, k])
                    + elastic["damping"] * (rate_m - v[:, k]))[:, None]
        if tau is None:
            raise ValueError(f"sensor {sensor.name}: the joint torque of a rigid gear "
                             "needs the run's joint torques (tau)")
        return np.atleast_2d(tau)[:, [i]]
    raise ValueError(f"sensor kind: got {sensor.kind!r}; expected one of {', '.join(KINDS)}")


def measure(sensor: Sensor, model, t, q, v, tau=None, seed: int = 0):
    """(t, y): the measured signal of ``sensor`` along a run (flex_model.sensors.measure:
    delay by linear interpolation, gain and bias, seeded white noise, quantisation)."""
    t = np.asarray(t, float)
    x = true_signal(sensor, model, q, v, tau)
    if sensor.delay > 0:
        x = np.column_stack([np.interp(t - sensor.delay, t, col, left=col[0]) for col in x.T])
    y = sensor.gain * x + sensor.bias
    if sensor.noise > 0:
        y = y + np.random.default_rng(seed).normal(0.0, sensor.noise, size=y.shape)
    return t, quantise(y, sensor.resolution)
