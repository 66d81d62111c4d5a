"""Is the lab's link a linear response to its own hub angle? (issue 22)

A link whose root turns with the hub obeys, in its first clamped mode and at any
amplitude where it stays linear,

    d'' + 2 zeta w d' + w^2 d = -gain theta''(t)

(base excitation: the tip deflection d driven by the hub's angular acceleration; the gain,
m/(rad/s^2), is the mode's participation times its tip amplitude, about the link length for
a tip-mass dominated link; the suite's beam gives 0.46 m for the Quanser link). The hub
angle is known from the encoder, so this needs no twin: :func:`base_excited_mode` fits the
mode to each run itself, and what it leaves no such single mode, with its root on the
encoder's shaft, explains on that run. Read as the lab's gauge logged it, at the encoder's
time, it leaves 2.2-8.3 mm with 0.36-0.80 of the twins' gain and 2-9 % damping; read 45-80
ms late (``delay=True``: the lag fitted per run; where it arises, in the gauge's signal
chain or in the link, the data do not say) it leaves 1.0-2.4 mm, and on the three units
besides Hagenau's with the twins' gain (0.43-0.47) and the link's stuck-hub damping (0-1.5
%). :func:`check_run` also drives the run's twin's link by the lab's hub angle
(:func:`driven_arm`, :func:`driven_link_policy`: torque input, the encoder tracked to a
fraction of a count) and fits the same mode to its output (with a lag if the twin's gauge
has one), which must give the twin's clamped mode back (the method's check: the twin's beam
answers the hub as one mode to within the log's quantisation).

:func:`step_modes` fits the mode to each stretch between two steps alone (does the link
answer its hub alike from step to step?), :func:`unit_mode` one mode to all runs of a unit
(a link fixed for the unit, driven by the lab's own hub angle).
"""
from __future__ import annotations

import dataclasses
from functools import partial
from pathlib import Path

import numpy as np
from scipy import signal
from scipy.optimize import least_squares

from flex_model.sensors import delayed, tip_gauge

#: zero-phase low-pass of the encoder angle before it is differentiated twice (Hz)
CUTOFF = 20.0
#: bandwidth of the twin's hub tracking of the lab's angle (Hz)
TRACKING = 20.0


def lab_deflection(run) -> np.ndarray:
    """A run's gauge in the twin's sign, its offset removed (m)."""
    return run.gauge_sign() * (run.deflection - run.gauge_bias())


def lab_series(run) -> tuple:
    """(t, theta'', d) of a run: its time, the hub's angular acceleration
    (:func:`hub_acceleration`) and :func:`lab_deflection`."""
    return run.t, hub_acceleration(run)[1], lab_deflection(run)


def hub_acceleration(run, cutoff: float = CUTOFF) -> tuple:
    """The encoder angle low-passed (2nd-order Butterworth, forward and back) and its
    second derivative (rad, rad/s^2)."""
    b, a = signal.butter(2, cutoff / (0.5 / run.dt))
    theta = signal.filtfilt(b, a, run.theta)
    return theta, np.gradient(np.gradient(theta, run.dt), run.dt)


def mode_response(t, acc, initial_m: float, frequency_hz: float, damping_ratio: float,
                  gain: float, offset_m: float = 0.0, initial_rate_m_s: float = 0.0,
                  delay_s: float = 0.0, **_) -> np.ndarray:
    """d(t) (m) of the mode above driven by ``acc``, from ``initial_m`` at
    ``initial_rate_m_s``, about ``offset_m``; read ``delay_s`` late (a gauge's lag,
    :func:`flex_model.sensors.delayed`)."""
    t = np.asarray(t, float)
    w = 2 * np.pi * frequency_hz
    sys = signal.StateSpace([[0.0, 1.0], [-w * w, -2 * damping_ratio * w]], [[0.0], [-gain]],
                            [[1.0, 0.0]], [[0.0]])
    d = signal.lsim(sys, acc, t - t[0], X0=[initial_m - offset_m, initial_rate_m_s])[1]
    return delayed(t, d, delay_s) + offset_m


