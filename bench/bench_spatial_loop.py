"""Benchmark: CPU time per step of the spatial arm's compiled loop (issue 43:
solvers.loop.fixed_step on compiled.SpatialModel). seed003_like_arm from rest under
constant joint torques, 2000 steps of 1 ms in one call (the best of 5 runs: the loop
without the Python call overhead), then 4-step calls continued with ``acceleration=``
(the spatial node's period). Prints figures; run it on main and on a branch to compare.

    python bench/bench_spatial_loop.py
"""
import time

import numpy as np
from flex_model.config import read_yaml
from flex_model.spatial.description import SPATIAL_PRESET_DIR
from flex_model.spatial.dynamics import SpatialArmModel
from flex_model.spatial.integrate import simulate_fixed_compiled as run
from flex_model.spatial.loader import spatial_arm_from_dict


def main():
    m = SpatialArmModel(spatial_arm_from_dict(
        read_yaml(SPATIAL_PRESET_DIR / "seed003_like_arm.yaml"), "seed003_like_arm"))
    tau, z = [1.0, -0.5, 0.2], np.zeros(m.nq)
    r = run(m, z, z, 1e-3, 4, joint_torques=tau)          # compiles (or loads) the loop
    best = []
    for _ in range(5):
        t0 = time.process_time()
        r = run(m, z, z, 1e-3, 2000, joint_torques=tau)
        best.append(time.process_time() - t0)
    print(f"2000 steps in one call: {1e6 * min(best) / 2000:.1f} us CPU per step (best of 5), "
          f"{r.newton_iterations} Newton iterations")
    q, v, acc, n = r.q[-1], r.v[-1], r.acceleration, 2000
    t0 = time.process_time()
    for _ in range(n):
        r = run(m, q, v, 1e-3, 4, joint_torques=tau, acceleration=acc)
        q, v, acc = r.q[-1], r.v[-1], r.acceleration
    print(f"4-step calls: {1e6 * (time.process_time() - t0) / n:.0f} us CPU per call")


if __name__ == "__main__":
    main()
