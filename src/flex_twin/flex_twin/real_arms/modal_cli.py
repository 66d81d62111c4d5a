"""``flex-twin cantilever`` and ``flex-twin frequency-gap``: measured natural frequencies
against the model, and the single effects that would explain the difference (issue 9).

    flex-twin cantilever [--data DIR] [--out DIR] [--json]
    flex-twin frequency-gap [--arm seed000_real_arm] [--measured-hz 8.24] [--out DIR] [--json]

Each writes ``report.md``, a PNG and ``result.json`` into ``--out`` (default
``runs/<timestamp>-<command>``).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from flex_model.plots import finish_figure, plt

#: ../shared beside the checkout (the product runs without it)
SHARED_DATA = Path(__file__).resolve().parents[4].parent / "shared" / "data" / "real"


def _say(args):
    quiet = getattr(args, "json", False)
    return lambda text: None if quiet else print(f"[{args.command}] {text}", file=sys.stderr)


def _fmt(v, unit=""):
    if v is None or not np.isfinite(v):
        return "rigid" if v is not None and v == np.inf else "-"
    return f"{v:.4g}{(' ' + unit) if unit and unit != '-' else ''}"


def _change(fit) -> str:
    r = fit.relative_change()[0]
    return "-" if not np.isfinite(r) else f"{100 * r:+.2f} %"


def _tol(fit) -> str:
    c, ok = fit.candidates[0], fit.within_tolerance()[0]
    if ok is None:
        return "no tolerance"
    return f"{'yes' if ok else 'no'} (±{100 * c.tolerance:.0f} %)"


# ----------------------------------------------------------------------------- cantilever
def cmd_cantilever(args) -> int:
    from flex_model.arm import load_arm
    from flex_model.command import run_dir
    from .cantilever import DATA_SET, cantilever_study, read_data_set

    say = _say(args)
    measured = np.asarray(args.measured_hz, float)
    if not (np.all(measured > 0) and np.all(np.diff(measured) > 0)):
        raise ValueError(f"--measured-hz: got {args.measured_hz}; expected increasing "
                         "frequencies > 0 Hz (modes 1, 2, ...)")
    if not args.sigma > 0:
        raise ValueError(f"--sigma: got {args.sigma}; expected a relative uncertainty > 0")
    arm = load_arm(args.arm, args.vars)
    data = Path(args.data) if args.data else SHARED_DATA / DATA_SET
    if args.data and not data.is_dir():
        raise FileNotFoundError(f"--data: {data} is not a directory")
    records = read_data_set(data) if data.is_dir() else []
    if not records:
        say(f"no shaker data at {data}: identification skipped")
    study = cantilever_study(arm, records, measured, sigma=args.sigma, progress=say)
    out = run_dir(args.out, "cantilever")
    result = study.as_dict()
    result["data"] = str(data) if records else None
    _plot_cantilever(study, out / "cantilever.png")
    (out / "report.md").write_text(_cantilever_report(study, data if records else None))
    (out / "result.json").write_text(json.dumps(result, indent=1))
    if args.json:
        print(json.dumps(result))
    else:
        print((out / "report.md").read_text())
        print(f"written: {out}/report.md, cantilever.png, result.json")
    return 0


def _cantilever_report(st, data) -> str:
    d = st.diagnosis
    n = len(st.measured_hz)
    lines = [f"# Cantilever: Euler-Bernoulli model of `{st.arm.name}` against measured modes",
             "", f"{st.arm.description}", "",
             "| mode | closed form (Hz) | flex_model (Hz) | measured (Hz) | model / measured |",
             "|---|---|---|---|---|"]
    for k in range(n):
        lines.append(f"| {k + 1} | {st.closed_form_hz[k]:.4f} | {st.model_hz[k]:.4f} | "
                     f"{st.measured_hz[k]:.4g} | {st.ratio[k]:.4f} |")
    lines += ["", "## Modes identified from the shaker records (H1 force -> acceleration)", ""]
    if data is None:
        lines.append("No shaker data found: identification skipped.")
    for name, peaks in st.identified.items():
        for k, p in enumerate(peaks):
            txt = (f"{p.frequency_hz:.3f} Hz, zeta {p.damping_ratio:.4f}" if p.identified
                   else f"not identified: {p.reason}")
            lines.append(f"- {name}, mode {k + 1} ({p.band[0]:g}-{p.band[1]:g} Hz): {txt}")
    if st.identified and not any(p.identified for v in st.identified.values() for p in v):
        lines += ["", "No record holds a resolved, coherent resonance: the shaker drove sines "
                  "at 100, 120 and 150 Hz (PROVENANCE.md), the broadband content is weak, and "
                  "the coherent |H1| has no peak at the reported modes (it is also 10-100 "
                  "times below the model's tip accelerance: the force does not enter as a "
                  "tip force into a free cantilever, the shaker position is not documented). "
                  "The diagnosis therefore uses the reported frequencies (impulse test)."]
    lines += ["", "## Single-effect diagnosis (each effect fitted alone, bounded least squares)",
              "", f"Relative uncertainty of each measured frequency: {d.sigma:.2%}; "
              "chi^2 with 2 degrees of freedom; one-sigma intervals.", "",
              "| rank | effect | class | fitted value | interval | change | within tolerance "
              "| predicted (Hz) | rms residual | chi^2 |", "|---" * 10 + "|"]
    for k, f in enumerate(d.fits):
        c = f.candidates[0]
        lines.append(f"| {k + 1} | {c.name} ({c.parameter}) | {d.class_of(k) + 1} | "
                     f"{_fmt(f.values[0], c.unit)} | {_fmt(f.intervals[0, 0])} - "
                     f"{_fmt(f.intervals[0, 1])} | {_change(f)} | {_tol(f)} | "
                     f"{', '.join(f'{x:.2f}' for x in f.predicted_hz[:n])} | "
                     f"{100 * f.rms_relative:.2f} % | {f.chi2:.2f} |")
    lines += ["", "Signatures: relative shift of modes 1-3 when the effect alone moves mode 1 to "
              "the measured value (and, first order, when it lowers mode 1 by 1 %):", ""]
    for name, f in st.signatures.items():
        s = 100 * (f.predicted_hz / st.model_hz[:n] - 1)
        first = st.first_order.get(name)
        s1 = "" if first is None else " (first order: " + ", ".join(
            f"{x:+.3f}" for x in 100 * (first.predicted_hz / st.model_hz[:n] - 1)) + " %)"
        lines.append(f"- {name}: {', '.join(f'{x:+.2f}' for x in s)} %{s1}")
    lines += ["", "## Verdict", ""] + _verdict(st)
    return "\n".join(lines) + "\n"


def _verdict(st) -> list:
    d = st.diagnosis
    best = d.fits[0]
    cls = [d.fits[k] for k in d.classes[0]]
    names = " and ".join(f.name for f in cls)
    out = [f"- The model is {100 * (np.mean(st.ratio) - 1):.1f} % high on average "
           f"({', '.join(f'{100 * (r - 1):+.1f}' for r in st.ratio)} % per mode)."]
    if len(cls) > 1:
        out.append(f"- Best explained by **{names}**: one equivalence class. They move every "
                   "mode by the same factor (f ~ sqrt(EI / m)), so natural frequencies alone "
                   "can never tell them apart; they fix only EI / m, here "
                   f"{best.values[0] if 'stiffness' in best.name else 1 / best.values[0]:.4f} "
                   "times nominal (a static stiffness test or a weighing separates them).")
    else:
        out.append(f"- Best explained by **{best.name}**.")
    if len(cls) > 1:
        ratio = best.values[0] if "stiffness" in best.name else 1 / best.values[0]
        arm = st.arm
        tol = float(np.hypot(arm.tolerance("E"), 3 * arm.tolerance("section")))
        out.append(f"- The same factor, f ~ h sqrt(E / rho) / L^2 for a rectangular section, "
                   f"is a thickness x{np.sqrt(ratio):.3f}, an E / rho x{ratio:.3f} or a free "
                   f"length x{ratio ** -0.25:.3f}. EI / m {100 * (ratio - 1):+.1f} % is "
                   f"{'outside' if abs(ratio - 1) > tol else 'within'} the manufacturing "
                   f"tolerances (E ±{100 * arm.tolerance('E'):.0f} %, section "
                   f"±{100 * arm.tolerance('section'):.0f} % so EI ±{100 * tol:.1f} %, rho "
                   f"±{100 * arm.tolerance('rho'):.0f} %): the assumed steel data (E = 200 GPa, "
                   "rho = 7850 kg/m^3 are not given by the source) or the dimensions are "
                   "suspect, not a single small defect.")
    rc = st.signatures.get("root compliance")
    if rc is not None:
        s = 100 * (rc.predicted_hz / st.model_hz[:len(rc.predicted_hz)] - 1)
        s1 = 100 * (st.first_order["root compliance"].predicted_hz
                    / st.model_hz[:len(rc.predicted_hz)] - 1)
        out.append(f"- Root compliance sized to lower mode 1 to the measured value lowers the "
                   f"modes by {', '.join(f'{x:.1f}' for x in s)} %: mode 1 more than modes "
                   "2-3, but only at second order. To first order a root spring shifts all "
                   "modes of a uniform cantilever alike (its share of the strain energy, "
                   "4 EI / (kp L), is the same for every mode, as is a tip mass's share of "
                   f"the kinetic energy): a 1 % drop of mode 1 gives "
                   f"{', '.join(f'{x:.3f}' for x in s1)} %.")
    tip = next((f for f in d.fits if f.name == "tip mass"), None)
    if tip is not None:
        from .modal_diagnosis import link_totals
        beam = link_totals(st.arm)[1]
        out.append(f"- A tip mass alone would need {1000 * tip.values[0]:.0f} g "
                   f"({100 * tip.values[0] / beam:.1f} % of the {beam:.3f} kg beam); an "
                   "accelerometer of a few grams (e.g. 6 g) lowers every mode by only about "
                   f"{200 * 0.006 / beam:.1f} % (first order, -2 M / (m L)).")
    if d.pair is not None and d.pair_p_value is not None:
        verdict = "not justified" if d.pair_p_value > 0.05 else "justified"
        out.append(f"- Parsimony: adding a second effect ({d.pair.name}) lowers chi^2 from "
                   f"{best.chi2:.2f} to {d.pair.chi2:.2f}; F-test p = {d.pair_p_value:.2f}: "
                   f"{verdict}.")
    if len(d.classes) > 1:
        f = d.fits[d.classes[1][0]]
        k = int(np.argmax(np.abs(f.residual - best.residual)))
        out.append(f"- Next class: {' and '.join(d.fits[j].name for j in d.classes[1])} "
                   f"(rms residual {100 * f.rms_relative:.2f} % against "
                   f"{100 * best.rms_relative:.2f} %). The classes differ most in mode "
                   f"{k + 1} ({100 * np.expm1(f.residual[k]):+.2f} % against "
                   f"{100 * np.expm1(best.residual[k]):+.2f} %): the ranking rests on "
                   f"differences of about 1 % and on the assumed {d.sigma:.1%} uncertainty.")
    return out


def _plot_cantilever(st, path) -> None:
    from .cantilever import tip_accelerance
    fig, ax = plt.subplots(2, 1, figsize=(11, 9))
    fmax = 1.3 * st.measured_hz[-1]
    for name, frf in st.frfs.items():
        m = (frf.frequency > 1.0) & (frf.frequency < fmax)
        good = m & (frf.coherence >= 0.8)
        ax[0].semilogy(frf.frequency[m], np.abs(frf.H[m]), lw=0.6, alpha=0.5,
                       label=f"{name}: |H1| measured")
        ax[0].semilogy(frf.frequency[good], np.abs(frf.H[good]), ".", ms=2)
    f = np.linspace(1.0, fmax, 3000)
    ax[0].semilogy(f, np.abs(tip_accelerance(st.arm, f)), "k", lw=1,
                   label="model: tip force -> tip acceleration (zeta 1 %)")
    best = st.diagnosis.fits[0]
    for k, fm in enumerate(st.measured_hz):
        ax[0].axvline(st.model_hz[k], color="C3", ls="--", label="model modes" if k == 0 else "")
        ax[0].axvline(fm, color="C2", ls=":", label="measured (reported)" if k == 0 else "")
        ax[0].axvline(best.predicted_hz[k], color="C4", ls="-.", lw=0.8,
                      label=f"fitted: {best.name}" if k == 0 else "")
    ax[0].set_xlabel("frequency (Hz)")
    ax[0].set_ylabel("accelerance (m/s^2)/N")
    ax[0].set_title("shaker records (dots: coherence >= 0.8) and the Euler-Bernoulli model")
    n = len(st.measured_hz)
    fits = st.diagnosis.fits
    width = 0.8 / (len(fits) + 1)
    x = np.arange(n)
    ax[1].bar(x, st.ratio - 1, width, label="nominal model", color="0.5")
    for j, fit in enumerate(fits):
        ax[1].bar(x + (j + 1) * width, fit.predicted_hz[:n] / st.measured_hz - 1, width,
                  label=f"{fit.name}: {_fmt(fit.values[0], fit.candidates[0].unit)} "
                        f"(rms {100 * fit.rms_relative:.2f} %)")
    ax[1].set_xticks(x + 0.4 - width / 2, [f"mode {k + 1}" for k in range(n)])
    ax[1].set_ylabel("model / measured - 1")
    ax[1].set_title("single-effect fits: remaining relative error per mode")
    finish_figure(fig, ax, path, f"{st.arm.name}: measured vs model")


# ----------------------------------------------------------------------------- frequency gap
def cmd_frequency_gap(args) -> int:
    from flex_model.arm import load_arm
    from flex_model.command import run_dir
    from .modal_diagnosis import ModalSetup, frequency_gap, modal_frequencies, reach_hz
    from .modal_diagnosis import standard_candidates

    say = _say(args)
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
    report = _gap_report(arm, args, nominal, fits, reach, kp)
    _plot_gap(arm, args, nominal, fits, out / "frequency_gap.png")
    (out / "report.md").write_text(report)
    (out / "result.json").write_text(json.dumps(result, indent=1))
    if args.json:
        print(json.dumps(result))
    else:
        print(report)
        print(f"written: {out}/report.md, frequency_gap.png, result.json")
    return 0


def _gap_report(arm, args, nominal, fits, reach, kp) -> str:
    k = args.mode - 1
    lines = [f"# One measured frequency: `{arm.name}` mode {args.mode}, "
             f"{nominal[k]:.4f} Hz modelled, {args.measured_hz} Hz measured "
             f"({100 * (args.measured_hz / nominal[k] - 1):+.2f} %)", "",
             "Each effect alone, sized to give the measured frequency exactly:", "",
             "| effect | parameter | size | added | change | within tolerance | reachable "
             "| predicted modes (Hz) |", "|---" * 8 + "|"]
    for f, r in zip(fits, reach):
        c = f.candidates[0]
        size = _fmt(f.values[0], c.unit) if f.reachable else \
            f"none in bounds (mode {args.mode}: {r[0]:.4f}-{r[1]:.4f} Hz)"
        added = _fmt(f.values[0] - c.nominal, c.unit) if f.reachable and c.unit != "-" \
            and np.isfinite(c.nominal) else "-"
        lines.append(f"| {c.name} | {c.parameter} | {size} | {added} | "
                     f"{_change(f) if f.reachable else '-'} | {_tol(f) if f.reachable else '-'}"
                     f" | {'yes' if f.reachable else 'no'} "
                     f"| {', '.join(f'{x:.2f}' for x in f.predicted_hz)} |")
    ok = [f for f in fits if f.reachable]
    inside = [f.name for f in ok if f.within_tolerance()[0]]
    untoleranced = [f.name for f in ok if f.within_tolerance()[0] is None]
    outside = [f"{f.name} ({_change(f)}, tolerance ±{100 * f.candidates[0].tolerance:.0f} %)"
               for f in ok if f.within_tolerance()[0] is False]
    nxt = np.array([f.predicted_hz[k + 1] for f in ok])
    lines += ["", "## What one frequency can and cannot tell", "",
              f"- It fixes one number: each of the {len(ok)} reachable effects explains "
              f"{args.measured_hz} Hz exactly (one equation, one unknown), so the frequency "
              "alone cannot choose between them.",
              f"- Within the manufacturing tolerances: {', '.join(inside) or 'none'}. "
              f"Outside: {'; '.join(outside) or 'none'}. Without a nominal tolerance "
              f"(plausibility to judge): {', '.join(untoleranced) or 'none'}."]
    lines += _plausibility(arm, {f.name: f for f in ok}, kp)
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


def _plausibility(arm, fits, kp) -> list:
    """Yardsticks for the sizes that have no tolerance, and EI's section tolerance."""
    from .modal_diagnosis import link_totals
    length, _, ei = link_totals(arm)
    out = []
    f = fits.get("stiffness scale")
    if f is not None:
        tol = float(np.hypot(arm.tolerance("E"), 3 * arm.tolerance("section")))
        out.append(f"- EI also carries the section tolerance (I ~ h^3: ±"
                   f"{300 * arm.tolerance('section'):.0f} %): EI toleranced ±{100 * tol:.1f} % "
                   f"(root sum square with E), so EI {_change(f)} is "
                   f"{'within' if abs(f.relative_change()[0]) <= tol else 'outside'} it.")
    f = fits.get("tip inertia")
    if f is not None and arm.payload_mass > 0:
        out.append(f"- Tip inertia {_fmt(f.values[0], 'kg m^2')}: a radius of gyration of "
                   f"{100 * np.sqrt(f.values[0] / arm.payload_mass):.1f} cm for the "
                   f"{1000 * arm.payload_mass:.1f} g tip body.")
    f = fits.get("root compliance")
    if f is not None:
        txt = (f"- Root spring {_fmt(f.values[0], 'N m/rad')} = "
               f"{f.values[0] / (ei / length):.0f} EI/L")
        if kp:
            txt += (f"; the PD joint's kp = {kp:.4g} N m/rad is {kp / f.values[0]:.3g} times "
                    "stiffer, so it would be a mechanical compliance (clamp, hub, gear)")
        out.append(txt + ".")
    return out