def base_excited_mode(t, acc, d, step: int = 5, delay: bool = False) -> dict:
    """Least-squares initial_m, frequency_hz, damping_ratio, gain (m/(rad/s^2)), offset_m
    and initial_rate_m_s (a run may start ringing) of :func:`mode_response` to d, and with
    ``delay`` the gauge's lag delay_s (0-0.2 s); with the fit's residual_rms_m and the
    signal_rms_m of d about its mean. Fitted on every ``step``-th sample (the acceleration
    is low-passed far below that rate), started from 1.5-2.5 Hz and damping ratios
    0.01 / 0.1 (with ``delay``: 0.01 and 60 ms), the best kept: a local search, so the
    residual bounds this mode's best fit from above."""
    t, acc, d = (np.asarray(x, float)[::step] for x in (t, acc, d))
    names = ("initial_m", "frequency_hz", "damping_ratio", "gain", "offset_m",
             "initial_rate_m_s") + (("delay_s",) if delay else ())
    lo, hi = [-0.2, 0.3, 0.0, -5.0, -0.1, -1.0], [0.2, 10.0, 1.0, 5.0, 0.1, 1.0]
    best = None
    for f0 in (1.5, 2.0, 2.5):
        for z0 in ((0.01,) if delay else (0.01, 0.1)):
            p0 = [d[0], f0, z0, 0.25, 0.0, 0.0] + ([0.06] if delay else [])
            fit = least_squares(lambda p: mode_response(t, acc, *p) - d, p0,
                                bounds=(lo + [0.0] * delay, hi + [0.2] * delay))
            if best is None or fit.cost < best.cost:
                best = fit
    out = {k: float(v) for k, v in zip(names, best.x)}
    out.update(residual_rms_m=float(np.sqrt(np.mean(best.fun ** 2))),
               signal_rms_m=float(np.std(d)))
    return out


#: the shortest stretch between two steps that :func:`step_modes` fits (s)
MIN_WINDOW = 1.5


def step_modes(run, acc, d, min_window: float = MIN_WINDOW) -> list:
    """:func:`base_excited_mode` with a lag fitted to every stretch of ``d`` from one
    reference step to the next (the first from the run's start), if at least
    ``min_window`` s long: whether the link answers the hub alike from step to step. Each
    with its start_s and the hub's change over it, hub_change_rad."""
    edges = [0] + [int(k) for k in run.step_indices()] + [len(run.t)]
    n_min = int(round(min_window / run.dt))
    out = []
    for a, b in zip(edges[:-1], edges[1:]):
        if b - a >= n_min:
            fit = base_excited_mode(run.t[a:b], acc[a:b], d[a:b], delay=True)
            out.append({"start_s": float(run.t[a] - run.t[0]),
                        "hub_change_rad": float(run.theta[b - 1] - run.theta[a]), **fit})
    return out


def unit_mode(series, step: int = 5, start: dict | None = None) -> dict:
    """One mode (frequency, damping ratio, gain, lag) for several runs of one unit, each
    run ``(t, acc, d)`` with its own initial deflection, rate and offset (:func:`lab_series`):
    the linear link fixed for the unit with the least squared error over its runs, driven
    by the lab's own hubs (in-sample, a local search from ``start``, default 1.85 Hz, zeta
    0.01, gain 0.4, 60 ms). Returns the shared values and residual_rms_m per run."""
    start = {"frequency_hz": 1.85, "damping_ratio": 0.01, "gain": 0.4, "delay_s": 0.06,
             **(start or {})}
    data = [tuple(np.asarray(x, float)[::step] for x in s) for s in series]

    def residual(p):
        f, z, g, lag = p[:4]
        return np.concatenate([
            mode_response(t, a, p[4 + 3 * k], f, z, g, p[6 + 3 * k], p[5 + 3 * k], lag) - d
            for k, (t, a, d) in enumerate(data)])

    p0 = [start[k] for k in ("frequency_hz", "damping_ratio", "gain", "delay_s")]
    for t, a, d in data:
        p0 += [d[0], 0.0, 0.0]
    lo = [0.3, 0.0, -5.0, 0.0] + [-0.2, -1.0, -0.1] * len(data)
    hi = [10.0, 1.0, 5.0, 0.2] + [0.2, 1.0, 0.1] * len(data)
    fit = least_squares(residual, p0, bounds=(lo, hi))
    e = np.split(fit.fun, np.cumsum([len(t) for t, _, _ in data])[:-1])
    return {"frequency_hz": float(fit.x[0]), "damping_ratio": float(fit.x[1]),
            "gain": float(fit.x[2]), "delay_s": float(fit.x[3]),
            "residual_rms_m": [float(np.sqrt(np.mean(x ** 2))) for x in e]}


