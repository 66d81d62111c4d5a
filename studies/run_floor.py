"""The model's floor on each held-out Quanser run (issue 22): the calibration's parameters
fitted to that run itself.

A twin fitted elsewhere (the split's fit runs, another session, another unit) cannot do
better on a run than the same model with every parameter the calibration fits chosen for
that run. Per held-out run this fits (:func:`real_arms.calibration.calibrate`) the servo stage on a
rigid-bar run and, on a flexible run, the link and the servo stage together (its unit's
servo may differ) and the lag of its tip gauge if it logs one, from the better of the
shared and the unit's twin, within bounds wider than the calibration's
(:func:`run_parameters`). What it scores bounds the model's floor from above: the search
is local, at most ``max_nfev`` iterations, and the cost rough.
Where it stays above an aim on a run, no parameter set the search reached within these
bounds meets it there.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from flex_twin.real_arms.calibration import (CUBOULDER_SPLIT, GAUGE, FitParameter, calibrate,
                                             link_parameters, servo_parameters, started_from,
                                             widened)

#: the held-out runs of the calibration's split (7 rigid-bar, 10 flexible)
HELD_OUT = CUBOULDER_SPLIT["servo_holdout"] + CUBOULDER_SPLIT["link_holdout"] + (
    "flexibleArm_test_1",)


#: upper bounds wider than the calibration's (F_s - F_c 0.2 N m, Rayleigh a 5 1/s)
UPPER = {"static_excess": 0.4, "rayleigh_mass": 10.0}


def run_parameters(arm, kind: str, gauge: bool = False) -> list:
    """The parameters fitted to one run, started from ``arm``'s values and bounded wider
    than the calibration's: the servo stage (rigid bar: friction, rotor inertia x0.3-6,
    K_t +-5 %), or on a flexible run the link stage (EI and tip mass within x0.5-2) with
    the servo stage and, with ``gauge`` (a run that logs the tip), the gauge's lag
    (:data:`real_arms.calibration.GAUGE`); F_s - F_c and the Rayleigh damping up to
    :data:`UPPER`."""
    servo = servo_parameters(arm)
    params = servo if kind == "rigid" else link_parameters(arm) + [
        p for p in servo if p.name not in ("coulomb", "static_excess")] + (
        [GAUGE["gauge_delay"]] if gauge else [])
    params = [FitParameter(p.name, p.nominal, p.lower, UPPER[p.name], p.start)
              if p.name in UPPER else p for p in widened(params)]
    return started_from(arm, params)


def starts(name: str, kind: str) -> dict:
    """The twins a run's fit may start from: the shared calibrated twin and, for a run of
    a unit with its own twin (:data:`.unit_calibration.UNITS`), that unit's."""
    from flex_model.arm import load_arm
    from flex_twin.real_arms.quanser_twin import calibrated_arm_for
    from .unit_calibration import UNITS
    out = {"shared": calibrated_arm_for("cuboulder", kind)}
    for unit, spec in UNITS.items():
        if kind == "flexible" and name in spec["fit"] + spec["holdout"]:
            out[unit] = load_arm(spec["preset"])
    return out


