"""A 6-joint URDF arm (UR5-like) whose forearm is a flexible aluminium tube.

The preset ur5_like_flexible_forearm is the URDF ur5_like_arm.urdf plus a side YAML that
makes the forearm an Euler-Bernoulli tube bending in two planes and twisting (wavelet
variables per plane and for torsion, docs/spatial.md). Prints the clamped-joint natural
frequencies (docs/spatial.md: 42.2, 43.5, 130.4, 214.7 Hz), the forearm's droop under
gravity at a horizontal pose, and a short run from that equilibrium, held by the static
joint torques, with the base turning at 1 rad/s: the compiled generalized-alpha loop.

    python examples/urdf_flexible_forearm.py              # 1 s
    FLEX_TWIN_EXAMPLES_QUICK=1 python examples/urdf_flexible_forearm.py   # 0.2 s
"""
import os

import numpy as np

from flex_model.spatial import SpatialArmModel, load_spatial_arm
from flex_model.spatial.analysis import natural_modes, static_equilibrium
from flex_model.spatial.integrate import simulate_fixed_compiled

model = SpatialArmModel(load_spatial_arm("ur5_like_flexible_forearm"))
print(f"{model.n_links} joints, {model.nq} coordinates")
frequencies = natural_modes(model).frequencies_hz[:4]           # clamped joints
print("natural frequencies (Hz):", ", ".join(f"{f:.1f}" for f in frequencies))

pose = np.radians([0.0, -90.0, 90.0, 0.0, 0.0, 0.0])        # upper arm up, forearm level
rest = static_equilibrium(model, pose)
forearm = rest.deflections["forearm_link"]
print(f"forearm tip under gravity: v = {1e3 * forearm['v']:.3f} mm, "
      f"w = {1e3 * forearm['w']:.3f} mm")

holding = model.gravity_force(rest.q)[model.off]              # N m: the static joint torques
v0 = np.zeros(model.nq)
v0[model.off[0]] = 1.0                                        # rad/s about the base axis
duration = 0.2 if os.environ.get("FLEX_TWIN_EXAMPLES_QUICK") else 1.0
run = simulate_fixed_compiled(model, rest.q, v0, 1e-3, int(round(duration / 1e-3)),
                              joint_torques=holding)                # 1 ms steps
print(f"after {run.t[-1]:.1f} s: base joint at {np.degrees(run.q[-1, model.off[0]]):.2f} deg, "
      f"tip at {np.round(model.tip_position(run.q[-1]), 4)} m, "
      f"{run.newton_iterations} Newton iterations")