def law_voltage_error(run, shift: int) -> float:
    """RMS (V) of the logged voltage minus the lab's law (its logged gains) on the logged
    hub and the gauge read ``shift`` samples later: least at 0 where the loop read the
    gauge as it was logged."""
    from flex_twin.real_arms.quanser_data import law_regressors
    X, k = law_regressors(run, shift)
    return float(np.sqrt(np.mean((X @ run.gains - run.voltage[k]) ** 2)))


def driven_arm(arm):
    """The arm without its motor and hub friction: a torque at the joint drives it (the
    gear's rotor inertia and the link's damping stay)."""
    return dataclasses.replace(arm, effects=tuple(
        e for e in arm.effects if e.TYPE not in ("dc_motor", "joint_friction",
                                                 "stick_slip_friction")))


def driven_link_policy(run, model, bandwidth_hz: float = TRACKING, theta=None):
    """A stiff PD (``bandwidth_hz``, damping 0.8, on the hub's inertia with the link) that
    makes the twin's hub follow the lab's low-passed encoder angle (``theta``, default
    :func:`hub_acceleration`'s; the replay's ``make_policy`` hook)."""
    if theta is None:
        theta, _ = hub_acceleration(run)
    rate = np.gradient(theta, run.dt)
    wb = 2 * np.pi * bandwidth_hz
    inertia = float(model.Ga[0] @ model.mass_matrix(np.zeros(model.nq)) @ model.Ga[0])
    kp, kd = inertia * wb ** 2, 2 * 0.8 * inertia * wb
    nq, g = model.nq, model.Ga[0]

    def policy(t, x):
        k = min(int(round(t / run.dt)), len(theta) - 1)
        return [kp * (theta[k] - g @ x[:nq]) + kd * (rate[k] - g @ x[nq:2 * nq])]

    return policy


def run_twin(name: str):
    """The twin of a flexible run's unit (:func:`.run_floor.starts`), else the shared one."""
    from .run_floor import starts
    from flex_twin.real_arms.quanser_twin import stored_calibrated_arm
    unit = next((arm for unit, arm in starts(name, "flexible").items() if unit != "shared"),
                None)
    return unit if unit is not None else stored_calibrated_arm("flexible")


