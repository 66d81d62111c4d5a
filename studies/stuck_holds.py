"""The link's own ringing while the hub sticks (issue 22).

While the lab's hub is stuck (:func:`.stiction_evidence.stuck_mask`: at most one encoder
count of travel over 0.1 s) the link rings as a cantilever clamped at the hub with its tip
mass: each such stretch of a hold measures the link's first clamped mode and its own
damping, free of the servo, the amplifier and the friction. A twin's link is compared with
it through its clamped-hub modal analysis (:func:`twin_link`).

- :func:`stuck_holds`: per hold, its longest stuck stretch of at least :data:`MIN_STUCK` s
  that rings at least 2.5 gauge steps peak to peak, fitted with a damped cosine
  (:func:`real_arms.replay.fit_damped_cosine`): frequency, damping ratio, amplitude; with the
  hub angle, the reference and the mean voltage (the motor's holding torque).
- :func:`one_frequency_floor`: how close any twin with one clamped frequency can come to a
  run's stuck stretches: all stretches fitted together with one common frequency and, per
  stretch, its own amplitude, phase, decay and offset (more freedom than a twin has: a
  lower bound). ``run_floor_m`` spreads that squared error over the whole run: no twin of
  one link frequency has a lower tip RMS on the run.
- :func:`twin_link` and :func:`hold_link`: a twin's first clamped mode, and an arm whose
  link has a given clamped frequency (EI scaled) and damping ratio (Rayleigh, mass
  proportional).
"""
from __future__ import annotations

import dataclasses

import numpy as np
from scipy.optimize import least_squares

from flex_model.arm import ArmDescription
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from flex_twin.real_arms.replay import GAUGE_RESOLUTION, fit_damped_cosine
from .stiction_evidence import TORQUE_PER_VOLT, intervals, stuck_mask

#: shortest stuck stretch measured (s)
MIN_STUCK = 1.0
#: the first part of a hold left out: the hub's own stop (s)
SETTLE = 0.3
#: the band in which the clamped mode is sought (Hz)
BAND = (1.0, 5.0)


@dataclasses.dataclass
class StuckHold:
    """One stuck stretch of a hold and its damped-cosine fit (SI units)."""

    run: str
    t_start: float
    t_end: float
    reference_rad: float
    hub_rad: float
    voltage_V: float
    frequency_hz: float
    damping_ratio: float
    amplitude_m: float
    residual_m: float

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


def stuck_holds(run, min_stuck: float = MIN_STUCK) -> list:
    """The stuck stretches of a run's holds (:class:`StuckHold`, at most one per hold)."""
    if not run.has_gauge:
        return []
    stuck = stuck_mask(run)
    skip = int(round(SETTLE / run.dt))
    out = []
    for a, b in run.holds():
        a += skip
        spans = [(i0 + a, i1 + a) for i0, i1 in intervals(stuck[a:b])
                 if (i1 - i0) * run.dt >= min_stuck]
        if not spans:
            continue
        i0, i1 = max(spans, key=lambda s: s[1] - s[0])
        d = run.deflection[i0:i1]
        if np.ptp(d) < 2.5 * GAUGE_RESOLUTION:
            continue
        fit = fit_damped_cosine(run.t[i0:i1] - run.t[i0], d, BAND)
        out.append(StuckHold(run=run.name, t_start=float(run.t[i0]), t_end=float(run.t[i1 - 1]),
                             reference_rad=float(run.reference[i0]),
                             hub_rad=float(np.mean(run.theta[i0:i1])),
                             voltage_V=float(np.mean(run.voltage[i0:i1])),
                             frequency_hz=fit["frequency_hz"],
                             damping_ratio=fit["damping_ratio"],
                             amplitude_m=fit["amplitude_m"], residual_m=fit["residual_rms_m"]))
    return out


