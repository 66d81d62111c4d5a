"""``flex-twin``: the user's entry point (analyses, simulation, demo).

Exit codes: 0 success, 2 bad input (one line on stderr), 1 a failed computation.
Every analysis takes ``--json`` for machine-readable output; units are in the key names.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from flex_model.ros import ros_environment
from flex_model.command import Progress, run_command, run_dir  # noqa: F401 (exit codes)


def _model(args):
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel

    arm = load_arm(args.arm, args.vars_per_link)
    if args.kinematics:
        arm = arm.with_kinematics(args.kinematics)
    if getattr(args, "no_gravity", False):
        arm = arm.without_gravity()
    return FlexArmModel(arm)


def _angles(args, model):
    if args.joint_angles_deg is None:
        return np.zeros(model.n_links)
    if len(args.joint_angles_deg) != model.n_links:
        raise ValueError(f"--joint-angles-deg: got {len(args.joint_angles_deg)} values; "
                         f"expected {model.n_links} (one per joint)")
    return np.radians(args.joint_angles_deg)


def _gains(values, name, model):
    if values is None:
        return None
    if len(values) not in (1, model.n_links):
        raise ValueError(f"--{name}: got {len(values)} values; expected 1 or {model.n_links}")
    return np.broadcast_to(np.asarray(values, float), (model.n_links,))


def cmd_modes(args) -> int:
    from flex_model.modes import natural_modes

    from .spatial_cli import cmd_spatial_modes, is_spatial
    if is_spatial(args.arm):
        return cmd_spatial_modes(args)
    model = _model(args)
    kp, kd = _gains(args.kp, "kp", model), _gains(args.kd, "kd", model)
    if args.joints == "pd" and kp is None:
        raise ValueError("--kp: required with --joints pd (N m/rad, per joint or one value)")
    res = natural_modes(model, _angles(args, model), joints=args.joints, kp=kp, kd=kd,
                        gravity_preload=args.gravity_preload)
    out = res.as_dict(args.count)
    if args.state_space:
        from flex_model.modes import linearize
        lin = linearize(model, _angles(args, model), joints=args.joints, kp=kp, kd=kd,
                        gravity_preload=args.gravity_preload)
        np.savez(args.state_space, A=lin.A, B=lin.B, C=lin.C, D=lin.D,
                 inputs=np.array(lin.input_names), outputs=np.array(lin.output_names))
        out["state_space"] = str(args.state_space)
    if args.plot:
        from flex_model.plots import plot_modes
        plot_modes(model, res, args.plot, title=f"{model.arm.name}: joints {args.joints}")
        out["plot"] = str(args.plot)
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{model.arm.name}: {model.nq} coordinates, joints {args.joints}, "
              f"cond(B) = {out['inertia_condition_number']:.3e}")
        print(f"{'mode':>4} {'f [Hz]':>12} {'omega [rad/s]':>14} {'zeta':>8}")
        for k, (f, w, z) in enumerate(zip(out["frequencies_hz"], out["omega_rad_s"],
                                          out["damping_ratio"])):
            print(f"{k + 1:>4} {f:12.6g} {w:14.6g} {z:8.4f}")
    return 0


def cmd_static(args) -> int:
    from flex_model.statics import TipLoad, static_equilibrium

    from .spatial_cli import cmd_spatial_static, is_spatial
    if is_spatial(args.arm):
        return cmd_spatial_static(args)
    model = _model(args)
    kp = _gains(args.kp, "kp", model)
    if args.joints == "pd" and kp is None:
        raise ValueError("--kp: required with --joints pd (N m/rad, per joint or one value)")
    load = TipLoad.from_magnitude(args.tip_force, args.tip_force_angle_deg, args.tip_torque)
    res = static_equilibrium(model, _angles(args, model), joints=args.joints, kp=kp,
                             load=load, linear=not args.nonlinear)
    out = res.as_dict()
    out["analysis"] = "nonlinear" if args.nonlinear else "linear"
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{model.arm.name} ({out['analysis']} static, joints {args.joints}):")
        print(f"  tip rotation      {out['tip_rotation_deg']:10.4f} deg")
        print(f"  tip displacement  {out['tip_displacement_mm']:10.3f} mm (vertical)")
        for lk, d in zip(model.arm.links, out["links"]):
            print(f"  {lk.name}: tip deflection {1e3 * d['tip_deflection_m']:9.3f} mm, "
                  f"tip rotation {np.degrees(d['tip_rotation_rad']):8.4f} deg")
    return 0


def _with_options(sc, args, spatial: bool):
    """The scenario with ``--kinematics``, ``--duration``, ``--method``, ``--step`` and
    ``--rho-inf``, each checked with one line."""
    from dataclasses import replace
    if args.kinematics:
        sc = replace(sc, arm=replace(sc.arm, kinematics=args.kinematics) if spatial
                     else sc.arm.with_kinematics(args.kinematics))
    if args.duration is not None:
        if not args.duration > 0:
            raise ValueError(f"--duration: got {args.duration}; expected a time > 0 s")
        sc = replace(sc, duration=args.duration,
                     sample_period=min(sc.sample_period, args.duration))
    if args.method and spatial:
        raise ValueError(f"--method: not available for a spatial scenario ({args.scenario}); "
                         "the fixed-step compiled integrator is the only method")
    if args.method:
        sc = replace(sc, method=args.method)
    if getattr(args, "step", None) is not None:
        if not 0 < args.step <= sc.sample_period:
            raise ValueError(f"--step: got {args.step}; expected a step > 0 s and at most "
                             f"the sample period ({sc.sample_period} s)")
        sc = replace(sc, step=args.step, **({} if spatial else {"method": "fixed"}))
    if getattr(args, "rho_inf", None) is not None:
        if not 0 <= args.rho_inf <= 1:
            raise ValueError(f"--rho-inf: got {args.rho_inf}; expected 0 <= rho_inf <= 1")
        sc = replace(sc, rho_inf=args.rho_inf)
    return sc


def _simulate(scenario_ref, args, label: str):
    """Any scenario (flex_model.scenario.load_scenario): run it and write CSV, PNG and
    (``--bag``, spatial arms) a bag. (scenario, result, summary)."""
    from dataclasses import replace

    from flex_model.plots import plot_simulation
    from flex_model.scenario import load_scenario

    sc = load_scenario(scenario_ref, args.vars_per_link)
    spatial = sc.spatial
    if getattr(args, "bag", False) and not spatial:
        raise ValueError(f"--bag: only for spatial scenarios so far ({args.scenario} is "
                         "planar; record the model node with flex-twin record)")
    sc = _with_options(sc, args, spatial)
    model = sc.model()
    advice = sc.advice(model, check=not getattr(args, "no_advice", False))
    if advice.warning:
        print(f"flex-twin: warning: {advice.warning}", file=sys.stderr)
    # numba loads (or compiles) the integrator on its first call: a run of two samples
    # first, timed apart, so the CPU-s per simulated second are the integration's alone
    t0, c0 = time.perf_counter(), time.process_time()
    short = replace(sc, duration=min(sc.duration, 2 * sc.sample_period))
    short.run(model=model, advise=False)
    load_wall, load_cpu = time.perf_counter() - t0, time.process_time() - c0
    t0, c0 = time.perf_counter(), time.process_time()
    res = sc.run(progress=Progress(label, not args.json), model=model, advise=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    out_dir = run_dir(args.out, sc.name)
    csv = out_dir / f"{sc.name}.csv"
    res.to_csv(csv)
    est = advice.estimate
    summary = {"scenario": sc.name, "arm": sc.arm.name, "kinematics": sc.arm.kinematics,
               "duration_s": sc.duration, "method": sc.method, "step_s": res.stats.get("dt"),
               "rho_inf": sc.rho_inf if sc.method == "fixed" else None,
               "wall_s": wall, "cpu_s": cpu, "cpu_s_per_simulated_s": cpu / sc.duration,
               "steps": res.stats["steps"], "load_compile_wall_s": load_wall,
               "load_compile_cpu_s": load_cpu, "highest_mode_hz": advice.highest_mode_hz,
               "highest_excited_mode_hz": advice.highest_excited_mode_hz,
               "warning": advice.warning, "estimated_tip_error": None if est is None else {
                   "step": est.step_error, "variables": est.vars_error,
                   "window_s": est.window, "cost_s": est.cost_s},
               "csv": str(csv), **res.summary()}
    if not args.no_plot:
        png = out_dir / f"{sc.name}.png"
        plot_simulation(res, png, title=f"{sc.name} ({sc.arm.name})")
        summary["png"] = str(png)
    if getattr(args, "bag", False):
        from .spatial_bags import write_spatial_bag
        write_spatial_bag(res, out_dir / "bag")
        summary["bag"] = str(out_dir / "bag")
    return sc, res, summary


def _print_summary(s: dict) -> None:
    step = f", step {s['step_s']:.3g} s, rho_inf {s['rho_inf']:g}" \
        if s.get("rho_inf") is not None else ""
    arm = f"spatial arm {s['arm']} ({s['coordinates']} coordinates" if s.get("spatial") \
        else f"arm {s['arm']} ({s['vars_per_link']} variables per link"
    print(f"scenario {s['scenario']} on {arm}, {s['kinematics']} kinematics, "
          f"{s['method']} step{step})")
    newton = f", {s['newton_iterations']} Newton iterations" if "newton_iterations" in s \
        else ""
    print(f"  simulated {s['duration_s']:g} s in {s['wall_s']:.3f} s wall, "
          f"{s['cpu_s_per_simulated_s']:.4f} CPU-s per simulated s, {s['steps']} steps"
          + newton)
    print(f"  numba load/compile before the run (not in the figure above): "
          f"{s['load_compile_cpu_s']:.2f} CPU-s, {s['load_compile_wall_s']:.2f} s wall")
    if s.get("spatial"):
        print("  final joint values [rad or m]: " + ", ".join(
            f"{n} {a:.6f}" for n, a in zip(s["joint_names"], s["final_joint_values"])))
        print("  final tip [m]: ({:.5f}, {:.5f}, {:.5f})".format(*s["final_tip_m"]))
        for name, d in s["max_abs_tip_deflection"].items():
            print(f"  {name}: max |tip deflection| y {d['y_mm']:.3f} mm, z {d['z_mm']:.3f} "
                  f"mm, twist {d['twist_mrad']:.3f} mrad")
    else:
        print("  final joint angles [deg]: " + ", ".join(
            f"{a:.4f}" for a in s["final_joint_angles_deg"]))
        print("  final tip [m]: ({:.5f}, {:.5f})".format(*s["final_tip_m"]))
        print("  max |tip deflection| [mm]: " + ", ".join(
            f"{a:.2f}" for a in s["max_abs_tip_deflection_mm"]))
    print(f"  wrote {s['csv']}" + (f" and {s['png']}" if "png" in s else "")
          + (f"; bag {s['bag']}" if "bag" in s else ""))


def cmd_simulate(args) -> int:
    _, _, summary = _simulate(args.scenario, args, "simulate")
    print(json.dumps(summary) if args.json else "", end="\n" if args.json else "")
    if not args.json:
        _print_summary(summary)
    return 0


#: Exudyn reference (VALIDATION.md section E): tip of link 3 (m) at 3.5, 5 and 10 s
SECTION_E_REFERENCE_TIP = {3.5: (6.11544, -4.15557), 5.0: (6.29235, -3.91276),
                           10.0: (6.09177, -4.21345)}


def cmd_demo(args) -> int:
    """The model demo: the thesis three-link arm under PD with a torque pulse (section E)."""
    print("flex-twin demo: three flexible steel links (thesis efficiency example), PD joints,"
          " 1 kN m pulse on joint 1 at 3-4 s", file=sys.stderr)
    args.kinematics = args.kinematics or "second_order"
    args.method = args.method or "fixed"
    sc, res, summary = _simulate("thesis_three_link_pd", args, "demo")
    tips = res.link_tips()[:, -1]
    rows = []
    for t, (x, y) in SECTION_E_REFERENCE_TIP.items():
        k = int(np.argmin(np.abs(res.t - t)))
        rows.append({"t_s": t, "tip_m": tips[k].tolist(), "reference_tip_m": [x, y],
                     "difference_mm": float(1e3 * np.hypot(tips[k, 0] - x, tips[k, 1] - y))})
    summary["reference_comparison"] = rows
    if args.json:
        print(json.dumps(summary))
        return 0
    _print_summary(summary)
    print("  tip of link 3 vs the geometrically exact Exudyn reference (VALIDATION.md E):")
    for r in rows:
        print(f"    t = {r['t_s']:4.1f} s: ours ({r['tip_m'][0]:.5f}, {r['tip_m'][1]:.5f}) m, "
              f"reference ({r['reference_tip_m'][0]:.5f}, {r['reference_tip_m'][1]:.5f}) m, "
              f"{r['difference_mm']:.1f} mm apart")
    return 0


def cmd_twin_demo(args) -> int:
    """The thesis Ch. V task over ROS: planner, controller and model nodes, recorded."""
    from .ros_twin_demo import run
    how = "controller (Eq. 95) -> model over ROS topics" if args.topic_loop else \
        "model with Eq. (95) in its loop"
    print(f"flex-twin twin demo: planner -> {how}, thesis Ch. V task", file=sys.stderr)
    s = run(args.out, duration=args.duration, progress=Progress("twin demo", not args.json),
            in_loop=not args.topic_loop)
    if args.json:
        print(json.dumps(s))
        return 0
    print(f"{'waypoint':>8} {'t [s]':>6} {'tip error [mm]':>15}")
    for k, w in enumerate(s["waypoints"]):
        print(f"{k + 1:>8} {w['t_s']:6.1f} {w['tip_error_mm']:15.2f}")
    print("max |tip deflection| per link [mm]: " + ", ".join(
        f"{v:.1f}" for v in s["max_abs_tip_deflection_mm"]))
    print("peak torques [N m]: " + ", ".join(f"{v:.1f}" for v in s["peak_torque_nm"]))
    print(f"simulated {s['simulated_s']:g} s in {s['wall_s']:.1f} s wall "
          f"(real-time factor {s['real_time_factor']:.2f}; the loop alone "
          f"{s['loop_real_time_factor']:.2f}, controller {s['controller']})")
    print(f"bag: {s['bag']} (open it in Foxglove: File > Open local file, the .mcap inside; "
          f"/flex/shape shows the deflected arm)")
    print(f"plots: {s['png']}")
    return 0


def cmd_effects(args) -> int:
    """The effect library: parameters with units, off values, bounds, tolerances."""
    from flex_model.effects import EFFECT_TYPES, NOMINAL_TOLERANCES
    lib = {"effects": [cls.describe() for cls in EFFECT_TYPES.values()],
           "nominal_tolerances": NOMINAL_TOLERANCES}
    if args.json:
        print(json.dumps(lib))
        return 0
    for e in lib["effects"]:
        print(f"{e['type']} ({e['target']}): {e['description']}")
        for p in e["parameters"]:
            print(f"    {p['name']:20s} [{p['unit']}] off {p['off']:g}, bounds "
                  f"{p['bounds'][0]:g}..{p['bounds'][1]:g}, tolerance {100 * p['tolerance']:g} %")
        print("    cannot be told apart from: " + "; ".join(e["equivalent"]))
    print("nominal parameter tolerances: " + ", ".join(
        f"{k} {100 * v:g} %" for k, v in NOMINAL_TOLERANCES.items()))
    return 0


def cmd_presets(args) -> int:
    from flex_model.arm import load_arm, preset_names
    from flex_model.scenario import scenario_names

    from flex_model.spatial.description import SPATIAL_PRESET_DIR
    from flex_model.spatial.loader import load_spatial_arm

    arms = {n: load_arm(n).description for n in preset_names()}
    spatial = {p.stem: load_spatial_arm(p).description
               for p in sorted(SPATIAL_PRESET_DIR.glob("*.yaml"))}
    if args.json:
        print(json.dumps({"arms": arms, "spatial_arms": spatial,
                          "scenarios": scenario_names(),
                          "spatial_scenarios": scenario_names(spatial=True)}))
        return 0
    for title, group in (("arms", arms), ("spatial arms (modes, static)", spatial)):
        print(f"{title}:")
        for n, d in group.items():
            print(f"  {n:26s} {d}")
    print("scenarios:")
    for n in scenario_names():
        print(f"  {n}")
    print("spatial scenarios (simulate):")
    for n in scenario_names(spatial=True):
        print(f"  {n}")
    return 0


def _kinematics_arg(sp) -> None:
    """--kinematics: the arm's kinematics override."""
    sp.add_argument("--kinematics", choices=["small_deflection", "second_order", "exact"],
                    default=None, help="override the arm's kinematics (second_order: "
                    "with the axial shortening of bent links, i.e. geometric stiffening; "
                    "exact: geometrically exact, simulate only)")


