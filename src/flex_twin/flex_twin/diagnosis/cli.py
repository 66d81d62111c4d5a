"""``flex-twin diagnose``: name the missing effect of a twin from a measured run."""
from __future__ import annotations

import json
import sys
from pathlib import Path

#: default link-side encoder topic of a bag (kept equal to ros_recording.LINK_TOPIC, which
#: needs rclpy to import)
LINK_TOPIC = "/flex/link_encoders"


def add_diagnose_parser(sub) -> None:
    sp = sub.add_parser(
        "diagnose", help="diagnose measured runs against the nominal twin",
        description="Replay a measured run (CSV or rosbag2) through the nominal twin in "
        "closed loop, recalibrate within tolerance, gate, and name the missing effect(s); "
        "writes diagnosed_arm.yaml, report.md, PNGs and diagnosis.json. Several runs (paths, "
        "a folder, a glob or a manifest YAML) are diagnosed one task each into OUT/<run>/ "
        "with a summary table (flex_twin.diagnosis.batch). An elastic joint's link-side "
        "encoder (CSV columns ql<i>, vl<i>, both or neither; in a bag the JointState topic "
        "--link-topic) makes each replay restart put the link side there and the motor at "
        "q<i>, v<i>; a CSV line '# start_window: <s>' sets the window of the fit that gives "
        "each restart its state (default 0.05 s; 2 samples or less: the first sample; in a bag: "
        "start_window in the custom_data of metadata.yaml).")
    sp.add_argument("data", nargs="+", help="CSV (t, q<i>, v<i>, tau<i>, qset<i>, [w<i>, "
                    "tip_x, tip_y, tau_ff<i>, ql<i> + vl<i>], optional '# start_window: <s>' "
                    "line) or rosbag2 directory / .mcap (/joint_states, "
                    "/flex_planner/trajectory, [/flex/deflections, /flex/tip_pose, "
                    "--link-topic]); or several, a folder, a glob, or a manifest YAML of runs")
    sp.add_argument("--link-topic", default=None, metavar="TOPIC", help="bags: the "
                    "sensor_msgs/JointState topic of the link-side encoders (name = joints of "
                    "/joint_states, position = ql<i>, velocity = vl<i>; default "
                    f"{LINK_TOPIC}, read when the bag has it; a manifest run's link_topic wins)")
    sp.add_argument("--arm", help="nominal arm YAML (or preset name); required unless a "
                    "manifest names each run's. A spatial arm with --controller: the "
                    "closed-loop diagnosis (CSV t, q<i>, v<i>, tau<i>, qset<i>, w<i>, wz<i>, "
                    "phi<i>: tip deflections in-plane, out of plane and twist; hypotheses "
                    "per bending plane, torsion, joint and elastic gear); without: one CSV "
                    "(t, q<i>, tau<i>, <link>_tip_deflection_y|z, <link>_tip_twist) "
                    "replayed open loop")
    sp.add_argument("--controller", help="controller YAML (flex_twin.diagnosis.controller); "
                    "required unless a manifest names each run's")
    sp.add_argument("--holdout", help="held-out recording of a single run (default: the last "
                    "40 %% of data)")
    sp.add_argument("--out", default="runs/diagnosis", help="output directory")
    sp.add_argument("--gate", type=float, default=None,
                    help="materiality gate on the held-out excess cost J - 1")
    sp.add_argument("--segment", type=float, default=None,
                    help="multiple shooting for long logs: restart the replay every SEGMENT s "
                    "from the measured joint state")
    sp.add_argument("--workers", type=int, default=None, help="local parallel processes")
    sp.add_argument("--scheduler", default=None, help="Dask scheduler tcp://HOST:PORT or "
                    "scheduler file: the runs (or one run's hypothesis fits) go to the cluster")
    sp.add_argument("--no-floor", action="store_true",
                    help="skip the twin's model-form floor (replay against a refined twin "
                    "before any hypothesis; flex_twin.diagnosis.floor)")
    sp.add_argument("--no-plots", action="store_true")
    sp.add_argument("--json", action="store_true", help="print the JSON summary")
    sp.set_defaults(func=cmd_diagnose)


def _single_run(data) -> bool:
    """One recording (a CSV, .mcap or rosbag2 directory), not a list, folder, glob or
    manifest of runs."""
    if len(data) != 1:
        return False
    p = Path(data[0])
    if p.suffix in (".yaml", ".yml"):
        return False
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return not any(ch in data[0] for ch in "*?[")