def one_frequency_floor(run, holds) -> dict | None:
    """The run's stuck stretches fitted with one common frequency (and per stretch its own
    amplitude, phase, decay rate and offset): the common frequency (Hz), the RMS of the
    stretches' own fits and of the common fit (m), and ``run_floor_m``, the common fit's
    squared error spread over the whole run (m). None without a stuck stretch."""
    if not holds:
        return None
    segs = []
    for h in holds:
        k = (run.t >= h.t_start - 1e-9) & (run.t <= h.t_end + 1e-9)
        segs.append((run.t[k] - h.t_start, run.deflection[k]))

    def residual(p):
        w = p[0]
        return np.concatenate([np.exp(-q[2] * tt) * (q[0] * np.cos(w * tt) + q[1] * np.sin(w * tt))
                               + q[3] - dd for (tt, dd), q in zip(segs, p[1:].reshape(-1, 4))])

    freqs = [h.frequency_hz for h in holds]
    best = None
    for f0 in np.unique(np.round(freqs + [np.median(freqs)], 4)):
        p0 = np.concatenate([[2 * np.pi * f0]] + [[h.amplitude_m, 0.0, 0.05, float(np.mean(dd))]
                                                   for h, (_, dd) in zip(holds, segs)])
        fit = least_squares(residual, p0)
        if best is None or fit.cost < best.cost:
            best = fit
    n_hold = sum(len(tt) for tt, _ in segs)
    sse_own = sum(h.residual_m ** 2 * len(tt) for h, (tt, _) in zip(holds, segs))
    sse = 2.0 * best.cost
    return {"run": run.name, "stretches": len(holds), "stuck_s": n_hold * run.dt,
            "frequencies_hz": freqs, "common_frequency_hz": float(best.x[0] / (2 * np.pi)),
            "hold_rms_own_m": float(np.sqrt(sse_own / n_hold)),
            "hold_rms_common_m": float(np.sqrt(sse / n_hold)),
            "run_floor_m": float(np.sqrt(sse / len(run.t)))}


def twin_link(arm: ArmDescription) -> tuple:
    """The arm's first clamped-hub mode: natural frequency (Hz) and damping ratio."""
    modes = natural_modes(FlexArmModel(arm), joints="clamped")
    return float(modes.frequencies_hz[0]), float(modes.damping_ratio[0])


def hold_link(arm: ArmDescription, frequency_hz: float, damping_ratio: float) -> ArmDescription:
    """The arm with its link's EI scaled to the clamped frequency and a mass-proportional
    Rayleigh damping that gives the first clamped mode ``damping_ratio`` (its ratio is
    linear in the coefficient; measured by the modal analysis, since the Rayleigh mass
    matrix leaves a payload out)."""
    from flex_twin.real_arms.calibration import apply_parameters
    from flex_twin.real_arms.quanser_twin import stiffness_for_frequency
    out = apply_parameters(arm, {"EI": stiffness_for_frequency(arm, frequency_hz),
                                 "rayleigh_mass": 1.0})
    return apply_parameters(out, {"rayleigh_mass": damping_ratio / twin_link(out)[1]})


#: the presets whose clamped link is set against the stuck stretches
TWINS = ("quanser_cuboulder_flexible", "quanser_cuboulder_calibrated",
         "quanser_cuboulder_hagenau_calibrated", "quanser_cuboulder_covington_calibrated")


def fit_hold_link(runs: dict, make_policy, progress=None, max_nfev: int = 12) -> dict:
    """Hagenau's unit twin with its link taken from the stuck stretches of the unit's fit
    runs (median frequency and damping ratio), the rest refitted on those runs: tip mass
    (EI follows it to keep the frequency), F_c, F_s - F_c, F_v and the rotor inertia.
    Its held-out replays against the unit twin's."""
    from flex_model.arm import load_arm
    from flex_twin.real_arms.calibration import (apply_parameters, calibrate, link_parameters,
                                                 servo_parameters, started_from)
    from flex_twin.real_arms.report import metrics_row
    from flex_twin.real_arms.replay import replay
    from .unit_calibration import UNITS
    spec = UNITS["hagenau"]
    stretches = [h for n in spec["fit"] for h in stuck_holds(runs[n])]
    if not stretches:
        raise ValueError(f"no stuck stretch on Hagenau's fit runs {spec['fit']}")
    f = float(np.median([h.frequency_hz for h in stretches]))
    z = float(np.median([h.damping_ratio for h in stretches]))
    unit = load_arm(spec["preset"])
    start = hold_link(unit, f, z)
    names = ("tip_mass", "coulomb", "static_excess", "viscous", "rotor_inertia")
    params = [p for p in started_from(start, link_parameters(start) + servo_parameters(start))
              if p.name in names]
    params = [p for k, p in enumerate(params) if p.name not in {q.name for q in params[:k]}]
    res = calibrate(start, [runs[n] for n in spec["fit"]], params, make_policy,
                    stage="hold link", max_nfev=max_nfev, progress=progress,
                    arm_of=lambda a, v: hold_link(apply_parameters(a, v), f, z))
    held = {}
    for label, arm in (("unit", unit), ("hold_link", res.arm)):
        model = FlexArmModel(arm)
        held[label] = {n: metrics_row(replay(model, runs[n], make_policy))
                       for n in spec["holdout"]}
    return {"frequency_hz": f, "damping_ratio": z, "stretches": len(stretches),
            "values": res.values, "cost_start": res.cost_nominal,
            "cost_fitted": res.cost_fitted, "held_out": held,
            "medians": {label: {"hub_rms_rad": float(np.median([m["hub_rms_rad"]
                                                                for m in rows.values()])),
                                "tip_rms_m": float(np.median([m["tip_rms_m"]
                                                              for m in rows.values()]))}
                        for label, rows in held.items()}}


