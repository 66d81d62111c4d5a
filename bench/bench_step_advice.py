"""Benchmark: does the step and variables advice warn exactly when a run is off? (issue 47)

A sweep of settings (fixed step, variables per link, kinematics) on four arms, two planar
and two spatial, short runs (0.5 s):

- ``tapered``: thesis Example 4 (two steel links tapered 50 -> 30 and 30 -> 10 mm) with a
  10 kg payload, PD on both joints, static start, a 10 deg set-point step of joint 1;
- ``sag``: one 1 m aluminium tube (20 x 1 mm, 0.2 kg at the tip) on a heavy hub
  (2 kg m^2), held by a PD, started undeformed and horizontal: it sags under gravity;
- ``seed000_3d``: the spatial preset ``seed000_3d_pd_step`` (set-point step at 0.1 s, a
  torque pulse over 0.3-0.35 s);
- ``seed003_3d``: the spatial preset ``seed003_like_pd_step`` (joint-1 step at 0.1 s, a
  20 N m pulse on joint 2 over 0.3-0.35 s).

Every run is compared with its own converged run (same arm and kinematics; a step 8x
below the sweep's smallest, 2x its largest variables): the error is
step_advice.tip_error (largest error of a link's tip deflection over the run, share of
that link's largest value). The advice (Scenario.advice on either arm,
step_advice.estimate_error: the distance to the run with a quarter of the step and twice
the variables) is asked for every setting. Acceptance: every run more than 2 % off
warned, at most 10 % of the runs within 1 % warned. Prints the table and the two counts.

    python bench/bench_step_advice.py [--arms tapered,sag,seed000_3d,seed003_3d] [--quick]
        [--variable]

``--variable``: the planar arms in the variable-step mode (small_deflection, rtol 1e-2,
1e-3, 1e-5; the advice's refined run has rtol / 16).
"""
from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from flex_model.arm import PRESET_DIR
from flex_model.config import read_yaml
from flex_model.scenario import scenario_from_dict
from flex_model.scenario import load_scenario
from flex_model.step_advice import TOLERANCE, tip_error

DURATION = 0.5


def tapered(kin: str, nv: int, step: float):
    arm = read_yaml(PRESET_DIR / "thesis_example4.yaml")
    arm["payload"] = {"mass": 10.0, "inertia": 0.05}
    return scenario_from_dict({
        "name": "tapered_payload", "arm": arm, "vars_per_link": nv, "kinematics": kin,
        "duration": DURATION, "sample_period": 5e-3,
        "initial": {"joint_angles_deg": [0.0, 0.0], "state": "static"},
        "control": {"pd": {"kp": [2.0e4, 5.0e3], "kd": [2.0e3, 5.0e2],
                           "setpoints_deg": [0.0, 0.0]},
                    "setpoint_schedule": [{"time": 0.05, "setpoints_deg": [10.0, 0.0]}]},
        "integrator": {"method": "fixed", "step": step}})


def sag(kin: str, nv: int, step: float):
    arm = {"name": "sag_heavy_hub", "gravity": [0.0, -9.81],
           "links": [{"name": "link1", "length": 1.0,
                      "material": {"E": 6.4e10, "rho": 2700.0},
                      "section": {"shape": "square_hollow", "side": 0.020, "wall": 0.001},
                      "variables": 2, "end_masses": {"J_minus": 2.0, "M_plus": 0.2}}],
           "joints": [{"name": "joint1"}]}
    return scenario_from_dict({
        "name": "sag_heavy_hub", "arm": arm, "vars_per_link": nv, "kinematics": kin,
        "duration": DURATION, "sample_period": 1e-2,
        "initial": {"joint_angles_deg": [0.0]},
        "control": {"pd": {"kp": [500.0], "kd": [100.0], "setpoints_deg": [0.0]}},
        "integrator": {"method": "fixed", "step": step}})


def spatial(preset: str):
    def make(kin: str, nv: int, step: float):
        sc = load_scenario(preset)
        pulse = dataclasses.replace(sc.pulses[0], start=0.3, end=0.35)
        sc = dataclasses.replace(sc, duration=DURATION, step=step, pulses=(pulse,),
                                 arm=dataclasses.replace(sc.arm, kinematics=kin))
        links = tuple(lk if lk.flexible is None else dataclasses.replace(
            lk, flexible=dataclasses.replace(
                lk.flexible, variables=nv,
                torsion_variables=nv if lk.flexible.torsion_variables else 0))
            for lk in sc.arm.links)
        return dataclasses.replace(sc, arm=dataclasses.replace(sc.arm, links=links))
    return make


