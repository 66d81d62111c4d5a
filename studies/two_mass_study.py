"""The two-mass bench study (issue 22): identification, replay on the twin, and the
diagnosis of the rigid nominal twin - ``python -m studies.two_mass_study``.

The diagnosis here is a frequency-domain one (``fd_diagnosis``): the time-domain engine
(``flex_twin.diagnosis``) replays the open-loop bench with restarts every second, where the
rigid-body drift under the current's unexcited low-frequency content dominates its cost
(``two_mass_diagnosis`` exports the case for it). Each library hypothesis of the joint and
the link (``joint_elasticity`` k and c, ``joint_friction`` viscous, ``gear`` rotor inertia,
link ``stiffness``, ``actuator_delay``) is applied to the rigid nominal twin and its
parameters fitted to record A's motor-side period FRF (the motor encoder: the channel the
engine sees) through the twin's linearization; the gap (RMS complex log ratio of the FRFs)
on held-out record B before and after names the effect.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from flex_model.arm import arm_from_dict, load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.effects import EFFECT_TYPES
from flex_twin.real_arms.two_mass_twin import arm_dict, parameters_from_arm
from studies.two_mass_data import (PeriodFRF, TwoMassRecord, fit_frf, period_frf,
                                   read_two_mass)
from studies.two_mass_replay import (frf_gap, peak_levels, replay_window, twin_frf,
                                     window_errors)

PRESET = "two_mass_bench"
#: a hypothesis is named when it removes at least this share of the held-out FRF gap
MIN_SHARE = 0.5


def _with_delay(h: PeriodFRF, delay: float) -> PeriodFRF:
    e = np.exp(-2j * np.pi * h.f * delay)
    return dataclasses.replace(h, motor=h.motor * e, load=h.load * e)


def _apply(nominal, kind: str, v) -> tuple:
    """(arm, delay) of the nominal rigid twin with hypothesis ``kind`` at values v; as
    ``flex_twin.diagnosis.hypotheses``: the gear's rotor moves to the motor side of an
    elastic joint."""
    E = EFFECT_TYPES
    j = nominal.joint_names[0]
    gear = nominal.effect("gear", j)
    if kind == "joint_elasticity":
        jm = gear["ratio"] ** 2 * gear["rotor_inertia"]
        return nominal.with_effects(dataclasses.replace(gear, values=(gear["ratio"], 0.0)),
                                    E["joint_elasticity"](j, (v[0], v[1], jm))), 0.0
    if kind == "joint_friction":
        return nominal.with_effects(E["joint_friction"](j, (v[0], 0.0, 0.0, 0.01, 1e-6))), 0.0
    if kind == "gear":
        return nominal.with_effects(E["gear"](j, (gear["ratio"], v[0]))), 0.0
    if kind == "stiffness":
        lk = nominal.links[0]
        lk = dataclasses.replace(lk, segments=tuple(sg.scaled(stiffness=v[0])
                                                    for sg in lk.segments))
        return dataclasses.replace(nominal, links=(lk,)), 0.0
    if kind == "actuator_delay":
        return nominal, v[0]
    raise ValueError(kind)


#: hypothesis -> (parameter names, units, starts (each a tuple), lower, upper bounds)
HYPOTHESES = {
    "joint_elasticity": (("stiffness", "damping"), ("N m/rad", "N m s/rad"),
                         [(k, c) for k in (100.0, 300.0, 1000.0, 3000.0) for c in (0.01, 0.1)],
                         (1.0, 0.0), (1e6, 100.0)),
    "joint_friction": (("viscous",), ("N m s/rad",), [(0.01,), (0.1,), (1.0,)], (0.0,),
                       (100.0,)),
    "gear": (("rotor_inertia",), ("kg m^2",), [(1e-3,), (5e-3,), (2e-2,)], (1e-6,), (1.0,)),
    "stiffness": (("EI scale",), ("-",), [(1e-4,), (1e-2,), (1.0,)], (1e-8,), (10.0,)),
    "actuator_delay": (("delay",), ("s",), [(1e-4,), (1e-3,)], (0.0,), (0.01,)),
}


def _twin(nominal, kind, v, f) -> PeriodFRF:
    arm, delay = _apply(nominal, kind, v)
    return _with_delay(twin_frf(FlexArmModel(arm), f), delay)


def fd_diagnosis(nominal, fit: PeriodFRF, holdout: PeriodFRF) -> dict:
    """Fit every hypothesis to the fit record's motor FRF; the held-out gap before/after."""
    before = {"fit": frf_gap(twin_frf(FlexArmModel(nominal), fit.f), fit),
              "holdout": frf_gap(twin_frf(FlexArmModel(nominal), holdout.f), holdout)}
    rows = []
    for kind, (names, units, starts, lb, ub) in HYPOTHESES.items():
        best = None
        for x0 in starts:
            def res(x):
                h = _twin(nominal, kind, np.exp(x) if kind != "actuator_delay" else x, fit.f)
                r = np.log(h.motor / fit.motor)
                return np.concatenate([r.real, r.imag])
            if kind == "actuator_delay":
                r = least_squares(res, x0, bounds=(lb, ub))
            else:
                r = least_squares(res, np.log(x0), bounds=(np.log(np.maximum(lb, 1e-12)),
                                                           np.log(ub)))
            if best is None or r.cost < best.cost:
                best = r
        v = best.x if kind == "actuator_delay" else np.exp(best.x)
        after = {"fit": frf_gap(_twin(nominal, kind, v, fit.f), fit),
                 "holdout": frf_gap(_twin(nominal, kind, v, holdout.f), holdout)}
        share = (before["holdout"] - after["holdout"]) / before["holdout"]
        rows.append({"hypothesis": f"{kind}@{nominal.joint_names[0]}"
                     if kind != "stiffness" else f"stiffness@{nominal.links[0].name}",
                     "kind": kind, "values": dict(zip(names, map(float, v))),
                     "units": dict(zip(names, units)), "gap_fit": after["fit"],
                     "gap_holdout": after["holdout"], "share": float(share)})
    rows.sort(key=lambda r: -r["share"])
    named = [r for r in rows[:1] if r["share"] >= MIN_SHARE]
    return {"before": before, "hypotheses": rows, "named": named}


