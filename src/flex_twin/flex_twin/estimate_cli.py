"""``flex-twin estimate``: the thin CLI over :mod:`flex_twin.estimate`."""
from __future__ import annotations

import json
from pathlib import Path


def parse_stds(items) -> dict:
    """``NAME=STD`` strings -> {channel: std}, one-line errors."""
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not out[name.strip()] > 0:
            raise ValueError(f"--std: got {item!r}; expected CHANNEL=STD with STD > 0 (SI)")
    return out


def cmd_estimate(args) -> int:
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_model.estimation import EstimatorSettings
    from .diagnosis.sources import load_recording
    from .estimate import estimate_file, write_outputs
    arm = load_arm(args.arm)
    rec = load_recording(args.recording, arm.n_links, gravity=arm.gravity)
    measure = [m.strip() for m in args.measure.split(",") if m.strip()]
    settings = EstimatorSettings(sample_period=rec.dt, torque_noise=args.torque_noise,
                                 modal_noise=args.modal_noise, adapt=tuple(args.adapt or ()),
                                 relinearize_every=args.relinearize_every,
                                 adapt_horizon=args.adapt_horizon, adapt_block=args.adapt_block)
    est = estimate_file(rec, FlexArmModel(arm), measure, stds=parse_stds(args.std),
                        settings=settings, duration=args.duration)
    out = Path(args.out)
    paths = write_outputs(est, out, f"{Path(args.recording).name}: measured "
                          f"{', '.join(measure)}")
    summary = est.summary()
    if args.json:
        print(json.dumps(summary, indent=1, default=float))
        return 0
    f = summary["filter"]
    print(f"{rec.source}: {len(est.t)} samples, measured {', '.join(measure)}; NIS mean "
          f"{f['nis_mean']:.2f} (dof {f['nis_dof_mean']:.1f}), within its 95 % bound "
          f"{100 * f['nis_95_fraction']:.1f} %")
    for p, v in f["parameters"].items():
        print(f"  adapted {p}: {v:.4g} +- {f['parameter_std'][p]:.2g}")
    for c, m in summary["held_out"].items():
        pct = "" if m["rms_pct_of_peak"] is None else f" ({m['rms_pct_of_peak']:.1f} % of peak)"
        print(f"  held out {c}: RMS error {m['rms']:.4g}{pct}, in the 95 % band "
              f"{100 * m['coverage_95']:.1f} %")
    print(f"  wrote {paths['csv']}, {paths['png']}, {paths['json']}")
    return 0


def add_estimate_parser(sub) -> None:
    sp = sub.add_parser(
        "estimate", help="estimate the arm's state from a recording (Kalman filter)",
        description="Run the extended Kalman filter of flex_model.estimation over a "
        "recording (CSV or rosbag2; the tau<i> channels are its input) with the channels "
        "--measure as measurements; every other q, v, w, tip channel is held out and "
        "compared (RMS, %% of its peak, fraction inside the estimate's 95 %% band). Writes "
        "estimate.csv, estimate.png and summary.json into --out.")
    sp.add_argument("recording", help="CSV (t, q<i>, v<i>, tau<i>, qset<i>, [w<i>, tip_x, "
                    "tip_y]) or rosbag2 directory / .mcap")
    sp.add_argument("--arm", required=True, help="arm preset name or YAML")
    sp.add_argument("--measure", required=True, help="comma-separated channels the filter "
                    "reads: q<i>, v<i>, w<i>, tip_x, tip_y")
    sp.add_argument("--std", action="append", metavar="CHANNEL=STD", help="a reading's "
                    "noise std (SI; default q 1e-3 rad, v 1e-2 rad/s, w 5e-4 m, tip 1e-3 m)")
    sp.add_argument("--torque-noise", type=float, default=0.1, help="process noise: std of "
                    "the input torque error per joint (N m; default 0.1)")
    sp.add_argument("--modal-noise", type=float, default=0.0, help="process noise: std of "
                    "the generalized force on each deformation variable (default 0)")
    sp.add_argument("--adapt", nargs="*", default=None, metavar="PARAM", help="adapted "
                    "parameters, e.g. coulomb_friction:0 payload_mass link_stiffness:0")
    sp.add_argument("--adapt-horizon", type=float, default=0.0, metavar="SECONDS",
                    help="fit the adapted joint frictions by least squares on the momentum "
                    "balance of the last SECONDS (the horizon fit, docs/estimation.md; "
                    "default 0: random walks)")
    sp.add_argument("--adapt-block", type=float, default=0.05, metavar="SECONDS",
                    help="the horizon fit's block: one fit per block (default 0.05 s)")
    sp.add_argument("--relinearize-every", type=int, default=10, help="samples between "
                    "Jacobians (default 10)")
    sp.add_argument("--duration", type=float, default=None, help="only the first seconds")
    sp.add_argument("--out", default="runs/estimate", help="output directory")
    sp.add_argument("--json", action="store_true", help="print the JSON summary")
    sp.set_defaults(func=cmd_estimate)
