"""Low-level command line of the spatial core (``flex-twin modes``, ``static``,
``simulate`` and ``plan`` take spatial arms and scenarios too)::

    python -m flex_model.spatial modes seed000_real_arm_3d [--joints hinged] [--count 6]
    python -m flex_model.spatial static seed000_real_arm_3d [--joint-values 0.3]
    python -m flex_model.spatial simulate seed000_real_arm_3d --duration 0.5 --step 1e-3 \
        [--joint-values 0.3] [--joint-rates 1.0] [--out run.npz]
    python -m flex_model.spatial modes thesis_three_link --from-planar
    python -m flex_model.spatial modes ur5_like_flexible_forearm       # URDF + side file

``simulate`` uses the compiled loop (numba; ``--python``: the reference loop).
Output is JSON on stdout. ``--from-planar`` reads a planar arm (flex_model.arm) and embeds it.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from .analysis import natural_modes, static_equilibrium
from .description import from_planar
from .loader import load_spatial_arm
from .dynamics import SpatialArmModel
from .integrate import simulate_fixed, simulate_fixed_compiled


def _model(args) -> SpatialArmModel:
    if args.from_planar:
        from ..arm import load_arm
        return SpatialArmModel(from_planar(load_arm(args.arm)))
    return SpatialArmModel(load_spatial_arm(args.arm))


def _values(text, n, what):
    if text is None:
        return np.zeros(n)
    vals = [float(v) for v in text.split(",")]
    if len(vals) != n:
        raise SystemExit(f"--{what}: got {len(vals)} values; expected {n} (comma-separated)")
    return np.array(vals)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m flex_model.spatial", description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("command", choices=["modes", "static", "simulate"])
    p.add_argument("arm", help="spatial preset name or YAML path (planar with --from-planar)")
    p.add_argument("--from-planar", action="store_true")
    p.add_argument("--joint-values", help="comma-separated joint values (rad or m)")
    p.add_argument("--joint-rates", help="comma-separated initial joint rates (simulate)")
    p.add_argument("--joints", choices=["clamped", "hinged"], default="clamped")
    p.add_argument("--gravity-preload", action="store_true")
    p.add_argument("--count", type=int, default=6)
    p.add_argument("--duration", type=float, default=0.5)
    p.add_argument("--step", type=float, default=1e-3)
    p.add_argument("--rho-inf", type=float, default=0.9)
    p.add_argument("--out", help="simulate: write t, q, v to this .npz")
    p.add_argument("--python", action="store_true",
                   help="simulate with the Python reference loop (default: compiled)")
    args = p.parse_args(argv)
    model = _model(args)
    qj = _values(args.joint_values, model.n_links, "joint-values")
    if args.command == "modes":
        md = natural_modes(model, qj, joints=args.joints, gravity_preload=args.gravity_preload)
        planes = []
        for k in range(min(args.count, len(md.omega))):
            s = md.shapes_q[:, k]
            share = {pl: float(np.linalg.norm(s[model.plane_indices(pl)]) ** 2
                               / max(np.linalg.norm(s) ** 2, 1e-300))
                     for pl in ("joints", "v", "w", "phi")}
            planes.append(max(share, key=share.get))
        out = {"frequencies_hz": [float(f) for f in md.frequencies_hz[:args.count]],
               "dominant": planes}
    elif args.command == "static":
        st = static_equilibrium(model, qj)
        out = {"tip_position_m": st.tip_position.tolist(),
               "links": {k: {n: float(x) for n, x in d.items()}
                         for k, d in st.deflections.items()},
               "iterations": st.iterations}
    else:
        q0 = np.zeros(model.nq)
        q0[model.off] = qj
        v0 = np.zeros(model.nq)
        v0[model.off] = _values(args.joint_rates, model.n_links, "joint-rates")
        n = int(round(args.duration / args.step))
        if args.python:
            run = simulate_fixed(model, q0, v0, args.step, n, rho_inf=args.rho_inf)
        else:
            run = simulate_fixed_compiled(model, q0, v0, args.step, n, rho_inf=args.rho_inf)
        if args.out:
            np.savez(args.out, t=run.t, q=run.q, v=run.v)
        e0, e1 = model.total_energy(q0, v0), model.total_energy(run.q[-1], run.v[-1])
        out = {"steps": n, "newton_iterations": run.newton_iterations,
               "final_joint_values": run.q[-1, model.off].tolist(),
               "final_tip_position_m": model.tip_position(run.q[-1]).tolist(),
               "energy_start_J": e0, "energy_end_J": e1}
    json.dump(out, sys.stdout, indent=2)
    print()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