def _check_topic(topic):
    """``--link-topic``: None (the default topic) or an absolute topic name."""
    if topic is not None and (not topic.startswith("/") or any(c.isspace() for c in topic)):
        raise ValueError(f"--link-topic: got {topic!r}; expected an absolute topic name "
                         "such as /flex/link_encoders")
    return topic


def _is_spatial(arm) -> bool:
    from flex_model.spatial.description import is_spatial_arm
    return is_spatial_arm(arm)


def _diagnose_spatial(args) -> int:
    """A spatial arm: one recording, open-loop replay of its torques, hypotheses per joint
    and bending plane (flex_twin.diagnosis.spatial)."""
    from flex_model.spatial import SpatialArmModel, load_spatial_arm
    from .spatial import diagnose_spatial, read_spatial_recording, write_outputs
    keys = ("controller", "holdout", "segment", "link_topic", "gate", "scheduler", "workers")
    given = [f"--{k.replace('_', '-')}" for k in keys
             if getattr(args, k, None) is not None]
    if getattr(args, "no_floor", False):
        given.append("--no-floor")
    if given or len(args.data) != 1 or not args.data[0].endswith(".csv"):
        raise ValueError(f"{args.arm} is a spatial arm: its diagnosis takes one recording CSV "
                         "(t, q<i>, tau<i>, <link>_tip_deflection_y|z, <link>_tip_twist) and "
                         "replays its torques open loop; " + (
                             f"{', '.join(given)} do(es) not apply" if given else
                             f"got {' '.join(args.data)}"))
    model = SpatialArmModel(load_spatial_arm(args.arm))
    rec = read_spatial_recording(args.data[0], model)
    diag = diagnose_spatial(model, rec,
                            progress=lambda m: print(m, file=sys.stderr, flush=True))
    write_outputs(diag, rec, args.out, plots=not args.no_plots)
    if args.json:
        print(json.dumps(diag.summary(), indent=1, default=float))
    else:
        print(f"verdict: {diag.verdict}; named: "
              f"{'; '.join(n.label for n in diag.named) or '-'}; held-out cost "
              f"{diag.cost_holdout[0]:.3g} -> {diag.cost_holdout[1]:.3g}; report "
              f"{args.out}/report.md")
    return 0


def cmd_diagnose(args) -> int:
    from ..cluster import batch_executor
    from .batch import RunSpec, diagnose_many, diagnose_run, expand_runs, named_text

    topic = _check_topic(getattr(args, "link_topic", None))
    if args.arm and _is_spatial(args.arm) and not args.controller:
        return _diagnose_spatial(args)   # with --controller: closed loop (spatial_loop.py)
    if _single_run(args.data):
        if not args.arm or not args.controller:
            raise ValueError("--arm and --controller are needed (or a manifest YAML of runs)")
        run = RunSpec(Path(args.data[0]).stem, args.data[0], args.arm, args.controller,
                      args.holdout, topic)
        with batch_executor(args.scheduler, args.workers) as ex:
            s = diagnose_run(run, args.out, args.gate, args.segment, not args.no_plots, ex,
                             progress=True, floor=not args.no_floor)
        if args.json:
            print(json.dumps(s, indent=1, default=float))
        else:
            print(f"verdict: {s['verdict']}; named: {named_text(s['named']) or '-'}; "
                  f"held-out error reduced by {100 * s['holdout_error_reduction']:.1f} %; "
                  f"model-form floor {s['gate']['model_form_holdout']:.3g}; report "
                  f"{args.out}/report.md", file=sys.stdout)
        return 0
    if args.holdout:
        raise ValueError("--holdout names the held-out recording of a single run; give "
                         "several runs' held-out recordings in a manifest")
    runs = expand_runs(args.data, args.arm, args.controller, topic)
    with batch_executor(args.scheduler, args.workers) as ex:
        rows = diagnose_many(runs, Path(args.out), ex, args.gate, args.segment,
                             not args.no_plots, floor=not args.no_floor,
                             log=lambda line: print(line, file=sys.stderr, flush=True))
    if args.json:
        print(json.dumps(rows, indent=1, default=float))
    else:
        bad = sum(1 for r in rows if r.get("error"))
        print(f"{len(rows)} runs diagnosed ({bad} failed): {args.out}/summary.md")
    return 1 if rows and all(r.get("error") for r in rows) else 0
