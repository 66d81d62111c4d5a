"""``flex-twin diagnose``: name the missing effect of a twin from a measured run."""
from __future__ import annotations

import json
import sys
from pathlib import Path


def add_diagnose_parser(sub) -> None:
    sp = sub.add_parser(
        "diagnose", help="diagnose a measured run against the nominal twin (issue 8)",
        description="Replay a measured run (CSV or rosbag2) through the nominal twin in "
        "closed loop, recalibrate within tolerance, gate, and name the missing effect(s); "
        "writes diagnosed_arm.yaml, report.md, PNGs and diagnosis.json.")
    sp.add_argument("data", help="CSV (t, q<i>, v<i>, tau<i>, qset<i>, [w<i>, tip_x, tip_y]) "
                    "or rosbag2 directory / .mcap")
    sp.add_argument("--arm", required=True, help="nominal arm YAML (or preset name)")
    sp.add_argument("--controller", required=True, help="controller YAML "
                    "(flex_twin.diagnosis.controller)")
    sp.add_argument("--holdout", help="held-out recording (default: the last 40 %% of data)")
    sp.add_argument("--out", default="runs/diagnosis", help="output directory")
    sp.add_argument("--gate", type=float, default=None,
                    help="materiality gate on the held-out excess cost J - 1")
    sp.add_argument("--segment", type=float, default=None,
                    help="multiple shooting for long logs: restart the replay every SEGMENT s "
                    "from the measured joint state")
    sp.add_argument("--workers", type=int, default=None, help="parallel processes")
    sp.add_argument("--no-plots", action="store_true")
    sp.add_argument("--json", action="store_true", help="print the JSON summary")
    sp.set_defaults(func=cmd_diagnose)


def cmd_diagnose(args) -> int:
    from flex_model.arm import load_arm, resolve_preset
    from .controller import load_controller
    from .engine import DEFAULT_GATE, diagnose
    from .evaluation import default_executor
    from .recording import load_recording
    from .report import write_report

    arm_path = resolve_preset(args.arm)
    arm = load_arm(arm_path)
    controller = load_controller(args.controller)
    if controller.n_joints != arm.n_links:
        raise ValueError(f"{args.controller}: {controller.n_joints} joints in the controller, "
                         f"{arm.n_links} in the arm {arm_path}")
    fit = load_recording(args.data, arm.n_links)
    holdout = load_recording(args.holdout, arm.n_links) if args.holdout else None
    if args.segment is not None and not args.segment > 0:
        raise ValueError(f"--segment: got {args.segment}; expected a time > 0 s")
    if args.workers is not None and args.workers < 1:
        raise ValueError(f"--workers: got {args.workers}; expected >= 1")
    executor = default_executor(args.workers)
    try:
        d = diagnose(arm, controller, fit, holdout, executor=executor,
                     gate=DEFAULT_GATE if args.gate is None else args.gate,
                     segment=args.segment, progress=True)
    finally:
        if hasattr(executor, "shutdown"):
            executor.shutdown()
    s = write_report(Path(args.out), arm_path, d, plots=not args.no_plots)
    if args.json:
        print(json.dumps(s, indent=1, default=float))
    else:
        named = ", ".join(
            c["label"] + " (" + ", ".join(f"{k} {v:.4g}" for k, v in c["parameters"].items())
            + ")" for c in s["named"]) or "-"
        print(f"verdict: {d.verdict}; named: {named}; held-out error reduced by "
              f"{100 * s['holdout_error_reduction']:.1f} %; report {args.out}/report.md",
              file=sys.stdout)
    return 0