#: arm: (scenario(kinematics, variables, step), kinematics, variables, steps (s))
ARMS = {
    "tapered": (tapered, ("small_deflection", "second_order", "exact"), (2, 4),
                (5e-3, 2.5e-3, 1.25e-3)),
    "sag": (sag, ("small_deflection", "second_order", "exact"), (2, 4),
            (1e-2, 5e-3, 2.5e-3, 1.25e-3)),
    "seed000_3d": (spatial("seed000_3d_pd_step"), ("small_deflection", "second_order"),
                   (4, 8), (1e-3, 5e-4, 2.5e-4)),
    "seed003_3d": (spatial("seed003_like_pd_step"), ("small_deflection", "second_order"),
                   (2, 4), (5e-3, 2.5e-3, 1.25e-3)),
}


def tips_and_advice(sc, advise: bool):
    """(tip deflections, warning, estimate) of a planar or a spatial scenario."""
    tips = sc.run(advise=False).tip_deflections
    if not advise:
        return tips, None, None
    adv = sc.advice()
    return tips, adv.warning, adv.estimate


#: --variable: the planar arms in the variable-step mode at these rtol (small_deflection)
RTOLS = (1e-2, 1e-3, 1e-5)


def variable(make):
    """The planar scenario in the variable-step mode: the "step" is its rtol."""
    return lambda kin, nv, rtol: dataclasses.replace(make(kin, nv, 1e-3), method="variable",
                                                     rtol=rtol)


def sweep(name: str, quick: bool, rtols: bool = False):
    make, kins, nvs, steps = ARMS[name]
    if quick:
        kins, nvs, steps = kins[:1], nvs[:1], steps[:2]
    if rtols:   # the converged run below: the fixed step 1/8 of the smallest
        return sweep_variable(name, make, nvs, min(steps) / 8)
    rows = []
    for kin in kins:
        ref, _, _ = tips_and_advice(make(kin, 2 * max(nvs), min(steps) / 8), False)
        for nv in nvs:
            for h in steps:
                t0 = time.perf_counter()
                try:
                    tips, warning, est = tips_and_advice(make(kin, nv, h), True)
                    err = tip_error(tips, ref)
                except Exception as exc:  # noqa: BLE001 - a failing run is a row too
                    tips, warning, est, err = None, f"run fails: {exc}", None, np.inf
                rows.append({"arm": name, "kin": kin, "nv": nv, "step": h, "error": err,
                             "estimate": np.nan if est is None else est.total,
                             "warns": warning is not None,
                             "seconds": time.perf_counter() - t0,
                             "cost": np.nan if est is None else est.cost_s})
                r = rows[-1]
                print(f"{name:>11} {kin:>16} {nv:3d} {1e3 * h:7.3f} {100 * err:9.3f} "
                      f"{100 * r['estimate']:9.3f} {'warns' if r['warns'] else '-':>6} "
                      f"{r['cost']:7.2f}", flush=True)
    return rows


def sweep_variable(name, make, nvs, h_ref):
    ref, _, _ = tips_and_advice(make("small_deflection", 2 * max(nvs), h_ref), False)
    rows = []
    for nv in nvs:
        for rtol in RTOLS:
            tips, warning, est = tips_and_advice(variable(make)("small_deflection", nv, rtol),
                                                 True)
            rows.append({"arm": name, "error": tip_error(tips, ref), "warns": bool(warning),
                         "estimate": est.total, "cost": est.cost_s})
            print(f"{name:>11} {'variable':>16} {nv:3d} {rtol:7.0e} "
                  f"{100 * rows[-1]['error']:9.3f} {100 * est.total:9.3f} "
                  f"{'warns' if warning else '-':>6} {est.cost_s:7.2f}", flush=True)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--arms", default=",".join(ARMS))
    ap.add_argument("--quick", action="store_true", help="first kinematics, 2 steps only")
    ap.add_argument("--variable", action="store_true", help="the planar arms in the "
                    "variable-step mode instead (rtol 1e-2, 1e-3, 1e-5; step column: rtol)")
    args = ap.parse_args(argv)
    if args.variable:
        args.arms = ",".join(a for a in args.arms.split(",") if not a.endswith("_3d"))
    print(f"{'arm':>11} {'kinematics':>16} {'nv':>3} {'step ms':>7} {'error %':>9} "
          f"{'estim. %':>9} {'advice':>6} {'check s':>7}")
    names = args.arms.split(",")
    rows = [r for name in names for r in sweep(name, args.quick, args.variable)]
    off = [r for r in rows if r["error"] > TOLERANCE]
    within = [r for r in rows if r["error"] <= TOLERANCE / 2]
    print(f"{len(rows)} runs on {len(set(r['arm'] for r in rows))} arms: "
          f"{sum(r['warns'] for r in off)} of {len(off)} runs more than 2 % off warned; "
          f"{sum(r['warns'] for r in within)} of {len(within)} runs within 1 % warned "
          f"(allowed {int(0.1 * len(within))}); between 1 and 2 %: "
          f"{len(rows) - len(off) - len(within)}; check cost median "
          f"{np.nanmedian([r['cost'] for r in rows]):.2f} s per 0.5 s run")


if __name__ == "__main__":
    main()
