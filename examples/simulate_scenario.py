"""Simulate a scenario: the thesis's three-link arm under PD with a torque pulse.

VALIDATION.md section E (the thesis's efficiency example): three links held by a PD at
-20, 20, -20 deg (relative), 1000 N m on joint 1 over 3-4 s; the equations of motion are
thesis Eq. (84) in the wavelet variables. The scenario file gives the arm, the start, the
PD and the integrator; here its duration is shortened and the step fixed. Prints the
largest tip deflection of each link and the last joint angles (the arm still swings after
the pulse) and writes scenario.png.

    python examples/simulate_scenario.py              # 6 s
    FLEX_TWIN_EXAMPLES_QUICK=1 python examples/simulate_scenario.py   # 4.5 s (the tests)
"""
import dataclasses
import os

import numpy as np

from flex_model.plots import plot_simulation
from flex_model.scenario import load_scenario

duration = 4.5 if os.environ.get("FLEX_TWIN_EXAMPLES_QUICK") else 6.0      # s
scenario = load_scenario("thesis_three_link_pd", vars_per_link=4)
scenario = dataclasses.replace(scenario, duration=duration, method="fixed", step=1e-3)
run = scenario.run()

peak = np.max(np.abs(run.tip_deflections), axis=0)
print(f"simulated {run.t[-1]:.1f} s at a fixed 1 ms step")
print("largest tip deflections (mm):", ", ".join(f"{1e3 * d:.1f}" for d in peak))
print("final joint angles (deg):", ", ".join(f"{a:.2f}" for a in np.degrees(run.joint_angles[-1])))
plot_simulation(run, "scenario.png", title="thesis_three_link_pd")
print("wrote scenario.png")
