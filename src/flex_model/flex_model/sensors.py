"""Sensors: what an instrumented arm measures, with noise, bias, quantisation and delay.

Each sensor turns a simulated trajectory into a measured signal:

    y(t) = Q( gain x(t - delay) + bias + noise ),   Q = rounding to the resolution

with white Gaussian noise of standard deviation ``noise`` (seeded, reproducible). Kinds:

- ``joint_encoder`` (rad): link-side joint angle; ``motor_encoder`` (rad): motor angle
  (gear ratio times the actuator coordinate);
- ``joint_torque`` (N m): the torque through the joint (spring torque of an elastic joint,
  actuator torque of a rigid one);
- ``tip_accelerometer`` (m/s^2): specific force a - g at the arm's end in the tip frame
  (x along the tip tangent), as the single-link arm of seed 000 carries;
- ``strain_gauge``: surface bending strain -c d''(z) of a link at ``position`` (m from the
  link root), ``surface_distance`` c (m) from the neutral axis;
- ``tip_position`` (m): x, y of the arm's end in the base frame;
- ``tip_deflection`` (m): a link's tip deflection from its root tangent, as a gauge
  calibrated to it reads it (the Quanser flexible link's); its ``gain`` is that
  calibration's error (1: exact), its ``delay`` the lag of its signal chain.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import Fields
from .inputs import JD_B, JD_BACKLASH, JD_K, JD_RATIO, JD_SMOOTHING
from .integrators import derivative

KINDS = ("joint_encoder", "motor_encoder", "joint_torque", "tip_accelerometer",
         "strain_gauge", "tip_position", "tip_deflection")


@dataclass(frozen=True)
class Sensor:
    """One sensor; ``target`` is a joint name (encoders, torque) or a link name (gauge)."""

    name: str
    kind: str
    target: str = ""
    noise: float = 0.0
    bias: float = 0.0
    resolution: float = 0.0
    delay: float = 0.0
    position: float = 0.0
    surface_distance: float = 0.0
    gain: float = 1.0

    @staticmethod
    def parse(f: Fields, joint_names, link_names) -> "Sensor":
        kind = f.string("kind", choices=list(KINDS))
        target = ""
        if kind in ("joint_encoder", "motor_encoder", "joint_torque"):
            target = f.string("joint", choices=list(joint_names))
        elif kind in ("strain_gauge", "tip_deflection"):
            target = f.string("link", choices=list(link_names))
        sensor = Sensor(
            name=f.string("name", f"{target or 'arm'}/{kind}"), kind=kind, target=target,
            noise=f.number("noise", 0.0, nonnegative=True),
            bias=f.number("bias", 0.0), resolution=f.number("resolution", 0.0,
                                                            nonnegative=True),
            delay=f.number("delay", 0.0, nonnegative=True, unit="s"),
            position=f.number("position", 0.0, nonnegative=True, unit="m"),
            surface_distance=f.number("surface_distance", 0.0, nonnegative=True, unit="m"),
            gain=f.number("gain", 1.0, positive=True))
        f.done()
        return sensor


def true_signal(sensor: Sensor, result) -> np.ndarray:
    """The noiseless, undelayed signal of a sensor along a SimulationResult (N, k)."""
    model = result.model
    joints = model.arm.joint_names
    if sensor.kind == "joint_encoder":
        return result.joint_angles[:, [joints.index(sensor.target)]]
    if sensor.kind == "motor_encoder":
        i = joints.index(sensor.target)
        return (result.q @ model.Ga[i] * model.joint_data[i, JD_RATIO])[:, None]
    if sensor.kind == "joint_torque":
        i = joints.index(sensor.target)
        jd = model.joint_data[i]
        if np.isfinite(jd[JD_K]):  # elastic: the spring carries the torque to the link
            return np.array([_spring_torque(model, i, q, v)
                             for q, v in zip(result.q, result.v)])[:, None]
        return result.tau[:, [i]]
    if sensor.kind == "tip_position":
        return result.tip_positions
    if sensor.kind == "tip_accelerometer":
        return tip_specific_force(result)
    if sensor.kind == "strain_gauge":
        i = [lk.name for lk in model.arm.links].index(sensor.target)
        curv = model.bases[i].curvature_matrix([sensor.position])[0]
        return -sensor.surface_distance * (result.q[:, model.flex_slice(i)] @ curv)[:, None]
    if sensor.kind == "tip_deflection":
        i = [lk.name for lk in model.arm.links].index(sensor.target)
        return result.tip_deflections[:, [i]]
    raise ValueError(f"sensor kind: got {sensor.kind!r}; expected one of {', '.join(KINDS)}")


def _spring_torque(model, i, q, v) -> float:
    from .integrators import dead_zone
    jd = model.joint_data[i]
    d = model.Ga[i] - model.G[i]
    x, xd = d @ q, d @ v
    k, b, backlash = jd[JD_K], jd[JD_B], jd[JD_BACKLASH]
    if backlash > 0:
        dz, slope = dead_zone(x, backlash, jd[JD_SMOOTHING])
        return k * dz + b * slope * xd
    return k * x + b * xd


def tip_specific_force(result) -> np.ndarray:
    """a_tip - g of the arm's end in the tip frame along a result (N, 2)."""
    model, E = result.model, result.inputs
    out = np.empty((len(result.t), 2))
    z = result.bristles
    if z is None:
        z = np.zeros((len(result.t), model.n_bristles))
    for k, (t, q, v) in enumerate(zip(result.t, result.q, result.v)):
        E.u[:] = result.u[k]
        a = derivative(t, np.concatenate([q, v, z[k]]), model.P, E)[model.nq:2 * model.nq]
        out[k] = model.tip_specific_force(q, v, a)
    return out