def _arm_args(sp) -> None:
    """The arm and its configuration (modes, static)."""
    sp.add_argument("arm", help="arm preset name or YAML path (planar, or spatial: a DH "
                    "table or a URDF side file)")
    sp.add_argument("--vars-per-link", type=int, default=None, metavar="N",
                    help="deformation variables of every link (even, >= 2)")
    sp.add_argument("--joint-angles-deg", type=float, nargs="+", default=None,
                    help="joint (relative) angles of the configuration, deg (a spatial "
                    "arm's prismatic joints: m)")
    sp.add_argument("--json", action="store_true", help="machine-readable output")
    _kinematics_arg(sp)


def _sim_args(sp) -> None:
    """The run options of a simulation (simulate, demo)."""
    sp.add_argument("--vars-per-link", type=int, default=None, metavar="N")
    sp.add_argument("--duration", type=float, default=None, help="override, s")
    sp.add_argument("--method", choices=["variable", "fixed"], default=None)
    sp.add_argument("--step", type=float, default=None, metavar="S",
                    help="fixed step (s; implies --method fixed)")
    sp.add_argument("--rho-inf", type=float, default=None, metavar="R",
                    help="fixed step: numerical damping of the unresolved high modes, "
                    "0 (most) .. 1 (none); default: the scenario's, else 0.9")
    sp.add_argument("--out", default=None, help="output directory (default runs/...)")
    sp.add_argument("--no-plot", action="store_true")
    sp.add_argument("--json", action="store_true")
    sp.add_argument("--no-advice", action="store_true",
                    help="fixed step: skip the step and variables check (it runs the "
                    "first 0.5 s at the step, a quarter of it and with twice the "
                    "variables)")
    _kinematics_arg(sp)


