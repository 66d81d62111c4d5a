"""One servo for the rigid-bar and the flexible-link runs (issue 22).

The calibration fits the servo on the rigid-bar runs alone
(:data:`real_arms.calibration.CUBOULDER_SPLIT`): rotor inertia 3.7x the handout and K_t at
-5 %, its tolerance; fitted to the flexible runs themselves, the servo takes K_t at the top
of its bound (+5 % over the calibrated value: the handout's) and less rotor inertia
(``studies.run_floor``). The rigid bar's inertia (handout J_load 0.0015 kg m^2) adds to the
rotor's reflected inertia Kg^2 J_r in those runs, and only there: if the bar were heavier
than the handout says, the rigid runs would put its excess on the rotor.

:func:`joint_fit` tests that: one least-squares fit
(:func:`real_arms.calibration.fit_values`) of the rigid fit runs (first
:data:`real_arms.calibration.SERVO_WINDOW` s) and the link fit runs together, the rotor
inertia and K_t shared, the bar's inertia free (x0.5-8 of the handout) with the rigid runs'
friction, the link stage (:func:`real_arms.calibration.link_parameters`, EI and tip mass
x0.5-2) with the gauge's lag on the flexible ones; started from the stored twins at the
best point of a grid of K_t (within ``kt_tolerance`` of the handout's) and rotor inertia
(:func:`grid_starts`). :func:`study` scores the two twins it gives against the stored ones
on the 17 held-out runs.
"""
from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_twin.real_arms.calibration import (CUBOULDER_SPLIT, SERVO_WINDOW, FitParameter,
                                             apply_parameters, fit_values, link_parameters,
                                             replay_residual, servo_parameters, started_from,
                                             with_gauge)
from flex_twin.real_arms.quanser_twin import (hub_inertia, nominal_arm_for,
                                              stored_calibrated_arm)
from flex_twin.real_arms.replay import replay
from flex_twin.real_arms.report import metrics_row
from .command import write_study
from .run_floor import HELD_OUT, change_cells, summarize, summary_lines

#: the servo's parameters both setups share
SHARED = ("rotor_inertia", "torque_constant")
#: prefix of the rigid-bar runs' own friction parameters
RIGID = "rigid_"
#: the handout's rigid bar (quanser_cuboulder_rigid: J_minus of its short stiff link)
BAR_INERTIA = 0.0015
#: the bar's inertia is free within these multiples of the handout's
BAR_RANGE = (0.5, 8.0)
#: the start grid's rotor inertias, times the stored twin's (3.7x the handout: 0.3 is 1.1x)
ROTOR_SCAN = (1.0, 0.8, 0.6, 0.45, 0.3)


def joint_parameters(rigid, flexible, kt_tolerance: float = 0.05) -> list:
    """The joint fit's unknowns: the shared rotor inertia (x0.3-6 of the handout, started
    from the ``flexible`` twin's) and K_t (within ``kt_tolerance`` of the handout's, from
    it), the bar's inertia and the rigid runs' friction (``rigid_*``) from the ``rigid``
    twin's, the link stage with the gauge's lag from the ``flexible`` twin's."""
    nominal = nominal_arm_for("cuboulder", "rigid")
    kt = nominal.effect("dc_motor", nominal.joint_names[0])["torque_constant"]
    servo = {p.name: p for p in servo_parameters(nominal)}
    shared = [servo["rotor_inertia"], FitParameter("torque_constant", kt,
                                                   (1 - kt_tolerance) * kt,
                                                   (1 + kt_tolerance) * kt)]
    own = [dataclasses.replace(p, name=RIGID + p.name) for p in started_from(
        rigid, [servo[n] for n in ("coulomb", "static_excess", "viscous")])]
    bar = FitParameter("bar_inertia", BAR_INERTIA, BAR_RANGE[0] * BAR_INERTIA,
                       BAR_RANGE[1] * BAR_INERTIA, rigid.links[0].J_minus)
    link = started_from(flexible, with_gauge(link_parameters(flexible), ("gauge_delay",)))
    return started_from(flexible, shared) + own + [bar] + link


def joint_arms(rigid, flexible, values: dict) -> tuple:
    """The (rigid-bar, flexible) twins with the joint fit's ``values`` applied."""
    shared = {k: values[k] for k in SHARED if k in values}
    r = apply_parameters(rigid, {**shared, **{k[len(RIGID):]: v for k, v in values.items()
                                              if k.startswith(RIGID)}})
    if "bar_inertia" in values:
        r = dataclasses.replace(r, links=(dataclasses.replace(
            r.links[0], J_minus=values["bar_inertia"]),) + r.links[1:])
    f = apply_parameters(flexible, {k: v for k, v in values.items()
                                    if not k.startswith(RIGID) and k != "bar_inertia"})
    return r, f


