"""``flex-twin estimate``: the state estimator (flex_model.estimation) run over a recording.

A recording (CSV or bag, :func:`flex_twin.diagnosis.sources.load_recording`) gives the
inputs (``tau<i>``: torques, or voltages on DC-motor joints) and the channels; the ones
named by ``measure`` (``q<i>``, ``v<i>``, ``w<i>``, ``tip_x``, ``tip_y``) enter the filter,
every other channel of those kinds is held out and compared with the estimate: RMS error,
the error relative to the channel's peak, and ``coverage_95``, the fraction of its samples
inside the estimate's 95 % band (1.96 sqrt(estimate variance + the reading's variance)).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flex_model.estimation import EstimatorSettings, Measurement, estimate_recording
from flex_model.estimation.measurements import DEFAULT_STD, NAME_PATTERN

#: channel kind -> (estimator kind, default reading std in SI units: the one table
#: flex_model.estimation.measurements.DEFAULT_STD, shared with the observer node)
CHANNELS = {k: (kind, DEFAULT_STD[kind]) for k, kind in (
    ("q", "joint_angle"), ("v", "joint_rate"), ("w", "tip_deflection"),
    ("tip_x", "tip_position"), ("tip_y", "tip_position"))}
#: 95 % two-sided normal quantile
Z95 = 1.959964


def channel_kind(name: str) -> tuple[str, int]:
    """('q'|'v'|'w'|'tip_x'|'tip_y', 0-based index) of a channel name, or a ValueError."""
    if name in ("tip_x", "tip_y"):
        return name, "xy".index(name[-1])
    match = NAME_PATTERN.match(name)
    if match and match[1] in "qvw" and match[2] and int(match[2]) >= 1 and not match[3]:
        return match[1], int(match[2]) - 1
    raise ValueError(f"measure: channel {name!r}; expected q<i>, v<i>, w<i>, tip_x or tip_y")


def measurement(name: str, std: float | None = None, quantum: float = 0.0,
                delay: float = 0.0) -> Measurement:
    """The estimator's Measurement of a recording channel (default std: :data:`CHANNELS`)."""
    kind, i = channel_kind(name)
    est_kind, default = CHANNELS[kind]
    sd = default if std is None else float(std)
    if kind.startswith("tip"):
        return Measurement(name, est_kind, 0, std=sd, quantum=quantum, delay=delay,
                           component=i)
    return Measurement(name, est_kind, i, std=sd, quantum=quantum, delay=delay)


def coverage_95(error, estimate_std, reading_std=0.0) -> float:
    """Fraction of samples with |error| <= 1.96 sqrt(estimate_std^2 + reading_std^2)."""
    band = Z95 * np.sqrt(np.square(estimate_std) + np.square(reading_std))
    return float(np.mean(np.abs(np.asarray(error)) <= band))