def fit_run(data_root: str, name: str, max_nfev: int = 12, out: str | None = None) -> dict:
    """One held-out run: the shared calibrated twin's and the run-fitted twin's replay
    errors; the fit starts from the better of :func:`starts` (a top-level function of
    picklable arguments: it runs on a pool or a Dask worker). With ``out``, their overlay
    ``floor_<run>.png`` is written there."""
    from flex_control.state_feedback import lab_policy_factory
    from flex_model.dynamics import FlexArmModel
    from flex_twin.real_arms.calibration import replay_residual
    from flex_twin.real_arms.quanser_data import (CUBOULDER, read_cuboulder_file,
                                                  cuboulder_files)
    from flex_twin.real_arms.replay import plot_replay, replay
    from flex_twin.real_arms.report import metrics_row
    path = next((p for p in cuboulder_files(Path(data_root) / CUBOULDER) if p.name == name),
                None)
    if path is None:
        raise ValueError(f"{name}: no such CU Boulder run under {data_root}")
    run = read_cuboulder_file(path)
    kind = run.kind
    twins = starts(name, kind)
    cost = {k: float(np.sqrt(np.mean(replay_residual(a, [run], lab_policy_factory) ** 2)))
            for k, a in twins.items()} if len(twins) > 1 else {}
    start = min(cost, key=cost.get) if cost else "shared"
    res = calibrate(twins[start], [run], run_parameters(twins[start], kind, run.has_gauge),
                    lab_policy_factory, stage="run", max_nfev=max_nfev)
    row = {"run": name, "kind": kind, "start": start, "start_costs": cost,
           "values": res.values, "evaluations": res.evaluations,
           "cost_run_fit": res.cost_fitted}
    replays = []
    for label, twin in (("calibrated", twins["shared"]), ("run_fit", res.arm)):
        r = replay(FlexArmModel(twin), run, lab_policy_factory)
        r.arm_name = {"calibrated": "calibrated", "run_fit": "fitted to this run"}[label]
        replays.append(r)
        row[label] = metrics_row(r)
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        plot_replay(replays, Path(out) / f"floor_{name.replace('.', '_')}.png")
    return row


def study(data_root, executor, progress=print, max_nfev: int = 12, runs=HELD_OUT,
          out=None) -> dict:
    """:func:`fit_run` on every run of ``runs`` (on ``executor``), in the order given;
    overlays into ``out``."""
    rows = []
    n = len(runs)
    for row in executor.map(fit_run, [str(data_root)] * n, runs, [max_nfev] * n,
                            [None if out is None else str(out)] * n):
        c, f = row["calibrated"], row["run_fit"]
        progress(f"{row['run']}: hub {c['hub_rms_rad']:.4f} -> {f['hub_rms_rad']:.4f} rad"
                 + (f", tip {1e3 * c['tip_rms_m']:.2f} -> {1e3 * f['tip_rms_m']:.2f} mm"
                    if f["tip_rms_m"] is not None else "")
                 + f" (from the {row['start']} twin, {row['evaluations']} evaluations)")
        rows.append(row)
    return {"max_evaluations": max_nfev, "runs": rows, "summary": summarize(rows)}


def summarize(rows, labels=("calibrated", "run_fit")) -> dict:
    """Medians (hub over all rows; tip, ring-down and hold ringing over those with a gauge)
    and how many rows meet the issue's aims (hub 0.01 rad, tip 2 mm, ring-down frequency
    3 %, damping ratio x1.5), for each twin of ``labels`` (default: the calibrated and the
    run-fitted twins)."""
    out = {"runs": len(rows)}
    for label in labels:
        m = [r[label] for r in rows]
        hub = np.array([x["hub_rms_rad"] for x in m])
        tip = np.array([x["tip_rms_m"] for x in m if x["tip_rms_m"] is not None])
        ring = np.array([abs(x["ring_freq_error_pct"]) for x in m
                         if x.get("ring_freq_error_pct") is not None])
        damp = np.array([x["ring_damping_twin"] / x["ring_damping_measured"] for x in m
                         if x.get("ring_damping_measured")])
        hold = np.array([abs(x["hold_freq_error_pct"]) for x in m
                         if x.get("hold_freq_error_pct") is not None])

        def med(v):
            return float(np.median(v)) if len(v) else float("nan")
        out[label] = {"hub_rms_median_rad": med(hub), "hub_under_aim": int(np.sum(hub < 0.01)),
                      "tip_rms_median_m": med(tip), "tip_under_aim": int(np.sum(tip < 0.002)),
                      "with_gauge": len(tip), "ring_freq_error_median_pct": med(ring),
                      "ring_under_aim": int(np.sum(ring < 3.0)), "with_ring": len(ring),
                      "damping_ratio_median": med(damp),
                      "damping_within_aim": int(np.sum((damp > 1 / 1.5) & (damp < 1.5))),
                      "hold_freq_error_median_pct": med(hold)}
    return out