def check_run(data_root: str, name: str, out: str | None = None) -> dict:
    """One CU Boulder run: :func:`base_excited_mode` fitted to the lab's gauge, and the
    run's twin (:func:`run_twin`) driven by the lab's hub angle: its hub and tip RMS errors
    and the same fit to its gauge output (a top-level function of picklable arguments: it
    runs on a pool or a Dask worker). With ``out``, ``link_<run>.png`` is written there."""
    from flex_model.dynamics import FlexArmModel
    from flex_twin.real_arms.quanser_data import (CUBOULDER, cuboulder_files,
                                                  read_cuboulder_file)
    from flex_twin.real_arms.replay import replay
    path = next((p for p in cuboulder_files(Path(data_root) / CUBOULDER) if p.name == name),
                None)
    if path is None:
        raise ValueError(f"{name}: no such CU Boulder run under {data_root}")
    run = read_cuboulder_file(path)
    if not run.has_gauge:
        raise ValueError(f"{name}: no tip deflection logged")
    theta, acc = hub_acceleration(run)
    d_lab = lab_deflection(run)
    sign, bias = run.gauge_sign(), run.gauge_bias()
    lab = base_excited_mode(run.t, acc, d_lab)
    lagged = base_excited_mode(run.t, acc, d_lab, delay=True)
    arm = run_twin(name)
    r = replay(FlexArmModel(driven_arm(arm)), run, partial(driven_link_policy, theta=theta))
    d_twin = sign * (r.twin_deflection - bias)
    shift = int(round(lagged["delay_s"] / run.dt))
    law = ({str(k): law_voltage_error(run, k) for k in (-shift, 0, shift)}
           if run.gains[1] or run.gains[3] else None)   # None: the law ignores the gauge
    row = {"run": name, "twin": arm.name, "lab": lab, "lab_lagged": lagged,
           "law_voltage_rms_V": law, "steps": step_modes(run, acc, d_lab),
           "twin_driven": {"hub_rms_rad": r.metrics["hub_rms_rad"],
                           "tip_rms_m": r.metrics["tip_rms_m"],
                           "fit": base_excited_mode(run.t, acc, d_twin,
                                                    delay=tip_gauge(arm).delay > 0)}}
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        plot_run(run, d_lab, mode_response(run.t, acc, **lab),
                 mode_response(run.t, acc, **lagged), d_twin,
                 Path(out) / f"link_{name.replace('.', '_')}.png")
    return row


def plot_run(run, d_lab, d_mode, d_lagged, d_twin, path) -> None:
    """The lab's tip (in the twin's sign), the mode fitted to it without and with a gauge
    lag, and the twin's link driven by the same hub angle; the hub angle below."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(2, 1, figsize=(10, 6), sharex=True,
                           gridspec_kw={"height_ratios": [2, 1]})
    ax[0].plot(run.t, 1e3 * d_lab, color="k", lw=1, label="lab gauge")
    ax[0].plot(run.t, 1e3 * d_mode, color="C1", lw=1,
               label="one linear mode driven by the lab's hub, fitted to this run")
    ax[0].plot(run.t, 1e3 * d_lagged, color="C3", lw=1,
               label="the same, read by a gauge that lags (lag fitted)")
    ax[0].plot(run.t, 1e3 * d_twin, color="C0", lw=1, alpha=0.7,
               label="twin's link driven by the lab's hub")
    ax[0].set_ylabel("tip deflection (mm)")
    ax[0].legend(fontsize=8, loc="upper right")
    ax[0].set_title(f"{run.name}: the link against its own hub angle")
    ax[1].plot(run.t, run.theta, color="k", lw=1)
    ax[1].set_ylabel("hub angle (rad)")
    ax[1].set_xlabel("time (s)")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def gauge_runs(data_root) -> list:
    """The CU Boulder runs with a tip deflection logged."""
    from flex_twin.real_arms.quanser_data import CUBOULDER, read_cuboulder
    return [n for n, r in read_cuboulder(Path(data_root) / CUBOULDER).items() if r.has_gauge]


def unit_modes(data_root, rows) -> dict:
    """:func:`unit_mode` for every unit of :data:`.unit_calibration.UNITS` with at least
    two of the ``rows``' runs, started from the median of their own lagged fits."""
    from flex_twin.real_arms.quanser_data import (CUBOULDER, cuboulder_files,
                                                  read_cuboulder_file)
    from .unit_calibration import UNITS
    files = {p.name: p for p in cuboulder_files(Path(data_root) / CUBOULDER)}
    by_run = {r["run"]: r for r in rows}
    out = {}
    for unit, spec in UNITS.items():
        names = [n for n in spec["fit"] + spec["holdout"] if n in by_run]
        if len(names) < 2:
            continue
        series = [lab_series(read_cuboulder_file(files[name])) for name in names]
        start = {k: float(np.median([by_run[n]["lab_lagged"][k] for n in names]))
                 for k in ("frequency_hz", "damping_ratio", "gain", "delay_s")}
        fit = unit_mode(series, start=start)
        fit["runs"] = {n: {"residual_rms_m": e,
                           "own_m": by_run[n]["lab_lagged"]["residual_rms_m"]}
                       for n, e in zip(names, fit.pop("residual_rms_m"))}
        out[unit] = fit
    return out


