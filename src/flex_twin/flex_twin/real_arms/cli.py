"""CLI of the real arms: ``flex-twin replay``, ``flex-twin import quanser`` and
``flex-twin real-arm calibrate|report|diagnose`` (hooked into flex_twin.cli when present).

The lab's control law comes from flex_control (imported here only, lazily): flex_model's
core never depends on it.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path


def _policy_factory():
    try:
        from flex_control.state_feedback import lab_policy_factory
    except ModuleNotFoundError:
        raise ValueError("closed-loop replay needs flex_control (the lab's state feedback); "
                         "install it or use --mode open") from None
    return lab_policy_factory   # reads q and v of x = [q; v; z] (z: stick-slip bristles)


def _gauge_options(parser, when: str) -> None:
    """``--gauge-gain``, ``--gauge-delay``: fit the lab's tip gauge with the link stage."""
    parser.add_argument("--gauge-gain", action="store_true", help=f"{when}fit the gain of "
                        "the lab's tip gauge too (a tip_deflection sensor in the presets)")
    parser.add_argument("--gauge-delay", action="store_true", help=f"{when}fit the lag of "
                        "the lab's tip gauge too (the law reads the gauge that late)")


def _gauge_flags(args) -> tuple:
    """The names of :data:`.calibration.GAUGE` whose ``--gauge-*`` flag is given."""
    from .calibration import GAUGE
    return tuple(g for g in GAUGE if getattr(args, g))


def _print_report(args, report, markdown: Path) -> int:
    """A study's report on stdout: its JSON with ``--json``, else its markdown file."""
    print(json.dumps(report, indent=1, default=float) if args.json else markdown.read_text())
    return 0


