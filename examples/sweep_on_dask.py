"""A parameter sweep on a Dask cluster: residual vibration of seed 002's arm against payload.

Seed 002's two-link arm (VALIDATION.md H) makes a 10 deg PD set-point step in the
horizontal plane; the sweep sets the payload mass of the scenario's arm per point and
measures the residual vibration (seed 002's radius of residual vibration about the goal)
and the tip's peak elastic deflection (docs/batch.md). Every point is a task of a Dask
LocalCluster of two single-threaded worker processes, through the same executor
interface as `flex-twin sweep --scheduler` (flex_twin.cluster.batch_executor). Writes
sweep/sweep.csv, sweep.json and sweep.png.

    python examples/sweep_on_dask.py              # 0, 1, 2 kg; docs/batch.md: 0.78, 4.51, 9.75 mm
    FLEX_TWIN_EXAMPLES_QUICK=1 python examples/sweep_on_dask.py   # 0, 1 kg, 1 s runs
"""
import os

from distributed import LocalCluster

from flex_twin.cluster import batch_executor
from flex_twin.sweep import run_sweep

if __name__ == "__main__":            # the workers are processes: guard the main module
    quick = bool(os.environ.get("FLEX_TWIN_EXAMPLES_QUICK"))
    vary = ["payload.mass=0,1" if quick else "payload.mass=0,1,2",
            f"duration={1.0 if quick else 3.0}"]
    with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cluster, \
            batch_executor(cluster.scheduler_address) as executor:
        rows = run_sweep("seed002_step", vary, "sweep", executor, after=0.5 if quick else 1.5)
    for row in rows:
        print(f"payload {row['payload.mass']:g} kg: residual vibration "
              f"{1e3 * row['residual_vibration_m']:.2f} mm, peak tip deflection "
              f"{1e3 * row['tip_peak_deflection_m']:.2f} mm {row['error']}")
    print("wrote sweep/sweep.csv, sweep/sweep.png")