#: a stretch whose hub turns less than this (rad) does not drive the link enough to fit a gain
DRIVEN = 0.05


def step_summary(rows, runs) -> dict:
    """Over the driven stretches (:data:`DRIVEN`) of ``runs``: the ranges of their own
    modes' frequency, gain and left RMS, the Spearman correlation of gain and frequency
    (:func:`.stuck_holds.rank_correlation`) and the exponent n of gain ~
    frequency^n (least squares in logs). A tip mass on a beam behind a root spring that
    gives a little more or less from step to step changes both together, its gain as the
    frequency squared."""
    from .stuck_holds import rank_correlation
    steps = [s for r in rows if r["run"] in runs for s in r["steps"]
             if abs(s["hub_change_rad"]) >= DRIVEN]
    if len(steps) < 3:
        return {}
    f = [s["frequency_hz"] for s in steps]
    g = [abs(s["gain"]) for s in steps]
    left = [s["residual_rms_m"] for s in steps]
    rho, p = rank_correlation(g, f)
    return {"stretches": len(steps), "frequency_range_hz": [min(f), max(f)],
            "gain_range": [min(g), max(g)], "left_range_m": [min(left), max(left)],
            "gain_frequency_spearman": rho, "gain_frequency_p_value": p,
            "gain_frequency_exponent": float(np.polyfit(np.log(f), np.log(g), 1)[0])}


def study(data_root, executor, progress=print, runs=None, out=None) -> dict:
    """:func:`check_run` on ``runs`` (default: every run with a gauge) on ``executor``,
    then :func:`unit_modes` and, for each such unit, :func:`step_summary`."""
    runs = list(runs or gauge_runs(data_root))
    if not runs:
        raise ValueError(f"{data_root}: no CU Boulder run with a tip deflection")
    n = len(runs)
    rows = []
    for row in executor.map(check_run, [str(data_root)] * n, runs,
                            [None if out is None else str(out)] * n):
        lab, lag, tw = row["lab"], row["lab_lagged"], row["twin_driven"]
        progress(f"{row['run']}: one mode leaves {1e3 * lab['residual_rms_m']:.2f} of "
                 f"{1e3 * lab['signal_rms_m']:.1f} mm (gain {lab['gain']:.3f}), read "
                 f"{1e3 * lag['delay_s']:.0f} ms late {1e3 * lag['residual_rms_m']:.2f} mm "
                 f"(gain {lag['gain']:.3f}; the twin's {tw['fit']['gain']:.3f}, left "
                 f"{1e3 * tw['fit']['residual_rms_m']:.2f} mm)")
        rows.append(row)
    lab = [r["lab"] for r in rows]
    lagged = [r["lab_lagged"] for r in rows]
    twin = [r["twin_driven"]["fit"] for r in rows]
    units = unit_modes(data_root, rows)
    for unit, fit in units.items():
        fit["steps"] = step_summary(rows, fit["runs"])
    return {"cutoff_hz": CUTOFF, "runs": rows, "units": units, "summary": {
        "runs": n,
        "lab_residual_min_m": min(x["residual_rms_m"] for x in lab),
        "lab_residual_median_m": float(np.median([x["residual_rms_m"] for x in lab])),
        "twin_residual_max_m": max(x["residual_rms_m"] for x in twin),
        "lagged_residual_range_m": [min(x["residual_rms_m"] for x in lagged),
                                    max(x["residual_rms_m"] for x in lagged)],
        "lagged_residual_median_m": float(np.median([x["residual_rms_m"] for x in lagged])),
        "delay_range_s": [min(x["delay_s"] for x in lagged), max(x["delay_s"] for x in lagged)],
        "delay_median_s": float(np.median([x["delay_s"] for x in lagged])),
        "law_reads_gauge": sum(r["law_voltage_rms_V"] is not None for r in rows),
        "law_best_unshifted": sum(min(r["law_voltage_rms_V"].values())
                                  == r["law_voltage_rms_V"]["0"] for r in rows
                                  if r["law_voltage_rms_V"] is not None),
        "gain_ratio_range": [min(a["gain"] / b["gain"] for a, b in zip(lab, twin)),
                             max(a["gain"] / b["gain"] for a, b in zip(lab, twin))],
        "twin_driven_tip_median_m": float(np.median([r["twin_driven"]["tip_rms_m"]
                                                     for r in rows]))}}