def _progress(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def cmd_replay(args) -> int:
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from .quanser_twin import load_lab_run, nominal_arm_for
    from .replay import plot_replay, replay
    run = load_lab_run(args.run)
    arm = load_arm(args.arm) if args.arm else nominal_arm_for(run.lab, run.kind)
    factory = _policy_factory() if args.mode == "closed" else None
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
    gauge = _gauge_flags(args)
    start = stored_calibrated_arm("flexible") if args.from_stored else None

    def progress(k, cost, values):
        _progress(f"  evaluation {k}: scaled RMS residual {cost:.4f}")
    servo, link = calibrate_cuboulder(nominal_arm_for("cuboulder", "rigid"),
                                      nominal_arm_for("cuboulder", "flexible"), runs,
                                      _policy_factory(), progress=progress,
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
    report = build_report(data_root(args.data), _policy_factory(), out, _progress,
                          diagnoses=args.diagnosis or ())
    return _print_report(args, report, out / "report.md")


def cmd_stick_slip(args) -> int:
    from .quanser_twin import data_root
    from .stick_slip_study import study, write_markdown
    out = Path(args.out)
    report = study(data_root(args.data), _policy_factory(), out, _progress,
                   session=args.session)
    write_markdown(report, out / "stick_slip.md")
    return _print_report(args, report, out / "stick_slip.md")


def cmd_units(args) -> int:
    from .quanser_data import CUBOULDER, read_cuboulder
    from .quanser_twin import data_root
    from .unit_calibration import study
    out = Path(args.out)
    gauge = _gauge_flags(args)
    if (gauge or args.from_units) and not args.fit:
        raise ValueError("--gauge-gain/--gauge-delay/--from-units refit the units' links: "
                         "give --fit too")
    report = study(read_cuboulder(data_root(args.data) / CUBOULDER), _policy_factory(), out,
                   fit=args.fit, progress=_progress, max_nfev=args.max_evaluations,
                   gauge=gauge, from_unit=args.from_units)
    return _print_report(args, report, out / "units.md")


def cmd_holds(args) -> int:
    from .quanser_data import CUBOULDER, read_cuboulder
    from .quanser_twin import data_root
    from .stuck_holds import study, write_report
    out = Path(args.out)
    report = study(read_cuboulder(data_root(args.data) / CUBOULDER), _policy_factory(),
                   _progress, fit_link=args.fit, max_nfev=args.max_evaluations)
    write_report(report, out)
    return _print_report(args, report, out / "stuck_holds.md")


def cmd_link_response(args) -> int:
    from flex_twin.cluster import batch_executor
    from .link_response import study, write_report
    from .quanser_twin import data_root
    out = Path(args.out)
    with batch_executor(args.scheduler, args.workers) as executor:
        report = study(data_root(args.data), executor, _progress, args.runs or None, out=out)
    write_report(report, out)
    return _print_report(args, report, out / "link_response.md")


def cmd_floor(args) -> int:
    from flex_twin.cluster import batch_executor
    from .quanser_twin import data_root
    from .run_floor import study, write_report
    out = Path(args.out)
    with batch_executor(args.scheduler, args.workers) as executor:
        report = study(data_root(args.data), executor, _progress, args.max_evaluations,
                       out=out)
    write_report(report, out)
    return _print_report(args, report, out / "run_floor.md")


def cmd_servo_split(args) -> int:
    from .quanser_data import CUBOULDER, read_cuboulder
    from .quanser_twin import data_root
    from .servo_split import study
    out = Path(args.out)
    report = study(read_cuboulder(data_root(args.data) / CUBOULDER), _policy_factory(), out,
                   args.kt_tolerance, args.max_evaluations, _progress)
    return _print_report(args, report, out / "servo_split.md")


def cmd_two_mass(args) -> int:
    """The two-mass motor bench (issue 22): replay of records A and B on the
    ``two_mass_bench`` twin, FRF and time overlays, the frequency-domain diagnosis of the
    rigid nominal twin; ``--engine`` also runs ``flex-twin diagnose`` on it (minutes)."""
    from .two_mass_data import data_dir, read_two_mass
    from .two_mass_study import study
    out = Path(args.out)
    report = study(data_dir(args.data), out, _progress)
    if args.engine:
        from .two_mass_diagnosis import export_case, run_diagnosis
        from .two_mass_twin import parameters_from_arm
        from flex_model.arm import load_arm
        root = data_dir(args.data)
        paths = export_case(read_two_mass("A", root), read_two_mass("B", root),
                            parameters_from_arm(load_arm("two_mass_bench")),
                            out / "engine" / "inputs", args.duration)
        s = run_diagnosis(paths, out / "engine", workers=args.workers)
        report["engine"] = {k: s.get(k) for k in ("verdict", "named",
                                                  "holdout_error_reduction")}
        (out / "two_mass.json").write_text(json.dumps(report, indent=1, default=float))
    if args.json:
        print(json.dumps(report, indent=1, default=float))
    else:
        print((out / "two_mass.md").read_text())
        if args.engine:
            print(f"engine: {report['engine']['verdict']}; report {out / 'engine'}/report.md")
    return 0


def cmd_transfer(args) -> int:
    """Replay the flexible-link runs on the handout twin and on a diagnosis's
    diagnosed_arm.yaml (issue 22: does the named effect transfer to the other runs?)."""
    from .quanser_twin import data_root
    from .transfer import transfer
    out = Path(args.out or Path(args.diagnosis) / "transfer")
    result = transfer(args.diagnosis, data_root(args.data), _policy_factory(), out, _progress,
                      runs=tuple(args.runs) if args.runs else None)
    return _print_report(args, result, out / "transfer.md")


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
    _progress(f"inputs: {p['data']}, {p['controller']}, {p['arm']}")
    ns = argparse.Namespace(data=[str(p["data"])], arm=str(p["arm"]),
                            controller=str(p["controller"]), holdout=holdout, out=args.out,
                            gate=None, segment=(SEGMENT if args.segment is None else
                                                args.segment or None),
                            workers=args.workers,
                            scheduler=None,
                            no_floor=False, no_plots=args.no_plots, json=args.json)
    return engine_diagnose(ns)


def _data_option(parser) -> None:
    parser.add_argument("--data", default=None, help="folder of the real data (default "
                        "../shared/data/real)")


def _batch_options(parser, out: str) -> None:
    """--out, --workers, --scheduler and --json of a study run on the batch executor."""
    parser.add_argument("--out", default=out, help="output directory")
    parser.add_argument("--workers", type=int, default=None, help="parallel processes")
    parser.add_argument("--scheduler", default=None, help="a Dask scheduler address or file "
                        "(default: processes on this machine)")
    parser.add_argument("--json", action="store_true")


def add_real_arm_parsers(sub) -> None:
    """``replay``, ``import quanser`` and
    ``real-arm calibrate|report|stick-slip|units|floor|servo-split|two-mass|diagnose|transfer``."""
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
    rsub = sp.add_subparsers(dest="action", required=True)
    cp = rsub.add_parser("calibrate", help="fit servo (rigid runs) and link (flexible "
                         "subset); writes calibrated arm YAMLs (minutes)")
    _data_option(cp)
    cp.add_argument("--out", default="runs/quanser-calibrated", help="output directory")
    cp.add_argument("--max-evaluations", type=int, default=10)
    _gauge_options(cp, "")
    cp.add_argument("--from-stored", action="store_true", help="start the link stage from "
                    "the stored calibrated twin's link (default: from the handout's)")
    cp.set_defaults(func=cmd_calibrate)
    rp = rsub.add_parser("report", help="nominal vs calibrated twin on held-out runs, the "
                         "second lab and the third lab's FRFs (markdown, PNG, JSON)")
    _data_option(rp)
    rp.add_argument("--out", default=None, help="output directory (default "
                    "runs/real-arm-report)")
    rp.add_argument("--diagnosis", nargs="*", default=None, metavar="DIR", help="output "
                    "directories of real-arm diagnose to add to the report")
    rp.add_argument("--json", action="store_true")
    rp.set_defaults(func=cmd_report)
    sp2 = rsub.add_parser("stick-slip", help="the calibrated twins with stick-slip friction "
                          "(levels refitted on the fit runs) on every CU Boulder run, and "
                          "the holds' evidence for stiction against backlash (minutes)")
    _data_option(sp2)
    sp2.add_argument("--out", default="runs/quanser-stick-slip", help="output directory")
    sp2.add_argument("--session", action="store_true",
                     help="also twins with F_c from each held-out run's first step, and with "
                     "F_c and a voltage offset from its first period, every twin scored after "
                     "that (about 10 more CPU-minutes)")
    sp2.add_argument("--json", action="store_true")
    sp2.set_defaults(func=cmd_stick_slip)
    up = rsub.add_parser("units", help="the twin per hardware unit: each unit's own link "
                         "stage against the shared calibrated twin on its held-out runs "
                         "(markdown, PNG, JSON; --fit refits the links first, minutes)")
    _data_option(up)
    up.add_argument("--out", default="runs/quanser-units", help="output directory")
    up.add_argument("--fit", action="store_true", help="refit every unit's link stage and "
                    "write its preset into --out (~2 CPU-min per unit)")
    _gauge_options(up, "with --fit: ")
    up.add_argument("--from-units", action="store_true", help="with --fit: start each "
                    "unit's fit from its stored preset (default: from the shared twin)")
    up.add_argument("--max-evaluations", type=int, default=12)
    up.add_argument("--json", action="store_true")
    up.set_defaults(func=cmd_units)
    hp = rsub.add_parser("holds", help="the link's ringing while the lab hub sticks: "
                         "frequency and damping per stuck stretch, the floor of a twin of "
                         "one link frequency, the twins' clamped links (markdown, PNG, JSON; "
                         "--fit: a twin with that link, ~2 CPU-min)")
    _data_option(hp)
    hp.add_argument("--out", default="runs/quanser-holds", help="output directory")
    hp.add_argument("--fit", action="store_true", help="refit Hagenau's twin around the "
                    "link of its fit runs' stuck stretches and replay its held-out runs")
    hp.add_argument("--max-evaluations", type=int, default=12)
    hp.add_argument("--json", action="store_true")
    hp.set_defaults(func=cmd_holds)
    lp = rsub.add_parser("link-response", help="the lab's link against its own hub angle: "
                         "one linear mode fitted to each run and to each step, one for each "
                         "unit, the twin's link driven by the lab's hub (markdown, JSON, PNG "
                         "per run; ~10 CPU-min)")
    _data_option(lp)
    lp.add_argument("runs", nargs="*", help="run names (default: every run with a gauge)")
    _batch_options(lp, "runs/quanser-link")
    lp.set_defaults(func=cmd_link_response)
    fp = rsub.add_parser("floor", help="the model's floor: the calibration's parameters "
                         "fitted to each held-out run itself (markdown, JSON, PNG; ~15 CPU-min)")
    _data_option(fp)
    fp.add_argument("--max-evaluations", type=int, default=12)
    _batch_options(fp, "runs/quanser-floor")
    fp.set_defaults(func=cmd_floor)
    vp = rsub.add_parser("servo-split", help="one servo fitted to the rigid-bar and the "
                         "flexible fit runs together, the rigid bar's inertia free, scored on "
                         "the held-out runs (markdown, JSON; ~5-10 CPU-min)")
    _data_option(vp)
    vp.add_argument("--kt-tolerance", type=float, default=0.05, help="K_t free within this "
                    "fraction of the handout's (default 0.05, its tolerance)")
    vp.add_argument("--max-evaluations", type=int, default=10)
    vp.add_argument("--out", default="runs/quanser-servo-split", help="output directory")
    vp.add_argument("--json", action="store_true")
    vp.set_defaults(func=cmd_servo_split)
    tp = rsub.add_parser("two-mass", help="the FdiTools two-mass motor bench: twin replay "
                         "of records A (fit) and B (held out), FRF and time overlays, the "
                         "diagnosis of the rigid nominal twin (markdown, PNG, JSON)")
    _data_option(tp)
    tp.add_argument("--out", default="runs/two-mass", help="output directory")
    tp.add_argument("--engine", action="store_true", help="also run flex-twin diagnose "
                    "(time domain, restarts every 0.1 s from the motor and load encoders) on the "
                    "rigid nominal twin (minutes; the full 20 s: ~12 CPU-min)")
    tp.add_argument("--duration", type=float, default=None, help="with --engine: only the "
                    "first seconds of each record")
    tp.add_argument("--workers", type=int, default=None, help="with --engine: processes")
    tp.add_argument("--json", action="store_true")
    tp.set_defaults(func=cmd_two_mass)
    dp = rsub.add_parser("diagnose", help="flex-twin diagnose on a lab run against the "
                         "nominal (handout) twin: writes the inputs (CSV, controller and arm "
                         "YAML) and the diagnosis report (minutes)")
    dp.add_argument("run", nargs="?", default=None, help="a CU Boulder lab file or run name "
                    "(default flexarm_K1_6, a link-fit run of CUBOULDER_SPLIT)")
    dp.add_argument("--holdout", default=None, help="held-out run with the same law (default:"
                    " the last 40 %% of RUN)")
    _data_option(dp)
    dp.add_argument("--out", default="runs/real-arm-diagnosis", help="output directory")
    dp.add_argument("--segment", type=float, default=None, help="restart the replay every "
                    "SEGMENT s from the measured hub angle and rate (multiple shooting; "
                    "default 0.5, 0: the whole run in one replay)")
    dp.add_argument("--workers", type=int, default=None, help="parallel processes")
    dp.add_argument("--no-plots", action="store_true")
    dp.add_argument("--json", action="store_true")
    dp.set_defaults(func=cmd_diagnose)
    fp = rsub.add_parser("transfer", help="replay the CU Boulder flexible-link runs on the "
                         "handout twin and on a real-arm diagnose output's diagnosed arm "
                         "(before/after table, overlay PNG per run)")
    fp.add_argument("diagnosis", help="output directory of real-arm diagnose (with "
                    "diagnosed_arm.yaml)")
    fp.add_argument("--runs", nargs="*", default=None, help="run names (default: every "
                    "flexible-link run with a gauge)")
    _data_option(fp)
    fp.add_argument("--out", default=None, help="output directory (default "
                    "DIAGNOSIS/transfer)")
    fp.add_argument("--json", action="store_true")
    fp.set_defaults(func=cmd_transfer)
