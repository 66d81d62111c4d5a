"""Does an effect named by ``flex-twin real-arm diagnose`` transfer to the other lab runs?
(issue 22)

The diagnosed arm (``diagnosed_arm.yaml`` of a diagnosis, the handout twin with the named
effects and the recalibrated scales) and the handout twin replay every CU Boulder
flexible-link run of the lab (closed loop, each run's own gains, whole run from its first
sample: :func:`real_arms.replay.replay`, as ``flex-twin replay``); the table gives the hub and tip
RMS errors of both and an overlay PNG per run. A run that the diagnosis did not see and
whose error falls is one the effect transfers to.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_twin.real_arms.quanser_data import CUBOULDER, read_cuboulder
from flex_twin.real_arms.quanser_twin import nominal_arm_for
from flex_twin.real_arms.replay import plot_replay, replay


def transfer(diagnosis_dir, data_root, make_policy, out, progress=print,
             runs: tuple | None = None) -> dict:
    """Replay the flexible-link runs (``runs``: names, default all with a gauge) on the
    handout twin and on ``diagnosis_dir/diagnosed_arm.yaml``; writes ``transfer.json``,
    ``transfer.md`` and ``<run>.png`` into ``out``. ``make_policy``: the lab's law for
    states [q; v; z] (``cli._policy_factory``: twins with stick-slip carry z). Returns the
    JSON mapping."""
    diagnosis_dir, out = Path(diagnosis_dir), Path(out)
    out.mkdir(parents=True, exist_ok=True)
    diagnosed = load_arm(str(diagnosis_dir / "diagnosed_arm.yaml"))
    nominal = nominal_arm_for("cuboulder", "flexible")
    seen = {}
    names_file = diagnosis_dir / "inputs" / "runs.json"
    if names_file.is_file():
        seen = json.loads(names_file.read_text())
    lab = read_cuboulder(Path(data_root) / CUBOULDER)
    names = runs or tuple(n for n, r in lab.items() if r.kind == "flexible" and r.has_gauge)
    unknown = [n for n in names if n not in lab or lab[n].kind != "flexible"]
    if unknown:
        raise ValueError(f"--runs: {unknown} are not CU Boulder flexible-link runs; known: "
                         f"{sorted(n for n, r in lab.items() if r.kind == 'flexible')}")
    rows = []
    for name in names:
        run = lab[name]
        res = [replay(FlexArmModel(a), run, make_policy) for a in (nominal, diagnosed)]
        row = {"run": name, "gains": [float(k) for k in run.gains],
               "role": ("fit" if name == seen.get("fit") else
                        "held out" if name == seen.get("holdout") else "other")}
        for key, r in zip(("nominal", "diagnosed"), res):
            row[key] = {k: r.metrics.get(k) for k in ("hub_rms_rad", "tip_rms_m")}
        plot_replay(res, out / f"{name.replace('.', '_')}.png",
                    f"{name}: handout twin and {diagnosis_dir.name}'s diagnosed twin")
        rows.append(row)
        progress(f"  {name} ({row['role']}): hub {row['nominal']['hub_rms_rad']:.4f} -> "
                 f"{row['diagnosed']['hub_rms_rad']:.4f} rad, tip "
                 f"{1e3 * row['nominal']['tip_rms_m']:.2f} -> "
                 f"{1e3 * row['diagnosed']['tip_rms_m']:.2f} mm")
    other = [r for r in rows if r["role"] == "other"]
    result = {"diagnosis": str(diagnosis_dir), "fit": seen.get("fit"),
              "holdout": seen.get("holdout"), "runs": rows,
              "other_hub_better": sum(r["diagnosed"]["hub_rms_rad"]
                                      < r["nominal"]["hub_rms_rad"] for r in other),
              "other_count": len(other)}
    for key in ("nominal", "diagnosed"):
        result[f"other_hub_median_{key}"] = float(np.median(
            [r[key]["hub_rms_rad"] for r in other])) if other else None
    (out / "transfer.json").write_text(json.dumps(result, indent=1, default=float))
    (out / "transfer.md").write_text("\n".join(markdown(result)) + "\n")
    return result


def markdown(result: dict) -> list:
    """The before/after table of :func:`transfer`."""
    lines = [f"Diagnosed twin of `{result['diagnosis']}` (fit {result['fit']}, held out "
             f"{result['holdout'] or 'its last 40 %'}) against the handout twin, whole-run "
             "closed-loop replays:", "",
             "| run | gains K1..K4 | role | hub RMS handout -> diagnosed | tip RMS handout -> "
             "diagnosed |", "|---|---|---|---|---|"]
    for r in result["runs"]:
        a, b = r["nominal"], r["diagnosed"]
        lines.append(f"| {r['run']} | {', '.join(f'{k:g}' for k in r['gains'])} | "
                     f"{r['role']} | {a['hub_rms_rad']:.4f} -> {b['hub_rms_rad']:.4f} rad | "
                     f"{1e3 * a['tip_rms_m']:.2f} -> {1e3 * b['tip_rms_m']:.2f} mm |")
    if result["other_count"]:
        lines += ["", f"Runs the diagnosis did not see: hub RMS lower on "
                  f"{result['other_hub_better']} of {result['other_count']}, median "
                  f"{result['other_hub_median_nominal']:.4f} -> "
                  f"{result['other_hub_median_diagnosed']:.4f} rad."]
    return lines


def cmd_transfer(args) -> int:
    """Replay the flexible-link runs on the handout twin and on a diagnosis's
    diagnosed_arm.yaml (issue 22: does the named effect transfer to the other runs?)."""
    from flex_twin.real_arms.cli import lab_policy, print_progress, print_report
    from flex_twin.real_arms.quanser_twin import data_root
    out = Path(args.out or Path(args.diagnosis) / "transfer")
    result = transfer(args.diagnosis, data_root(args.data), lab_policy(), out,
                      print_progress, runs=tuple(args.runs) if args.runs else None)
    return print_report(args, result, out / "transfer.md")


def build_parser():
    from flex_twin.real_arms.cli import add_data_option
    from .command import study_parser
    parser = study_parser("transfer", "replay the CU Boulder flexible-link runs on the "
                          "handout twin and on a real-arm diagnose output's diagnosed arm "
                          "(before/after table, overlay PNG per run)")
    parser.add_argument("diagnosis", help="output directory of flex-twin real-arm diagnose "
                        "(with diagnosed_arm.yaml)")
    parser.add_argument("--runs", nargs="*", default=None, help="run names (default: every "
                        "flexible-link run with a gauge)")
    add_data_option(parser)
    parser.add_argument("--out", default=None, help="output directory (default "
                        "DIAGNOSIS/transfer)")
    parser.add_argument("--json", action="store_true")
    parser.set_defaults(func=cmd_transfer)
    return parser


def main(argv=None) -> int:
    """``python -m studies.transfer DIAGNOSIS_DIR [--runs RUN ...] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
