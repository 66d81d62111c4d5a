"""Benchmark of the twin diagnosis on synthetic runs with hidden effects (issue 8).

    python bench/bench_diagnosis.py [--runs N] [--cases KIND ...] [--jobs J] [--out DIR]
                                    [--noise LEVEL] [--seed0 S] [--resume]

For every case kind and run (seed) it generates the case (flex_twin.diagnosis.synthetic),
runs the diagnosis on fit.csv / holdout.csv with the nominal arm and controller (the
truth stays in truth.json), and scores the verdict against the truth. The healthy case
of the same seed differs from every other case of that seed by its hidden effects only,
so the benchmark also measures how material each hidden effect is: the power of the
recording's change in units of the channel noise power (``materiality``; material when
>= 1). Prints the confusion matrix (hidden kind x named verdict) and every target figure
of the issue; writes ``summary.json`` and ``summary.md`` to ``--out``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

from flex_twin.diagnosis.synthetic import CASE_KINDS, parse_kind
from diagnosis_scoring import DEFAULT_TWO, add_part_visibility, report, run_one, summarise


def _g(x):
    return "-" if x is None else f"{x:.3g}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=10, help="runs (seeds) per case kind")
    ap.add_argument("--cases", nargs="*", default=None,
                    help=f"case kinds (default: {', '.join(CASE_KINDS)} and "
                         f"{', '.join(DEFAULT_TWO)})")
    ap.add_argument("--jobs", type=int, default=1, help="runs in parallel (processes)")
    ap.add_argument("--out", default="runs/bench_diagnosis")
    ap.add_argument("--noise", default="nominal")
    ap.add_argument("--seed0", type=int, default=1000)
    ap.add_argument("--no-materiality", action="store_true",
                    help="skip the healthy twin run that measures materiality")
    ap.add_argument("--resume", action="store_true",
                    help="keep the runs of DIR/results.json and run only the missing ones")
    ap.add_argument("--summary-only", action="store_true",
                    help="summarise DIR/results.json without running anything")
    ap.add_argument("--add-visibility", action="store_true",
                    help="add each effect's own replay materiality to the two-effect runs "
                         "of DIR/results.json that lack it (no diagnosis is rerun)")
    args = ap.parse_args(argv)
    kinds = args.cases or list(CASE_KINDS) + list(DEFAULT_TWO)
    for k in kinds:
        parse_kind(k)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results = []
    if args.resume or args.summary_only or args.add_visibility:
        done = out / "results.json"
        results = json.loads(done.read_text()) if done.exists() else []
    if args.add_visibility:
        results = [add_part_visibility(r, args.noise) for r in results]
        (out / "results.json").write_text(json.dumps(results, indent=1, default=str))
    have = {(r["kind"], r["seed"]) for r in results}
    jobs = [(k, args.seed0 + s) for s in range(args.runs) for k in kinds
            if (k, args.seed0 + s) not in have
            and not (args.summary_only or args.add_visibility)]
    t0 = time.perf_counter()
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futs = {pool.submit(run_one, k, s, str(out), args.noise, not args.no_materiality):
                (k, s) for k, s in jobs}
        # submitted seed by seed: every kind gets its first runs before any its later ones
        for i, fut in enumerate(as_completed(futs), start=1):
            try:
                r = fut.result()
            except Exception as exc:  # a crashed run is reported with the others
                k, s = futs[fut]
                r = {"kind": k, "seed": s, "materiality": None,
                     "error": f"{type(exc).__name__}: {exc}"}
            results.append(r)
            named = ",".join(f"{n['kind']}@{n['target']}" for n in r.get("named", []))
            print(f"[{i}/{len(jobs)} {time.perf_counter() - t0:.0f} s] {r['kind']} seed "
                  f"{r['seed']}: {r.get('verdict', r.get('error'))} {named} "
                  f"(materiality {_g(r['materiality'])}, replay "
                  f"{_g(r.get('materiality_replay'))}, {r.get('diagnose_s', 0):.1f} s)",
                  file=sys.stderr, flush=True)
            (out / "results.json").write_text(json.dumps(results, indent=1, default=str))
    summary = summarise(results)
    summary["wall_s"] = time.perf_counter() - t0
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=str))
    md = report(summary)
    (out / "summary.md").write_text(md + "\n")
    print(md)
    return 0


if __name__ == "__main__":
    sys.exit(main())