def summary_lines(summary: dict, labels) -> list:
    """The markdown table of :func:`summarize`'s medians and aims, a row per label."""
    lines = ["| twin | hub RMS median (rad) | under 0.01 rad | tip RMS median (mm) | under 2 "
             "mm | ring-down freq. error median | under 3 % | damping ratio twin / lab "
             "median | within x1.5 | hold ringing freq. error median |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for label in labels:
        m = summary[label]
        lines.append(f"| {label} | {m['hub_rms_median_rad']:.4f} | {m['hub_under_aim']} of "
                     f"{summary['runs']} | {1e3 * m['tip_rms_median_m']:.2f} | "
                     f"{m['tip_under_aim']} of {m['with_gauge']} | "
                     f"{m['ring_freq_error_median_pct']:.1f} % | {m['ring_under_aim']} of "
                     f"{m['with_ring']} | {m['damping_ratio_median']:.2f} | "
                     f"{m['damping_within_aim']} of {m['with_ring']} | "
                     f"{m['hold_freq_error_median_pct']:.1f} % |")
    return lines


def change_cells(before: dict, after: dict) -> str:
    """``hub a -> b | tip a -> b`` table cells of two :func:`real_arms.report.metrics_row`
    (rad, mm; ``-`` for a run without a gauge)."""
    tip = (f"{1e3 * before['tip_rms_m']:.2f} -> {1e3 * after['tip_rms_m']:.2f}"
           if after["tip_rms_m"] is not None else "-")
    return f"{before['hub_rms_rad']:.4f} -> {after['hub_rms_rad']:.4f} | {tip}"


def write_report(report: dict, out) -> None:
    """``run_floor.json`` and ``run_floor.md`` (per-run table and medians) in ``out``."""
    from .command import write_study
    s = report["summary"]
    lines = ["# The model's floor: every fitted parameter chosen per held-out run", "",
             "Least squares from the better of the shared calibrated twin and the run's "
             f"unit twin, at most {report['max_evaluations']} iterations per run (the servo "
             "stage on rigid-bar runs, the link and the servo stage on flexible runs; bounds "
             "in run_floor.run_parameters).", "",
             *summary_lines(s, ("calibrated", "run_fit"))]
    lines += ["", "| run | hub RMS calibrated -> run fit (rad) | tip RMS (mm) | start | fitted |",
              "|---|---|---|---|---|"]
    for r in report["runs"]:
        vals = ", ".join(f"{k} {v:.4g}" for k, v in r["values"].items())
        lines.append(f"| {r['run']} | {change_cells(r['calibrated'], r['run_fit'])} | "
                     f"{r['start']} | {vals} |")
    write_study(out, "run_floor", report, lines)


def cmd_floor(args) -> int:
    from flex_twin.cluster import batch_executor
    from flex_twin.real_arms.cli import print_progress, print_report
    from flex_twin.real_arms.quanser_twin import data_root
    out = Path(args.out)
    with batch_executor(args.scheduler, args.workers) as executor:
        report = study(data_root(args.data), executor, print_progress, args.max_evaluations,
                       out=out)
    write_report(report, out)
    return print_report(args, report, out / "run_floor.md")


def build_parser():
    from flex_twin.real_arms.cli import add_data_option
    from .command import add_batch_options, study_parser
    parser = study_parser("run_floor", "the model's floor: the calibration's parameters "
                          "fitted to each held-out run itself (markdown, JSON, PNG; ~15 "
                          "CPU-min)")
    add_data_option(parser)
    parser.add_argument("--max-evaluations", type=int, default=12)
    add_batch_options(parser, "runs/quanser-floor")
    parser.set_defaults(func=cmd_floor)
    return parser


def main(argv=None) -> int:
    """``python -m studies.run_floor [--workers N] [--max-evaluations N] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
