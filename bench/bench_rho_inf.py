"""Benchmark: the fixed step's error against a converged run for several rho_inf (issue 47).

Planar: issue 24's hub-less two-link arm (bench_stiff_hubless.scenario: PD 625 / 176.8, a
15 deg set-point step on joint 2 at 0.1 s), the largest error of the two links' tip
deflections in % of their largest value. Spatial: the preset ``seed000_3d_pd_step``
(hub-less strip, a 0.05 rad set-point step at 0.1 s), link 1's in-plane tip deflection
(y) in % of its largest change. Both against a run at rho_inf 0.9 and ``--ref`` ms.

    python bench/bench_rho_inf.py [--duration 0.3] [--vars 8] [--rho 0,0.5,0.9,1]
        [--steps 1,0.5,0.25,0.125] [--ref 0.03125] [--spatial-duration 0.2]
        [--spatial-steps 1,0.4,0.2,0.1] [--spatial-ref 0.05]
"""
from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from bench_stiff_hubless import scenario


def planar_errors(duration, nv, rhos, steps_ms, ref_ms):
    """{(rho, step): (link 1, link 2) tip deflection error in % of the largest}."""
    ref = scenario(duration, nv, 1e-3 * ref_ms, 0.9).run(advise=False).tip_deflections
    scale = np.abs(ref).max(axis=0)
    out = {}
    for rho in rhos:
        for h in steps_ms:
            try:
                d = scenario(duration, nv, 1e-3 * h, rho).run(advise=False).tip_deflections
                out[rho, h] = tuple(100 * np.abs(d - ref).max(axis=0) / scale)
            except Exception as exc:  # noqa: BLE001  (a figure, not a crash)
                out[rho, h] = str(exc)[:40]
    return out


def spatial_errors(duration, rhos, steps_ms, ref_ms):
    """{(rho, step): link 1's y tip deflection error in % of its largest change}."""
    from flex_model.scenario import load_scenario
    base = load_scenario("seed000_3d_pd_step")

    def tip_y(h, rho):
        run = replace(base, duration=duration, step=1e-3 * h, rho_inf=rho).run(advise=False)
        return next(iter(run.link_deflections().values()))["y"]
    ref = tip_y(ref_ms, 0.9)
    scale = np.abs(ref - ref[0]).max()
    return {(rho, h): (100 * np.abs(tip_y(h, rho) - ref).max() / scale,)
            for rho in rhos for h in steps_ms}


def table(title, errs, rhos, steps_ms):
    print(title)
    print("| rho_inf | " + " | ".join(f"{h:g} ms" for h in steps_ms) + " |")
    print("|---" * (len(steps_ms) + 1) + "|")
    for rho in rhos:
        cells = [errs[rho, h] if isinstance(errs[rho, h], str) else
                 " / ".join(f"{e:.3g}" for e in errs[rho, h]) for h in steps_ms]
        print(f"| {rho:g} | " + " | ".join(cells) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=0.3)
    ap.add_argument("--vars", type=int, default=8)
    ap.add_argument("--rho", default="0,0.5,0.9,1")
    ap.add_argument("--steps", default="1,0.5,0.25,0.125", help="ms")
    ap.add_argument("--ref", type=float, default=1 / 32, help="ms")
    ap.add_argument("--spatial-duration", type=float, default=0.2)
    ap.add_argument("--spatial-steps", default="1,0.4,0.2,0.1", help="ms; empty: none")
    ap.add_argument("--spatial-ref", type=float, default=0.05, help="ms")
    args = ap.parse_args()
    rhos = [float(r) for r in args.rho.split(",")]
    steps = [float(s) for s in args.steps.split(",")]
    table(f"planar hub-less arm, {args.vars} variables per link, {args.duration:g} s, tip "
          f"deflections of links 1 / 2, % of their largest, against rho_inf 0.9 at "
          f"{args.ref:g} ms", planar_errors(args.duration, args.vars, rhos, steps, args.ref),
          rhos, steps)
    if args.spatial_steps:
        sp = [float(s) for s in args.spatial_steps.split(",")]
        table(f"spatial seed000_3d_pd_step, {args.spatial_duration:g} s, link 1's tip "
              f"deflection y, % of its largest change, against rho_inf 0.9 at "
              f"{args.spatial_ref:g} ms",
              spatial_errors(args.spatial_duration, rhos, sp, args.spatial_ref), rhos, sp)


if __name__ == "__main__":
    main()