def rank_correlation(x, y) -> tuple:
    """Spearman's rank correlation of ``x`` and ``y`` and its two-sided p-value: exact by
    permutation for up to 8 pairs, the t approximation above."""
    from scipy.stats import permutation_test, spearmanr
    r = spearmanr(x, y)
    if len(x) > 8:
        return float(r.statistic), float(r.pvalue)
    p = permutation_test((x,), lambda xx: spearmanr(xx, y).statistic, n_resamples=np.inf,
                         permutation_type="pairings").pvalue
    return float(r.statistic), float(p)


def frequency_rank_correlations(stretches) -> dict:
    """Spearman rank correlation (and its p-value) of the stretches' ringing frequency with
    the holding voltage |V| and with the stuck hub angle |theta|: does the clamped link
    ring faster under more holding torque, or at some hub positions? (Empty with fewer than
    three stretches.)"""
    if len(stretches) < 3:
        return {}
    f = [h.frequency_hz for h in stretches]
    out = {}
    for key, x in (("holding_voltage", [abs(h.voltage_V) for h in stretches]),
                   ("hub_angle", [abs(h.hub_rad) for h in stretches])):
        rho, p = rank_correlation(x, f)
        out[key] = {"spearman": rho, "p_value": p}
    return out


def study(runs: dict, make_policy=None, progress=print, fit_link: bool = False,
          max_nfev: int = 12) -> dict:
    """Stuck stretches and one-frequency floors of ``runs`` ({name: LabRun}), the twins'
    clamped links (:data:`TWINS`); with ``fit_link`` also :func:`fit_hold_link`."""
    from flex_model.arm import load_arm
    holds = {n: stuck_holds(r) for n, r in runs.items()}
    stretches = [h for hs in holds.values() for h in hs]
    floors = [one_frequency_floor(runs[n], hs) for n, hs in holds.items() if hs]
    twins = {}
    for name in TWINS:
        try:
            twins[name] = dict(zip(("frequency_hz", "damping_ratio"),
                                   twin_link(load_arm(name))))
        except ValueError as exc:   # a calibrated preset not written yet
            progress(f"{name}: {exc}")
    freq = [h.frequency_hz for h in stretches]
    report = {"stretches": [h.as_dict() for h in stretches], "floors": floors, "twins": twins,
              "summary": {"stretches": len(stretches), "runs": len(floors),
                          "frequency_min_hz": min(freq, default=None),
                          "frequency_max_hz": max(freq, default=None),
                          "frequency_median_hz": float(np.median(freq)) if freq else None,
                          "damping_median": (float(np.median([h.damping_ratio
                                                              for h in stretches]))
                                             if stretches else None),
                          "run_floor_max_m": max((f["run_floor_m"] for f in floors),
                                                 default=None),
                          "rank_correlation": frequency_rank_correlations(stretches)}}
    if fit_link:
        progress("fitting the hold link (Hagenau's fit runs, a few minutes)")
        report["hold_link_fit"] = fit_hold_link(
            runs, make_policy, lambda k, cost, _: progress(f"  {k}: cost {cost:.3f}"),
            max_nfev)
    return report


