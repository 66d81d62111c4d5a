"""Cost of a payload change in the spatial model node (issue 25; spatial/payload.py).

    python bench/bench_spatial_payload.py [--repeat 7]

For seed003_like_arm (8 coordinates) and ur5_like_flexible_forearm (19 coordinates):
the CPU time of a payload change followed by the first 10-step period of the compiled
loop (1 ms steps: one 100 Hz period), built the node's way (a shallow copy of the model
with the last end body replaced, ``model_with_payload``) and by a new SpatialArmModel
(the beams' bases rebuilt), against a following period. Process CPU time, medians.
"""
from __future__ import annotations

import argparse
import time

import numpy as np


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    from flex_model.spatial import SpatialArmModel, load_spatial_arm
    from flex_model.spatial.integrate import simulate_fixed_compiled
    from flex_model.spatial.payload import model_with_payload, with_payload
    for name in ("seed003_like_arm", "ur5_like_flexible_forearm"):
        arm = load_spatial_arm(name)
        model = SpatialArmModel(arm)
        q, v = np.zeros(model.nq), np.zeros(model.nq)
        simulate_fixed_compiled(model, q, v, 1e-3, 10)      # compile or load the cache
        rows = {"copy": [], "new": [], "period": []}
        for k in range(args.repeat):
            mass = 0.5 + 0.1 * k
            for how, make in (("copy", lambda: model_with_payload(model, arm, mass)),
                              ("new", lambda: SpatialArmModel(with_payload(arm, mass)))):
                t0 = time.process_time()
                m2 = make()
                run = simulate_fixed_compiled(m2, q, v, 1e-3, 10)
                rows[how].append(time.process_time() - t0)
            t0 = time.process_time()
            simulate_fixed_compiled(m2, q, v, 1e-3, 10, acceleration=run.acceleration)
            rows["period"].append(time.process_time() - t0)
        med = {k: 1e3 * float(np.median(x)) for k, x in rows.items()}
        print(f"{name} ({model.nq} coordinates): payload change + first period "
              f"{med['copy']:.2f} ms (node: model copy), {med['new']:.1f} ms (new model); "
              f"a following period {med['period']:.2f} ms CPU")


if __name__ == "__main__":
    main()
