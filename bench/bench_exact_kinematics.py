"""Kinematics options side by side on the sagging seed-000 link (issue 24, item 3).

One link of L = 0.28 m, 0.1289 kg/m, EI = 0.70656 N m^2, a 25.607 g tip mass (the preset
seed000_real_arm) clamped to a 5 kg m^2 hub that turns freely (no joint torque), in the
vertical plane under gravity. At t = 0 the link is straight, horizontal and at rest; it
falls into its sag and oscillates about it. Printed per kinematics (small_deflection,
second_order, exact; variable step and fixed steps) and for Exudyn's ANCF cable
(bench/exact_kinematics_exudyn.py, run in the peer venv): the period of the tip
deflection (mean spacing of its maxima, sampled every 1e-4 s or every fixed step if
longer), its error against Exudyn, the largest difference of the tip deflection from
Exudyn's over the run (% of the deflection's peak-to-peak amplitude), and CPU seconds (the
twin's after a warm-up run, without numba's compile; Exudyn's solve).

Measured (one run, loaded 2-core machine, 8 variables): period - Exudyn (16 elements,
1e-4 s: 0.1181222 s, 4.4 CPU-s) small_deflection +5.0e-5 s (3.5 % of the deflection off),
second_order +4.2e-5 s (2.8 %), exact -1.2e-7 s (0.11 %) at a fixed 1e-4 s in 1.6 CPU-s,
-4.3e-7 s (0.14 %) at 2.5e-4 s in 0.75 CPU-s; variable step at rtol 1e-10: exact +1.1e-6 s
in 63 CPU-s, second_order 40, small_deflection 19.

    python bench/bench_exact_kinematics.py                  # 8 variables, 3 s, rtol 1e-10
    python bench/bench_exact_kinematics.py --no-variable    # the fixed steps only (fast)
    python bench/bench_exact_kinematics.py --gscale 2       # twice the sag (error ~ sag^2)
    python bench/bench_exact_kinematics.py --no-exudyn      # the twin only
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from exact_kinematics_exudyn import period_of_maxima  # noqa: E402 (stdlib-only module)

from flex_model.arm import load_arm  # noqa: E402
from flex_model.dynamics import FlexArmModel  # noqa: E402
from flex_model.simulate import simulate  # noqa: E402

HUB_J = 5.0
#: the issue's figures (issue 24, item 3)
ISSUE_PERIOD, ISSUE_SECOND_ORDER_ERROR = 0.11815, 3.6e-4


def sag_model(kinematics: str, n_vars: int = 8, gscale: float = 1.0) -> FlexArmModel:
    """The seed-000 link on the free 5 kg m^2 hub in the vertical plane."""
    arm = load_arm("seed000_real_arm", vars_per_link=n_vars)
    link = dataclasses.replace(arm.links[0], J_minus=HUB_J)
    arm = dataclasses.replace(arm, links=(link,), gravity=(0.0, -9.81 * gscale))
    return FlexArmModel(arm.with_kinematics(kinematics))


def run_twin(kinematics, n_vars, gscale, t_end, sample, rtol, dt=None):
    """One run: variable step at rtol (dt None) or fixed step dt (rho_inf 0.9)."""
    model = sag_model(kinematics, n_vars, gscale)
    q0 = np.zeros(model.nq)
    kw = dict(rtol=rtol) if dt is None else dict(method="fixed", dt=dt)
    sample = sample if dt is None else max(sample, dt)  # the fixed step divides it
    simulate(model, q0, t_final=2 * sample, sample_period=sample, **kw)  # compile/warm up
    c0 = time.process_time()
    res = simulate(model, q0, t_final=t_end, sample_period=sample, **kw)
    cpu = time.process_time() - c0
    w = res.tip_deflections[:, 0]
    period = period_of_maxima(res.t, w)[0]
    return {"t": res.t, "w": w, "period": period, "cpu_s": cpu, "hub": res.q[:, 0]}


def run_exudyn(nel, h, gscale, t_end, sample):
    cmd = [sys.executable, os.path.join(HERE, "exact_kinematics_exudyn.py"), "--nel",
           str(nel), "--h", repr(h), "--t-end", repr(t_end), "--sample", repr(sample),
           "--gscale", repr(gscale)]
    out = subprocess.run(cmd, capture_output=True, text=True)
    if out.returncode != 0:
        print("Exudyn run failed:\n" + out.stderr[-2000:])
        return None
    d = json.loads(out.stdout.strip().splitlines()[-1])
    d["t"] = np.array(d["t"])
    d["w"] = np.array(d["w"])
    return d


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--vars", type=int, default=8, help="variables of the link (even)")
    ap.add_argument("--t-end", type=float, default=3.0)
    ap.add_argument("--sample", type=float, default=1e-4)
    ap.add_argument("--rtol", type=float, default=1e-10)
    ap.add_argument("--gscale", type=float, default=1.0, help="gravity scale (sag)")
    ap.add_argument("--nel", type=int, default=16, help="Exudyn ANCF elements")
    ap.add_argument("--h", type=float, default=1e-4, help="Exudyn step (s)")
    ap.add_argument("--steps", type=float, nargs="*", default=[1e-4, 2.5e-4],
                    help="fixed steps of the twin's rows (s)")
    ap.add_argument("--no-variable", action="store_true", help="no variable-step rows")
    ap.add_argument("--no-exudyn", action="store_true")
    a = ap.parse_args()
    runs = {}
    if not a.no_exudyn:
        ex = run_exudyn(a.nel, a.h, a.gscale, a.t_end, a.sample)
        if ex is not None:
            runs["Exudyn ANCF"] = ex
    for kin in ("small_deflection", "second_order", "exact"):
        if not a.no_variable:
            runs[f"{kin} var"] = run_twin(kin, a.vars, a.gscale, a.t_end, a.sample, a.rtol)
        for dt in a.steps:
            runs[f"{kin} h {dt:g}"] = run_twin(kin, a.vars, a.gscale, a.t_end, a.sample,
                                               a.rtol, dt)
    ref = runs.get("Exudyn ANCF")
    amp = np.ptp(ref["w"]) if ref is not None else np.ptp(next(iter(runs.values()))["w"])
    print(f"seed-000 link sagging on a free {HUB_J} kg m^2 hub, g x {a.gscale}, "
          f"{a.t_end} s; twin: {a.vars} variables, variable step (var) at rtol {a.rtol:g}, "
          f"fixed step (h) rho_inf 0.9; Exudyn: "
          f"{a.nel} ANCF elements, h {a.h:g}")
    print(f"peak-to-peak tip deflection {amp * 1e3:.3f} mm; the issue: {ISSUE_PERIOD} s, "
          f"second_order +{ISSUE_SECOND_ORDER_ERROR:g} s")
    print(f"{'model':26s} {'period (s)':>12s} {'vs Exudyn (s)':>14s} "
          f"{'vs 0.11815 (s)':>15s} {'max |dw| (%)':>13s} {'CPU (s)':>8s}")
    for name, r in runs.items():
        dper = r["period"] - ref["period"] if ref is not None else float("nan")
        if ref is not None and name != "Exudyn ANCF":
            dw = 100 * np.max(np.abs(r["w"] - np.interp(r["t"], ref["t"], ref["w"]))) / amp
        else:
            dw = float("nan")
        print(f"{name:26s} {r['period']:12.7f} {dper:+14.2e} {r['period'] - ISSUE_PERIOD:+15.2e}"
              f" {dw:13.3f} {r['cpu_s']:8.2f}")


if __name__ == "__main__":
    main()