def grid_starts(rigid, params: list, kt_tolerance: float) -> list:
    """The start grid: K_t at the handout's and at both ends of its tolerance, the rotor
    inertia at :data:`ROTOR_SCAN` times its start, each with the bar's inertia that keeps
    the rigid twin's torque per hub inertia K_t / (Kg^2 J_r + J_bar)
    (:func:`real_arms.quanser_twin.hub_inertia`) where the bar's bounds allow (clipped into them).
    Along such a line the rigid-bar runs replay alike, so the grid scans what the flexible
    runs say about the split of the inertia between rotor and bar."""
    p = {x.name: x for x in params}
    gear = rigid.effect("gear", rigid.joint_names[0])
    kt_now = rigid.effect("dc_motor", rigid.joint_names[0])["torque_constant"]
    per_kt = hub_inertia(rigid) / kt_now
    kt0, jr0, bar = p["torque_constant"].nominal, p["rotor_inertia"].start, p["bar_inertia"]
    out = []
    for kt in (kt0, (1 - kt_tolerance) * kt0, (1 + kt_tolerance) * kt0):
        for jr in (f * jr0 for f in ROTOR_SCAN):
            j_bar = per_kt * kt - gear["ratio"] ** 2 * jr
            out.append({"torque_constant": kt, "rotor_inertia": jr,
                        "bar_inertia": min(max(j_bar, bar.lower), bar.upper)})
    return out


def stored_twins() -> dict:
    """The stored calibrated twins, {"rigid": ..., "flexible": ...}."""
    return {k: stored_calibrated_arm(k) for k in ("rigid", "flexible")}


def joint_fit(runs: dict, make_policy: Callable, kt_tolerance: float = 0.05,
              max_nfev: int = 10, progress: Callable | None = None,
              twins: dict | None = None) -> dict:
    """The joint fit from the stored calibrated twins (``twins``, default
    :func:`stored_twins`), started from the best point of :func:`grid_starts`: the fitted
    values, the scaled RMS residual of the fit runs on the stored twins, at every grid
    point and fitted, and the evaluations (all counted)."""
    twins = twins or stored_twins()
    rigid, flexible = twins["rigid"], twins["flexible"]
    rigid_runs = [runs[n] for n in CUBOULDER_SPLIT["servo_fit"]]
    link_runs = [runs[n] for n in CUBOULDER_SPLIT["link_fit"]]

    def residual(values):
        r, f = joint_arms(rigid, flexible, values)
        return np.concatenate([replay_residual(r, rigid_runs, make_policy, SERVO_WINDOW),
                               replay_residual(f, link_runs, make_policy)])

    def cost(values):
        return float(np.sqrt(np.mean(residual(values) ** 2)))
    params = joint_parameters(rigid, flexible, kt_tolerance)
    starts = {x.name: x.nominal if x.start is None else x.start for x in params}
    grid = []
    for g in grid_starts(rigid, params, kt_tolerance):
        grid.append({"cost": cost({**starts, **g}), **g})
        if progress is not None:
            progress(0, grid[-1]["cost"], g)
    best = min(grid, key=lambda g: g["cost"])
    params = [dataclasses.replace(x, start=best[x.name]) if x.name in best else x
              for x in params]
    values, fitted, count = fit_values(params, residual, max_nfev, progress)
    return {"values": values, "kt_tolerance": kt_tolerance,
            "evaluations": count + len(grid) + 1, "cost_stored": cost({}),
            "cost_grid": best["cost"], "cost_fitted": fitted, "grid": grid,
            "runs": [r.name for r in rigid_runs + link_runs]}


def study(runs: dict, make_policy: Callable, out, kt_tolerance: float = 0.05,
          max_nfev: int = 10, progress: Callable = print) -> dict:
    """:func:`joint_fit`, then the stored twins and the joint fit's on every held-out run;
    ``servo_split.md`` and ``.json`` in ``out``."""
    stored = stored_twins()
    fit = joint_fit(runs, make_policy, kt_tolerance, max_nfev,
                    lambda k, c, v: progress(f"  evaluation {k or 'of the start grid'}: "
                                             f"scaled RMS residual {c:.4f}"), stored)
    joint = dict(zip(("rigid", "flexible"),
                     joint_arms(stored["rigid"], stored["flexible"], fit["values"])))
    rows = []
    for name in HELD_OUT:
        run = runs[name]
        row = {"run": name, "kind": run.kind}
        for label, arms in (("calibrated", stored), ("joint_servo", joint)):
            row[label] = metrics_row(replay(FlexArmModel(arms[run.kind]), run, make_policy))
        progress(f"{name}: hub {row['calibrated']['hub_rms_rad']:.4f} -> "
                 f"{row['joint_servo']['hub_rms_rad']:.4f} rad")
        rows.append(row)
    report = {**fit, "held_out": rows,
              "summary": summarize(rows, ("calibrated", "joint_servo"))}
    write_report(report, out)
    return report