def _add_modes_parser(sub) -> None:
    """flex-twin modes."""
    sp = sub.add_parser("modes", help="natural frequencies and mode shapes")
    _arm_args(sp)
    sp.add_argument("--joints", choices=["clamped", "hinged", "pd"], default="clamped")
    sp.add_argument("--kp", type=float, nargs="+", help="PD stiffness, N m/rad (--joints pd)")
    sp.add_argument("--kd", type=float, nargs="+", help="PD damping, N m s/rad")
    sp.add_argument("--count", type=int, default=None, help="number of modes to print")
    sp.add_argument("--gravity-preload", action="store_true",
                    help="linearize about the equilibrium under gravity (default: unloaded)")
    sp.add_argument("--plot", default=None, help="write the mode shapes to this PNG")
    sp.add_argument("--state-space", default=None, metavar="FILE.npz",
                    help="write the linearization x' = A x + B u, y = C x + D u (with input "
                    "and output names) to this file")
    sp.set_defaults(func=cmd_modes)


def _add_static_parser(sub) -> None:
    """flex-twin static."""
    sp = sub.add_parser("static", help="static equilibrium: tip rotation and displacement")
    _arm_args(sp)
    sp.add_argument("--joints", choices=["clamped", "pd"], default="clamped")
    sp.add_argument("--kp", type=float, nargs="+", help="PD stiffness, N m/rad (--joints pd)")
    sp.add_argument("--tip-torque", type=float, default=0.0, help="tip torque C, N m (CCW +)")
    sp.add_argument("--tip-force", type=float, default=0.0, help="tip force F, N")
    sp.add_argument("--tip-force-angle-deg", type=float, default=90.0,
                    help="direction of F from the x axis, deg (default 90: upwards)")
    sp.add_argument("--no-gravity", action="store_true", help="switch gravity off")
    sp.add_argument("--nonlinear", action="store_true",
                    help="full equilibrium of the model (default: linear static response)")
    sp.set_defaults(func=cmd_static)


