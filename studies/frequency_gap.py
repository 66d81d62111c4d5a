"""One measured natural frequency against the model: the size of each single effect (EI or
mass scale, tip mass or inertia, root spring, hub inertia behind a PD joint) that alone
explains it (issue 9; seed 000's real arm: 8.24 Hz measured, 8.46 Hz modelled).

    python -m studies.frequency_gap [--arm seed000_real_arm] [--measured-hz 8.24] [--out DIR]

Writes ``report.md``, ``frequency_gap.png`` and ``result.json`` into ``--out`` (default
``runs/<timestamp>-frequency_gap``).
"""
from __future__ import annotations

import json

import numpy as np

from flex_model.plots import finish_figure, plt
from .modal_diagnosis import (ModalSetup, change_text, fmt_value, frequency_gap, link_totals,
                              modal_frequencies, reach_hz, say_for, standard_candidates,
                              tolerance_text)


def cmd_frequency_gap(args) -> int:
    from flex_model.arm import load_arm
    from flex_model.command import run_dir
    say = say_for(args)
    if not args.measured_hz > 0:
        raise ValueError(f"--measured-hz: got {args.measured_hz}; expected a frequency > 0 Hz")
    if not args.sigma > 0:
        raise ValueError(f"--sigma: got {args.sigma}; expected a relative uncertainty > 0")
    arm = load_arm(args.arm, args.vars)
    setup = ModalSetup(arm)
    kp, kd = args.pd_kp, args.pd_kd
    if kp is None:
        try:   # seed 000 Eq. (45) at the joint: kp = n^2 Kpv Kpp, kd = n^2 Kpv
            from flex_control.step_response import GEAR_RATIO, KPP, KPV
            kp, kd = GEAR_RATIO ** 2 * KPV * KPP, GEAR_RATIO ** 2 * KPV
        except ImportError:
            kp = None
    cands = standard_candidates(setup, pd_kp=kp, pd_kd=kd)
    count = max(3, args.mode + 2)
    nominal = modal_frequencies(setup, count)
    say(f"sizing {len(cands)} effects to move mode {args.mode} from "
        f"{nominal[args.mode - 1]:.4f} to {args.measured_hz} Hz")
    fits = frequency_gap(setup, cands, args.measured_hz, mode=args.mode, sigma=args.sigma,
                         count=count)
    reach = [reach_hz(setup, c, args.mode) for c in cands]
    out = run_dir(args.out, "frequency-gap")
    result = {"arm": arm.name, "mode": args.mode, "measured_hz": args.measured_hz,
              "nominal_hz": nominal.tolist(), "sigma": args.sigma,
              "fits": [dict(f.as_dict(), reach_hz=list(r)) for f, r in zip(fits, reach)]}
    report = gap_report(arm, args, nominal, fits, reach, kp)
    plot_gap(arm, args, nominal, fits, out / "frequency_gap.png")
    (out / "report.md").write_text(report)
    (out / "result.json").write_text(json.dumps(result, indent=1))
    if args.json:
        print(json.dumps(result))
    else:
        print(report)
        print(f"written: {out}/report.md, frequency_gap.png, result.json")
    return 0


def gap_report(arm, args, nominal, fits, reach, kp) -> str:
    k = args.mode - 1
    lines = [f"# One measured frequency: `{arm.name}` mode {args.mode}, "
             f"{nominal[k]:.4f} Hz modelled, {args.measured_hz} Hz measured "
             f"({100 * (args.measured_hz / nominal[k] - 1):+.2f} %)", "",
             "Each effect alone, sized to give the measured frequency exactly:", "",
             "| effect | parameter | size | added | change | within tolerance | reachable "
             "| predicted modes (Hz) |", "|---" * 8 + "|"]
    for f, r in zip(fits, reach):
        c = f.candidates[0]
        size = fmt_value(f.values[0], c.unit) if f.reachable else \
            f"none in bounds (mode {args.mode}: {r[0]:.4f}-{r[1]:.4f} Hz)"
        added = fmt_value(f.values[0] - c.nominal, c.unit) if f.reachable and c.unit != "-" \
            and np.isfinite(c.nominal) else "-"
        change, within = (change_text(f), tolerance_text(f)) if f.reachable else ("-", "-")
        lines.append(f"| {c.name} | {c.parameter} | {size} | {added} | {change} | {within}"
                     f" | {'yes' if f.reachable else 'no'} "
                     f"| {', '.join(f'{x:.2f}' for x in f.predicted_hz)} |")
    ok = [f for f in fits if f.reachable]
    inside = [f.name for f in ok if f.within_tolerance()[0]]
    untoleranced = [f.name for f in ok if f.within_tolerance()[0] is None]
    outside = [f"{f.name} ({change_text(f)}, tolerance ±{100 * f.candidates[0].tolerance:.0f} %)"
               for f in ok if f.within_tolerance()[0] is False]
    nxt = np.array([f.predicted_hz[k + 1] for f in ok])
    lines += ["", "## What one frequency can and cannot tell", "",
              f"- It fixes one number: each of the {len(ok)} reachable effects explains "
              f"{args.measured_hz} Hz exactly (one equation, one unknown), so the frequency "
              "alone cannot choose between them.",
              f"- Within the manufacturing tolerances: {', '.join(inside) or 'none'}. "
              f"Outside: {'; '.join(outside) or 'none'}. Without a nominal tolerance "
              f"(plausibility to judge): {', '.join(untoleranced) or 'none'}."]
    lines += plausibility(arm, {f.name: f for f in ok}, kp)
    unreach = [f.name for f in fits if not f.reachable]
    if unreach:
        lines.append(f"- Cannot explain it at any size within bounds: {', '.join(unreach)}"
                     + (f" (behind the PD joint kp = {kp:.4g} N m/rad the hub is held as if "
                        "clamped)" if kp else "") + ".")
    gaps = [(abs(a.predicted_hz[k + 1] / b.predicted_hz[k + 1] - 1), a.name, b.name)
            for i, a in enumerate(ok) for b in ok[i + 1:]]
    close = min(gaps) if gaps else None
    lines.append(f"- What would separate them: mode {args.mode + 1}, predicted "
                 f"{nxt.min():.2f}-{nxt.max():.2f} Hz across the candidates (nominal "
                 f"{nominal[k + 1]:.2f} Hz)"
                 + (f"; the closest pair, {close[1]} and {close[2]}, differs by only "
                    f"{100 * close[0]:.2f} % there" if close else "")
                 + ". A uniform EI scale and a uniform mass scale never separate by "
                 "frequencies alone (a static deflection or a weighing does).")
    return "\n".join(lines) + "\n"