def write_report(report: dict, out) -> None:
    """``servo_split.md`` (the fit, the medians, a row per run) and ``.json`` in ``out``."""
    v = report["values"]
    nominal = nominal_arm_for("cuboulder", "rigid")
    jr = nominal.effect("gear", nominal.joint_names[0])["rotor_inertia"]
    kt = nominal.effect("dc_motor", nominal.joint_names[0])["torque_constant"]
    n = len(ROTOR_SCAN)
    clipped = [r * BAR_INERTIA for r in BAR_RANGE]
    lines = ["# One servo for the rigid-bar and the flexible runs, the bar's inertia free", "",
             f"Fit runs: {', '.join(report['runs'])}; scaled RMS residual "
             f"{report['cost_stored']:.3f} (the stored twins), {report['cost_grid']:.3f} (the "
             f"start grid's best) -> {report['cost_fitted']:.3f}, {report['evaluations']} "
             f"evaluations; K_t within {100 * report['kt_tolerance']:.0f} % of the "
             "handout's.", "",
             f"Shared servo: rotor inertia {v['rotor_inertia']:.4g} kg m^2 "
             f"({v['rotor_inertia'] / jr:.2f}x the handout), K_t {v['torque_constant']:.4g}"
             f" N m/A ({100 * (v['torque_constant'] / kt - 1):+.1f} %); rigid bar "
             f"{v['bar_inertia']:.4g} kg m^2 ({v['bar_inertia'] / BAR_INERTIA:.2f}x the "
             "handout's).", "",
             "Fitted: " + ", ".join(f"{k} {x:.4g}" for k, x in v.items()), "",
             "The start grid: scaled RMS residual of the fit runs, the bar's inertia keeping "
             "the rigid runs' torque per inertia (clipped into its bounds where marked *).",
             "", "| K_t / handout | " + " | ".join(
                 f"rotor {g['rotor_inertia'] / jr:.2f}x" for g in report["grid"][:n]) + " |",
             "|---" * (n + 1) + "|"]
    for i in range(0, len(report["grid"]), n):
        row = report["grid"][i:i + n]
        lines.append(f"| {row[0]['torque_constant'] / kt:.3f} | " + " | ".join(
            f"{g['cost']:.3f} (bar {g['bar_inertia'] / BAR_INERTIA:.2f}x"
            f"{'*' if g['bar_inertia'] in clipped else ''})" for g in row) + " |")
    lines += ["", "Held out: the stored calibrated twins (calibrated) and the joint fit's.", "",
              *summary_lines(report["summary"], ("calibrated", "joint_servo")), "",
              "| run | hub RMS calibrated -> joint servo (rad) | tip RMS (mm) |",
              "|---|---|---|"]
    lines += [f"| {r['run']} | {change_cells(r['calibrated'], r['joint_servo'])} |"
              for r in report["held_out"]]
    write_study(out, "servo_split", report, lines)


def cmd_servo_split(args) -> int:
    from pathlib import Path
    from flex_twin.real_arms.cli import lab_policy, print_progress, print_report
    from flex_twin.real_arms.quanser_data import CUBOULDER, read_cuboulder
    from flex_twin.real_arms.quanser_twin import data_root
    out = Path(args.out)
    report = study(read_cuboulder(data_root(args.data) / CUBOULDER), lab_policy(), out,
                   args.kt_tolerance, args.max_evaluations, print_progress)
    return print_report(args, report, out / "servo_split.md")


def build_parser():
    from flex_twin.real_arms.cli import add_data_option
    from .command import study_parser
    parser = study_parser("servo_split", "one servo fitted to the rigid-bar and the "
                          "flexible fit runs together, the rigid bar's inertia free, scored "
                          "on the held-out runs (markdown, JSON; ~5-10 CPU-min)")
    add_data_option(parser)
    parser.add_argument("--kt-tolerance", type=float, default=0.05, help="K_t free within "
                        "this fraction of the handout's (default 0.05, its tolerance)")
    parser.add_argument("--max-evaluations", type=int, default=10)
    parser.add_argument("--out", default="runs/quanser-servo-split", help="output directory")
    parser.add_argument("--json", action="store_true")
    parser.set_defaults(func=cmd_servo_split)
    return parser


def main(argv=None) -> int:
    """``python -m studies.servo_split [--kt-tolerance F] [--max-evaluations N] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
