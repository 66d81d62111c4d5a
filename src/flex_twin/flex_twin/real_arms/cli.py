"""CLI of the real arms: ``flex-twin replay``, ``flex-twin import quanser`` and
``flex-twin real-arm calibrate|report|diagnose`` (hooked into flex_twin.cli when present).
The one-off studies that were ``real-arm`` sub-commands run from the repository root as
``python -m studies.<name>`` (:data:`MOVED_STUDIES`; their old names say so).

The lab's control law comes from flex_control (imported here only, lazily): flex_model's
core never depends on it.
"""
from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

#: the one-off studies that were ``flex-twin real-arm`` sub-commands -> their module in the
#: repository's ``studies/`` (issue 43), run from the repository root with the same options
MOVED_STUDIES = {"stick-slip": "stick_slip_study", "units": "unit_calibration",
                 "holds": "stuck_holds", "link-response": "link_response",
                 "floor": "run_floor", "servo-split": "servo_split",
                 "two-mass": "two_mass_study", "transfer": "transfer"}
#: the same for the top-level sub-commands that were one-off studies
MOVED_COMMANDS = {"cantilever": "cantilever", "frequency-gap": "frequency_gap"}
KEPT_ACTIONS = ("calibrate", "report", "diagnose", "estimate")


def lab_policy():
    """The lab's state-feedback policy factory (flex_control), or a ValueError without it."""
    try:
        from flex_control.state_feedback import lab_policy_factory
    except ModuleNotFoundError:
        raise ValueError("closed-loop replay needs flex_control (the lab's state feedback); "
                         "install it or use --mode open") from None
    return lab_policy_factory   # reads q and v of x = [q; v; z] (z: stick-slip bristles)


def add_gauge_options(parser, when: str) -> None:
    """``--gauge-gain``, ``--gauge-delay``: fit the lab's tip gauge with the link stage."""
    parser.add_argument("--gauge-gain", action="store_true", help=f"{when}fit the gain of "
                        "the lab's tip gauge too (a tip_deflection sensor in the presets)")
    parser.add_argument("--gauge-delay", action="store_true", help=f"{when}fit the lag of "
                        "the lab's tip gauge too (the law reads the gauge that late)")


def gauge_flags(args) -> tuple:
    """The names of :data:`.calibration.GAUGE` whose ``--gauge-*`` flag is given."""
    from .calibration import GAUGE
    return tuple(g for g in GAUGE if getattr(args, g))


def print_report(args, report, markdown: Path) -> int:
    """A study's report on stdout: its JSON with ``--json``, else its markdown file."""
    print(json.dumps(report, indent=1, default=float) if args.json else markdown.read_text())
    return 0


