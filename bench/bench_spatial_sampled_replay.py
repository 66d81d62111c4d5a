"""The spatial replay of a sampled PD against Exudyn (issue 44, item 4): step and restart.

    G=bench/independent_suite/generate_spatial.py; C=S-samp500-healthy-s1
    python $G --out /tmp/ex_noisy_h500 --only $C
    python $G --out /tmp/ex_clean_h500 --only $C --noise 0
    python $G --out /tmp/ex_clean_h125 --only $C --noise 0 --step 1.25e-4
    python bench/bench_spatial_sampled_replay.py --case $C --refs /tmp/ex_noisy_h500 \\
        /tmp/ex_clean_h500 /tmp/ex_clean_h125 [--steps 1e-3,5e-4,2.5e-4]

The nominal twin (the healthy truth) replays the case under its sampled PD
(spatial_loop.predict) at each step, its periods restarting at each command jump
(spatial_loop.SAMPLED_RESTART) or carrying the acceleration history across it, and is
compared with each reference recording; the references are compared with each other
(Exudyn's own step error). Figures: J (mean squared residual in the noise units of the
noisy recording, evaluation.noise_levels) and per channel, with the CPU time per replay.
"""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _row(label, a, b, sigma, names) -> str:
    per = {c: float(np.mean(((a.channels[c] - b.channels[c]) / sigma[c]) ** 2)) for c in names}
    return f"{label:52s} J {np.mean(list(per.values())):6.3f}  " + " ".join(
        f"{c} {v:.2f}" for c, v in per.items() if v >= 0.05)


def main(argv=None) -> int:
    from flex_twin.diagnosis import evaluation, spatial_loop
    from flex_twin.diagnosis.batch import load_any_arm
    from flex_twin.diagnosis.baseline import baseline_parameters
    from flex_twin.diagnosis.controller import load_controller
    from flex_twin.diagnosis.recording import load_csv
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", default="S-samp500-healthy-s1")
    ap.add_argument("--refs", nargs="+", required=True,
                    help="suite folders holding the case (the first: the noisy recording)")
    ap.add_argument("--steps", default="1e-3,5e-4,2.5e-4")
    a = ap.parse_args(argv)
    case = Path(a.refs[0]) / a.case
    arm = load_any_arm(str(case / "arm.yaml"))
    ctl = load_controller(str(case / "controller.yaml"))
    refs = {Path(r).name: load_csv(str(Path(r) / a.case / "recording.csv"), arm.n_links)
            for r in a.refs}
    first = refs[Path(a.refs[0]).name]
    sigma = evaluation.noise_levels(first)
    names = first.residual_channels
    tags = list(refs)
    for i, x in enumerate(tags):
        for y in tags[i + 1:]:
            print(_row(f"Exudyn {x} vs {y}", refs[x], refs[y], sigma, names))
    params = baseline_parameters(arm)
    for restart in (False, True):
        spatial_loop.SAMPLED_RESTART = restart
        for dt in (float(s) for s in a.steps.split(",")):
            ctx = evaluation.Context.build(arm, ctl, first, params, sigma=sigma, dt=dt)
            old, spatial_loop.MAX_STEP = spatial_loop.MAX_STEP, dt
            evaluation.predict_channels(ctx, arm)    # compiled, warm
            c0 = time.process_time()
            pred = evaluation.predict_channels(ctx, arm)
            cpu = time.process_time() - c0
            spatial_loop.MAX_STEP = old
            for tag in tags:
                print(_row(f"twin {'restart' if restart else 'carry'} {dt * 1e3:g} ms "
                           f"({cpu:.1f} CPU-s) vs {tag}", refs[tag], pred, sigma, names))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
