"""The Quanser twin with stick-slip friction (issue 22): the calibrated twin's regularized
``joint_friction`` replaced by the elasto-plastic ``stick_slip_friction`` (Dupont et al.
2002; flex_model.effects.stick_slip), its levels refitted on the split's fit runs, and
every CU Boulder run replayed (held-out hub and tip RMS, ring-down during holds); and what
the data say about gearbox backlash against stiction.

Backlash or stiction (:func:`hold_evidence`): at rest a play transmits no torque (the
motor side moves freely inside it), so a hub that holds still while the law commands a
steady voltage is held by friction, not by a play. Per hold of a reference step the
steady error r - theta, the voltage V and the hub rate over the last second of the hold
give the torque the joint holds, tau = K_g K_m V / R_m (at rest, no back-EMF).
"""
from __future__ import annotations

import numpy as np

from flex_twin.real_arms.replay import TRANSIENT, plot_replay, replay

from .session_friction import PRESLIDING, with_stick_slip


def hold_evidence(run, gear=48.4, km=0.0107, rm=3.29, last: float = 1.0) -> list:
    """Per hold (the last ``last`` s before each reference step and before the end):
    steady error (rad), voltage (V), holding torque (N m), hub rate RMS (rad/s) and the
    hub's travel over the window (rad)."""
    steps = list(run.step_indices()) + [len(run.t) - 1]
    n = int(round(last / run.dt))
    out = []
    for k in steps[1:]:
        sl = slice(max(0, k - n), k)
        e = run.reference[sl] - run.theta[sl]
        v = run.voltage[sl]
        out.append({"error_rad": float(np.mean(e)), "voltage_V": float(np.mean(v)),
                    "torque_Nm": float(gear * km * np.mean(v) / rm),
                    "rate_rms": float(np.sqrt(np.mean(run.theta_rate[sl] ** 2))),
                    "travel_rad": float(np.ptp(run.theta[sl]))})
    return out


def replay_metrics(arm, run, make_policy) -> dict:
    """One replay (:func:`real_arms.replay.replay`, states [q; v; z]) and its
    :func:`real_arms.report.metrics_row`."""
    from flex_model.dynamics import FlexArmModel
    from flex_twin.real_arms.report import metrics_row
    r = replay(FlexArmModel(arm), run, make_policy)
    return r, metrics_row(r)


def level_cost(arm, runs, make_policy, coulomb: float, static: float) -> float:
    """Mean replay cost of the arm with stick-slip levels (F_c, F_s) on ``runs``: hub /
    10 mrad and tip / 2 mm squared, as :mod:`real_arms.calibration`."""
    a = with_stick_slip(arm, coulomb=coulomb, static=static)
    cost = []
    for run in runs:
        _, m = replay_metrics(a, run, make_policy)
        c = (m["hub_rms_rad"] / 0.01) ** 2
        if m["tip_rms_m"] is not None:
            c += (m["tip_rms_m"] / 0.002) ** 2
        cost.append(c)
    return float(np.mean(cost))


def refit_levels(arm, runs, make_policy, coulomb, static, step: float = 0.01,
                 flat: float = 0.01, progress=print, max_points: int = 80) -> tuple:
    """The (F_c, F_s) of least :func:`level_cost` on ``runs``, searched on a lattice
    (where the hub sticks jumps with the levels: the cost is rough): from the best of the
    ``coulomb`` x ``static`` grid it moves to the best of the 8 neighbours ``step`` away
    (F_c >= step, F_s >= F_c) while that lowers the cost by more than ``flat`` (relative:
    a smaller change does not resolve the level), then looks once at half the step.
    Returns ((F_c, F_s), table of every point evaluated)."""
    seen = {}

    def cost(p):
        key = (round(p[0], 6), round(p[1], 6))
        if key not in seen and key[1] >= key[0] >= step - 1e-9 and len(seen) < max_points:
            seen[key] = level_cost(arm, runs, make_policy, *key)
            progress(f"  F_c {key[0]:.4f} F_s {key[1]:.4f} N m: cost {seen[key]:.3f}")
        return seen.get(key, np.inf)

    def around(p, h):
        return [(p[0] + i * h, p[1] + k * h) for i in (-1, 0, 1) for k in (-1, 0, 1)
                if i or k]

    best = min(((fc, fs) for fc in coulomb for fs in static), key=cost)
    if not np.isfinite(cost(best)):
        raise ValueError(f"no feasible start level (F_s >= F_c >= {step} N m) among "
                         f"F_c {tuple(coulomb)} x F_s {tuple(static)}")
    while True:
        nxt = min(around(best, step), key=cost)
        if not cost(nxt) < cost(best) * (1.0 - flat):
            break
        best = nxt
    best = min([best] + around(best, step / 2), key=cost)
    table = [{"coulomb": fc, "static": fs, "cost": c} for (fc, fs), c in seen.items()]
    return (round(best[0], 6), round(best[1], 6)), table


