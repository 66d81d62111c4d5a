"""The model's floor on each held-out Quanser run (issue 22): the calibration's parameters
fitted to that run itself.

A twin fitted elsewhere (the split's fit runs, another session, another unit) cannot do
better on a run than the same model with every fitted parameter chosen for that run. Per
held-out run this fits (:func:`.calibration.calibrate`) the servo stage on a rigid-bar run
and, on a flexible run, the link stage plus the rotor inertia and torque constant (its
unit's servo may differ), from the better of the shared and the unit's twin. What it
scores bounds the model's floor from above (the search is local and the cost rough, as in
the calibration): where it stays above an aim, the search found no choice of these
parameters that meets the aim on that run, evidence that the limit is the model's form
rather than the spread of its parameters between runs.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .calibration import (CUBOULDER_SPLIT, FitParameter, calibrate, link_parameters,
                          servo_parameters)

#: the held-out runs of the calibration's split (7 rigid-bar, 10 flexible)
HELD_OUT = CUBOULDER_SPLIT["servo_holdout"] + CUBOULDER_SPLIT["link_holdout"] + (
    "flexibleArm_test_1",)


def run_parameters(arm, kind: str) -> list:
    """The parameters fitted to one run, each started from the calibrated twin's value:
    the servo stage (rigid bar), or the link stage (EI within x0.5-1.5) with the rotor
    inertia (x0.5-2 of the calibrated) and the torque constant (flexible)."""
    servo = {p.name: p for p in servo_parameters(arm)}
    jr = servo["rotor_inertia"].nominal
    link = [FitParameter("EI", p.nominal, 0.5 * p.nominal, 1.5 * p.nominal)
            if p.name == "EI" else p for p in link_parameters(arm)]
    params = (list(servo.values()) if kind == "rigid" else link + [
        FitParameter("rotor_inertia", jr, 0.5 * jr, 2.0 * jr), servo["torque_constant"]])
    fr = arm.effect("joint_friction", arm.joint_names[0])
    damping = arm.effect("structural_damping", arm.links[0].name)
    now = {"coulomb": fr["coulomb"], "static_excess": fr["static"] - fr["coulomb"],
           "viscous": fr["viscous"], "rotor_inertia": jr}
    if damping is not None:
        now["rayleigh_mass"] = damping["rayleigh_mass"]
    return [FitParameter(p.name, p.nominal, p.lower, p.upper,
                         min(max(now.get(p.name, p.nominal), p.lower), p.upper))
            for p in params]


def starts(name: str, kind: str) -> dict:
    """The twins a run's fit may start from: the shared calibrated twin and, for a run of
    a unit with its own twin (:data:`.unit_calibration.UNITS`), that unit's."""
    from flex_model.arm import load_arm
    from .quanser_twin import calibrated_arm_for
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
    from .calibration import replay_residual
    from .quanser_data import CUBOULDER, read_cuboulder_file, cuboulder_files
    from .replay import plot_replay, replay
    from .stick_slip_study import _kind, mechanical_policy
    path = next(p for p in cuboulder_files(Path(data_root) / CUBOULDER) if p.name == name)
    run = read_cuboulder_file(path)
    kind = _kind(name)
    policy = mechanical_policy(lab_policy_factory)
    twins = starts(name, kind)
    cost = {k: float(np.sqrt(np.mean(replay_residual(a, [run], policy) ** 2)))
            for k, a in twins.items()}
    start = min(cost, key=cost.get)
    res = calibrate(twins[start], [run], run_parameters(twins[start], kind), policy,
                    stage="run", max_nfev=max_nfev)
    row = {"run": name, "kind": kind, "start": start, "start_costs": cost,
           "values": res.values, "evaluations": res.evaluations,
           "cost_run_fit": res.cost_fitted}
    replays = []
    for label, twin in (("calibrated", twins["shared"]), ("run_fit", res.arm)):
        r = replay(FlexArmModel(twin), run, policy)
        r.arm_name = {"calibrated": "calibrated", "run_fit": "fitted to this run"}[label]
        replays.append(r)
        row[label] = {"hub_rms_rad": r.metrics["hub_rms_rad"],
                      "tip_rms_m": r.metrics.get("tip_rms_m")}
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


def summarize(rows) -> dict:
    """Medians (hub over all rows, tip over those with a gauge) and how many rows meet the
    aims (0.01 rad, 2 mm), for the calibrated and the run-fitted twins."""
    out = {"runs": len(rows)}
    for label in ("calibrated", "run_fit"):
        hub = np.array([r[label]["hub_rms_rad"] for r in rows])
        tip = np.array([r[label]["tip_rms_m"] for r in rows
                        if r[label]["tip_rms_m"] is not None])
        out[label] = {"hub_rms_median_rad": float(np.median(hub)),
                      "hub_under_aim": int(np.sum(hub < 0.01)),
                      "tip_rms_median_m": float(np.median(tip)) if len(tip) else float("nan"),
                      "tip_under_aim": int(np.sum(tip < 0.002)), "with_gauge": len(tip)}
    return out


def write_report(report: dict, out) -> None:
    """``run_floor.json`` and ``run_floor.md`` (per-run table and medians) in ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "run_floor.json").write_text(json.dumps(report, indent=1))
    s = report["summary"]
    lines = ["# The model's floor: every fitted parameter chosen per held-out run", "",
             "Least squares from the better of the shared calibrated twin and the run's "
             f"unit twin, at most {report['max_evaluations']} iterations per run (servo "
             "stage on rigid-bar runs; link stage, rotor inertia and torque constant on "
             "flexible runs).", "",
             "| twin | hub RMS median (rad) | runs under 0.01 rad | tip RMS median (mm) | "
             "runs under 2 mm |", "|---|---|---|---|---|"]
    for label in ("calibrated", "run_fit"):
        m = s[label]
        lines.append(f"| {label} | {m['hub_rms_median_rad']:.4f} | {m['hub_under_aim']} of "
                     f"{s['runs']} | {1e3 * m['tip_rms_median_m']:.2f} | {m['tip_under_aim']}"
                     f" of {m['with_gauge']} |")
    lines += ["", "| run | hub RMS calibrated -> run fit (rad) | tip RMS (mm) | start | fitted |",
              "|---|---|---|---|---|"]
    for r in report["runs"]:
        c, f = r["calibrated"], r["run_fit"]
        tip = (f"{1e3 * c['tip_rms_m']:.2f} -> {1e3 * f['tip_rms_m']:.2f}"
               if f["tip_rms_m"] is not None else "-")
        vals = ", ".join(f"{k} {v:.4g}" for k, v in r["values"].items())
        lines.append(f"| {r['run']} | {c['hub_rms_rad']:.4f} -> {f['hub_rms_rad']:.4f} | "
                     f"{tip} | {r['start']} | {vals} |")
    (out / "run_floor.md").write_text("\n".join(lines) + "\n")
