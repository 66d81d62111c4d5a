"""What drives the compiled integrators besides the state: the built-in joint PD, torque
and tip-load pulses, the held command, packed with the model's matrices into the input data
``E`` of :mod:`flex_model.integrators` (used by simulate, the stepper, modes and the
diagnosis replay)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class JointPD:
    """tau = kp (theta_set - theta) - kd theta_dot per joint (N m/rad, N m s/rad, rad)."""

    kp: np.ndarray
    kd: np.ndarray
    setpoints: np.ndarray


def ramp_fraction(t, t0: float, r: float):
    """(y, area): a set-point ramp's fraction y(t) = clip((t - t0) / r, 0, 1) over [t0,
    t0 + r] and its integral from t0 (t a number or an array): the ramps of every
    scenario's set-point schedule."""
    t = np.asarray(t, float)
    y = np.clip((t - t0) / r, 0.0, 1.0)
    area = np.where(t <= t0, 0.0, np.where(t <= t0 + r, (t - t0) ** 2 / (2 * r),
                                           r / 2 + (t - t0 - r)))
    return y, area


@dataclass(frozen=True)
class Pulse:
    """Constant joint torques (N m), tip force (N, base frame) and tip torque (N m) on
    ``start <= t < end`` (s)."""

    start: float
    end: float
    joint_torques: tuple = ()
    tip_force: tuple = (0.0, 0.0)
    tip_torque: float = 0.0


def input_data(model, pd: JointPD | None, pulses, u) -> tuple:
    """The input data ``E`` of the compiled integrators (:mod:`flex_model.integrators`) for
    ``model``: its matrices, gravity, the built-in joint PD, the held command ``u`` and the
    pulses."""
    nl = model.n_links
    if pd is None:
        kp = kd = sp = np.zeros(nl)
    else:
        # fresh C-contiguous, writable copies: a read-only (np.broadcast_to) or strided
        # gain array is another numba type, and every new type of E compiles the whole
        # integrator again (~10 s each on a fresh clone)
        kp, kd, sp = (np.array(a, float).reshape(nl) for a in (pd.kp, pd.kd, pd.setpoints))
    n = len(pulses)
    t0 = np.array([p.start for p in pulses], float)
    t1 = np.array([p.end for p in pulses], float)
    ptau = np.zeros((n, nl))
    pf = np.zeros((n, 2))
    pc = np.zeros(n)
    for k, p in enumerate(pulses):
        if len(p.joint_torques):
            ptau[k] = p.joint_torques
        pf[k] = p.tip_force
        pc[k] = p.tip_torque
    return (model.K, model.D, model.G, float(model.gravity[0]), float(model.gravity[1]),
            kp, kd, sp, u, t0, t1, ptau, pf, pc, model.torque_limit, model.contact,
            model.Ga, model.joint_data)