def study(root=None, out=None, progress=print, windows=None) -> dict:
    """Everything of the report: identification on A, replay on A and B (windows and FRFs),
    the frequency-domain diagnosis of the rigid nominal twin. ``windows``: which 1-s
    periods to replay (default all but the first)."""
    recs = {r: read_two_mass(r, root) for r in "AB"}
    labs = {r: period_frf(rec) for r, rec in recs.items()}
    twin_arm = load_arm(PRESET)
    model = FlexArmModel(twin_arm)
    p = parameters_from_arm(twin_arm)
    report = {"twin": p.as_dict(), "records": {}}
    ident = {}
    for r in "AB":
        ident[r] = {"twin_class": fit_frf(labs[r], delay=False),
                    "load_friction_and_delay": fit_frf(labs[r], load_friction=True)}
    report["identification"] = {r: {k: {"parameters": v[0].as_dict(), "rms_log": v[1]}
                                    for k, v in d.items()} for r, d in ident.items()}
    for r, rec in recs.items():
        progress(f"record {r}: FRF and {len(windows or range(1, rec.n_periods))} windows")
        lab, tw = labs[r], twin_frf(model, labs[r].f)
        lab_p, twin_p = ident[r]["twin_class"][0], fit_frf(tw, delay=False)[0]
        row = {"current_offset_A": rec.current_offset,
               "lab": {"anti_resonance_hz": lab_p.anti_resonance_hz,
                       "resonance_hz": lab_p.resonance_hz, **peak_levels(lab)},
               "twin": {"anti_resonance_hz": twin_p.anti_resonance_hz,
                        "resonance_hz": twin_p.resonance_hz, **peak_levels(tw)},
               "frf_gap_motor": frf_gap(tw, lab), "frf_gap_load": frf_gap(tw, lab, "load")}
        for key in ("anti_resonance_hz", "resonance_hz"):
            row[f"{key}_error_pct"] = 100 * (row["twin"][key] / row["lab"][key] - 1)
        for key in ("resonance_level", "anti_resonance_level"):
            row[f"{key}_db"] = 20 * np.log10(row["twin"][key] / row["lab"][key])
        row["windows"] = window_errors(model, rec, windows)
        report["records"][r] = row
    nominal = arm_from_dict(arm_dict(p, elastic=False))
    progress("frequency-domain diagnosis of the rigid nominal twin (fit A, held out B)")
    report["diagnosis"] = fd_diagnosis(nominal, labs["A"], labs["B"])
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        plot_frf(labs, model, out / "two_mass_frf.png")
        plot_time(model, recs["B"], out / "two_mass_time.png")
        (out / "two_mass.json").write_text(json.dumps(report, indent=1, default=float))
        write_markdown(report, out / "two_mass.md")
    return report


