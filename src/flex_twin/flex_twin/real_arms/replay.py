"""Replay a recorded lab run on a twin: closed loop (the lab's law) or open loop (the
recorded voltage), with RMS/peak errors, the ring-down of the tip after every step and its
ringing during the holds.

The closed loop takes a ``make_policy(run, model) -> policy(t, x) -> [V]`` callable (for
the Quanser arms: ``flex_control.state_feedback.lab_policy_factory``), built by the caller,
so that flex_model never imports flex_control. The twin's gauge output is the lab's
(:func:`gauge_reading`: ``gauge_sign * gain * d + gauge_bias``, gain the twin's
``tip_deflection`` sensor's, 1 without one), lagging by that sensor's ``delay`` and rounded
to the log's 1 mm.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import least_squares

from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from flex_model.sensors import delayed, tip_gauge
from flex_model.simulate import SimulationDivergedError, simulate
from .quanser_data import LabRun

#: the CU Boulder logs keep 3 decimals: 1 mm of tip deflection
GAUGE_RESOLUTION = 1e-3
#: ring-down window after a step: from the first deflection peak, this long (s)
RING_WINDOW = 1.6
#: shortest usable window (s): UC Merced steps every 0.76 s, its last one 0.25 s before the end
RING_MIN = 0.4
#: a hold's ringing is measured from this long after its step (s)
HOLD_SETTLE = 1.0
#: the first TRANSIENT seconds after a step are its transient (hub_ and tip_transient_share)
TRANSIENT = 0.75


@dataclass
class RingDown:
    """Damped oscillation d = A exp(-zeta w t) cos(w_d t + phi) + c fitted after a step."""

    t_step: float
    frequency_hz: float        # damped frequency w_d / 2 pi
    damping_ratio: float
    amplitude: float           # m

    def as_dict(self) -> dict:
        return {"t_step": self.t_step, "frequency_hz": self.frequency_hz,
                "damping_ratio": self.damping_ratio, "amplitude_m": self.amplitude}


def ring_down(t, d, t_step: float, t_end: float) -> RingDown | None:
    """The ring-down after a step at ``t_step`` (window up to ``t_end``): starts at the
    largest |d| within 0.6 s, lasts RING_WINDOW; frequency from a zero-padded FFT, then a
    least-squares fit of a damped cosine. None if the window is shorter than RING_MIN
    or holds no oscillation above the gauge's resolution."""
    sel = (t >= t_step) & (t < min(t_end, t_step + 0.6))
    if sel.sum() < 20:
        return None
    k0 = np.flatnonzero(sel)[np.argmax(np.abs(d[sel]))]
    win = (t >= t[k0]) & (t < min(t_end, t[k0] + RING_WINDOW))
    tw, dw = t[win] - t[k0], d[win]
    if tw[-1] < RING_MIN or np.ptp(dw) < 2.5 * GAUGE_RESOLUTION:
        return None
    fit = fit_damped_cosine(tw, dw)
    return RingDown(t_step=float(t_step), frequency_hz=fit["frequency_hz"],
                    damping_ratio=fit["damping_ratio"], amplitude=fit["amplitude_m"])


def fit_damped_cosine(tw, dw, f_band=(0.5, 10.0)) -> dict:
    """d = A exp(-s t) cos(w t + phi) + c by least squares on a window (tw from 0): w
    started at the peak of a zero-padded Hann-windowed FFT in ``f_band`` (Hz), A and phi at
    the undamped cosine's linear fit. Returns frequency_hz (w / 2 pi), damping_ratio
    (s / |s + i w|), amplitude_m, phase_rad, offset_m and residual_rms_m."""
    tw, dw = np.asarray(tw, float), np.asarray(dw, float)
    nfft = max(2 ** 16, 2 * len(dw))
    spec = np.abs(np.fft.rfft((dw - dw.mean()) * np.hanning(len(dw)), n=nfft))
    freqs = np.fft.rfftfreq(nfft, tw[1] - tw[0])
    band = (freqs > f_band[0]) & (freqs < f_band[1])
    w0 = 2 * np.pi * float(freqs[band][np.argmax(spec[band])])
    basis = np.column_stack([np.cos(w0 * tw), np.sin(w0 * tw), np.ones_like(tw)])
    ca, sa, c0 = np.linalg.lstsq(basis, dw, rcond=None)[0]

    def model(p):
        a, s, w, ph, c = p
        return a * np.exp(-s * tw) * np.cos(w * tw + ph) + c

    lo, hi = [0, 0, 2 * np.pi * 0.3, -2 * np.pi, -1], [1, 50, 2 * np.pi * 12, 2 * np.pi, 1]
    p0 = np.clip([np.hypot(ca, sa), 1.0, w0, np.arctan2(-sa, ca), c0], lo, hi)
    fit = least_squares(lambda p: model(p) - dw, p0, bounds=(lo, hi))
    a, s, w, ph, c = fit.x
    return {"frequency_hz": float(w / (2 * np.pi)), "damping_ratio": float(s / np.hypot(s, w)),
            "amplitude_m": float(a), "phase_rad": float(ph), "offset_m": float(c),
            "residual_rms_m": float(np.sqrt(np.mean(fit.fun ** 2)))}


