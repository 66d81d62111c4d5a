"""PNG of a plan (matplotlib, headless): tip path vs waypoints, joint angles, deflections,
nominal torques (thesis Figs. 39-41)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from flex_model.plots import finish_figure  # noqa: E402


def plot_plan(model, result, waypoints, path, title: str = "") -> None:
    """Write the four panels of a :class:`flex_planner.planning.Plan` to ``path``."""
    traj = result.trajectory
    fig, ax = plt.subplots(2, 2, figsize=(12, 8))
    for pose in result.poses:  # the static deflected poses (thesis Fig. 39)
        for line in model.shape(pose.q, 21):
            ax[0, 0].plot(line[:, 0], line[:, 1], color="0.6", lw=0.9)
    ax[0, 0].plot(traj.tip[:, 0], traj.tip[:, 1], lw=1.2, label="nominal tip path")
    ax[0, 0].plot(waypoints[:, 0], waypoints[:, 1], "o", color="tab:red", label="waypoints")
    ax[0, 0].set(xlabel="x [m]", ylabel="y [m]", title="tip path and static poses")
    ax[0, 0].set_aspect("equal", adjustable="datalim")
    for i, name in enumerate(traj.joint_names):
        ax[0, 1].plot(traj.t, np.degrees(traj.positions[:, i]), label=name)
        ax[1, 1].plot(traj.t, traj.efforts[:, i], label=name)
    for i, lk in enumerate(model.arm.links):
        ax[1, 0].plot(traj.t, 1e3 * traj.q_nominal[:, model.tip_deflection_index(i)],
                      label=f"{lk.name} tip deflection")
    ax[0, 1].set(xlabel="t [s]", ylabel="joint angle [deg]", title="joint trajectory (splines)")
    ax[1, 0].set(xlabel="t [s]", ylabel="deflection [mm]", title="nominal deflections")
    ax[1, 1].set(xlabel="t [s]", ylabel="torque [N m]", title="admissible nominal torque")
    finish_figure(fig, ax, path, title)