def hold_stick_spread(run, settle: float = 1.0) -> dict:
    """What a deterministic twin cannot follow: per hold (``settle`` s after each step
    to the next) the lab's mean error e_k and step direction d_k. A twin of symmetric
    friction sticks at d_k a after every step (one a for the run), so it leaves at least
    e_k - d_k a (a the hold-weighted mean of d_k e_k); a twin that sticks at one offset per
    direction leaves the spread about the direction means. Both as RMS over the whole run
    (rad), and the offset common to both directions (asymmetry, rad)."""
    n0 = int(round(settle / run.dt))
    offs, dirs, lens = [], [], []
    for a, b in run.holds():
        if b - (a + n0) < 100:
            continue
        sl = slice(a + n0, b)
        offs.append(float(np.mean(run.reference[sl] - run.theta[sl])))
        dirs.append(float(np.sign(run.reference[a] - run.reference[max(a - 1, 0)])))
        lens.append(b - a - n0)
    offs, dirs, lens = map(np.asarray, (offs, dirs, lens))
    n = len(run.t)
    spread = np.zeros_like(offs)
    for d in (-1, 1):
        k = dirs == d
        if k.any():
            spread[k] = offs[k] - np.average(offs[k], weights=lens[k])
    sym = offs - dirs * np.average(dirs * offs, weights=lens) if len(offs) else offs
    return {"offsets_rad": offs.tolist(), "directions": dirs.tolist(),
            "spread_rms_rad": float(np.sqrt(np.sum(lens * spread ** 2) / n)),
            "symmetric_rms_rad": float(np.sqrt(np.sum(lens * sym ** 2) / n)),
            "asymmetry_rad": float(np.average(offs, weights=lens)) if len(offs) else 0.0,
            "hold_fraction": float(np.sum(lens) / n)}


def study(data, make_policy, out, progress=print, session: bool = False) -> dict:
    """The stick-slip twins (servo levels refitted on the rigid fit runs, link levels on
    the flexible fit runs, the rest of the calibrated twins kept) on every CU Boulder
    run; the hold evidence (backlash or stiction) and the lab's step-to-step spread.
    ``session``: also the held-out runs' session twins (:mod:`.session_friction`): F_c
    from the first step, and F_c with a voltage offset from the first period."""
    import json
    from pathlib import Path
    from flex_twin.real_arms.calibration import CUBOULDER_SPLIT
    from flex_twin.real_arms.quanser_data import CUBOULDER, read_cuboulder
    from flex_twin.real_arms.quanser_twin import calibrated_arm_for
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    runs = read_cuboulder(Path(data) / CUBOULDER)
    report = {"levels": {}, "grid": {}, "runs": []}
    # the lattice search starts from the best of the first study's grids (2026-11)
    grids = {"rigid": ((0.04, 0.05, 0.06), (0.08, 0.1)),
             "flexible": ((0.05, 0.06, 0.07), (0.1, 0.12))}
    fit_runs = {"rigid": CUBOULDER_SPLIT["servo_fit"], "flexible": CUBOULDER_SPLIT["link_fit"]}
    held = {"rigid": CUBOULDER_SPLIT["servo_holdout"],
            "flexible": CUBOULDER_SPLIT["link_holdout"] + ("flexibleArm_test_1",)}
    for kind in ("rigid", "flexible"):
        cal = calibrated_arm_for("cuboulder", kind)
        progress(f"{kind}: grid on {', '.join(fit_runs[kind])}")
        (fc, fs), table = refit_levels(cal, [runs[n] for n in fit_runs[kind]], make_policy,
                                       *grids[kind], progress=progress)
        report["levels"][kind], report["grid"][kind] = {"coulomb": fc, "static": fs}, table
        slip = with_stick_slip(cal, coulomb=fc, static=fs)
        for name in fit_runs[kind] + held[kind]:
            run = runs[name]
            rc, mc = replay_metrics(cal, run, make_policy)
            rs, ms = replay_metrics(slip, run, make_policy)
            rc.arm_name, rs.arm_name = "calibrated", "stick-slip"
            plot_replay([rc, rs], out / f"stick_slip_{name.replace('.', '_')}.png")
            row = {"run": name, "kind": kind, "role": "fit" if name in fit_runs[kind]
                   else "held out", "calibrated": mc, "stick_slip": ms,
                   "holds": hold_evidence(run), "spread": hold_stick_spread(run)}
            if session and row["role"] == "held out":
                from .session_friction import OFFSETS, compare
                for key, steps, offsets in (("session", 1, (0.0,)),
                                            ("session_period", 2, OFFSETS)):
                    try:
                        row[key] = compare(cal, run, fc, fs, steps, offsets)
                    except ValueError as exc:   # too short to score after the window
                        progress(f"  no {key} score: {exc}")
                        continue
                    progress(f"  {key}: hub after step {steps + 1}, "
                             + " / ".join(f"{k} {row[key][k]['hub_rms_rad']:.4f}" for k in
                                          ("calibrated", "fixed", "session",
                                           "session_offset") if k in row[key]) + " rad")
            report["runs"].append(row)
            progress(f"{name}: hub {mc['hub_rms_rad']:.4f} -> {ms['hub_rms_rad']:.4f} rad"
                     + (f", tip {1e3 * mc['tip_rms_m']:.2f} -> {1e3 * ms['tip_rms_m']:.2f}"
                        " mm" if ms["tip_rms_m"] is not None else "")
                     + f" (symmetric-twin floor {row['spread']['symmetric_rms_rad']:.4f} rad)")
            (out / "stick_slip_study.json").write_text(json.dumps(report, indent=1))
    return report