def ring_downs(t, d, steps) -> list:
    """Ring-downs after every step index in ``steps`` (None where none is found)."""
    ends = list(t[steps[1:]]) + [t[-1]]
    return [ring_down(t, d, t[k], e) for k, e in zip(steps, ends)]


def ring_spread(rings) -> dict:
    """How much the ring-downs of one run differ from step to step: frequency_spread_pct
    = 100 (max / min - 1) of their frequencies and damping_spread = max / min of their
    damping ratios (None with a ratio of 0); {} with fewer than two."""
    rings = [r for r in rings if r is not None]
    if len(rings) < 2:
        return {}
    f = [r.frequency_hz for r in rings]
    z = [r.damping_ratio for r in rings]
    return {"frequency_spread_pct": 100.0 * (max(f) / min(f) - 1.0),
            "damping_spread": max(z) / min(z) if min(z) > 0 else None}


def hold_ringing(t, d, steps, settle: float = HOLD_SETTLE) -> list:
    """Frequency (Hz) of the tip's ringing during every hold: from ``settle`` s after a
    step to the next step (at least 1 s), the peak of a zero-padded Hann-windowed FFT in
    0.5-5 Hz; None for a shorter hold or a ringing under 2.5 gauge steps peak to peak. With
    the hub stuck this is the link's clamped-hub mode, not the ring-down after the step."""
    ends = list(t[steps[1:]]) + [t[-1]]
    out = []
    for k, e in zip(steps, ends):
        sel = (t >= t[k] + settle) & (t < e)
        x = d[sel] - np.mean(d[sel]) if sel.sum() > 1 else None
        if x is None or np.ptp(t[sel]) < 1.0 or np.ptp(x) < 2.5 * GAUGE_RESOLUTION:
            out.append(None)
            continue
        spec = np.abs(np.fft.rfft(x * np.hanning(len(x)), n=2 ** 17))
        f = np.fft.rfftfreq(2 ** 17, t[1] - t[0])
        band = (f > 0.5) & (f < 5.0)
        out.append(float(f[band][np.argmax(spec[band])]))
    return out


@dataclass
class ReplayResult:
    """Twin vs lab along one run (SI units); ``twin_deflection`` in the lab's sign."""

    run: LabRun
    arm_name: str
    mode: str
    t: np.ndarray
    twin_theta: np.ndarray
    twin_deflection: np.ndarray
    twin_voltage: np.ndarray
    metrics: dict = field(default_factory=dict)
    steps: list = field(default_factory=list)   # [{"measured": RingDown, "twin": ...}]

    def summary(self) -> dict:
        out = {"run": self.run.name, "lab": self.run.lab, "arm": self.arm_name,
               "mode": self.mode, **self.metrics, "steps": []}
        for s in self.steps:
            out["steps"].append({k: (v.as_dict() if v is not None else None)
                                 for k, v in s.items()})
        return out


def twin_gauge(model: FlexArmModel):
    """The twin's tip gauge: its first link's ``tip_deflection`` sensor (gain, delay)."""
    return tip_gauge(model.arm, model.arm.links[0].name)


def gauge_reading(model: FlexArmModel, run: LabRun, d):
    """What the lab's gauge reads for the twin's tip deflection d (m):
    gauge_sign * gain * d + gauge_bias (the law's input and the replay's output)."""
    return run.gauge_sign() * twin_gauge(model).gain * np.asarray(d) + run.gauge_bias()


