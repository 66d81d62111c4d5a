"""``flex-twin compare``: every discretization on the same arms, a markdown report with
plots (paper value next to ours) in an output directory."""
from __future__ import annotations

import json
import sys
from pathlib import Path


#: seed 000 Table 4 step response: (label, discretization, variables, options)
STEP_METHODS = (("wavelet", "wavelet", 8, {}),
                ("assumed modes (2, clamped with tip mass)", "assumed_modes", 2,
                 {"mode_type": "clamped_mass"}),
                ("lumped (1 mass)", "lumped", 1, {"mode_type": "clamped_mass"}),
                ("lumped (8 masses)", "lumped", 8, {"mode_type": "clamped_mass"}))


def seed000_step_responses(progress=None):
    """Seed 000 Table 4: the Eq. (45) step 10 -> 30 deg on the Table 3 link for each method
    (flex_control.step_response, imported here only); None without flex_control."""
    try:
        from flex_control.step_response import step_response
    except ModuleNotFoundError:
        return None
    from flex_model.arm import load_arm
    from .methods import with_discretization
    rows = []
    for label, disc, n, opt in STEP_METHODS:
        if progress:
            progress(f"seed 000 Table 4 step response: {label}")
        r = step_response(with_discretization(load_arm("seed000_table3"), disc, n, **opt))
        rows.append({"method": label, "tip_frequency_hz": float(r.tip_frequency_hz),
                     "tip_amplitude_m": float(r.tip_amplitude_m)})
    return rows


def cmd_compare(args) -> int:
    from .report import write_report

    def say(msg):
        if not args.quiet:
            print(f"compare: {msg}", file=sys.stderr, flush=True)
    out = Path(args.out)
    res = write_report(out, with_cost=not args.no_cost, with_frequency=not args.no_frequency,
                       step_responses=None if args.no_step else seed000_step_responses,
                       progress=say)
    summary = {"report": str(out / "report.md"), "results": str(out / "results.json"),
               "plots": sorted(str(p) for p in out.glob("*.png"))}
    if args.json:
        print(json.dumps(summary | {"table_I": {r["method"]: r["I"]
                                                for r in res["tables_I_III"]}}))
    else:
        print(f"report: {summary['report']}")
        for r in res["tables_I_III"]:
            paper = r["paper_I"]
            print(f"  Table I {r['method']:>20}: {r['I'][0]:.3f}, {r['I'][1]:.3f} Hz"
                  + (f" (paper {paper[0]}, {paper[1]})" if paper else ""))
    return 0


def add_compare_parser(sub) -> None:
    sp = sub.add_parser("compare", help="compare the discretizations of the seeds (wavelets, "
                        "assumed/optimized modes, Ritz, lumped, FEM) on the same arms")
    sp.add_argument("--out", default="runs/compare", help="output directory (report.md, "
                    "PNG plots, results.json)")
    sp.add_argument("--no-cost", action="store_true",
                    help="skip the cost table (section E timings, about a minute)")
    sp.add_argument("--no-frequency", action="store_true",
                    help="skip the frequency responses of sections C and D")
    sp.add_argument("--no-step", action="store_true",
                    help="skip the seed 000 Table 4 step responses (needs flex_control)")
    sp.add_argument("--json", action="store_true", help="print a JSON summary")
    sp.add_argument("--quiet", action="store_true", help="no progress on stderr")
    sp.set_defaults(func=cmd_compare)
