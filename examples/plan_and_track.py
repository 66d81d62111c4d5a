"""Plan the thesis Ch. V task and track it with the PD of thesis Eq. (95) in the loop.

VALIDATION.md section F: the Example 1 arm in the vertical plane moves its tip through
P1..P4 at 0, 5, 10, 15 s. The planner inverts the waypoints on the static flexible arm
(thesis Ch. IV), splines the joint angles and computes the admissible nominal torque
(Ch. V.1); the nonlinear arm then runs under Eq. (95) (h = 25, a = 5, thesis V.3) with
that torque as feed-forward. Prints the tip error at each waypoint (thesis Fig. 43; here
0.54, 0.58, 0.12 mm at P2..P4, docs/planning-control.md) and writes tracking.png.

    python examples/plan_and_track.py              # the whole 15 s task
    FLEX_TWIN_EXAMPLES_QUICK=1 python examples/plan_and_track.py   # P1, P2 only (5 s)
"""
import os

import numpy as np

from flex_control.tracking import simulate_tracking
from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.plots import plot_simulation
from flex_planner import SECTION_F_TIMES, SECTION_F_WAYPOINTS, plan_tip_path

model = FlexArmModel(load_arm("thesis_example1"))               # gravity on
trajectory = plan_tip_path(model, SECTION_F_WAYPOINTS, SECTION_F_TIMES, sample_period=0.01)
t_final = 5.0 if os.environ.get("FLEX_TWIN_EXAMPLES_QUICK") else SECTION_F_TIMES[-1]
run = simulate_tracking(model, trajectory, h=25.0, a=5.0, t_final=t_final)

for name, t, waypoint in zip(("P1", "P2", "P3", "P4"), SECTION_F_TIMES, SECTION_F_WAYPOINTS):
    if t > run.t[-1] + 1e-9:
        break
    k = int(np.argmin(np.abs(run.t - t)))
    error = np.hypot(*(run.tip_positions[k] - waypoint))
    print(f"{name} at t = {t:4.1f} s: tip error = {1e3 * error:.3f} mm")
plot_simulation(run, "tracking.png", title="thesis Ch. V task under Eq. (95)")
print("wrote tracking.png")