def write_report(report: dict, out) -> None:
    """``link_response.json`` and ``link_response.md`` in ``out``."""
    from .command import write_study
    s = report["summary"]
    lines = ["# The lab's link against its own hub angle", "",
             "One linear mode d'' + 2 zeta w d' + w^2 d = -gain theta'' driven by the encoder's "
             f"hub angle (2nd-order Butterworth at {report['cutoff_hz']:g} Hz, forward and "
             "back), fitted to each run itself; the same fit on the run's twin driven by that "
             "hub angle checks the method (the 1 mm log alone leaves 0.29 mm).", "",
             "| run | lab: frequency (Hz) | damping ratio | gain (m s^2/rad) | left (mm) | "
             "of (mm) | read late: lag (ms) | frequency | damping ratio | gain | left (mm) | "
             "twin driven: frequency | damping ratio | gain | left (mm) | twin's tip RMS (mm) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in report["runs"]:
        a, g, t = r["lab"], r["lab_lagged"], r["twin_driven"]["fit"]
        lines.append(f"| {r['run']} | {a['frequency_hz']:.3f} | {a['damping_ratio']:.4f} | "
                     f"{a['gain']:.3f} | {1e3 * a['residual_rms_m']:.2f} | "
                     f"{1e3 * a['signal_rms_m']:.1f} | {1e3 * g['delay_s']:.1f} | "
                     f"{g['frequency_hz']:.3f} | {g['damping_ratio']:.4f} | {g['gain']:.3f} | "
                     f"{1e3 * g['residual_rms_m']:.2f} | {t['frequency_hz']:.3f} | "
                     f"{t['damping_ratio']:.4f} | {t['gain']:.3f} | "
                     f"{1e3 * t['residual_rms_m']:.2f} | "
                     f"{1e3 * r['twin_driven']['tip_rms_m']:.1f} |")
    lo, hi = s["gain_ratio_range"]
    (l0, l1), (d0, d1) = s["lagged_residual_range_m"], s["delay_range_s"]
    lines += ["", f"{s['runs']} runs: the lab's mode leaves {1e3 * s['lab_residual_min_m']:.2f}"
              f" mm at least (median {1e3 * s['lab_residual_median_m']:.2f}); the twin's at "
              f"most {1e3 * s['twin_residual_max_m']:.2f}; lab gain / twin gain "
              f"{lo:.2f}-{hi:.2f}; the twins driven by the lab's hub: tip RMS median "
              f"{1e3 * s['twin_driven_tip_median_m']:.1f} mm. Read by a gauge that lags "
              f"{1e3 * d0:.0f}-{1e3 * d1:.0f} ms (median {1e3 * s['delay_median_s']:.0f}), the "
              f"lab's mode leaves {1e3 * l0:.2f}-{1e3 * l1:.2f} mm (median "
              f"{1e3 * s['lagged_residual_median_m']:.2f}). The logged voltage is the lab's "
              f"law on the gauge as logged (not shifted by the lag either way) on "
              f"{s['law_best_unshifted']} of the {s['law_reads_gauge']} runs whose law "
              "reads it: the loop read the lagging gauge."]
    lines += unit_lines(report)
    write_study(out, "link_response", report, lines)


def unit_lines(report: dict) -> list:
    """The markdown of the step-by-step modes and of the units' fixed modes."""
    lines = ["", "## From step to step", "",
             "The same mode, read late, fitted to each stretch from one step to the next "
             f"(at least {MIN_WINDOW:g} s long, the hub turning at least {DRIVEN} rad in "
             "it).", "",
             "| run | from (s) | hub turns (rad) | frequency (Hz) | damping ratio | gain | "
             "lag (ms) | left (mm) |", "|---|---|---|---|---|---|---|---|"]
    for r in report["runs"]:
        lines += [f"| {r['run']} | {s['start_s']:.1f} | {s['hub_change_rad']:+.3f} | "
                  f"{s['frequency_hz']:.3f} | {s['damping_ratio']:.4f} | {abs(s['gain']):.3f} | "
                  f"{1e3 * s['delay_s']:.0f} | {1e3 * s['residual_rms_m']:.2f} |"
                  for s in r["steps"] if abs(s["hub_change_rad"]) >= DRIVEN]
    lines += ["", "## One link for each unit", "",
              "One mode (frequency, damping, gain, lag) for all runs of a unit, each run with "
              "its own start and offset, driven by the lab's hubs: the link fixed for the unit "
              "with the least squared error over its runs.", "",
              "| unit | frequency (Hz) | damping ratio | gain | lag (ms) | run | left (mm) | "
              "its own mode (mm) |", "|---|---|---|---|---|---|---|---|"]
    notes = []
    for unit, u in report.get("units", {}).items():
        for k, (name, e) in enumerate(u["runs"].items()):
            head = (f"{unit} | {u['frequency_hz']:.3f} | {u['damping_ratio']:.4f} | "
                    f"{abs(u['gain']):.3f} | {1e3 * u['delay_s']:.0f}" if k == 0 else " | | | |")
            lines.append(f"| {head} | {name} | {1e3 * e['residual_rms_m']:.2f} | "
                         f"{1e3 * e['own_m']:.2f} |")
        st = u.get("steps")
        if st:
            notes += ["", f"{unit}: {st['stretches']} driven stretches ring at "
                      f"{st['frequency_range_hz'][0]:.2f}-{st['frequency_range_hz'][1]:.2f} Hz "
                      f"with a gain {st['gain_range'][0]:.3f}-{st['gain_range'][1]:.3f} "
                      f"(Spearman of gain and frequency {st['gain_frequency_spearman']:+.2f}, "
                      f"p {st['gain_frequency_p_value']:.1e}; gain ~ frequency^"
                      f"{st['gain_frequency_exponent']:.1f}); each leaves "
                      f"{1e3 * st['left_range_m'][0]:.2f}-{1e3 * st['left_range_m'][1]:.2f} "
                      "mm."]
    return lines + notes


def cmd_link_response(args) -> int:
    from flex_twin.cluster import batch_executor
    from flex_twin.real_arms.cli import print_progress, print_report
    from flex_twin.real_arms.quanser_twin import data_root
    out = Path(args.out)
    with batch_executor(args.scheduler, args.workers) as executor:
        report = study(data_root(args.data), executor, print_progress, args.runs or None,
                       out=out)
    write_report(report, out)
    return print_report(args, report, out / "link_response.md")


def build_parser():
    from flex_twin.real_arms.cli import add_data_option
    from .command import add_batch_options, study_parser
    parser = study_parser("link_response", "the lab's link against its own hub angle: one "
                          "linear mode fitted to each run and to each step, one for each "
                          "unit, the twin's link driven by the lab's hub (markdown, JSON, "
                          "PNG per run; ~10 CPU-min)")
    add_data_option(parser)
    parser.add_argument("runs", nargs="*", help="run names (default: every run with a "
                        "gauge)")
    add_batch_options(parser, "runs/quanser-link")
    parser.set_defaults(func=cmd_link_response)
    return parser


def main(argv=None) -> int:
    """``python -m studies.link_response [RUN ...] [--workers N] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