def print_progress(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def cmd_replay(args) -> int:
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from .quanser_twin import load_lab_run, nominal_arm_for
    from .replay import plot_replay, replay
    run = load_lab_run(args.run)
    arm = load_arm(args.arm) if args.arm else nominal_arm_for(run.lab, run.kind)
    factory = lab_policy() if args.mode == "closed" else None
    res = replay(FlexArmModel(arm), run, factory, mode=args.mode, t_final=args.duration)
    out = Path(args.out or f"runs/replay-{run.name.replace('.', '_')}")
    out.mkdir(parents=True, exist_ok=True)
    plot_replay([res], out / "replay.png")
    summary = res.summary()
    (out / "replay.json").write_text(json.dumps(summary, indent=1))
    if args.json:
        print(json.dumps(summary, indent=1))
        return 0
    m = res.metrics
    print(f"{run.lab} {run.name} on {arm.name} ({args.mode} loop, gains "
          f"{[round(float(k), 3) for k in run.gains]}, gauge sign {m['gauge_sign']:+.0f})")
    print(f"  hub angle: RMS error {m['hub_rms_rad']:.4f} rad, peak {m['hub_peak_rad']:.4f} rad")
    if "tip_rms_m" in m:
        print(f"  tip deflection: RMS error {1e3 * m['tip_rms_m']:.2f} mm, peak "
              f"{1e3 * m['tip_peak_m']:.1f} mm")
    for k, s in enumerate(res.steps):
        a, b = s["measured"], s["twin"]
        fmt = (lambda r: "-" if r is None else
               f"{r.frequency_hz:.2f} Hz, zeta {r.damping_ratio:.3f}")
        print(f"  step {k + 1} at {run.t[run.step_indices()[k]]:.2f} s: ring-down lab "
              f"{fmt(a)} | twin {fmt(b)}")
    print(f"  wrote {out / 'replay.png'}, {out / 'replay.json'}")
    return 0


def cmd_import_quanser(args) -> int:
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from .ros_quanser_import import import_run
    from .quanser_twin import load_lab_run, nominal_arm_for
    run = load_lab_run(args.run)
    arm = load_arm(args.arm) if args.arm else nominal_arm_for(run.lab, run.kind)
    if args.duration:
        run = run.head(args.duration)
    counts = import_run(run, FlexArmModel(arm), args.output)
    if args.json:
        print(json.dumps({"bag": str(args.output), "counts": counts}))
    else:
        print(f"wrote {args.output}: " + ", ".join(f"{t} {n}" for t, n in counts.items()))
    return 0


def cmd_calibrate(args) -> int:
    from .calibration import calibrate_cuboulder, gauge_options, write_calibrated_presets
    from .quanser_data import CUBOULDER, read_cuboulder
    from .quanser_twin import data_root, nominal_arm_for, stored_calibrated_arm
    root = data_root(args.data)
    runs = read_cuboulder(root / CUBOULDER)
    gauge = gauge_flags(args)
    start = stored_calibrated_arm("flexible") if args.from_stored else None

    def progress(k, cost, values):
        print_progress(f"  evaluation {k}: scaled RMS residual {cost:.4f}")
    servo, link = calibrate_cuboulder(nominal_arm_for("cuboulder", "rigid"),
                                      nominal_arm_for("cuboulder", "flexible"), runs,
                                      lab_policy(), progress=progress,
                                      max_nfev=args.max_evaluations, gauge=gauge,
                                      link_start=start)
    options = gauge_options(gauge) + (
        " --from-stored, started from the stored quanser_cuboulder_calibrated"
        if args.from_stored else "") + (
        f" --max-evaluations {args.max_evaluations}" if args.max_evaluations != 10 else "")
    paths = write_calibrated_presets(servo, link, Path(args.out), options)
    print(json.dumps({"servo": servo.as_dict(), "link": link.as_dict(),
                      "wrote": [str(p) for p in paths]}, indent=1))
    return 0


def cmd_report(args) -> int:
    from .quanser_twin import data_root
    from .report import build_report
    out = Path(args.out or "runs/real-arm-report")
    report = build_report(data_root(args.data), lab_policy(), out, print_progress,
                          diagnoses=args.diagnosis or ())
    return print_report(args, report, out / "report.md")


def cmd_diagnose(args) -> int:
    """Export a lab run (and a held-out run with the same law) as diagnosis inputs into
    ``OUT/inputs`` and run ``flex-twin diagnose`` on them (report, diagnosed_arm.yaml)."""
    import argparse

    from ..diagnosis.cli import cmd_diagnose as engine_diagnose
    from .quanser_diagnosis import DEFAULT_RUN, SEGMENT, controller_dict, export_run, \
        run_path, same_law
    from .quanser_twin import data_root
    if args.segment is not None and args.segment < 0:
        raise ValueError(f"--segment: got {args.segment}; expected >= 0 s (0: the whole run)")
    given = [r for r in (args.run, args.holdout) if r]
    root = None if given and all(Path(r).is_file() for r in given) and not args.data \
        else data_root(args.data)
    fit = export_run(run_path(args.run or DEFAULT_RUN, root), Path(args.out) / "inputs")
    holdout = None
    if args.holdout:
        ho = export_run(run_path(args.holdout, root), Path(args.out) / "inputs")
        a, b = fit["case"], ho["case"]
        if (a["run"].lab, a["run"].kind) != (b["run"].lab, b["run"].kind) or \
                not same_law(controller_dict(a), controller_dict(b)):
            raise ValueError(f"--holdout {args.holdout}: gains {b['run'].gains.tolist()}, gauge "
                             f"sign {b['run'].gauge_sign():+.0f} differ from the fit run's "
                             f"{a['run'].gains.tolist()}, {a['run'].gauge_sign():+.0f} (the "
                             "diagnosis replays both runs with one controller)")
        holdout = str(ho["paths"]["data"])
    p = fit["paths"]
    (Path(args.out) / "inputs" / "runs.json").write_text(json.dumps(
        {"fit": fit["case"]["run"].name, "holdout": args.holdout and ho["case"]["run"].name}))
    print_progress(f"inputs: {p['data']}, {p['controller']}, {p['arm']}")
    ns = argparse.Namespace(data=[str(p["data"])], arm=str(p["arm"]),
                            controller=str(p["controller"]), holdout=holdout, out=args.out,
                            gate=None, segment=(SEGMENT if args.segment is None else
                                                args.segment or None),
                            workers=args.workers,
                            scheduler=None,
                            no_floor=False, no_plots=args.no_plots, json=args.json)
    return engine_diagnose(ns)


def cmd_estimate(args) -> int:
    """The tip estimated from hub encoder and voltage on the held-out runs (issue 45)."""
    from .quanser_estimate import HELD_OUT, estimate_held_out
    from .quanser_twin import data_root
    out = Path(args.out) if args.out else None
    report = estimate_held_out(data_root(args.data), args.runs or HELD_OUT,
                               progress=None if args.json else print_progress, out=out,
                               workers=args.workers, structure=args.structure)
    if out is not None:
        (out / "estimate.json").write_text(json.dumps(report, indent=1, default=float))
    if args.json:
        print(json.dumps(report, indent=1, default=float))
        return 0
    s = report["summary"]
    print(f"{s['runs']} runs, {report['arm']} (tuned on "
          f"{', '.join(report['tuned_on'])}): tip RMS median {s['tip_rms_median_mm']:.2f} mm "
          f"({s['tip_rms_from_first_step_median_mm']:.2f} mm from the first step on), hub "
          f"{s['hub_rms_median_rad']:.4f} rad, gauge in the 95 % band "
          f"{100 * s['coverage_95']:.1f} %")
    return 0


def moved_study(args) -> int:
    """A sub-command that moved to ``studies/``: one line saying where to run it now."""
    given = shlex.join(args.study_args)
    raise ValueError(f"{args.moved} moved out of the package (issue 43): from the "
                     f"repository root run python -m studies.{args.study}"
                     f"{' ' + given if given else ''} (studies/README.md)")


def add_moved_studies(sub, moved: dict = MOVED_STUDIES, prefix: str = "real-arm ",
                      listed: bool = False) -> None:
    """Sub-parsers of the moved studies (``moved``: old name -> module; hidden unless
    ``listed``): they take any arguments (even ``--help``) and point at ``python -m
    studies.<module>``."""
    for name, module in moved.items():
        shown = {"help": f"moved: python -m studies.{module}"} if listed else {}
        mp = sub.add_parser(name, prefix_chars="\0", add_help=False, **shown)
        mp.add_argument("study_args", nargs="*")
        mp.set_defaults(func=moved_study, moved=prefix + name, study=module)


def add_data_option(parser) -> None:
    """``--data DIR``: where the labs' data are."""
    parser.add_argument("--data", default=None, help="folder of the real data (default "
                        "../shared/data/real)")


def add_real_arm_parsers(sub) -> None:
    """``replay``, ``import quanser`` and ``real-arm calibrate|report|diagnose`` (the moved
    studies' old names only point at ``studies/``)."""
    sp = sub.add_parser("replay", help="replay a recorded real-arm run on its twin "
                        "(closed loop with the lab's law, or open loop from the voltage)")
    sp.add_argument("run", help="a CU Boulder lab log, or the UC Merced data folder")
    sp.add_argument("--arm", default=None, help="arm preset or YAML (default: the lab's "
                    "nominal Quanser arm)")
    sp.add_argument("--mode", choices=["closed", "open"], default="closed")
    sp.add_argument("--duration", type=float, default=None, help="replay only this long, s")
    sp.add_argument("--out", default=None, help="output directory (default runs/replay-...)")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_replay)

    sp = sub.add_parser("import", help="import real-arm data into a rosbag2 (MCAP) bag")
    isub = sp.add_subparsers(dest="source", required=True)
    ip = isub.add_parser("quanser", help="a Quanser lab run -> /joint_states, "
                         "/flex/deflections, /effort_controller/commands, "
                         "/flex_planner/trajectory")
    ip.add_argument("run", help="a CU Boulder lab log, or the UC Merced data folder")
    ip.add_argument("-o", "--output", required=True, help="new bag directory")
    ip.add_argument("--arm", default=None, help="arm for the motor torque (default nominal)")
    ip.add_argument("--duration", type=float, default=None, help="only the first seconds")
    ip.add_argument("--json", action="store_true")
    ip.set_defaults(func=cmd_import_quanser)

    sp = sub.add_parser("real-arm", help="calibrate and validate the Quanser twins")
    rsub = sp.add_subparsers(dest="action", required=True,
                             metavar="{" + ",".join(KEPT_ACTIONS) + "}")
    cp = rsub.add_parser("calibrate", help="fit servo (rigid runs) and link (flexible "
                         "subset); writes calibrated arm YAMLs (minutes)")
    add_data_option(cp)
    cp.add_argument("--out", default="runs/quanser-calibrated", help="output directory")
    cp.add_argument("--max-evaluations", type=int, default=10)
    add_gauge_options(cp, "")
    cp.add_argument("--from-stored", action="store_true", help="start the link stage from "
                    "the stored calibrated twin's link (default: from the handout's)")
    cp.set_defaults(func=cmd_calibrate)
    rp = rsub.add_parser("report", help="nominal vs calibrated twin on held-out runs, the "
                         "second lab and the third lab's FRFs (markdown, PNG, JSON)")
    add_data_option(rp)
    rp.add_argument("--out", default=None, help="output directory (default "
                    "runs/real-arm-report)")
    rp.add_argument("--diagnosis", nargs="*", default=None, metavar="DIR", help="output "
                    "directories of real-arm diagnose to add to the report")
    rp.add_argument("--json", action="store_true")
    rp.set_defaults(func=cmd_report)
    dp = rsub.add_parser("diagnose", help="flex-twin diagnose on a lab run against the "
                         "nominal (handout) twin: writes the inputs (CSV, controller and arm "
                         "YAML) and the diagnosis report (minutes)")
    dp.add_argument("run", nargs="?", default=None, help="a CU Boulder lab file or run name "
                    "(default flexarm_K1_6, a link-fit run of CUBOULDER_SPLIT)")
    dp.add_argument("--holdout", default=None, help="held-out run with the same law (default:"
                    " the last 40 %% of RUN)")
    add_data_option(dp)
    dp.add_argument("--out", default="runs/real-arm-diagnosis", help="output directory")
    dp.add_argument("--segment", type=float, default=None, help="restart the replay every "
                    "SEGMENT s from the measured hub angle and rate (multiple shooting; "
                    "default 0.5, 0: the whole run in one replay)")
    dp.add_argument("--workers", type=int, default=None, help="parallel processes")
    dp.add_argument("--no-plots", action="store_true")
    dp.add_argument("--json", action="store_true")
    dp.set_defaults(func=cmd_diagnose)
    ep = rsub.add_parser("estimate", help="the tip deflection estimated from the hub "
                         "encoder and the voltage (Kalman filter on the stored calibrated "
                         "twin; --structure driven_link: the link driven by the encoder "
                         "alone) on the held-out flexible runs, against the lab's gauge")
    add_data_option(ep)
    ep.add_argument("--runs", nargs="*", default=None, metavar="RUN", help="CU Boulder run "
                    "names (default: the held-out flexible runs of CUBOULDER_SPLIT)")
    ep.add_argument("--out", default=None, help="write estimate.json and a PNG per run here")
    ep.add_argument("--workers", type=int, default=1, help="parallel processes (one run each)")
    ep.add_argument("--structure", choices=("full", "driven_link"), default="full",
                    help="the filter (docs/estimation.md, Real Quanser arm)")
    ep.add_argument("--json", action="store_true")
    ep.set_defaults(func=cmd_estimate)
    add_moved_studies(rsub)
