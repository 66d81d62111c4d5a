"""Large deflections of a soft spatial yaw + pitch arm: ``kinematics: exact`` against Exudyn.

    python bench/bench_spatial_exact.py [--duration 0.6] [--quick] [--cost]

The arm of bench_spatial_torsion.py (its builders, run and comparison, issue 47) with
soft links: both links a 1 m aluminium square tube 8 x 0.5 mm (EI 9.9 N m^2, rhoA 0.041
kg/m), a 0.2 kg tip mass on each link, 0.05 kg m^2 hubs, gravity -z, PD kp 200 N m/rad,
kd 20 N m s/rad about the start pose (the static equilibrium under gravity: both links
sag by tens of centimetres, beyond the linear range), then a 5 N m sin^2 yaw pulse over
0.1 s that swings the drooping links sideways (bending in both planes, twist). Ours with
``small_deflection``, ``second_order`` and ``exact`` kinematics at a few discretizations,
against Exudyn's geometrically exact beams (ObjectBeamGeometricallyExact, 16 and 32
elements per link). Prints each run's largest tip distance from the finest Exudyn run,
the start tip (the static sag) and the deflection differences in % of their amplitude.
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import bench_spatial_torsion as base  # noqa: E402
from peer_exudyn import peer_runs  # noqa: E402

#: the soft tube (square, b x t) and the pulse
B_TUBE, T_TUBE = 0.008, 0.0005
base.TAU1 = 5.0


def soft_tube():
    """A, Ib, I_p, J of the b x t square tube (J by Bredt, as bench_spatial_torsion)."""
    b, t = B_TUBE, T_TUBE
    A = b * b - (b - 2 * t) ** 2
    Ib = (b ** 4 - (b - 2 * t) ** 4) / 12
    bm = b - t
    return A, Ib, 2 * Ib, 4 * bm ** 4 * t / (4 * bm)


base.tube = soft_tube


def run_ours(kinematics: str, variables: int, h: float, duration: float) -> dict:
    base.KINEMATICS = kinematics
    return base.run_ours(variables, h, duration)


def _peer(argv) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n-el", type=int)
    ap.add_argument("--h", type=float)
    ap.add_argument("--duration", type=float)
    a, _ = ap.parse_known_args(argv)
    import json
    print("JSON" + json.dumps(base.run_exudyn(a.n_el, a.h, a.duration)))
    return 0


def _row(label, c):
    return (f"  {label}: tip {c['tip_mm']:.2f} mm (start {c['tip0_mm']:.2f}), joints "
            f"{c['dq_deg']:.1e} deg; of the amplitude: " + ", ".join(
                f"{lk[-1]}{k} {100 * c[f'{lk}_{k}']:.2f} %" for lk in ("link1", "link2")
                for k in ("v", "w", "phi")))


def cost(variables: int = 8, calls: int = 2000) -> None:
    """CPU time of one compiled evaluation (with M, and the residual only) per kinematics."""
    import time

    from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
    from flex_model.spatial.compiled import pack, spatial_eval
    for kin in ("second_order", "exact"):
        base.KINEMATICS = kin
        m = SpatialArmModel(spatial_arm_from_dict(base.arm_dict(variables)))
        P = pack(m)
        rng = np.random.default_rng(0)
        q, v, a = (rng.normal(scale=s_, size=m.nq) for s_ in (0.05, 1.0, 1.0))
        out = []
        for want in (True, False):
            spatial_eval(P, q, v, a, want)
            t0 = time.process_time()
            for _ in range(calls):
                spatial_eval(P, q, v, a, want)
            out.append(1e6 * (time.process_time() - t0) / calls)
        print(f"  {kin:>12} {variables} var.: {out[0]:.0f} us with M, {out[1]:.0f} us the "
              f"residual (CPU; load {os.getloadavg()[0]:.1f})")


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if "--peer" in argv:
        return _peer(argv)
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=0.6)
    ap.add_argument("--quick", action="store_true", help="one resolution each")
    ap.add_argument("--cost", action="store_true", help="only the evaluation cost")
    args = ap.parse_args(argv)
    if args.cost:
        cost()
        return 0
    ours_res = [("exact", 8, 5e-4), ("second_order", 8, 5e-4), ("small_deflection", 8, 5e-4)]
    if not args.quick:
        ours_res = [("exact", 4, 5e-4), ("exact", 12, 2.5e-4)] + ours_res
    peer_res = [(16, 5e-4)] if args.quick else [(16, 5e-4), (32, 2.5e-4)]
    ours = {r: run_ours(*r, args.duration) for r in ours_res}
    peer = peer_runs(__file__, peer_res, args.duration)
    if peer is None:
        return 1
    print(f"soft yaw + pitch tubes ({1e3 * B_TUBE:g} x {1e3 * T_TUBE:g} mm), "
          f"{base.TAU1:g} N m yaw pulse over {base.T_PULSE:g} s, {args.duration:g} s; "
          f"load {os.getloadavg()[0]:.1f}")
    for r, o in ours.items():
        print(f"  ours {r[0]:>16} {r[1]:2d} var., h {r[2]:.2e}: nq {o['nq']}, "
              f"{o['cpu']:.2f} s CPU")
    for r, o in peer.items():
        print(f"  Exudyn {r[0]:2d} el., h {r[1]:.2e}: {o['n']} ODE2, {o['cpu']:.2f} s CPU")
    ref_p = peer[peer_res[-1]]
    for r in peer_res[:-1]:
        print(_row(f"Exudyn {r} vs Exudyn finest", base.compare(peer[r], ref_p)))
    for r in ours_res:
        print(_row(f"ours {r} vs Exudyn finest", base.compare(ours[r], ref_p)))
    c = base.compare(ours[ours_res[-3]], ref_p)
    tip = np.array(ref_p["tip"])
    print(f"  Exudyn finest: start tip {np.round(tip[0], 4).tolist()} m, amplitudes " +
          ", ".join(f"{lk}.{k} {c[f'{lk}_{k}_amp']:.3e}" for lk in ("link1", "link2")
                    for k in ("v", "w", "phi")) + " (m, rad)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
