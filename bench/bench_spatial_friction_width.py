"""The twin at a spatial-suite case's true hidden effects, per friction width (issue 44).

    python bench/bench_spatial_friction_width.py runs/spatial_suite/CASE [--widths 1e-3,0.02]

Replays the nominal spatial twin with the hidden effects of the case's truth.yaml at their
true values (joint friction viscous and Coulomb, a plane's bending or the torsion
stiffness, the payload), the friction's Coulomb transition at each width eps (rad/s) of
the friction hypothesis (hypotheses.joint_friction), and prints J on the fit part and the
held-out part (the last 40 %, as the diagnosis splits a run) in noise units, and each
effect alone. The generator's law is tanh(w / 0.02 rad/s): docs/diagnosis.md, "Joint
friction: the width of its Coulomb transition".
"""
from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
import yaml

from flex_twin.diagnosis import spatial_loop
from flex_twin.diagnosis.baseline import baseline_parameters
from flex_twin.diagnosis.batch import RunSpec, load_any_arm
from flex_twin.diagnosis.controller import load_controller
from flex_twin.diagnosis.evaluation import Context, cost, evaluate
from flex_twin.diagnosis.hypotheses import FRICTION_EPS, FRICTION_WIDTH, library_hypotheses
from flex_twin.diagnosis.sources import load_recording


def true_effects(case: Path, hyps: dict, eps: float) -> list:
    """(hypothesis, x) of each hidden effect at its true value, friction width eps."""
    out = []
    for e in yaml.safe_load((case / "truth.yaml").read_text())["hidden"]:
        p = e["parameters"]
        if e["kind"] == "joint_friction":
            h = hyps["joint_friction@" + e["target"]]
            x = [p["viscous"] / h.scale[0], p["coulomb"] / h.scale[1], 0.0,
                 (eps - FRICTION_EPS) / FRICTION_WIDTH]
        elif e["kind"] in ("bending_stiffness", "torsion_stiffness"):
            kind = e["kind"] if "plane" not in p else "bending_stiffness_" + p["plane"]
            h = hyps[f"{kind}@{e['target']}"]
            x = [(p["scale"] - 1.0) / h.scale[0]]
        elif e["kind"] == "payload":
            h = hyps["payload"]
            x = [p["mass"] / h.scale[0]]
        else:
            raise SystemExit(f"{case}: {e['kind']} not replayed here")
        out.append((h, np.array(x, float)))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case")
    ap.add_argument("--widths", default="1e-3,5e-3,0.02")
    a = ap.parse_args(argv)
    case = Path(a.case)
    run = RunSpec.from_case_dir(case)
    arm, ctl = load_any_arm(run.arm), load_controller(run.controller)
    rec = load_recording(run.data, arm.n_links, None, arm.gravity)
    split = rec.t[0] + 0.6 * (rec.t[-1] - rec.t[0])
    fit = rec.window(rec.t[0], split)
    params = baseline_parameters(arm)
    ctx = Context.build(arm, ctl, fit, params, dt=spatial_loop.MAX_STEP)
    ctx_ho = Context.build(arm, ctl, rec, params, sigma=ctx.sigma, dt=spatial_loop.MAX_STEP,
                           score_from=split)
    hyps = {h.label: h for h in library_hypotheses(arm, fit, ctl)}
    ones = np.ones(len(params))

    def J(effects):
        return " / ".join(f"{cost(evaluate((c, ones, effects))):.3g}" for c in (ctx, ctx_ho))
    print(f"{case.name}: J fit / held out; nominal {J([])}")
    for eps in (float(w) for w in a.widths.split(",")):
        eff = true_effects(case, hyps, eps)
        print(f"width {eps:g} rad/s: all true {J(eff)}; alone "
              + ", ".join(f"{h.label} {J([(h, x)])}" for h, x in eff))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