def _median(rows, twin, key):
    v = [r[twin][key] for r in rows if r[twin].get(key) is not None]
    return float(np.median(v)) if v else float("nan")


def summarize(report: dict) -> dict:
    """Held-out medians (hub RMS over all 16-17 held-out runs, tip RMS and ring-down over
    the flexible ones) of the calibrated and the stick-slip twins, and the holds."""
    held = [r for r in report["runs"] if r["role"] == "held out"]
    flex = [r for r in held if r["kind"] == "flexible"]
    out = {"held_out_runs": len(held)}
    for twin in ("calibrated", "stick_slip"):
        ring = [r[twin] for r in flex if r[twin].get("ring_freq_twin_hz")]
        out[twin] = {
            "hub_rms_median_rad": _median(held, twin, "hub_rms_rad"),
            "hub_transient_share_median": _median(held, twin, "hub_transient_share"),
            "tip_rms_median_m": _median(flex, twin, "tip_rms_m"),
            "ring_freq_error_median_pct": float(np.median(
                [abs(m["ring_freq_error_pct"]) for m in ring])) if ring else float("nan"),
            "ring_damping_ratio_median": float(np.median(
                [m["ring_damping_twin"] / m["ring_damping_measured"] for m in ring]))
            if ring else float("nan")}
    holds = [h for r in report["runs"] for h in r["holds"] if h["travel_rad"] <= 3.5e-3]
    tau = np.abs([h["torque_Nm"] for h in holds])
    out["holds_at_rest"] = {"count": len(holds), "torque_median_Nm": float(np.median(tau)),
                            "torque_max_Nm": float(tau.max())}
    out["symmetric_floor_median_rad"] = float(np.median(
        [r["spread"]["symmetric_rms_rad"] for r in held]))
    return out


