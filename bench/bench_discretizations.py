"""Benchmark: the cost of every link discretization on the section E arm (issue 4).

Prints, for wavelets, clamped-free / hinged-free / optimized modes, Ritz polynomials,
FEM at 4 and 8 variables per link and the lumped link (4 and 8 masses, one variable per
link): microseconds per evaluation of the equations of motion (mass matrix, bias,
Cholesky solve) and CPU seconds per simulated second (generalized-alpha, 1 ms, first 5 s
of the scenario) and the highest natural frequency of the model (clamped joints), with the
growth exponents d ln(cost) / d ln(variables) (thesis Tables VII-XI, Remark 9). Every
method runs through the same compiled kernels, so at equal variables the differences are
timing noise.

    python bench/bench_discretizations.py [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import sys

from flex_twin.comparison.cost import cost_table


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", help="also write the figures to this JSON file")
    args = ap.parse_args(argv)
    rows = cost_table(progress=lambda msg: print(msg, file=sys.stderr, flush=True))
    counts = list(rows[0]["eval_us"])
    print(f"{'method':>20} " + " ".join(f"{'us/eval ' + str(n):>11}" for n in counts)
          + f" {'exp':>5} " + " ".join(f"{'CPU s/s ' + str(n):>11}" for n in counts)
          + f" {'exp':>5} " + " ".join(f"{'f_max Hz ' + str(n):>12}" for n in counts))
    for r in rows:
        print(f"{r['method']:>20} " + " ".join(f"{r['eval_us'][n]:11.2f}" for n in counts)
              + f" {r['eval_exponent']:5.2f} "
              + " ".join(f"{r['cpu_per_sim_s'][n]:11.4f}" for n in counts)
              + f" {r['sim_exponent']:5.2f} "
              + " ".join(f"{r['f_max_hz'][n]:12.4g}" for n in counts))
    base = {n: rows[0]["eval_us"][n] for n in counts}
    print("ratio to wavelets (us/eval): " + ", ".join(
        f"{r['method']} " + "/".join(f"{r['eval_us'][n] / base[n]:.2f}" for n in counts)
        for r in rows[1:]))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)


if __name__ == "__main__":
    main()