def gauge_deflection(model: FlexArmModel, run: LabRun, reading, rate: bool = False):
    """The twin's tip deflection (or, ``rate``, its rate) for a gauge reading: the inverse
    of :func:`gauge_reading`."""
    bias = 0.0 if rate else run.gauge_bias()
    return run.gauge_sign() * (np.asarray(reading) - bias) / twin_gauge(model).gain


def initial_state(model: FlexArmModel, run: LabRun):
    """(q0, v0) matching the first sample: hub angle and rate, and the tip deflection and
    its rate (through the gauge, :func:`gauge_deflection`) as the first clamped-hub mode
    (the link often still rings at t = 0)."""
    theta0, rate0 = run.theta[0], run.theta_rate[0]
    if not run.has_gauge:
        return model.q_from_joint_angles([theta0]), model.q_from_joint_angles([rate0])
    shape = natural_modes(model, joints="clamped").shapes_q[:, 0]
    shape = shape / shape[model.tip_deflection_index(0)]
    flex = shape[model.flex_indices]
    d0 = gauge_deflection(model, run, run.deflection[0])
    dd0 = gauge_deflection(model, run, run.deflection_rate[0], rate=True)
    return (model.q_from_joint_angles([theta0], d0 * flex),
            model.q_from_joint_angles([rate0], dd0 * flex))


def _lab_ringing(run: LabRun, n: int, steps) -> tuple:
    """The lab's ring-downs and hold ringing over its first ``n`` samples, computed once per
    run: every replay of it (a calibration replays a run per evaluation) compares with the
    same lab data."""
    cache = run.__dict__.setdefault("_ringing", {})
    if n not in cache:
        t, d = run.t[:n], run.deflection[:n]
        cache[n] = (ring_downs(t, d, steps), hold_ringing(t, d, steps))
    return cache[n]


def rms(x) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def transient_share(error, steps, samples: int) -> float:
    """Share of ``error``'s sum of squares within ``samples`` after each step index (the
    rest: the holds from that long after a step on, and the time before the first step)."""
    near = np.zeros(len(error), bool)
    for k in steps:
        near[k:k + samples] = True
    total = float(np.sum(np.square(error)))
    return float(np.sum(np.square(error[near])) / total) if total > 0 else 0.0