def _add_run_parsers(sub) -> None:
    """flex-twin simulate, demo and twin-demo."""
    sp = sub.add_parser("simulate", help="simulate a scenario file; writes CSV and PNG")
    sp.add_argument("scenario", help="scenario preset name or YAML path (planar, or spatial: "
                    "its arm a spatial arm)")
    _sim_args(sp)
    sp.add_argument("--bag", action="store_true", help="spatial scenarios: also write a "
                    "rosbag2 (MCAP) of the run to <out>/bag")
    sp.set_defaults(func=cmd_simulate)

    sp = sub.add_parser("demo", help="the model demo (section E scenario)")
    _sim_args(sp)
    sp.set_defaults(func=cmd_demo)

    sp = sub.add_parser("twin-demo", help="the thesis Ch. V task over ROS (planner, "
                        "controller, model), recorded to a bag")
    sp.add_argument("--out", default=None, help="output directory (default runs/...)")
    sp.add_argument("--duration", type=float, default=15.0, help="simulated time, s")
    sp.add_argument("--topic-loop", action="store_true",
                    help="the controller node over topics instead of Eq. (95) in the model's "
                    "loop (the default)")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_twin_demo)


def _add_listing_parsers(sub) -> None:
    """flex-twin effects and presets."""
    sp = sub.add_parser("effects", help="the library of model effects and their parameters")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_effects)

    sp = sub.add_parser("presets", help="list arm and scenario presets")
    sp.add_argument("--json", action="store_true")
    sp.set_defaults(func=cmd_presets)


