"""UC Merced rotary flexible link, the 60 s 1 kHz record beside the 5 s one (issue 22):
the link's response to the measured hub motion, alpha / theta.

The 60 s record has no documented input: ``theta`` row 2 is an undocumented channel
(+-140, broadband; PROVENANCE.md), so neither the closed loop (no reference, no logged
gains) nor the open loop (no voltage) can be replayed. What is defined without the input:
the link is driven only through the hub, so alpha / theta = H_w(s) / (L H_theta(s)) of the
twin (tip deflection w over L and hub angle, both per hub torque; any controller acting
through the hub torque cancels) - the clamped-hub link mode is its peak (thesis Ch. II: the
zero of the hub's transfer). Measured: Welch estimate S_theta,alpha / S_theta,theta with
coherence, fitted by one link mode; twin: its linearization (``flex_model.modes.linearize``,
hub hinged). (Driving the twin's alpha / theta with the measured theta is no replay either:
the twin's link mode is undamped and amplifies whatever theta holds at its frequency.)

``python -m flex_twin.real_arms.ucmerced_long [DATA]`` prints the figures.
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import scipy.signal as sg

from flex_model.dynamics import FlexArmModel
from flex_model.modes import linearize
from .quanser_data import UCMERCED, load_mat_file


def read_60s(root) -> dict:
    """t (s), theta (rad, row 3), alpha (rad, row 2 of alpha), the undocumented row 2."""
    d = Path(root) / UCMERCED if (Path(root) / UCMERCED).is_dir() else Path(root)
    a = load_mat_file(d / "alpha_exp_1k_60s_p1_use.mat", "alpha")
    th = load_mat_file(d / "theta_exp_1k_60s_p1_use.mat", "theta")
    if not np.allclose(a[0], th[0]):
        raise ValueError(f"{d}: alpha and theta records do not share their time")
    return {"name": "ucmerced_60s", "t": th[0] - th[0, 0], "theta": th[2], "alpha": a[1],
            "unknown": th[1]}


def read_5s(root) -> dict:
    """The 5 s record (degrees -> rad)."""
    d = Path(root) / UCMERCED if (Path(root) / UCMERCED).is_dir() else Path(root)
    a = load_mat_file(d / "data_alpha.mat", "data_alpha")
    th = load_mat_file(d / "data_theta.mat", "data_theta")
    return {"name": "ucmerced_5s", "t": th[:, 0] - th[0, 0], "theta": np.radians(th[:, 2]),
            "alpha": np.radians(a[:, 1])}


def alpha_theta_frf(rec: dict, nperseg: int):
    """(f, alpha / theta, coherence): Welch H1 estimate over segments of nperseg."""
    fs = 1.0 / float(rec["t"][1] - rec["t"][0])
    f, pxy = sg.csd(rec["theta"], rec["alpha"], fs, nperseg=nperseg)
    _, pxx = sg.welch(rec["theta"], fs, nperseg=nperseg)
    _, coh = sg.coherence(rec["theta"], rec["alpha"], fs, nperseg=nperseg)
    return f, pxy / np.where(pxx > 0, pxx, np.inf), coh


def twin_alpha_theta(model: FlexArmModel, f) -> np.ndarray:
    """alpha / theta of the twin: (tip deflection / L) over the hub angle, per hub torque."""
    lin = linearize(model, joints="hinged")
    i_th = lin.output_names.index(f"{model.arm.joint_names[0]}/angle")
    i_w = lin.output_names.index(f"{model.arm.links[0].name}/tip_deflection")
    L = model.arm.links[0].length
    w, V = np.linalg.eig(lin.A)
    b = np.linalg.solve(V, lin.B[:, 0])
    s = 2j * np.pi * np.asarray(f, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        resp = (1.0 / (s[:, None] - w[None, :])) * b[None, :]      # modal, (nf, n)
    x = resp @ V.T
    h_th, h_w = x @ lin.C[i_th], x @ lin.C[i_w]
    with np.errstate(divide="ignore", invalid="ignore"):
        out = h_w / (L * h_th)
    out[~np.isfinite(out)] = 0.0
    return out


def fit_link_mode(f, h, coh, band=(0.3, 10.0), min_coherence: float = 0.5) -> dict:
    """One link mode seen from the hub: alpha / theta = g s^2 / (s^2 + 2 zeta w s + w^2)
    (a clamped-hub mode of frequency w driven by the hub's acceleration), least squares of
    the complex ratio on the bins of coherence >= min_coherence, weighted by coherence."""
    from scipy.optimize import least_squares
    ok = (f >= band[0]) & (f <= band[1]) & (coh >= min_coherence)
    fk, hk, wk = f[ok], h[ok], np.sqrt(coh[ok])
    s = 2j * np.pi * fk

    def model(x):
        g, fn, z = x
        w = 2 * np.pi * fn
        return -g * s * s / (s * s + 2 * z * w * s + w * w)

    def res(x):
        r = (model(x) - hk) * wk / (1.0 + np.abs(hk))
        return np.concatenate([r.real, r.imag])

    best = None
    for f0 in np.geomspace(band[0] * 1.5, band[1] / 1.5, 12):
        r = least_squares(res, [1.0, f0, 0.05], bounds=([0, band[0], 1e-4], [10, band[1], 1]))
        if best is None or r.cost < best.cost:
            best = r
    g, fn, z = best.x
    return {"frequency_hz": float(fn), "damping_ratio": float(z), "high_level": float(g),
            "bins": int(ok.sum())}


def with_ei_scale(arm, scale: float):
    lk = arm.links[0]
    lk = dataclasses.replace(lk, segments=tuple(sg_.scaled(stiffness=scale)
                                                for sg_ in lk.segments))
    return dataclasses.replace(arm, links=(lk,) + tuple(arm.links[1:]))


def study(root, arm) -> dict:
    """Per record: the link mode of the measured alpha / theta (frequency, damping ratio,
    high-frequency level g) against the twin's (the same fit on its ratio, undamped), and
    the EI scale that puts the twin's mode on the record's (clamped frequency ~ sqrt(EI))."""
    out = {}
    model = FlexArmModel(arm)
    for rec, nper in ((read_5s(root), 1250), (read_60s(root), 16384)):
        f, h, coh = alpha_theta_frf(rec, nper)
        meas = fit_link_mode(f, h, coh)
        fine = np.linspace(0.3, 10.0, 2000)
        ht = twin_alpha_theta(model, fine)
        twin = {"frequency_hz": float(fine[np.argmax(np.abs(ht))]),
                "high_level": float(np.median(np.abs(ht[(fine >= 5) & (fine <= 10)])))}
        row = {"measured": meas, "twin": twin,
               "frequency_error_pct": 100 * (twin["frequency_hz"] / meas["frequency_hz"] - 1),
               "ei_scale_for_mode": (meas["frequency_hz"] / twin["frequency_hz"]) ** 2,
               "coherence_median_0.3_10Hz": float(np.median(coh[(f > 0.3) & (f < 10)])),
               "duration_s": float(rec["t"][-1])}
        if "unknown" in rec:
            _, cu = sg.coherence(rec["unknown"], rec["theta"], 1000.0, nperseg=nper)
            row["unknown_theta_coherence_median"] = float(np.median(cu[(f > 0.3) & (f < 10)]))
        out[rec["name"]] = row
    return out


def main(argv=None) -> int:
    import json
    from .quanser_twin import nominal_arm_for
    argv = sys.argv[1:] if argv is None else argv
    root = Path(argv[0]) if argv else Path.cwd().parent / "shared" / "data" / "real"
    print(json.dumps(study(root, nominal_arm_for("ucmerced", "flexible")), indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
