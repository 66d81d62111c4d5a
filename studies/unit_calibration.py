"""One link twin per hardware unit (issue 22): the CU Boulder runs come from several SRV02 +
flexible-link units (PROVENANCE: two student groups; Hagenau's folder also holds the runs
of groups 37 and "Unit7"), and the shared calibrated twin fits one link to all of them.

A unit with a run to fit and runs to hold out gets its own link stage
(:func:`calibration.link_parameters`: EI, Rayleigh damping, tip mass, hub friction),
started from the shared calibrated twin (its servo kept): Hagenau's own flexible runs
(fit: the split's two Hagenau link-fit runs) and Covington's (fit: flexibleArm_test_3,
which test_4 repeats; test_2 runs other gains). Groups 37 and Unit7 log one flexible run
each and keep the shared twin. :func:`compare` replays the held-out runs on both.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Callable

import numpy as np

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_twin.real_arms.calibration import (calibrate, calibrated_dict, gauge_options,
                                             link_parameters, started_from, with_gauge,
                                             write_preset)
from flex_twin.real_arms.quanser_twin import stored_calibrated_arm
from flex_twin.real_arms.replay import plot_replay, replay
from flex_twin.real_arms.report import fmt, metrics_row

#: per unit: its preset, the link-fit runs and the held-out runs (of that unit only)
UNITS = {
    "hagenau": {"preset": "quanser_cuboulder_hagenau_calibrated",
                "fit": ("flexarm_K1_6", "flexarm_K1K2K3k4_6_-3_213_4"),
                "holdout": ("flexarm_k1k2_6_-3", "flexarm_K1K2_6_-5",
                            "flexarm_K1K2K3_6_-3_213", "flexarm_K1K2K3_6_-5_213",
                            "flexarm_K1K2K3k4_6_-3_213_2")},
    "covington": {"preset": "quanser_cuboulder_covington_calibrated",
                  "fit": ("flexibleArm_test_3",),
                  "holdout": ("flexibleArm_test_2", "flexibleArm_test_4",
                              "flexibleArm_test_1")},
}
#: the shared twin's runs of no unit above: one flexible run per unit, nothing to hold out
SINGLE_RUN_UNITS = ("4PM_Group37_FlexArm_Unit6", "Unit7_Flex_trial1.csv")


def calibrate_unit(unit: str, runs: dict, make_policy: Callable, *, max_nfev: int = 12,
                   progress: Callable | None = None, gauge: tuple = (),
                   from_unit: bool = False):
    """The link stage on the unit's fit runs, started from the shared calibrated flexible
    twin's values (EI, tip mass, damping, friction), or with ``from_unit`` from the unit's
    stored preset; with ``gauge`` (:func:`calibration.with_gauge`) also the lab's tip gauge's gain
    and/or delay (EI and tip mass then within x0.5-2 of the start)."""
    spec = UNITS[unit]
    start = load_arm(spec["preset"]) if from_unit else stored_calibrated_arm("flexible")
    params = started_from(start, with_gauge(link_parameters(start), gauge))
    return calibrate(start, [runs[n] for n in spec["fit"]], params, make_policy,
                     stage=f"link@{unit}", max_nfev=max_nfev, progress=progress)


def write_unit_preset(unit: str, result, out_dir, options: str = "",
                      from_unit: bool = False) -> Path:
    """``<preset>.yaml``: the shared calibrated twin with the unit's link values (its
    header names the ``units --fit`` ``options`` that made it); ``from_unit``: the unit's
    stored twin with them (what the fit did not free, such as its gauge, kept)."""
    from flex_model.arm import resolve_preset
    from flex_model.config import read_yaml
    name = UNITS[unit]["preset"]
    base = read_yaml(resolve_preset(name if from_unit else "quanser_cuboulder_calibrated"))
    fr = next(e for e in base["effects"] if e["type"] == "joint_friction")
    data = calibrated_dict(base, {"viscous": fr["viscous"], **result.values}, name)
    data["description"] = (f"Quanser SRV02 + flexible link, {unit}'s unit: the shared "
                           "calibrated twin with its own link stage (issue 22)")
    start = f", started from the stored {name}" if from_unit else ""
    return write_preset(data, Path(out_dir) / f"{name}.yaml", "quanser_cuboulder_calibrated "
                        "with the link refitted by python -m studies.unit_calibration "
                        f"--fit{options}{start} (issue 22)", result)


def compare(runs: dict, make_policy: Callable, out=None, presets: dict | None = None,
            progress: Callable = print) -> dict:
    """Every unit's fit and held-out runs on the shared twin and on the unit's own;
    ``presets`` maps a unit to an arm (name, path or ArmDescription; default its
    preset). Overlay PNGs when ``out`` is given."""
    shared_arm = stored_calibrated_arm("flexible")
    shared = FlexArmModel(shared_arm)
    rows = []
    for unit, spec in UNITS.items():
        arm = (presets or {}).get(unit, spec["preset"])
        own = FlexArmModel(load_arm(arm) if isinstance(arm, (str, Path)) else arm)
        for name in spec["fit"] + spec["holdout"]:
            a, b = replay(shared, runs[name], make_policy), replay(own, runs[name],
                                                                   make_policy)
            a.arm_name, b.arm_name = "shared calibrated", f"{unit}'s unit"
            rows.append({"unit": unit, "run": name,
                         "role": "fit" if name in spec["fit"] else "held out",
                         "shared": metrics_row(a), "unit_twin": metrics_row(b)})
            if out is not None:
                plot_replay([a, b], Path(out) / f"unit_{name.replace('.', '_')}.png")
            progress(f"{unit} {name}: hub {a.metrics['hub_rms_rad']:.4f} -> "
                     f"{b.metrics['hub_rms_rad']:.4f} rad")
    return {"rows": rows, "summary": summarize(rows)}


def summarize(rows) -> dict:
    """Medians over the held-out runs (with a gauge for tip and ring-down)."""
    held = [r for r in rows if r["role"] == "held out"]

    def med(which, key, absolute=False):
        v = [r[which][key] for r in held if r[which].get(key) is not None]
        v = np.abs(v) if absolute else np.asarray(v)
        return float(np.median(v)) if len(v) else None
    return {f"{k}_{w}": med(w, k, k.endswith("error_pct"))
            for w in ("shared", "unit_twin")
            for k in ("hub_rms_rad", "tip_rms_m", "ring_freq_error_pct",
                      "hold_freq_error_pct")} | {
        "held_out_runs": len(held),
        "tip_runs": sum(r["shared"].get("tip_rms_m") is not None for r in held)}


def write_markdown(report: dict, path) -> None:
    """The comparison as a table and the held-out medians."""
    lines = ["# The Quanser twin per hardware unit (issue 22)", "",
             "Shared calibrated twin (one link fitted to three units' runs) against each "
             "unit's own link stage (fitted on that unit's fit runs only); closed-loop "
             "replays with the lab's law.", "",
             "| unit | run | role | hub RMS shared / unit (rad) | tip RMS shared / unit (mm) |"
             " ring-down lab / shared / unit (Hz) | hold ringing lab / shared / unit (Hz) |",
             "|---|---|---|---|---|---|---|"]
    for r in report["rows"]:
        a, b = r["shared"], r["unit_twin"]
        lines.append(f"| {r['unit']} | {r['run']} | {r['role']} | {fmt(a['hub_rms_rad'])} /"
                     f" {fmt(b['hub_rms_rad'])} | {fmt(a['tip_rms_m'], 1e3, 3)} / "
                     f"{fmt(b['tip_rms_m'], 1e3, 3)} | "
                     f"{fmt(a['ring_freq_measured_hz'], 1, 3)} / "
                     f"{fmt(a['ring_freq_twin_hz'], 1, 3)} / "
                     f"{fmt(b['ring_freq_twin_hz'], 1, 3)} | "
                     f"{fmt(a['hold_freq_measured_hz'], 1, 3)} / "
                     f"{fmt(a['hold_freq_twin_hz'], 1, 3)} / "
                     f"{fmt(b['hold_freq_twin_hz'], 1, 3)} |")
    s = report["summary"]
    lines += ["", f"Held out ({s['held_out_runs']} runs, {s['tip_runs']} with a gauge), "
              f"medians shared -> per unit: hub {fmt(s['hub_rms_rad_shared'])} -> "
              f"{fmt(s['hub_rms_rad_unit_twin'])} rad, tip "
              f"{fmt(s['tip_rms_m_shared'], 1e3, 3)} -> "
              f"{fmt(s['tip_rms_m_unit_twin'], 1e3, 3)} mm, ring-down frequency error "
              f"{fmt(s['ring_freq_error_pct_shared'], 1, 2)} -> "
              f"{fmt(s['ring_freq_error_pct_unit_twin'], 1, 2)} %, hold ringing "
              f"frequency error {fmt(s['hold_freq_error_pct_shared'], 1, 2)} -> "
              f"{fmt(s['hold_freq_error_pct_unit_twin'], 1, 2)} %."]
    if report.get("fits"):
        lines += ["", "Fitted link values:", ""]
        lines += [f"- {u}: " + ", ".join(f"{k} {v:.4g}" for k, v in f["values"].items())
                  + f" (runs {', '.join(f['runs'])}; scaled residual "
                  f"{f['rms_scaled_residual_start']:.3f} -> "
                  f"{f['rms_scaled_residual_fitted']:.3f})"
                  for u, f in report["fits"].items()]
    Path(path).write_text("\n".join(lines) + "\n")


def study(runs: dict, make_policy: Callable, out, fit: bool = False,
          progress: Callable = print, max_nfev: int = 12, gauge: tuple = (),
          from_unit: bool = False) -> dict:
    """``fit``: refit every unit's link stage first (minutes; with ``gauge`` the gauge's
    gain and/or delay too; ``from_unit``: from the unit's stored preset) and write its
    preset into ``out``; then :func:`compare` and write
    units.md, units.json and the PNGs."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    presets, fits = {}, {}
    if fit:
        for unit in UNITS:
            res = calibrate_unit(unit, runs, make_policy, max_nfev=max_nfev, gauge=gauge,
                                 from_unit=from_unit)
            options = gauge_options(gauge) + \
                (" --from-units" if from_unit else "") + \
                (f" --max-evaluations {max_nfev}" if max_nfev != 12 else "")
            presets[unit] = write_unit_preset(unit, res, out, options, from_unit)
            fits[unit] = res.as_dict()
            progress(f"{unit}: fitted {res.values}")
    report = compare(runs, make_policy, out, presets, progress)
    report["fits"] = fits
    (out / "units.json").write_text(json.dumps(report, indent=1, default=float))
    write_markdown(report, out / "units.md")
    return report