def plausibility(arm, fits, kp) -> list:
    """Yardsticks for the sizes that have no tolerance, and EI's section tolerance."""
    length, _, ei = link_totals(arm)
    out = []
    f = fits.get("stiffness scale")
    if f is not None:
        tol = float(np.hypot(arm.tolerance("E"), 3 * arm.tolerance("section")))
        out.append(f"- EI also carries the section tolerance (I ~ h^3: ±"
                   f"{300 * arm.tolerance('section'):.0f} %): EI toleranced ±{100 * tol:.1f} % "
                   f"(root sum square with E), so EI {change_text(f)} is "
                   f"{'within' if abs(f.relative_change()[0]) <= tol else 'outside'} it.")
    f = fits.get("tip inertia")
    if f is not None and arm.payload_mass > 0:
        out.append(f"- Tip inertia {fmt_value(f.values[0], 'kg m^2')}: a radius of gyration of "
                   f"{100 * np.sqrt(f.values[0] / arm.payload_mass):.1f} cm for the "
                   f"{1000 * arm.payload_mass:.1f} g tip body.")
    f = fits.get("root compliance")
    if f is not None:
        txt = (f"- Root spring {fmt_value(f.values[0], 'N m/rad')} = "
               f"{f.values[0] / (ei / length):.0f} EI/L")
        if kp:
            txt += (f"; the PD joint's kp = {kp:.4g} N m/rad is {kp / f.values[0]:.3g} times "
                    "stiffer, so it would be a mechanical compliance (clamp, hub, gear)")
        out.append(txt + ".")
    return out


def plot_gap(arm, args, nominal, fits, path) -> None:
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.8))
    ok = [f for f in fits if f.reachable]
    names = [f.name for f in ok]
    y = np.arange(len(ok))
    change = [100 * f.relative_change()[0] for f in ok]
    tol = [100 * (f.candidates[0].tolerance or np.nan) for f in ok]
    ax[0].barh(y, np.nan_to_num(change), color="C0", label="needed change (%)")
    ax[0].errorbar(np.zeros(len(ok)), y, xerr=np.nan_to_num(tol), fmt="none", ecolor="C3",
                   capsize=6, label="manufacturing tolerance")
    for yy, f, c in zip(y, ok, change):
        if not np.isfinite(c):
            ax[0].text(0, yy, f"  {fmt_value(f.values[0], f.candidates[0].unit)} (nominal "
                       f"{fmt_value(f.candidates[0].nominal)})", va="center", fontsize=8)
    ax[0].set_yticks(y, names)
    ax[0].set_xlabel("relative change of the parameter (%)")
    ax[0].set_title(f"size that alone gives {args.measured_hz} Hz")
    k = args.mode
    ax[1].barh(y, [f.predicted_hz[k] for f in ok], color="C1")
    ax[1].axvline(nominal[k], color="k", ls="--", label=f"nominal mode {k + 1}")
    ax[1].set_yticks(y, names)
    ax[1].set_xlabel(f"predicted mode {k + 1} (Hz)")
    ax[1].set_title("what a second measured mode would show")
    finish_figure(fig, ax, path, f"{arm.name}: {nominal[k - 1]:.3f} Hz modelled, "
                  f"{args.measured_hz} Hz measured")


def build_parser():
    """The parser of ``python -m studies.frequency_gap``."""
    from .command import study_parser
    sp = study_parser("frequency_gap", "one measured frequency against the model: the "
                      "size of each single effect that explains it (issue 9)")
    sp.add_argument("--arm", default="seed000_real_arm", help="arm preset or YAML")
    sp.add_argument("--vars", type=int, default=None, help="deformation variables per link")
    sp.add_argument("--measured-hz", type=float, default=8.24, help="measured frequency (Hz)")
    sp.add_argument("--mode", type=int, default=1, choices=range(1, 6), metavar="N",
                    help="which mode was measured (1-5, default 1)")
    sp.add_argument("--sigma", type=float, default=0.002,
                    help="relative uncertainty of the measured frequency (default 0.002)")
    sp.add_argument("--pd-kp", type=float, default=None, help="PD joint stiffness for the "
                    "hub-inertia candidate, N m/rad (default: seed 000 Eq. 45, n^2 Kpv Kpp)")
    sp.add_argument("--pd-kd", type=float, default=None, help="PD joint damping, N m s/rad")
    sp.add_argument("--out", help="output directory (default runs/<timestamp>-frequency-gap)")
    sp.add_argument("--json", action="store_true", help="print the result as JSON")
    sp.set_defaults(func=cmd_frequency_gap, command="frequency_gap")
    return sp


def main(argv=None) -> int:
    """``python -m studies.frequency_gap [--arm A] [--measured-hz F] [--out DIR] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