def _add_module_parsers(sub) -> None:
    """The commands written next to their code (bags, ROS suite, control, planning,
    comparison, diagnosis, estimation, real arms, sweeps, viewer)."""
    from .bag_cli import add_bag_parsers  # record, play, bag info (rclpy imported lazily)
    add_bag_parsers(sub)
    from .ros_suite import add_observe_parser, add_up_parser  # (rclpy imported lazily)
    add_up_parser(sub)
    add_observe_parser(sub)
    from flex_control.cli import add_control_parser
    from flex_planner.cli import add_plan_parser

    from .comparison.cli import add_compare_parser
    from .diagnosis.cli import add_diagnose_parser
    from .estimate_cli import add_estimate_parser
    from .real_arms.cli import add_real_arm_parsers
    from .real_arms.modal_cli import add_modal_parsers
    from .sweep import add_sweep_parser
    from .view_cli import add_view_parser
    for add in (add_compare_parser, add_diagnose_parser, add_estimate_parser,
                add_real_arm_parsers,
                add_modal_parsers, add_sweep_parser, add_plan_parser, add_control_parser,
                add_view_parser):
        add(sub)


def build_parser() -> argparse.ArgumentParser:
    """The flex-twin command line: its own commands, then those of the modules."""
    p = argparse.ArgumentParser(prog="flex-twin", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    _add_modes_parser(sub)
    _add_static_parser(sub)
    _add_run_parsers(sub)
    _add_listing_parsers(sub)
    _add_module_parsers(sub)
    return p


BAG_COMMANDS = ("record", "play", "bag")


def main(argv=None) -> int:
    ros_environment()  # also done on importing flex_model; repeated for embedding callers
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv and argv[0] in BAG_COMMANDS:
        # the recorder starts in ~1 s: without the analyses' imports (scipy, numba: seconds)
        from .bag_cli import main as bag_main
        return bag_main(argv)
    return run_command(build_parser().parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