def estimated_channel(result, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(estimate, std) over time of a channel from an EstimationResult."""
    kind, i = channel_kind(name)
    if kind == "q":
        return result.joint_angles[:, i], result.joint_angles_std[:, i]
    if kind == "v":
        return result.joint_rates[:, i], result.joint_rates_std[:, i]
    if kind == "w":
        return result.tip_deflections[:, i], result.tip_deflections_std[:, i]
    return result.tip_position[:, i], np.sqrt(np.maximum(result.tip_position_cov[:, i, i], 0))


@dataclass
class RecordingEstimate:
    """The estimate of one recording and its comparison with the held-out channels."""

    t: np.ndarray
    result: object              # flex_model.estimation.EstimationResult
    measured: list
    held_out: dict              # channel -> measured array
    metrics: dict               # channel -> {rms, peak, rms_pct_of_peak, coverage_95}

    def summary(self) -> dict:
        return {"measured": self.measured, "samples": len(self.t),
                "filter": self.result.summary, "held_out": self.metrics}


def estimate_file(recording, model, measure, *, stds=None, settings=None,
                  duration: float | None = None) -> RecordingEstimate:
    """Run the estimator over a Recording with the channels ``measure`` as measurements
    (``stds``: channel -> reading std, else :data:`CHANNELS`'); compare the held-out
    channels (every other q, v, w, tip channel the recording has)."""
    stds = dict(stds or {})
    for name in measure:
        if not recording.has(name):
            raise ValueError(f"measure: {recording.source} has no channel {name!r} (has "
                             f"{', '.join(recording.residual_channels)})")
    n = len(recording.t) if duration is None else int(round(duration / recording.dt)) + 1
    t = recording.t[:n]
    meas = [measurement(nm, stds.get(nm)) for nm in measure]
    Y = np.column_stack([recording.channels[nm][:n] for nm in measure])
    settings = settings or EstimatorSettings(sample_period=recording.dt)
    res = estimate_recording(model, t, recording.stack("tau")[:n], Y, meas, settings)
    held = {c: recording.channels[c][:n] for c in recording.residual_channels
            if c not in measure and not c.startswith("tau")}
    metrics = {}
    for c, y in held.items():
        est, sd = estimated_channel(res, c)
        err = est - y
        peak = float(np.max(np.abs(y)))
        rms = float(np.sqrt(np.mean(err ** 2)))
        metrics[c] = {"rms": rms, "peak": peak,
                      "rms_pct_of_peak": 100 * rms / peak if peak > 0 else None,
                      "coverage_95": coverage_95(err, sd, stds.get(c, CHANNELS[
                          channel_kind(c)[0]][1]))}
    return RecordingEstimate(t, res, list(measure), held, metrics)


def write_outputs(est: RecordingEstimate, out, title: str = "") -> dict:
    """estimate.csv (every q, v, w estimate with its std, NIS, adapted parameters),
    estimate.png and summary.json in ``out``; returns the paths."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    r = est.result
    cols, names = [est.t], ["t"]
    for kind, arr, sd in (("q", r.joint_angles, r.joint_angles_std),
                          ("v", r.joint_rates, r.joint_rates_std),
                          ("w", r.tip_deflections, r.tip_deflections_std)):
        for i in range(arr.shape[1]):
            cols += [arr[:, i], sd[:, i]]
            names += [f"{kind}{i + 1}", f"{kind}{i + 1}_std"]
    cols.append(r.nis)
    names.append("nis")
    for p, a in r.parameters.items():
        cols += [a, r.parameter_std[p]]
        names += [p, f"{p}_std"]
    paths = {"csv": out / "estimate.csv", "png": out / "estimate.png",
             "json": out / "summary.json"}
    np.savetxt(paths["csv"], np.column_stack(cols), delimiter=",", header=",".join(names),
               comments="", fmt="%.9g")
    plot_estimate(est, paths["png"], title)
    paths["json"].write_text(json.dumps(est.summary(), indent=1, default=float))
    return paths


def plot_estimate(est: RecordingEstimate, path, title: str = "") -> None:
    """Each link's tip deflection: estimate, its 95 % band and the held-out measurement;
    then the joint angles (estimate and band)."""
    from flex_model.plots import finish_figure, plt
    r = est.result
    nl, nj = r.tip_deflections.shape[1], r.joint_angles.shape[1]
    fig, ax = plt.subplots(nl + nj, 1, figsize=(10, 2.4 * (nl + nj)), sharex=True)
    ax = np.atleast_1d(ax)
    rows = [f"w{i + 1}" for i in range(nl)] + [f"q{i + 1}" for i in range(nj)]
    for a, c in zip(ax, rows):
        scale, unit = (1e3, "mm") if c[0] == "w" else (1.0, "rad")
        m, sd = estimated_channel(r, c)
        a.fill_between(est.t, scale * (m - Z95 * sd), scale * (m + Z95 * sd), alpha=0.3,
                       color="C0", label="95 % band")
        a.plot(est.t, scale * m, "C0", lw=1.0, label="estimate")
        if c in est.held_out:
            a.plot(est.t, scale * est.held_out[c], "k", lw=0.8, label="held out")
        a.set_ylabel(f"{c} ({unit})")
    ax[-1].set_xlabel("t (s)")
    finish_figure(fig, ax, path, title)