def plot(report: dict, path) -> None:
    """Stuck-stretch frequency against the mean holding voltage, one marker per run, the
    twins' clamped frequencies as lines."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    runs = sorted({h["run"] for h in report["stretches"]})
    for k, run in enumerate(runs):
        hs = [h for h in report["stretches"] if h["run"] == run]
        ax.plot([h["voltage_V"] for h in hs], [h["frequency_hz"] for h in hs], "osD^v<>"[k % 7],
                ms=8, label=run)
    for k, (name, tw) in enumerate(report["twins"].items()):
        ax.axhline(tw["frequency_hz"], ls="--", color=f"C{k + len(runs)}", lw=1,
                   label=f"{name} (clamped)")
    ax.set_xlabel(f"mean voltage while stuck (V): holding torque {TORQUE_PER_VOLT:.3f} N m/V")
    ax.set_ylabel("tip ringing frequency, hub stuck (Hz)")
    ax.set_title("The link's ringing while the lab hub sticks")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_report(report: dict, out) -> None:
    """``stuck_holds.json``, ``stuck_holds.md`` and ``stuck_holds.png`` in ``out``."""
    from .command import write_study
    lines = ["# The link's ringing while the hub sticks", "",
             "| run | stuck (s) | reference (rad) | hub (rad) | mean V | frequency (Hz) | "
             "damping ratio | amplitude (mm) | fit residual (mm) |",
             "|---|---|---|---|---|---|---|---|---|"]
    for h in report["stretches"]:
        lines.append(f"| {h['run']} | {h['t_start']:.2f}-{h['t_end']:.2f} | "
                     f"{h['reference_rad']:+.2f} | {h['hub_rad']:+.3f} | {h['voltage_V']:+.2f} "
                     f"| {h['frequency_hz']:.3f} | {h['damping_ratio']:.4f} | "
                     f"{1e3 * h['amplitude_m']:.1f} | {1e3 * h['residual_m']:.2f} |")
    rank = report["summary"].get("rank_correlation") or {}
    if rank:
        lines += ["", "Frequency against the holding voltage |V| and the stuck hub angle "
                  "|theta| (Spearman rank correlation over the stretches): " + "; ".join(
                      f"{k.replace('_', ' ')} {c['spearman']:+.2f} (p {c['p_value']:.3f})"
                      for k, c in rank.items()) + "."]
    lines += ["", "One clamped frequency per run (per stretch its own amplitude, phase, decay "
              "and offset): the least tip RMS any twin of one link frequency can have.", "",
              "| run | stretches | common frequency (Hz) | stuck RMS own fits (mm) | "
              "stuck RMS one frequency (mm) | floor over the run (mm) |",
              "|---|---|---|---|---|---|"]
    for f in report["floors"]:
        lines.append(f"| {f['run']} | {f['stretches']} | {f['common_frequency_hz']:.3f} | "
                     f"{1e3 * f['hold_rms_own_m']:.2f} | {1e3 * f['hold_rms_common_m']:.2f} | "
                     f"{1e3 * f['run_floor_m']:.2f} |")
    lines += ["", "| twin | clamped frequency (Hz) | damping ratio |", "|---|---|---|"]
    for name, tw in report["twins"].items():
        lines.append(f"| {name} | {tw['frequency_hz']:.3f} | {tw['damping_ratio']:.4f} |")
    fit = report.get("hold_link_fit")
    if fit:
        m = fit["medians"]
        lines += ["", f"Hagenau's twin with the link of its fit runs' {fit['stretches']} stuck "
                  f"stretches ({fit['frequency_hz']:.3f} Hz, damping ratio "
                  f"{fit['damping_ratio']:.4f}), the rest refitted: "
                  + ", ".join(f"{k} {v:.4g}" for k, v in fit["values"].items()), "",
                  "| held-out run | unit twin hub / tip (tip's share in the 0.75 s after the "
                  "steps) | hold-link twin hub / tip (share) |", "|---|---|---|"]
        for n, u in fit["held_out"]["unit"].items():
            h = fit["held_out"]["hold_link"][n]
            lines.append(f"| {n} | " + " | ".join(
                f"{x['hub_rms_rad']:.4f} rad / {1e3 * x['tip_rms_m']:.2f} mm "
                f"({100 * x['tip_transient_share']:.0f} %)" for x in (u, h)) + " |")
        lines.append(f"| median | {m['unit']['hub_rms_rad']:.4f} / "
                     f"{1e3 * m['unit']['tip_rms_m']:.2f} | {m['hold_link']['hub_rms_rad']:.4f}"
                     f" / {1e3 * m['hold_link']['tip_rms_m']:.2f} |")
    plot(report, write_study(out, "stuck_holds", report, lines).parent / "stuck_holds.png")


def cmd_holds(args) -> int:
    from pathlib import Path
    from flex_twin.real_arms.cli import lab_policy, print_progress, print_report
    from flex_twin.real_arms.quanser_data import CUBOULDER, read_cuboulder
    from flex_twin.real_arms.quanser_twin import data_root
    out = Path(args.out)
    report = study(read_cuboulder(data_root(args.data) / CUBOULDER), lab_policy(),
                   print_progress, fit_link=args.fit, max_nfev=args.max_evaluations)
    write_report(report, out)
    return print_report(args, report, out / "stuck_holds.md")


def build_parser():
    from flex_twin.real_arms.cli import add_data_option
    from .command import study_parser
    parser = study_parser("stuck_holds", "the link's ringing while the lab hub sticks: "
                          "frequency and damping per stuck stretch, the floor of a twin of "
                          "one link frequency, the twins' clamped links (markdown, PNG, "
                          "JSON; --fit: a twin with that link, ~2 CPU-min)")
    add_data_option(parser)
    parser.add_argument("--out", default="runs/quanser-holds", help="output directory")
    parser.add_argument("--fit", action="store_true", help="refit Hagenau's twin around "
                        "the link of its fit runs' stuck stretches and replay its held-out "
                        "runs")
    parser.add_argument("--max-evaluations", type=int, default=12)
    parser.add_argument("--json", action="store_true")
    parser.set_defaults(func=cmd_holds)
    return parser


def main(argv=None) -> int:
    """``python -m studies.stuck_holds [--fit] [--out DIR] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
