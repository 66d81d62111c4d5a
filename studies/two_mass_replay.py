"""Replay of the two-mass bench on its twin: the measured current drives the twin open loop.

The rigid-body mode of an open-loop twin drifts (the current's unexcited low-frequency
content meets bearing friction on the bench), so the comparisons are the well-defined ones:

- per-period windows (1 s), each started from the measured state (both angles and their
  central-difference speeds; the coupling's twist is the measured th_m - th_l): RMS speed
  errors, raw and with each window's mean error removed;
- the period-averaged FRF of the twin (its linearization, ``flex_model.modes.linearize``,
  the same model the windows integrate) against the lab's: resonance / anti-resonance
  frequencies (both estimated by the two-inertia fit of ``two_mass_data.fit_frf`` on the
  lines) and levels.
"""
from __future__ import annotations

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.modes import linearize
from flex_model.simulate import simulate
from flex_twin.real_arms.two_mass_twin import TORQUE_CONSTANT

from studies.two_mass_data import PeriodFRF, TwoMassRecord


def twin_state(model: FlexArmModel, theta_m, theta_l, omega_m, omega_l):
    """(q, v) of the twin with the load (link-side joint) at theta_l and the motor
    coordinate at theta_m (a rigid twin: the motor's angle and speed); link flat."""
    T = model.joint_coordinate_matrix()
    z, zd = np.zeros(model.nq), np.zeros(model.nq)
    z[model.off[0]], zd[model.off[0]] = theta_l, omega_l
    if model.elastic_joints:
        z[model.nq_arm], zd[model.nq_arm] = theta_m, omega_m
    else:
        z[model.off[0]], zd[model.off[0]] = theta_m, omega_m
    return T @ z, T @ zd


def twin_angles(model: FlexArmModel, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(motor, load) angles of twin states q (n, nq)."""
    Ti = np.linalg.inv(model.joint_coordinate_matrix())
    z = q @ Ti.T
    motor = q @ model.Ga[0]
    return motor, z[:, model.off[0]]


#: integration steps per sample: generalized-alpha's period error (w h)^2 / 12 is 0.3 % at
#: 76 Hz with h = 0.4 ms (a quarter cycle over a 1 s window), 0.02 % with h = 0.1 ms
SUBSTEPS = 4


def replay_window(model: FlexArmModel, rec: TwoMassRecord, start: int, n: int,
                  substeps: int = SUBSTEPS) -> dict:
    """The twin from the measured state at sample ``start`` for n samples under the
    measured torque K_t i (zero-order hold at the record's period), ``substeps``
    integration steps per sample."""
    tau = TORQUE_CONSTANT * rec.current[start:start + n]
    wm, wl = rec.omega_m, rec.omega_l
    q0, v0 = twin_state(model, rec.theta_m[start], rec.theta_l[start], wm[start], wl[start])

    def policy(t, x):
        return np.array([tau[min(int(t / rec.dt + 1e-6), n - 1)]])

    r = simulate(model, q0, v0, t_final=(n - 1) * rec.dt, sample_period=rec.dt,
                 policy=policy, control_period=rec.dt, method="fixed",
                 dt=rec.dt / substeps)
    qm, ql = twin_angles(model, r.q)
    vm, vl = twin_angles(model, r.v)
    return {"theta_m": qm, "theta_l": ql, "omega_m": vm, "omega_l": vl}


def window_errors(model: FlexArmModel, rec: TwoMassRecord, windows=None,
                  substeps: int = SUBSTEPS) -> dict:
    """RMS speed errors (rad/s) per 1-s window (default: periods 2..20), raw and with the
    window's mean error removed, motor and load side; medians; the measured speeds' RMS."""
    n = rec.period_samples
    windows = list(range(1, rec.n_periods)) if windows is None else list(windows)
    rows = []
    for w in windows:
        s = slice(w * n, (w + 1) * n)
        tw = replay_window(model, rec, w * n, n, substeps)
        row = {"window": w}
        for side in ("m", "l"):
            e = tw[f"omega_{side}"] - getattr(rec, f"omega_{side}")[s]
            row[f"rms_{side}"] = float(np.sqrt(np.mean(e ** 2)))
            row[f"rms_{side}_mean_removed"] = float(np.std(e))
        rows.append(row)
    out = {"windows": rows}
    for key in ("rms_m", "rms_l", "rms_m_mean_removed", "rms_l_mean_removed"):
        out[f"median_{key}"] = float(np.median([r[key] for r in rows]))
    out["speed_rms_m"] = float(np.std(rec.omega_m))
    out["speed_rms_l"] = float(np.std(rec.omega_l))
    return out


def twin_frf(model: FlexArmModel, f) -> PeriodFRF:
    """theta_m / i and theta_l / i (rad/A) of the twin's linearization (joint hinged at
    rest: every coordinate free), K_t = TORQUE_CONSTANT."""
    lin = linearize(model, joints="hinged")
    free, T = lin.free, lin.T
    n = len(free)
    b = lin.M @ lin.B[n:, 0] * TORQUE_CONSTANT               # generalized force of 1 N m
    Ti = T[:, free]
    c_m = model.Ga[0] @ Ti
    c_l = np.eye(model.nq)[model.off[0]][free] if not model.elastic_joints else \
        np.linalg.inv(T)[model.off[0]] @ Ti
    s = 2j * np.pi * np.asarray(f, float)
    hm, hl = np.empty(len(s), complex), np.empty(len(s), complex)
    for k, si in enumerate(s):
        x = np.linalg.solve(si * si * lin.M + si * lin.Cd + lin.K, b)
        hm[k], hl[k] = c_m @ x, c_l @ x
    z = np.zeros(len(s))
    return PeriodFRF(f=np.asarray(f, float), motor=hm, load=hl, motor_std=z, load_std=z)


def frf_gap(a: PeriodFRF, b: PeriodFRF, side: str = "motor") -> float:
    """RMS of the complex log ratio log(H_a / H_b) over the lines (0.1 ~ 10 % / 6 deg)."""
    r = np.log(getattr(a, side) / getattr(b, side))
    return float(np.sqrt(np.mean(r.real ** 2 + r.imag ** 2)))


def peak_levels(h: PeriodFRF, side: str = "motor") -> dict:
    """Level |H| w^2 ((rad/s^2)/A) at the resonance peak (60-100 Hz) and the motor-side
    anti-resonance dip (30-70 Hz), and the lines where they sit (Hz)."""
    a = np.abs(getattr(h, side)) * (2 * np.pi * h.f) ** 2
    hi = (h.f >= 60) & (h.f <= 100)
    lo = (h.f >= 30) & (h.f <= 70)
    kr = np.flatnonzero(hi)[np.argmax(a[hi])]
    ka = np.flatnonzero(lo)[np.argmin(a[lo])]
    return {"resonance_line_hz": float(h.f[kr]), "resonance_level": float(a[kr]),
            "anti_resonance_line_hz": float(h.f[ka]), "anti_resonance_level": float(a[ka])}