def _plot_gap(arm, args, nominal, fits, path) -> None:
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
            ax[0].text(0, yy, f"  {_fmt(f.values[0], f.candidates[0].unit)} (nominal "
                       f"{_fmt(f.candidates[0].nominal)})", va="center", fontsize=8)
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


def add_modal_parsers(sub) -> None:
    """Add the ``cantilever`` and ``frequency-gap`` subcommands to a subparsers object."""
    from .cantilever import REPORTED_MODES_HZ

    sp = sub.add_parser("cantilever", help="shaker cantilever: measured modes vs the "
                        "Euler-Bernoulli model, single-effect diagnosis (issue 9)")
    sp.add_argument("--data", help="data set directory (default: ../shared/data/real/"
                    "cantilever_beam_shaker_usc_chowdhury beside the checkout)")
    sp.add_argument("--arm", default="usc_cantilever", help="arm preset or YAML")
    sp.add_argument("--vars", type=int, default=None, help="deformation variables per link")
    sp.add_argument("--measured-hz", type=float, nargs="+", default=list(REPORTED_MODES_HZ),
                    help="measured modes 1..n (Hz; default: the reported 6.62 41.4 117.5)")
    sp.add_argument("--sigma", type=float, default=0.005,
                    help="relative uncertainty of each measured frequency (default 0.005)")
    sp.add_argument("--out", help="output directory (default runs/<timestamp>-cantilever)")
    sp.add_argument("--json", action="store_true", help="print the result as JSON")
    sp.set_defaults(func=cmd_cantilever, command="cantilever")

    sp = sub.add_parser("frequency-gap", help="one measured frequency against the model: "
                        "the size of each single effect that explains it (issue 9)")
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
    sp.set_defaults(func=cmd_frequency_gap, command="frequency-gap")
