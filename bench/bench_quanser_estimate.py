"""Issue 45: the Quanser tip estimated from the hub encoder and the voltage alone, against
the lab's gauge, on the held-out flexible runs (flex_twin.real_arms.quanser_estimate).

    python bench/bench_quanser_estimate.py [--structure full|driven_link] [--workers 3]
        [--tune] [--tune-link] [--data DIR] [--out DIR]

``--tune`` first runs the link-fit runs (TUNED_ON) and prints the link model error
(DRIVEN_MODEL_STD, or TIP_MODEL_STD for the full EKF) that makes the band hold 95 % of their
gauge samples. ``--tune-link`` prints the driven link (DRIVEN_LINK) fitted to the link-fit
runs: a grid over frequency, damping ratio and the hub's jerk noise, the gain (linear) and
the gauge's lag by least squares, "hagenau" on Hagenau's two fit runs and "shared" on all
three. Both only on TUNED_ON, never on a held-out run. Prints the JSON report (``summary``:
tip_rms_median_mm, hub_rms_median_rad, coverage_95, runs). Full EKF: ~40 CPU-s per run;
driven link: ~0.1 CPU-s per run, the link grid ~1 CPU-min.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import itertools

import numpy as np
from scipy.optimize import brentq

from flex_model.estimation.driven_link import LinkMode, estimate_driven_link
from flex_model.sensors import delayed
from flex_twin.estimate import coverage_95
from flex_twin.real_arms import quanser_estimate as qe
from flex_twin.real_arms.quanser_data import CUBOULDER, cuboulder_files, read_cuboulder_file
from flex_twin.real_arms.quanser_twin import data_root

#: the driven link's grid (--tune-link): frequency (Hz), damping ratio, jerk noise
LINK_GRID = (np.arange(1.65, 2.051, 0.05), (0.0, 0.015, 0.03, 0.06), (100.0, 300.0, 1000.0))
LAGS = np.arange(0.0, 0.1001, 0.005)


def model_std_for(rows, target: float = 0.95) -> float:
    """The constant model std (m) whose band, with each sample's filter std and the gauge's
    rounding, holds ``target`` of the pooled samples of ``rows``."""
    err = np.concatenate([r["tip_error_m"] for r in rows])
    sd = np.concatenate([r["tip_std_m"] for r in rows])

    def miss(s):
        return coverage_95(err, np.hypot(sd, s), qe.GAUGE_STD) - target
    return float(brentq(miss, 0.0, 0.2)) if miss(0.0) < 0 else 0.0


def tune_link(runs) -> dict:
    """The DRIVEN_LINK entry with the least squared gauge error over ``runs`` (LabRuns):
    a grid (LINK_GRID, LAGS), the gain by linear least squares at each point."""
    labs = np.concatenate([r.gauge_sign() * (r.deflection - r.gauge_bias()) for r in runs])
    best = None
    for f, z, jerk in itertools.product(*LINK_GRID):
        unit = [estimate_driven_link(r.theta, r.dt, LinkMode(f, z, 1.0), jerk, 0.0, 0.0,
                                     qe.HUB_QUANTUM).deflection for r in runs]
        for lag in LAGS:
            x = np.concatenate([delayed(r.t, u, lag) for r, u in zip(runs, unit)])
            g = float(x @ labs / (x @ x))
            sse = float(np.sum((g * x - labs) ** 2))
            if best is None or sse < best[0]:
                best = (sse, {"frequency_hz": round(float(f), 3), "damping_ratio": z,
                              "gain": g, "lag_s": round(float(lag), 3), "jerk_noise": jerk})
    return best[1]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", default=None)
    p.add_argument("--workers", type=int, default=3)
    p.add_argument("--tune", action="store_true")
    p.add_argument("--tune-link", action="store_true")
    p.add_argument("--structure", choices=qe.STRUCTURES, default="full")
    p.add_argument("--out", default=None, help="PNG per run and estimate.json here")
    args = p.parse_args(argv)
    root = data_root(args.data)
    out = Path(args.out) if args.out else None
    report = {}
    if args.tune_link:
        files = {p.name: p for p in cuboulder_files(root / CUBOULDER)}
        for unit, names in (("hagenau", qe.TUNED_ON[:2]), ("shared", qe.TUNED_ON)):
            link = tune_link([read_cuboulder_file(files[n]) for n in names])
            report.setdefault("link_tuning", {})[unit] = link
            print(f"DRIVEN_LINK[{unit!r}] on {', '.join(names)}: {link}", file=sys.stderr)
    if args.tune:
        fit = qe.estimate_held_out(root, qe.TUNED_ON, workers=args.workers, errors=True,
                                   structure=args.structure)
        std = model_std_for(fit["runs"])
        for r in fit["runs"]:
            r.pop("tip_error_m"), r.pop("tip_std_m")
        report["tuning"] = {"runs": fit["runs"], "summary": fit["summary"],
                            "tip_model_std_m": std}
        print(f"model std for 95 % on {', '.join(qe.TUNED_ON)} ({args.structure}): "
              f"{std:.6f} m", file=sys.stderr)
    held = qe.estimate_held_out(root, workers=args.workers, out=out,
                                progress=lambda s: print(s, file=sys.stderr, flush=True),
                                model_std=std if args.tune else None,
                                structure=args.structure)
    report.update(held)
    if out is not None:
        (out / "estimate.json").write_text(json.dumps(report, indent=1, default=float))
    print(json.dumps(report, indent=1, default=float))
    return 0


if __name__ == "__main__":
    sys.exit(main())
