"""``flex-twin plan``: plan a tip path (thesis Ch. IV-V.1) and write CSV + PNG.

flex_model's ``flex-twin`` registers it with :func:`add_plan_parser`; ``python -m
flex_planner.cli plan ...`` runs it alone. Exit codes as flex-twin: 0 success, 2 bad input
(an unreachable waypoint included; one line on stderr), 1 a failed computation.

    flex-twin plan thesis_example1 --task thesis_ch5 --out runs/plan
    flex-twin plan thesis_three_link waypoints.yaml --elbow down --json
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from flex_model.command import run_dir

from .config import DESCRIPTIONS, TASKS, PlannerConfig, load_waypoint_file, named_task


def trajectory_table(model, traj) -> tuple[list[str], np.ndarray]:
    """Columns and data of the plan CSV (SI units, rad): time, joint positions, velocities,
    accelerations, nominal torques, nominal tip, nominal tip deflection/rotation per link."""
    names = ["t"]
    cols = [traj.t[:, None]]
    for field, arr in (("position", traj.positions), ("velocity", traj.velocities),
                       ("acceleration", traj.accelerations), ("effort", traj.efforts)):
        names += [f"{j}_{field}" for j in traj.joint_names]
        cols.append(arr)
    names += ["tip_x", "tip_y"]
    cols.append(traj.tip)
    for i, lk in enumerate(model.arm.links):
        names += [f"{lk.name}_tip_deflection", f"{lk.name}_tip_rotation"]
        cols.append(traj.q_nominal[:, [model.tip_deflection_index(i),
                                       model.tip_rotation_index(i)]])
    return names, np.hstack(cols)


def cmd_plan(args) -> int:
    """Run the plan subcommand; returns the exit code."""
    from flex_model.statics import TipLoad, static_equilibrium

    from .planning import plan

    from flex_model.spatial.description import is_spatial_arm
    if is_spatial_arm(args.arm):           # issue 25: a spatial arm (flex_planner.spatial_plan)
        from .spatial_plan import cmd_spatial_plan
        return cmd_spatial_plan(args)
    if (args.waypoints is None) == (args.task is None):
        raise ValueError("waypoints: give a waypoint YAML file or --task "
                         f"({', '.join(TASKS)}), not both and not neither")
    task = named_task(args.task) if args.task else load_waypoint_file(Path(args.waypoints))
    cfg = PlannerConfig(arm=args.arm, vars_per_link=args.vars_per_link or 0,
                        sample_period=args.sample_period,
                        elbow=args.elbow or task.elbow or "up")
    model = cfg.model()
    t0 = time.perf_counter()
    try:
        result = plan(model, task.waypoints, task.times, sample_period=cfg.sample_period,
                      elbow=cfg.elbow, orientations=task.orientations, tip_load=task.tip_load)
    except RuntimeError as exc:
        print(f"flex-twin: failed: {exc}", file=sys.stderr)
        return 1
    wall = time.perf_counter() - t0
    traj = result.trajectory
    checks = []
    for k, (pose, p, tk) in enumerate(zip(result.poses, task.waypoints, task.times)):
        forward = static_equilibrium(model, pose.joint_angles, load=task.tip_load or TipLoad())
        j = int(np.argmin(np.abs(traj.t - tk)))
        checks.append({"index": k, "t_s": float(tk), "target_m": p.tolist(),
                       "joint_angles_deg": np.degrees(pose.joint_angles).tolist(),
                       "static_tip_error_m": float(np.linalg.norm(
                           np.asarray(forward.tip_position) - p)),
                       "nominal_tip_error_mm": float(1e3 * np.linalg.norm(traj.tip[j] - p))})
    out = run_dir(args.out, f"plan-{task.name}")
    csv = out / "plan.csv"
    names, data = trajectory_table(model, traj)
    np.savetxt(csv, data, delimiter=",", header=",".join(names), comments="", fmt="%.17g")
    summary = {"arm": model.arm.name, "task": task.name, "elbow": cfg.elbow,
               "sample_period_s": cfg.sample_period, "samples": len(traj.t),
               "duration_s": traj.duration, "wall_s": wall, "waypoints": checks,
               "max_abs_torque_nm": np.max(np.abs(traj.efforts), axis=0).tolist(),
               "balance_residual": result.nominal.balance_residual, "csv": str(csv)}
    if not args.no_plot:
        from .plots import plot_plan

        png = out / "plan.png"
        plot_plan(model, result, task.waypoints, png, title=f"{task.name} on {model.arm.name}")
        summary["png"] = str(png)
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"plan {task.name} on {model.arm.name} (elbow {cfg.elbow}): {len(traj.t)} samples "
          f"over {traj.duration:g} s in {wall:.3f} s")
    for c in checks:
        print(f"  waypoint {c['index']} at t = {c['t_s']:g} s: joint angles "
              + ", ".join(f"{a:.4f}" for a in c["joint_angles_deg"])
              + f" deg, static tip error {c['static_tip_error_m']:.2e} m, nominal tip "
              f"{c['nominal_tip_error_mm']:.3f} mm away")
    print("  max |nominal torque| [N m]: " + ", ".join(
        f"{v:.3f}" for v in summary["max_abs_torque_nm"]))
    print(f"  wrote {csv}" + (f" and {summary['png']}" if "png" in summary else ""))
    return 0


def add_plan_parser(subparsers) -> argparse.ArgumentParser:
    """Register the ``plan`` subcommand on an argparse ``subparsers`` object."""
    sp = subparsers.add_parser("plan", help="plan a tip path: static-flexible inversion, "
                               "splines, admissible nominal torque (thesis Ch. IV-V)")
    sp.add_argument("arm", help=DESCRIPTIONS["arm"])
    sp.add_argument("waypoints", nargs="?", default=None,
                    help="waypoint YAML file (see flex_planner.config)")
    sp.add_argument("--task", choices=sorted(TASKS), default=None,
                    help="a built-in task instead of a file (thesis_ch5: VALIDATION.md F)")
    sp.add_argument("--elbow", choices=["up", "down"], default=None,
                    help="elbow branch (default: the file's, else up)")
    sp.add_argument("--sample-period", type=float, default=1e-3, metavar="S",
                    help=DESCRIPTIONS["sample_period"] + " (default 1e-3)")
    sp.add_argument("--vars-per-link", type=int, default=None, metavar="N",
                    help="deformation variables of every link (even, >= 2)")
    sp.add_argument("--out", default=None, help="output directory (default runs/...)")
    sp.add_argument("--no-plot", action="store_true", help="do not write the PNG")
    sp.add_argument("--json", action="store_true", help="machine-readable summary")
    sp.set_defaults(func=cmd_plan)
    return sp


def main(argv=None) -> int:
    """``python -m flex_planner.cli plan ...`` (the same errors and exit codes as flex-twin)."""
    from flex_model.config import ConfigError

    parser = argparse.ArgumentParser(prog="flex-planner", description=__doc__.splitlines()[0])
    add_plan_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (ConfigError, ValueError, FileNotFoundError) as exc:
        print(f"flex-planner: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