def write_markdown(report: dict, path) -> None:
    """The before/after table of :func:`study` (markdown)."""
    s = summarize(report)
    lines = ["# The Quanser twin with stick-slip friction (issue 22)", "",
             f"Levels refitted on the fit runs: servo F_c {report['levels']['rigid']['coulomb']}"
             f" / F_s {report['levels']['rigid']['static']} N m, link F_c "
             f"{report['levels']['flexible']['coulomb']} / F_s "
             f"{report['levels']['flexible']['static']} N m (pre-sliding "
             f"{PRESLIDING * 1e3:.2f} mrad).", "",
             "| twin | hub RMS median (rad) | share of it in the transients (median) | tip "
             "RMS median (mm) | ring freq. error median (%) | damping twin/lab median |",
             "|---|---|---|---|---|---|"]
    for twin in ("calibrated", "stick_slip"):
        m = s[twin]
        lines.append(f"| {twin} | {m['hub_rms_median_rad']:.4f} | "
                     f"{m['hub_transient_share_median']:.2f} | "
                     f"{1e3 * m['tip_rms_median_m']:.2f} | "
                     f"{m['ring_freq_error_median_pct']:.1f} | "
                     f"{m['ring_damping_ratio_median']:.2f} |")
    h = s["holds_at_rest"]
    lines += ["", f"Holds at rest (hub travel <= 3.5 mrad over the last second): {h['count']}, "
              f"holding torque median {h['torque_median_Nm'] * 1e3:.0f} mN m, max "
              f"{h['torque_max_Nm'] * 1e3:.0f} mN m (a play holds none: stiction). A twin of "
              f"symmetric friction leaves at least {s['symmetric_floor_median_rad']:.4f} rad "
              "hub RMS (median over the held-out runs: the lab sticks short by different "
              "amounts after up- and down-steps). Transients: the first "
              f"{TRANSIENT} s after each step; the rest of the squared hub error lies in the "
              "holds.", "",
              "| run | kind | role | hub RMS cal -> stick-slip (rad) | tip RMS (mm) | "
              "symmetric floor (rad) |", "|---|---|---|---|---|---|"]
    for r in report["runs"]:
        c, t = r["calibrated"], r["stick_slip"]
        tip = (f"{1e3 * c['tip_rms_m']:.2f} -> {1e3 * t['tip_rms_m']:.2f}"
               if t.get("tip_rms_m") is not None else "-")
        lines.append(f"| {r['run']} | {r['kind']} | {r['role']} | {c['hub_rms_rad']:.4f} -> "
                     f"{t['hub_rms_rad']:.4f} | {tip} | "
                     f"{r['spread']['symmetric_rms_rad']:.4f} |")
    from .session_friction import MIN_SCORED, summarize as session_summary
    for key, what in (("session", "F_c chosen on the first step (to the second step)"),
                      ("session_period", "F_c and V_0 chosen on the first period (to the "
                       "third step)")):
        rows = [r[key] for r in report["runs"] if key in r]
        if not rows:
            continue
        m = session_summary(rows)
        lines += ["", f"Session twins, {what}; scored after it on the {m['runs']} held-out "
                  f"runs with at least {MIN_SCORED} s left:", "",
                  "| twin | hub RMS median (rad) | runs under 0.01 rad | tip RMS median (mm) |",
                  "|---|---|---|---|"]
        for label in ("calibrated", "fixed", "session", "session_offset"):
            if label in m:
                lines.append(f"| {label} | {m[label]['hub_rms_median_rad']:.4f} | "
                             f"{m[label]['hub_under_aim']} | "
                             f"{1e3 * m[label]['tip_rms_median_m']:.2f} |")
    from pathlib import Path
    Path(path).write_text("\n".join(lines) + "\n")


def cmd_stick_slip(args) -> int:
    from pathlib import Path
    from flex_twin.real_arms.cli import lab_policy, print_progress, print_report
    from flex_twin.real_arms.quanser_twin import data_root
    out = Path(args.out)
    report = study(data_root(args.data), lab_policy(), out, print_progress,
                   session=args.session)
    write_markdown(report, out / "stick_slip.md")
    return print_report(args, report, out / "stick_slip.md")


def build_parser():
    from flex_twin.real_arms.cli import add_data_option
    from .command import study_parser
    parser = study_parser("stick_slip_study", "the calibrated twins with stick-slip friction "
                          "(levels refitted on the fit runs) on every CU Boulder run, and "
                          "the holds' evidence for stiction against backlash (minutes)")
    add_data_option(parser)
    parser.add_argument("--out", default="runs/quanser-stick-slip", help="output directory")
    parser.add_argument("--session", action="store_true",
                        help="also twins with F_c from each held-out run's first step, and "
                        "with F_c and a voltage offset from its first period, every twin "
                        "scored after that (about 10 more CPU-minutes)")
    parser.add_argument("--json", action="store_true")
    parser.set_defaults(func=cmd_stick_slip)
    return parser


def main(argv=None) -> int:
    """``python -m studies.stick_slip_study [--session] [--out DIR] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
