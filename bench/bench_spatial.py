"""Speed of the spatial core (issue 25): compiled M, c evaluation and fixed-step runs.

    python bench/bench_spatial.py [--duration 2.0] [--step 1e-3]

Prints, for seed 000's arm in 3D (26 coordinates) and the 6-joint URDF arm with a flexible
forearm (ur5_like_flexible_forearm, 4 variables per direction, 19 coordinates): the numba
compile-or-cache-load time (separately), the cost of one M, c evaluation (Python reference
with complex step vs compiled analytic form, CPU time), their agreement, and the fixed-step
generalized-alpha run (rho_inf 0.9) as a real-time factor (simulated time / CPU time of one
process). Timings are process CPU time (the machine is shared), medians of repeats.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def cpu(fn, repeat=5, number=1):
    out = []
    for _ in range(repeat):
        t0 = time.process_time()
        for _ in range(number):
            fn()
        out.append((time.process_time() - t0) / number)
    return float(np.median(out))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=2.0)
    ap.add_argument("--step", type=float, default=1e-3)
    args = ap.parse_args(argv)
    t0 = time.process_time()
    from flex_model.spatial import SpatialArmModel, load_spatial_arm
    from flex_model.spatial.compiled import CompiledSpatialModel
    from flex_model.spatial.analysis import static_equilibrium
    from flex_model.spatial.integrate import simulate_fixed, simulate_fixed_compiled
    from flex_model.spatial.limits import joint_limits
    t_import = time.process_time() - t0
    print(f"import (numba module load): {t_import:.2f} s CPU")
    first = True
    for preset in ("ur5_like_flexible_forearm", "seed000_real_arm_3d"):
        model = SpatialArmModel(load_spatial_arm(preset))
        cm = CompiledSpatialModel(model)
        rng = np.random.default_rng(0)
        q, v = rng.normal(scale=0.1, size=model.nq), rng.normal(size=model.nq)
        t0 = time.process_time()
        Mc, cc = cm.terms(q, v)
        t_first = time.process_time() - t0
        n_short = 5
        simulate_fixed_compiled(model, np.zeros(model.nq), np.zeros(model.nq), args.step, 2)
        t_loop_first = time.process_time() - t0 - t_first
        if first:
            print(f"numba compile or cache load: terms {t_first:.2f} s, fixed-step loop "
                  f"{t_loop_first:.2f} s CPU (once per process; cache=True)")
            first = False
        Mr, cr = model.terms(q, v)
        err = max(np.max(np.abs(Mc - Mr)) / np.max(np.abs(Mr)),
                  np.max(np.abs(cc - cr)) / np.max(np.abs(cr)))
        t_py = cpu(lambda: model.terms(q, v), repeat=3, number=5)
        t_nb = cpu(lambda: cm.terms(q, v), repeat=5, number=200)
        print(f"\n{preset}: nq = {model.nq}, joints = {model.n_links}")
        print(f"  M, c evaluation: Python+complex step {t_py * 1e3:.2f} ms, compiled "
              f"{t_nb * 1e6:.1f} us ({t_py / t_nb:.0f}x); max relative difference {err:.1e}")
        # from the static equilibrium under gravity (joints held at zero: the outstretched
        # pose), the holding torques plus a 0.1 s sin^2 pulse of 5 % of the joint's effort limit
        # (seed 000's arm: 0.05 N m)
        h = args.step
        n = int(round(args.duration / h))
        q0 = static_equilibrium(model).q
        hold = model.gravity_force(q0)[model.off]
        effort = joint_limits(model.arm)["effort"]
        pulse = np.where(np.isfinite(effort), 0.05 * effort, 0.05)
        t = h * np.arange(1, n + 1)
        shape = np.where(t < 0.1, np.sin(np.pi * t / 0.1) ** 2, 0.0)   # smooth sin^2 pulse
        tau = hold[None, :] + shape[:, None] * pulse[None, :]
        v0 = np.zeros(model.nq)
        best = []
        for _ in range(3):
            t0 = time.process_time()
            run = simulate_fixed_compiled(model, q0, v0, h, n, joint_torques=tau)
            best.append(time.process_time() - t0)
        t_run = float(np.median(best))
        print(f"  fixed step h = {h * 1e3:g} ms, {args.duration:g} s simulated: "
              f"{t_run:.3f} s CPU -> {args.duration / t_run:.1f}x real time "
              f"({run.newton_iterations / n:.2f} Newton iterations a step, tol 1e-10)")
        best = []
        for _ in range(3):
            t0 = time.process_time()
            loose = simulate_fixed_compiled(model, q0, v0, h, n, joint_torques=tau, tol=1e-7)
            best.append(time.process_time() - t0)
        t_loose = float(np.median(best))
        dq = np.max(np.abs(loose.q - run.q)[:, model.off])
        print(f"  same with Newton tol 1e-7: {args.duration / t_loose:.1f}x real time "
              f"({loose.newton_iterations / n:.2f} iterations a step); joint angles differ "
              f"from tol 1e-10 by {np.degrees(dq):.1e} deg at most")
        # the Python reference loop on a short stretch, for the ratio
        m = n_short * 20
        H = np.zeros((model.nq, model.n_links))
        H[model.off, np.arange(model.n_links)] = 1.0
        t0 = time.process_time()
        ref = simulate_fixed(model, q0, v0, h, m, force=lambda t, q, v: H @ tau[min(
            max(int(round(t / h)) - 1, 0), n - 1)])
        t_ref = time.process_time() - t0
        diff = np.max(np.abs(ref.q[-1] - run.q[m]))
        print(f"  Python reference loop: {m * h / t_ref:.2f}x real time "
              f"({t_run / n / (t_ref / m):.3f} of its CPU per step); state difference "
              f"after {m} steps {diff:.1e}")


if __name__ == "__main__":
    main()