def cmd_units(args) -> int:
    from flex_twin.real_arms.cli import gauge_flags, lab_policy, print_progress, print_report
    from flex_twin.real_arms.quanser_data import CUBOULDER, read_cuboulder
    from flex_twin.real_arms.quanser_twin import data_root
    out = Path(args.out)
    gauge = gauge_flags(args)
    if (gauge or args.from_units) and not args.fit:
        raise ValueError("--gauge-gain/--gauge-delay/--from-units refit the units' links: "
                         "give --fit too")
    report = study(read_cuboulder(data_root(args.data) / CUBOULDER), lab_policy(), out,
                   fit=args.fit, progress=print_progress, max_nfev=args.max_evaluations,
                   gauge=gauge, from_unit=args.from_units)
    return print_report(args, report, out / "units.md")


def build_parser():
    from flex_twin.real_arms.cli import add_data_option, add_gauge_options
    from .command import study_parser
    parser = study_parser("unit_calibration", "the twin per hardware unit: each unit's own "
                          "link stage against the shared calibrated twin on its held-out "
                          "runs (markdown, PNG, JSON; --fit refits the links first, minutes)")
    add_data_option(parser)
    parser.add_argument("--out", default="runs/quanser-units", help="output directory")
    parser.add_argument("--fit", action="store_true", help="refit every unit's link stage "
                        "and write its preset into --out (~2 CPU-min per unit)")
    add_gauge_options(parser, "with --fit: ")
    parser.add_argument("--from-units", action="store_true", help="with --fit: start each "
                        "unit's fit from its stored preset (default: from the shared twin)")
    parser.add_argument("--max-evaluations", type=int, default=12)
    parser.add_argument("--json", action="store_true")
    parser.set_defaults(func=cmd_units)
    return parser


def main(argv=None) -> int:
    """``python -m studies.unit_calibration [--fit [--gauge-delay] ...] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
