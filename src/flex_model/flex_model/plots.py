"""PNG plots of simulation results (matplotlib, headless)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def finish_figure(fig, ax, path, title: str = "") -> None:
    """Grid and legends on every axis, the title, a tight layout; save as PNG and close."""
    for a in np.ravel(ax):
        a.grid(True, alpha=0.3)
        if a.get_legend_handles_labels()[0]:
            a.legend(fontsize=8)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_simulation(result, path, title: str = "") -> None:
    """Joint angles, tip deflections, joint torques and the tip path in one figure (a
    spatial arm's run: joints, bending y, z and twist per flexible link, tip position)."""
    if result.spatial:
        return _plot_spatial(result, path, title)
    model = result.model
    names = [lk.name for lk in model.arm.links]
    fig, ax = plt.subplots(2, 2, figsize=(12, 8))
    t = result.t
    for i, jn in enumerate(model.arm.joint_names):
        ax[0, 0].plot(t, np.degrees(result.joint_angles[:, i]), label=jn)
        ax[1, 0].plot(t, result.tau[:, i], label=jn)
    for i, n in enumerate(names):
        ax[0, 1].plot(t, 1e3 * result.tip_deflections[:, i], label=n)
    tips = result.link_tips()
    for i, n in enumerate(names):
        ax[1, 1].plot(tips[:, i, 0], tips[:, i, 1], lw=0.8, label=f"{n} tip")
    # the deflected arm at a few instants
    for k in np.linspace(0, len(t) - 1, 5).astype(int):
        for line in model.shape(result.q[k], 15):
            ax[1, 1].plot(line[:, 0], line[:, 1], color="0.6", lw=0.8)
    ax[0, 0].set(xlabel="t [s]", ylabel="joint angle [deg]", title="joint angles (encoder)")
    ax[0, 1].set(xlabel="t [s]", ylabel="tip deflection [mm]", title="link tip deflections")
    ax[1, 0].set(xlabel="t [s]", ylabel="torque [N m]", title="joint torques")
    ax[1, 1].set(xlabel="x [m]", ylabel="y [m]", title="tip paths and deflected shapes")
    ax[1, 1].set_aspect("equal", adjustable="datalim")
    finish_figure(fig, ax, path, title)


def _plot_spatial(res, path, title: str) -> None:
    """Joint values, tip deflections (y, z) and twist per flexible link, and the tip path."""
    fig, ax = plt.subplots(2, 2, figsize=(11, 7))
    names = res.model.arm.joint_names
    for i, n in enumerate(names):
        ax[0, 0].plot(res.t, res.joint_angles[:, i], label=n)
    ax[0, 0].set(xlabel="t [s]", ylabel="joint value [rad or m]", title="joints")
    ax[0, 0].legend(fontsize=8)
    for name, d in res.link_deflections().items():
        ax[0, 1].plot(res.t, 1e3 * d["y"], label=f"{name} y")
        ax[0, 1].plot(res.t, 1e3 * d["z"], "--", label=f"{name} z")
        ax[1, 0].plot(res.t, 1e3 * d["twist"], label=f"{name}")
    ax[0, 1].set(xlabel="t [s]", ylabel="tip deflection [mm]", title="bending (beam y, z)")
    ax[1, 0].set(xlabel="t [s]", ylabel="tip twist [mrad]", title="torsion")
    for a in (ax[0, 1], ax[1, 0]):
        if a.lines:
            a.legend(fontsize=8)
    tip = res.tip_positions
    for k, lab in enumerate("xyz"):
        ax[1, 1].plot(res.t, 1e3 * (tip[:, k] - tip[0, k]), label=f"tip {lab} - {lab}(0)")
    ax[1, 1].set(xlabel="t [s]", ylabel="[mm]", title="tip position")
    ax[1, 1].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_modes(model, modal, path, count: int = 4, title: str = "") -> None:
    """The first ``count`` mode shapes drawn on the arm's undeformed configuration."""
    fig, ax = plt.subplots(1, 1, figsize=(9, 5))
    q0 = np.zeros(model.nq)
    for line in model.shape(q0, 2):
        ax.plot(line[:, 0], line[:, 1], "k--", lw=0.8)
    span = sum(lk.length for lk in model.arm.links)
    for k in range(min(count, modal.shapes_q.shape[1])):
        phi = modal.shapes_q[:, k]
        shp = np.vstack(model.shape(0.1 * span * phi / max(1e-12, np.max(np.abs(phi))), 31))
        ax.plot(shp[:, 0], shp[:, 1], label=f"mode {k + 1}: {modal.frequencies_hz[k]:.4g} Hz")
    ax.set(xlabel="x [m]", ylabel="y [m]", title=title or "mode shapes")
    finish_figure(fig, ax, path)