def replay(model: FlexArmModel, run: LabRun, make_policy: Callable | None = None, *,
           mode: str = "closed", t_final: float | None = None,
           dt: float = 5e-4) -> ReplayResult:
    """Run the twin along a recorded run and compare.

    ``mode='closed'``: ``make_policy(run, model)`` is the lab's law in closed loop with the
    recorded reference; ``'open'``: the recorded voltage drives the twin. The twin starts
    at the recorded first hub angle and tip deflection. ``t_final`` shortens the run (s).
    ``dt``: integration step; 0.5 ms resolves the stick-slip of the calibrated friction
    (at 1 ms a break-away torque of 0.24 N m was under-resolved: hub RMS 0.012 instead of
    the converged 0.141 rad, equal at 0.25 ms).
    """
    if mode not in ("closed", "open"):
        raise ValueError(f"mode: got {mode!r}; expected 'closed' or 'open'")
    n = len(run.t) if t_final is None else int(round(t_final / run.dt)) + 1
    n = min(n, len(run.t))
    t = run.t[:n]
    if mode == "closed":
        if make_policy is None:
            raise ValueError("closed-loop replay needs make_policy(run, model)")
        policy = make_policy(run, model)
    else:
        volts = run.voltage

        def policy(tt, x):
            return [volts[min(int(round(tt / run.dt)), len(volts) - 1)]]
    sign, bias = run.gauge_sign(), run.gauge_bias()
    q0, v0 = initial_state(model, run)
    for k in range(3):  # stick-slip of a strong friction can stall Newton: halve the step
        try:
            res = simulate(model, q0, v0, t_final=float(t[-1]), sample_period=run.dt,
                           policy=policy, method="fixed", dt=min(dt, run.dt) / 2 ** k)
            break
        except SimulationDivergedError:
            if k == 2:
                raise
    theta = res.joint_angles[:n, 0]
    defl = gauge_reading(model, run, delayed(t, res.tip_deflections[:n, 0],
                                             twin_gauge(model).delay))
    if run.lab == "cuboulder":
        defl = np.round(defl / GAUGE_RESOLUTION) * GAUGE_RESOLUTION
    out = ReplayResult(run=run, arm_name=model.arm.name, mode=mode, t=t, twin_theta=theta,
                       twin_deflection=defl, twin_voltage=res.u[:n, 0])
    e_th = theta - run.theta[:n]
    steps = run.step_indices()
    out.metrics = {"hub_rms_rad": rms(e_th), "hub_peak_rad": float(np.max(np.abs(e_th))),
                   "hub_transient_share": transient_share(
                       e_th, steps, int(round(TRANSIENT / run.dt))),
                   "voltage_rms_V": rms(out.twin_voltage - run.voltage[:n]),
                   "gauge_sign": sign, "gauge_bias_m": bias, "duration_s": float(t[-1])}
    if run.has_gauge:
        e_d = defl - run.deflection[:n]
        out.metrics.update(tip_rms_m=rms(e_d), tip_peak_m=float(np.max(np.abs(e_d))),
                           tip_transient_share=transient_share(
                               e_d, steps, int(round(TRANSIENT / run.dt))))
        steps = steps[steps < n - 100]
        meas, lab_hold = _lab_ringing(run, n, steps)
        twin = ring_downs(t, defl, steps)
        out.steps = [{"measured": a, "twin": b} for a, b in zip(meas, twin)]
        pairs = [(a, b) for a, b in zip(meas, twin) if a is not None and b is not None]
        if pairs:
            out.metrics["ring_freq_measured_hz"] = float(np.mean([a.frequency_hz
                                                                   for a, _ in pairs]))
            out.metrics["ring_freq_twin_hz"] = float(np.mean([b.frequency_hz
                                                               for _, b in pairs]))
            out.metrics["ring_freq_error_pct"] = float(np.mean(
                [100 * (b.frequency_hz / a.frequency_hz - 1) for a, b in pairs]))
            out.metrics["ring_damping_measured"] = float(np.mean([a.damping_ratio
                                                                   for a, _ in pairs]))
            out.metrics["ring_damping_twin"] = float(np.mean([b.damping_ratio
                                                               for _, b in pairs]))
            spread = ring_spread([a for a, _ in pairs])
            out.metrics["ring_freq_measured_spread_pct"] = spread.get("frequency_spread_pct")
            out.metrics["ring_damping_measured_spread"] = spread.get("damping_spread")
        twin_hold = hold_ringing(t, defl, steps)
        for key, f in (("hold_freq_measured_hz", lab_hold), ("hold_freq_twin_hz", twin_hold)):
            if any(x is not None for x in f):
                out.metrics[key] = float(np.mean([x for x in f if x is not None]))
        holds = [(a, b) for a, b in zip(lab_hold, twin_hold)
                 if a is not None and b is not None]
        if holds:
            out.metrics["hold_freq_error_pct"] = float(np.mean([100 * (b / a - 1)
                                                                for a, b in holds]))
    return out


def plot_replay(results, path, title: str = "") -> None:
    """Overlay of lab and twin(s): hub angle, tip deflection, voltage (PNG).

    ``results``: ReplayResults of one run (e.g. nominal and calibrated twins)."""
    from flex_model.plots import finish_figure, plt
    run = results[0].run
    n = len(results[0].t)
    rows = 3 if run.has_gauge else 2
    fig, ax = plt.subplots(rows, 1, figsize=(10, 2.6 * rows), sharex=True)
    t = run.t[:n]
    ax[0].plot(t, run.reference[:n], "k:", lw=0.8, label="reference")
    ax[0].plot(t, run.theta[:n], "k", lw=1.2, label="lab")
    for r in results:
        ax[0].plot(t, r.twin_theta, lw=1.0, label=f"twin {r.arm_name}")
    ax[0].set_ylabel("hub angle (rad)")
    k = 1
    if run.has_gauge:
        ax[1].plot(t, 1e3 * run.deflection[:n], "k", lw=1.2, label="lab")
        for r in results:
            ax[1].plot(t, 1e3 * r.twin_deflection, lw=1.0, label=f"twin {r.arm_name}")
        ax[1].set_ylabel("tip deflection (mm)")
        k = 2
    ax[k].plot(t, run.voltage[:n], "k", lw=1.0, label="lab")
    for r in results:
        ax[k].plot(t, r.twin_voltage, lw=0.8, label=f"twin {r.arm_name}")
    ax[k].set_ylabel("voltage (V)")
    ax[k].set_xlabel("t (s)")
    finish_figure(fig, ax, path, title or f"{run.lab} {run.name}")