def plot_frf(labs: dict, model, path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    f = np.linspace(10, 260, 1001)
    tw = twin_frf(model, f)
    fig, ax = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    for c, side in enumerate(("motor", "load")):
        for r, style in (("A", "C0."), ("B", "C1x")):
            h = labs[r]
            ax[0, c].semilogy(h.f, np.abs(getattr(h, side)) * (2 * np.pi * h.f) ** 2, style,
                              ms=3, label=f"lab, record {r}")
            ax[1, c].plot(h.f, np.angle(getattr(h, side), deg=True), style, ms=3)
        ax[0, c].semilogy(f, np.abs(getattr(tw, side)) * (2 * np.pi * f) ** 2, "k-", lw=1,
                          label="twin (two_mass_bench)")
        ax[1, c].plot(f, np.angle(getattr(tw, side), deg=True), "k-", lw=1)
        ax[0, c].set_title(f"theta_{side[0]} / i_q: |H| w^2 ((rad/s^2)/A)")
        ax[1, c].set_ylabel("phase (deg)")
        ax[1, c].set_xlabel("frequency (Hz)")
        ax[0, c].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_time(model, rec: TwoMassRecord, path, window: int = 10, seconds: float = 0.3) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    n = rec.period_samples
    tw = replay_window(model, rec, window * n, n)
    s = slice(window * n, (window + 1) * n)
    t = rec.t[s] - rec.t[s][0]
    keep = t <= seconds
    fig, ax = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    ax[0].plot(t[keep], rec.current[s][keep], "C2", lw=0.8)
    ax[0].set_ylabel("i_q - offset (A)")
    for k, side in enumerate(("m", "l")):
        ax[k + 1].plot(t[keep], getattr(rec, f"omega_{side}")[s][keep], "C0", lw=1,
                       label="lab (angle derivative)")
        ax[k + 1].plot(t[keep], tw[f"omega_{side}"][keep], "k--", lw=1, label="twin")
        ax[k + 1].set_ylabel(f"omega_{side} (rad/s)")
        ax[k + 1].legend(fontsize=8, loc="upper right")
    ax[2].set_xlabel(f"time in period {window + 1} of record {rec.name} (s), twin started "
                     "from the measured state")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_markdown(report: dict, path) -> None:
    p = report["twin"]
    lines = ["# Two-mass motor bench: twin against the lab (issue 22)", "",
             f"Twin `{PRESET}` (K_t fixed {p['K_t']} N m/A): J_m {p['J_m']:.4g}, J_l "
             f"{p['J_l']:.4g} kg m^2, k {p['k']:.1f} N m/rad, c {p['c']:.4g} N m s/rad "
             f"(zeta {p['damping_ratio']:.3f}), motor viscous {p['b_m']:.4g} N m s/rad.", "",
             "| record | anti-res. lab / twin (Hz) | err % | resonance lab / twin (Hz) | "
             "err % | resonance / anti-res. level twin/lab (dB) | FRF gap motor / load | "
             "window speed RMS err motor / load (rad/s) | mean removed | "
             "speed RMS motor / load |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r, row in report["records"].items():
        w = row["windows"]
        lines.append(
            f"| {r}{' (fit)' if r == 'A' else ' (held out)'} | "
            f"{row['lab']['anti_resonance_hz']:.2f} / {row['twin']['anti_resonance_hz']:.2f} | "
            f"{row['anti_resonance_hz_error_pct']:+.2f} | {row['lab']['resonance_hz']:.2f} / "
            f"{row['twin']['resonance_hz']:.2f} | {row['resonance_hz_error_pct']:+.2f} | "
            f"{row['resonance_level_db']:+.1f} / {row['anti_resonance_level_db']:+.1f} | "
            f"{row['frf_gap_motor']:.3f} / "
            f"{row['frf_gap_load']:.3f} | {w['median_rms_m']:.2f} / {w['median_rms_l']:.2f} | "
            f"{w['median_rms_m_mean_removed']:.2f} / {w['median_rms_l_mean_removed']:.2f} | "
            f"{w['speed_rms_m']:.2f} / {w['speed_rms_l']:.2f} |")
    d = report["diagnosis"]
    lines += ["", "Frequency-domain diagnosis of the rigid nominal twin (fit A's motor FRF, "
              f"held-out B): gap before {d['before']['fit']:.3f} (A) / "
              f"{d['before']['holdout']:.3f} (B).", "",
              "| hypothesis | values | gap A after | gap B after | share of B's gap |",
              "|---|---|---|---|---|"]
    for h in d["hypotheses"]:
        vals = ", ".join(f"{k} {v:.4g} {h['units'][k]}" for k, v in h["values"].items())
        lines.append(f"| {h['hypothesis']} | {vals} | {h['gap_fit']:.3f} | "
                     f"{h['gap_holdout']:.3f} | {h['share']:.2f} |")
    named = d["named"][0]["hypothesis"] if d["named"] else "nothing (unexplained)"
    lines += ["", f"Named: **{named}**.", ""]
    Path(path).write_text("\n".join(lines))


def run_engine(data, out: Path, report: dict, duration, workers) -> None:
    """``--engine``: ``flex-twin diagnose`` on the rigid nominal twin (its summary into
    ``report["engine"]`` and two_mass.json)."""
    from studies.two_mass_data import data_dir
    from studies.two_mass_diagnosis import export_case, run_diagnosis
    root = data_dir(data)
    paths = export_case(read_two_mass("A", root), read_two_mass("B", root),
                        parameters_from_arm(load_arm("two_mass_bench")),
                        out / "engine" / "inputs", duration)
    s = run_diagnosis(paths, out / "engine", workers=workers)
    report["engine"] = {k: s.get(k) for k in ("verdict", "named", "holdout_error_reduction")}
    (out / "two_mass.json").write_text(json.dumps(report, indent=1, default=float))


def cmd_two_mass(args) -> int:
    """The two-mass motor bench (issue 22): replay of records A and B on the
    ``two_mass_bench`` twin, FRF and time overlays, the frequency-domain diagnosis of the
    rigid nominal twin; ``--engine`` also runs ``flex-twin diagnose`` on it (minutes)."""
    from flex_twin.real_arms.cli import print_progress
    from studies.two_mass_data import data_dir
    out = Path(args.out)
    report = study(data_dir(args.data), out, print_progress)
    if args.engine:
        run_engine(args.data, out, report, args.duration, args.workers)
    if args.json:
        print(json.dumps(report, indent=1, default=float))
    else:
        print((out / "two_mass.md").read_text())
        if args.engine:
            print(f"engine: {report['engine']['verdict']}; report {out / 'engine'}/report.md")
    return 0


def build_parser():
    from flex_twin.real_arms.cli import add_data_option
    from .command import study_parser
    parser = study_parser("two_mass_study", "the FdiTools two-mass motor bench: twin replay "
                          "of records A (fit) and B (held out), FRF and time overlays, the "
                          "diagnosis of the rigid nominal twin (markdown, PNG, JSON)")
    add_data_option(parser)
    parser.add_argument("--out", default="runs/two-mass", help="output directory")
    parser.add_argument("--engine", action="store_true", help="also run flex-twin diagnose "
                        "(time domain, restarts every 0.1 s from the motor and load "
                        "encoders) on the rigid nominal twin (minutes; the full 20 s: ~12 "
                        "CPU-min)")
    parser.add_argument("--duration", type=float, default=None, help="with --engine: only "
                        "the first seconds of each record")
    parser.add_argument("--workers", type=int, default=None, help="with --engine: processes")
    parser.add_argument("--json", action="store_true")
    parser.set_defaults(func=cmd_two_mass)
    return parser


def main(argv=None) -> int:
    """``python -m studies.two_mass_study [--engine [--duration S]] [--out DIR] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