def measure(sensor: Sensor, result, seed: int = 0):
    """(t, y): the measured signal of ``sensor`` along a simulation result."""
    t = result.t
    y = sensor.gain * delayed(t, true_signal(sensor, result), sensor.delay) + sensor.bias
    if sensor.noise > 0:
        y = y + np.random.default_rng(seed).normal(0.0, sensor.noise, size=y.shape)
    y = quantise(y, sensor.resolution)
    return t, y


def delayed(t, x, delay: float) -> np.ndarray:
    """x (N,) or (N, k) sampled at t, as read ``delay`` (s) later: x(t - delay), linearly
    interpolated, the first sample held before t[0]."""
    x = np.asarray(x, float)
    if delay <= 0:
        return x
    cols = x.reshape(len(t), -1).T
    out = np.column_stack([np.interp(np.asarray(t) - delay, t, c, left=c[0]) for c in cols])
    return out.reshape(x.shape)


def declared_tip_gauge(arm, link: str | None = None) -> Sensor | None:
    """The arm's (first) ``tip_deflection`` sensor on ``link`` (default: any link), None
    without one."""
    return next((s for s in arm.sensors if s.kind == "tip_deflection"
                 and (link is None or s.target == link)), None)


def tip_gauge(arm, link: str | None = None) -> Sensor:
    """:func:`declared_tip_gauge`, or without one an exact gauge (gain 1, no delay)."""
    return declared_tip_gauge(arm, link) or Sensor("tip_gauge", "tip_deflection", link or "")


def with_tip_gauge(arm, link: str, **fields):
    """The arm with ``link``'s tip gauge (:func:`tip_gauge`: declared, else exact) given
    ``fields`` (e.g. ``delay``, ``gain``); the declared one is replaced, not duplicated."""
    from dataclasses import replace
    prior = declared_tip_gauge(arm, link)
    new = replace(tip_gauge(arm, link), **fields)
    return replace(arm, sensors=tuple(s for s in arm.sensors if s is not prior) + (new,))


def tip_gauge_entry(sensors: list, link: str) -> dict:
    """In an arm description's ``sensors`` list (parsed YAML): the ``tip_deflection``
    entry of ``link``, appended as an exact gauge where there is none (in place)."""
    entry = next((s for s in sensors if s.get("kind") == "tip_deflection"
                  and s.get("link") == link), None)
    if entry is None:
        entry = {"name": "tip_gauge", "kind": "tip_deflection", "link": link}
        sensors.append(entry)
    return entry


def quantise(x, resolution: float):
    """Round to the resolution (an encoder's or ADC's step); unchanged for resolution 0."""
    if resolution <= 0:
        return x
    return np.round(np.asarray(x) / resolution) * resolution
