"""PNG plots of the control analyses (matplotlib, headless)."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from flex_model.plots import finish_figure  # noqa: E402


def plot_step(resp, path) -> None:
    """Joint and tip angle, tip deflection and joint torque of an Eq. (45) step."""
    fig, ax = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
    ax[0].plot(resp.t, np.degrees(resp.joint_angle), label="joint angle")
    ax[0].plot(resp.t, np.degrees(resp.tip_angle), label="tip angle atan2(y, x)")
    ax[0].set(ylabel="angle [deg]")
    ax[1].plot(resp.t, 1e3 * resp.tip_deflection)
    ax[1].set(ylabel="tip deflection w [mm]",
              title=f"residual oscillation {resp.tip_frequency_hz:.4g} Hz, "
                    f"amplitude {1e3 * resp.tip_amplitude_m:.4g} mm")
    ax[2].plot(resp.t, resp.torque)
    ax[2].set(xlabel="t [s]", ylabel="joint torque [N m]", yscale="symlog")
    finish_figure(fig, ax, path, f"{resp.arm}: Eq. (45) step "
                  f"{np.degrees(resp.start):.0f} -> {np.degrees(resp.end):.0f} deg")


def plot_design(result, path) -> None:
    """Designed h, a per joint and the frozen-time zeta_min, tau_max at the design points."""
    t = np.array([p.t for p in result.points])
    h = np.array([p.h for p in result.points])
    a = np.array([p.a for p in result.points])
    names = result.schedule.joint_names
    fig, ax = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    for j, n in enumerate(names):
        ax[0, 0].plot(t, h[:, j], "o-", label=n)
        ax[0, 1].plot(t, a[:, j], "o-", label=n)
    ax[1, 0].plot(t, [p.zeta_min for p in result.points], "o-")
    ax[1, 1].plot(t, [p.tau_max for p in result.points], "o-")
    ax[0, 0].set(ylabel="h [kg m^2]", yscale="log")
    ax[0, 1].set(ylabel="a [rad/s]", yscale="log")
    ax[1, 0].set(xlabel="t [s]", ylabel="zeta_min")
    ax[1, 1].set(xlabel="t [s]", ylabel="tau_max [s]")
    finish_figure(fig, ax, path, "gain-scheduled design of Eq. (95) (cyclic coordinate ascent)")


def plot_ltv(report, model, path, title: str = "") -> None:
    """LTV free responses (weighted norms; link-2 tip deflection at 80/90/100 %, cf. thesis
    Fig. 42) and impulse responses."""
    fig, ax = plt.subplots(3, 1, figsize=(10, 10), sharex=True)
    t = report.t
    ax[0].semilogy(t, np.maximum(report.free_norms, 1e-300), lw=0.8)
    ax[0].set(ylabel="|dx/m|_inf", title=f"{report.free_norms.shape[1]} free responses "
              f"(converged: {report.free_converged})")
    last = model.n_links - 1
    d = model.tip_deflection_index(last)
    X = report.free_responses
    if X is not None:
        k = int(np.argmax(np.max(np.abs(X[:, d, :]), axis=0)))
        for s in report.scales:
            ax[1].plot(t, 1e3 * s * X[:, d, k], label=f"{100 * s:.0f} % of the maximum")
        ax[1].set(ylabel=f"link {last + 1} tip deflection [mm]",
                  title=f"free response from initial condition #{k + 1}")
    for t0, H in zip(report.impulse_t0, report.impulse_responses):
        tt = t[t >= t0 - 1e-12][:len(H)]
        for i, name in enumerate(report.outputs):
            for j in range(H.shape[2]):
                ax[2].plot(tt, H[:, i, j], lw=0.8, label=f"{name} <- tau{j + 1}")
    ax[2].set(xlabel="t [s]", ylabel="impulse response (per N m s)",
              title=f"impulse response matrix (converged: {report.impulse_converged})")
    finish_figure(fig, ax, path, title or "LTV check of the closed loop")


def plot_frozen(points, path) -> None:
    """Frozen-time zeta_min, tau_max and gain margins along the trajectory."""
    t = [p.t for p in points]
    fig, ax = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    ax[0].plot(t, [p.zeta_min for p in points], "o-")
    ax[1].plot(t, [p.tau_max for p in points], "o-")
    ax[2].semilogy(t, [p.gain_margin_low for p in points], "o-", label="h may be divided by")
    ax[2].semilogy(t, [p.gain_margin_high for p in points], "s-",
                   label="h may be multiplied by")
    ax[0].set(ylabel="zeta_min")
    ax[1].set(ylabel="tau_max [s]")
    ax[2].set(xlabel="t [s]", ylabel="gain margin")
    finish_figure(fig, ax, path, "frozen-time eigenvalues of the closed loop")


def plot_tracking(run, trajectory, path) -> None:
    """Tip x and y of the nonlinear closed loop against the nominal tip (thesis Fig. 43)."""
    fig, ax = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    for k, name in enumerate(("x", "y")):
        ax[k].plot(run.t, run.tip_positions[:, k], label="closed loop")
        if trajectory.tip is not None:
            ax[k].plot(trajectory.t, trajectory.tip[:, k], "--", label="nominal")
        ax[k].set(ylabel=f"tip {name} [m]")
    ax[1].set(xlabel="t [s]")
    finish_figure(fig, ax, path, "nonlinear arm under Eq. (95) with the nominal feed-forward")
