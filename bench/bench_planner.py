"""Benchmark of the planner (thesis Ch. IV-V.1) on this machine.

Prints:
- static-flexible inversion time per waypoint: the 4 waypoints of VALIDATION.md section F
  (from the rigid guess each) and a dense path of 200 waypoints (each from the previous
  pose), two and four deformation variables per link, plus the three-link arm with tip
  orientation; aim: under 1 ms per waypoint;
- time to compute the admissible nominal input of the 15 s section F task at 1 ms
  sampling (15001 samples), alone and as the whole ``plan_tip_path``; aim: under 1 s.

Best of several repeats, after a warm-up run (numba's cached kernels load once per
process).

    python bench/bench_planner.py [--repeats 5] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import time

import numpy as np
from scipy.interpolate import CubicSpline

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_planner import SECTION_F_TIMES, SECTION_F_WAYPOINTS, invert_waypoints, plan_tip_path
from flex_planner.nominal_input import NominalInputSolver
from flex_planner.trajectories import SampledTrajectory, sample_times


def best(fn, repeats):
    fn()  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def inversion_rows(repeats):
    rows = []
    arc = np.linspace(0.55 * np.pi, 1.45 * np.pi, 200)
    dense = 3.0 * np.c_[np.cos(arc), np.sin(arc)]
    for nv in (2, 4):
        model = FlexArmModel(load_arm("thesis_example1", nv))
        for name, pts in (("section F (4 points)", SECTION_F_WAYPOINTS),
                          ("dense arc (200 points)", dense)):
            t = best(lambda: invert_waypoints(model, pts), repeats)
            rows.append({"arm": "thesis_example1", "vars_per_link": nv, "path": name,
                         "ms_per_waypoint": 1e3 * t / len(pts)})
    model = FlexArmModel(load_arm("thesis_three_link", 2))
    pts = np.array([[5.0, -2.0], [4.0, 1.0], [3.0, 3.0]])
    phis = np.array([-0.8, 0.2, 1.0])
    t = best(lambda: invert_waypoints(model, pts, phis), repeats)
    rows.append({"arm": "thesis_three_link", "vars_per_link": 2,
                 "path": "3 poses with orientation", "ms_per_waypoint": 1e3 * t / 3})
    return rows


def nominal_rows(repeats):
    rows = []
    for nv in (2, 4):
        model = FlexArmModel(load_arm("thesis_example1", nv))
        poses = invert_waypoints(model, SECTION_F_WAYPOINTS)
        spline = CubicSpline(SECTION_F_TIMES, [p.joint_angles for p in poses], axis=0,
                             bc_type="clamped")
        t = sample_times(0.0, 15.0, 1e-3)
        traj = SampledTrajectory(t, spline(t), spline(t, 1), spline(t, 2))
        solver = NominalInputSolver(model)
        t_nominal = best(lambda: solver.solve(traj), repeats)
        t_plan = best(lambda: plan_tip_path(model, SECTION_F_WAYPOINTS, SECTION_F_TIMES,
                                            sample_period=1e-3), repeats)
        rows.append({"vars_per_link": nv, "samples": len(t), "nominal_input_s": t_nominal,
                     "plan_tip_path_s": t_plan})
    return rows


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--json", default=None, help="also write the results to this file")
    args = p.parse_args()
    inv = inversion_rows(args.repeats)
    nom = nominal_rows(args.repeats)
    print("static-flexible inversion (aim < 1 ms per waypoint)")
    for r in inv:
        print(f"  {r['arm']:18s} {r['vars_per_link']} vars/link  {r['path']:26s} "
              f"{r['ms_per_waypoint']:7.3f} ms/waypoint")
    print("admissible nominal input, section F task, 15 s at 1 ms (aim < 1 s)")
    for r in nom:
        print(f"  {r['vars_per_link']} vars/link, {r['samples']} samples: nominal input "
              f"{r['nominal_input_s']:.3f} s, whole plan_tip_path {r['plan_tip_path_s']:.3f} s")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"inversion": inv, "nominal_input": nom}, f, indent=2)


if __name__ == "__main__":
    main()
