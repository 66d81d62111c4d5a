"""``flex-twin control``: design and analysis of the joint controllers.

    flex-twin control step   [--arm seed000_real_arm seed000_table3] ...   Eq. (45) steps
    flex-twin control design ARM (--trajectory PLAN.npz | --waypoints-deg .. --times ..)
    flex-twin control check  ARM (--trajectory .. | --waypoints-deg ..) (--schedule F | --h --a)

Every command takes ``--json`` and writes PNG plots (and the schedule YAML) to ``--out DIR``
(default ``runs/<time>-control-<command>``). ``check`` exits with 1 when the LTV responses
do not converge. Hooked into ``flex-twin`` by :func:`add_control_parser`; standalone:
``python -m flex_control.cli control ...``.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from flex_model.command import run_dir


def _model(args):
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel

    return FlexArmModel(load_arm(args.arm, args.vars_per_link))


def _trajectory(args, model):
    from .nominal import load_trajectory, quasi_static_trajectory

    if args.trajectory:
        data = load_trajectory(args.trajectory)
        if list(data.joint_names) != list(model.arm.joint_names):
            raise ValueError(f"--trajectory: joint_names: got {list(data.joint_names)}; "
                             f"expected {model.arm.joint_names} (arm {model.arm.name})")
        return data
    if args.waypoints_deg is None or args.times is None:
        raise ValueError("--trajectory or --waypoints-deg with --times: got neither; "
                         "expected a nominal trajectory")
    nj = model.n_links
    if len(args.waypoints_deg) != nj * len(args.times):
        raise ValueError(f"--waypoints-deg: got {len(args.waypoints_deg)} values; expected "
                         f"{nj} per time x {len(args.times)} times = {nj * len(args.times)}")
    wp = np.radians(np.reshape(args.waypoints_deg, (len(args.times), nj)))
    return quasi_static_trajectory(model, args.times, wp, args.sample_period)


def _gain_function(args, model):
    from .gain_schedule import GainSchedule
    from .ltv import GainFunction

    if args.schedule:
        sched = GainSchedule.load(args.schedule)
        if list(sched.joint_names) != list(model.arm.joint_names):
            raise ValueError(f"--schedule: joint_names: got {list(sched.joint_names)}; "
                             f"expected {model.arm.joint_names}")
        return GainFunction(schedule=sched), {"schedule": str(args.schedule)}
    if args.h is None or args.a is None:
        raise ValueError("--schedule or --h with --a: got neither; expected the gains")
    nj = model.n_links
    for name, v in (("h", args.h), ("a", args.a)):
        if len(v) not in (1, nj) or min(v) <= 0:
            raise ValueError(f"--{name}: got {v}; expected 1 or {nj} values > 0")
    return GainFunction(args.h, args.a, n_joints=nj), {"h": args.h, "a": args.a}


def cmd_step(args) -> int:
    from .step_response import step_response

    out_dir = None if args.no_plot else run_dir(args.out, "control-step")
    results = []
    for arm in args.arm:
        r = step_response(arm, start_deg=args.start_deg, end_deg=args.end_deg, kpp=args.kpp,
                          kpv=args.kpv, gear_ratio=args.gear_ratio,
                          rotor_inertia=args.rotor_inertia, damping_ratio=args.damping_ratio,
                          t_final=args.duration)
        d = r.as_dict()
        if out_dir is not None:
            from .plots import plot_step
            png = out_dir / f"step_{Path(arm).stem}.png"
            plot_step(r, png)
            d["png"] = str(png)
        results.append(d)
    if args.json:
        print(json.dumps({"law": "seed 000 Eq. (45)", "kpp": args.kpp, "kpv": args.kpv,
                          "gear_ratio": args.gear_ratio, "results": results}))
        return 0
    for d in results:
        print(f"{d['arm']}: step {d['step_deg'][0]:g} -> {d['step_deg'][1]:g} deg, "
              f"link damping ratio {d['link_damping_ratio']:g}")
        print(f"  joint: rise time {1e3 * d['joint_rise_time_s']:.2f} ms, overshoot "
              f"{d['joint_overshoot_pct']:.3g} %")
        print(f"  tip angle: rise time {1e3 * d['tip_rise_time_s']:.2f} ms, overshoot "
              f"{d['tip_overshoot_pct']:.1f} %")
        print(f"  residual tip oscillation: {d['tip_frequency_hz']:.4f} Hz, amplitude "
              f"{1e3 * d['tip_amplitude_m']:.1f} mm (clamped f1 "
              f"{d['clamped_first_frequency_hz']:.4f} Hz)")
        print("  paper: " + ", ".join(f"{k} {v}" for k, v in d["paper"].items()))
        if "png" in d:
            print(f"  wrote {d['png']}")
    return 0


def cmd_design(args) -> int:
    from .closed_loop import LinearizedTrajectory, NominalTrajectory
    from .design import DesignSettings, design_schedule
    from .ltv import GainFunction, LTVSettings, ltv_check

    model = _model(args)
    data = _trajectory(args, model)
    settings = DesignSettings(n_points=args.points, h_bounds=tuple(args.h_bounds),
                              a_bounds=tuple(args.a_bounds), tau_weight=args.tau_weight,
                              per_joint=not args.shared_gains,
                              deflection_weight=args.deflection_weight)
    result = design_schedule(model, data, settings)
    out_dir = run_dir(args.out, "control-design")
    path = result.schedule.save(out_dir / "schedule.yaml")
    out = result.as_dict()
    out["schedule"] = str(path)
    if args.check:
        lin = LinearizedTrajectory(model, NominalTrajectory.from_data(model, data))
        h_max, a_max = result.schedule.max_gains()
        out["ltv_schedule"] = ltv_check(lin, GainFunction(schedule=result.schedule),
                                        LTVSettings(), keep_responses=False).as_dict()
        out["ltv_max_gains"] = ltv_check(lin, GainFunction(h_max, a_max,
                                                           n_joints=model.n_links),
                                         LTVSettings(), keep_responses=False).as_dict()
    if not args.no_plot:
        from .plots import plot_design
        plot_design(result, out_dir / "design.png")
        out["png"] = str(out_dir / "design.png")
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{model.arm.name}: {len(result.points)} design points, cost {out['cost']}")
    print(f"{'t [s]':>7} {'h':>18} {'a':>18} {'zeta_min':>9} {'tau_max [s]':>11}")
    for p in result.points:
        print(f"{p.t:7.2f} {np.array2string(p.h, precision=3):>18} "
              f"{np.array2string(p.a, precision=3):>18} {p.zeta_min:9.4f} {p.tau_max:11.3f}")
    print(f"stabilizing: {result.stabilizing}; largest gains h {out['h_max']}, "
          f"a {out['a_max']}")
    for key in ("ltv_schedule", "ltv_max_gains"):
        if key in out:
            print(f"LTV check ({key[4:]}): converged {out[key]['converged']}")
    print(f"wrote {path}" + (f" and {out['png']}" if "png" in out else ""))
    return 0


def cmd_check(args) -> int:
    from .closed_loop import LinearizedTrajectory, NominalTrajectory
    from .ltv import LTVSettings, frozen_time_report, ltv_check

    model = _model(args)
    data = _trajectory(args, model)
    gains, gain_info = _gain_function(args, model)
    lin = LinearizedTrajectory(model, NominalTrajectory.from_data(model, data))
    settings = LTVSettings(step=args.step, hold=args.hold, tolerance=args.tolerance)
    report = ltv_check(lin, gains, settings)
    times = np.linspace(lin.t[0], lin.t[-1], args.points)
    frozen = frozen_time_report(lin, gains, times)
    out = {"arm": model.arm.name, "gains": gain_info, **report.as_dict(),
           "frozen_time": [p.as_dict() for p in frozen],
           "frozen_time_stable": all(p.decay_rate > 0 for p in frozen)}
    nonlinear = run = None
    if args.nonlinear:
        from .tracking import nonlinear_free_responses, simulate_tracking
        kw = ({"schedule": gains.schedule} if gains.schedule is not None
              else {"h": gains.h, "a": gains.a})
        last = model.n_links - 1
        idx = [model.alpha_index(0), model.tip_deflection_index(last)]
        nonlinear = nonlinear_free_responses(model, data, indices=idx, settings=settings, **kw)
        out["nonlinear"] = nonlinear.as_dict()
        run = simulate_tracking(model, data, **kw)
        if data.tip is not None:
            ref = np.column_stack([np.interp(run.t, data.t, data.tip[:, k]) for k in (0, 1)])
            out["nonlinear"]["max_tip_error_m"] = float(np.max(np.hypot(
                *(run.tip_positions - ref).T)))
    if not args.no_plot:
        from .plots import plot_frozen, plot_ltv
        out_dir = run_dir(args.out, "control-check")
        plot_ltv(report, model, out_dir / "ltv.png", title=f"{model.arm.name}: LTV check")
        plot_frozen(frozen, out_dir / "frozen.png")
        out["png"] = [str(out_dir / "ltv.png"), str(out_dir / "frozen.png")]
        if run is not None:
            from .plots import plot_tracking
            plot_tracking(run, data, out_dir / "tracking.png")
            out["png"].append(str(out_dir / "tracking.png"))
    if args.json:
        print(json.dumps(out))
    else:
        fr = out["free_responses"]
        ir = out["impulse_responses"]
        print(f"{model.arm.name}: LTV closed loop over {out['horizon_s'][0]:g} - "
              f"{out['horizon_s'][1]:g} s, gains {gain_info}")
        print(f"  {fr['count']} free responses: converged {fr['converged']} (worst tail/peak "
              f"{fr['worst_tail_ratio']:.3g}, tolerance {fr['tolerance']:g})")
        print(f"  impulse response matrix: converged {ir['converged']} (tail/peak "
              f"{max(ir['end_ratio']):.3g})")
        print(f"  frozen time: zeta_min {min(p.zeta_min for p in frozen):.4f}, tau_max "
              f"{max(p.tau_max for p in frozen):.3f} s, gain margins: h / "
              f"{min(p.gain_margin_low for p in frozen):.3g} .. h x "
              f"{min(p.gain_margin_high for p in frozen):.3g}")
        if nonlinear is not None:
            nl = out["nonlinear"]
            print(f"  nonlinear loop, {len(nl['indices'])} initial conditions x "
                  f"{nl['scales']}: converged {nl['converged']}, linearity error "
                  f"{nl['worst_linearity_error']:.3g}"
                  + (f", max tip error {1e3 * nl['max_tip_error_m']:.2f} mm"
                     if "max_tip_error_m" in nl else ""))
        if "png" in out:
            print("  wrote " + ", ".join(out["png"]))
    ok = report.converged and (nonlinear is None or nonlinear.converged)
    return 0 if ok else 1


def add_control_parser(subparsers) -> argparse.ArgumentParser:
    """Register ``control`` (with ``step``, ``design``, ``check``) on ``subparsers``."""
    from .step_response import GEAR_RATIO, KPP, KPV, ROTOR_INERTIA

    p = subparsers.add_parser("control", help="controller design and analysis (Eqs. 45, 95)",
                              description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="control_command", required=True)

    def common(sp):
        sp.add_argument("--json", action="store_true", help="machine-readable output")
        sp.add_argument("--out", default=None, help="output directory for PNG/YAML")
        sp.add_argument("--no-plot", action="store_true", help="write no plots")

    def trajectory_args(sp):
        sp.add_argument("arm", help="arm preset name or YAML path")
        sp.add_argument("--vars-per-link", type=int, default=None, metavar="N")
        sp.add_argument("--trajectory", default=None,
                        help="nominal trajectory .npz (t, positions, velocities, "
                             "accelerations, efforts, q_nominal, joint_names)")
        sp.add_argument("--waypoints-deg", type=float, nargs="+", default=None,
                        help="joint waypoints, deg, n_joints per time (quasi-static nominal)")
        sp.add_argument("--times", type=float, nargs="+", default=None,
                        help="times of the waypoints, s")
        sp.add_argument("--sample-period", type=float, default=0.02,
                        help="sample period of the quasi-static nominal, s")

    sp = sub.add_parser("step", help="seed 000 Eq. (45) step responses (VALIDATION.md G)")
    sp.add_argument("--arm", nargs="+", default=["seed000_real_arm", "seed000_table3"])
    sp.add_argument("--start-deg", type=float, default=10.0)
    sp.add_argument("--end-deg", type=float, default=30.0)
    sp.add_argument("--kpp", type=float, default=KPP, help="position gain K_pp, 1/s")
    sp.add_argument("--kpv", type=float, default=KPV, help="velocity gain K_pv, N m s/rad")
    sp.add_argument("--gear-ratio", type=float, default=GEAR_RATIO)
    sp.add_argument("--rotor-inertia", type=float, default=ROTOR_INERTIA, help="kg m^2")
    sp.add_argument("--damping-ratio", type=float, default=None,
                    help="link first-mode damping ratio (default: the seed's xi_1)")
    sp.add_argument("--duration", type=float, default=None, help="s")
    common(sp)
    sp.set_defaults(func=cmd_step)

    sp = sub.add_parser("design", help="gain-scheduled design of Eq. (95) (thesis V.2)")
    trajectory_args(sp)
    sp.add_argument("--points", type=int, default=16, help="design points on the trajectory")
    sp.add_argument("--h-bounds", type=float, nargs=2, default=[0.01, 100.0])
    sp.add_argument("--a-bounds", type=float, nargs=2, default=[0.1, 20.0])
    sp.add_argument("--tau-weight", type=float, default=1.0,
                    help="w in J = ln zeta_min - w ln tau_max")
    sp.add_argument("--shared-gains", action="store_true", help="one (h, a) for all joints")
    sp.add_argument("--deflection-weight", type=float, default=0.0,
                    help="rad/m: schedule on tip deflections too")
    sp.add_argument("--check", action="store_true",
                    help="also run the LTV check on the schedule and on its largest gains")
    common(sp)
    sp.set_defaults(func=cmd_design)

    sp = sub.add_parser("check", help="LTV free/impulse responses and frozen-time "
                                      "eigenvalues (thesis V.3); exit 1 if not converged")
    trajectory_args(sp)
    sp.add_argument("--schedule", default=None, help="gain schedule YAML")
    sp.add_argument("--h", type=float, nargs="+", default=None, help="constant h per joint")
    sp.add_argument("--a", type=float, nargs="+", default=None, help="constant a per joint")
    sp.add_argument("--step", type=float, default=0.01, help="transition-matrix step, s")
    sp.add_argument("--hold", type=float, default=0.0, help="hold the end pose this long, s")
    sp.add_argument("--tolerance", type=float, default=0.05, help="tail/peak bound")
    sp.add_argument("--points", type=int, default=16, help="frozen-time report points")
    sp.add_argument("--nonlinear", action="store_true",
                    help="also run the nonlinear closed loop: free responses from the first "
                         "link angle and the last tip deflection, and the tracking run")
    common(sp)
    sp.set_defaults(func=cmd_check)
    return p


def main(argv=None) -> int:
    """Standalone entry (same exit codes as flex-twin: 2 bad input, 1 failed)."""
    parser = argparse.ArgumentParser(prog="flex-control")
    add_control_parser(parser.add_subparsers(dest="command", required=True))
    from flex_model.command import run_command
    return run_command(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
