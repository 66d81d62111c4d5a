"""Where a twin disagrees with the data: channels, time (moves, holds, velocity reversals,
high torque), frequency (residual spectra), residual whiteness and residual-input
correlation (issue 8, step 3).

- channel shares: the part of the weighted squared residual on each channel;
- time classes: the mean weighted squared residual on the samples of each class relative
  to the whole run (> 1: the class concentrates the error); holds are joint speeds below
  5 % of their peak, reversals the +-50 ms around a sign change of a joint speed, high
  torque the top 10 % of |tau|;
- frequency: the peak of the residual power spectrum (Welch) per channel;
- whiteness: lag-1 autocorrelation of the residuals (0 for white residuals), and the
  effective number of independent samples n (1 - rho) / (1 + rho) used by the
  identifiability check; residual-input correlation: the correlation of each joint's
  torque residual with its measured command.
"""
from __future__ import annotations

import numpy as np
from scipy.signal import welch

from .evaluation import channel_sigma, predict_channels, twin_arm


def lag1(r: np.ndarray) -> float:
    r = r - np.mean(r)
    d = float(np.dot(r, r))
    return float(np.dot(r[1:], r[:-1]) / d) if d > 0 else 0.0


def effective_samples(r: np.ndarray, n_channels: int) -> float:
    """n (1 - rho) / (1 + rho) summed over the concatenated channels."""
    total = 0.0
    for part in np.array_split(r, max(n_channels, 1)):
        rho = min(max(lag1(part), 0.0), 0.999)
        total += len(part) * (1 - rho) / (1 + rho)
    return max(total, 1.0)


def time_classes(rec) -> dict:
    """Boolean masks of the time classes of a recording."""
    v = rec.stack("v")
    tau = rec.stack("tau")
    speed = np.max(np.abs(v) / np.maximum(np.max(np.abs(v), axis=0), 1e-9), axis=1)
    classes = {"hold": speed < 0.05, "move": speed >= 0.05}
    rev = np.zeros(len(rec.t), bool)
    half = max(1, int(round(0.05 / rec.dt)))
    for j in range(v.shape[1]):
        for k in np.flatnonzero(np.diff(np.sign(v[:, j])) != 0):
            rev[max(0, k - half):k + half] = True
    classes["reversal"] = rev
    mag = np.max(np.abs(tau) / np.maximum(np.max(np.abs(tau), axis=0), 1e-9), axis=1)
    classes["high_torque"] = mag >= np.quantile(mag, 0.9)
    return classes


def localise(ctx, scales, effects) -> dict:
    """The localisation of the residuals of a twin on the context's recording."""
    rec = ctx.rec
    pred = predict_channels(ctx, twin_arm(ctx, scales, effects))
    n = len(pred.t)
    res = {c: (rec.channels[c][:n] - pred.channels[c]) for c in rec.residual_channels}
    w2 = {c: (res[c] / channel_sigma(ctx, c, 0, n)) ** 2 for c in res}
    total = sum(float(np.sum(v)) for v in w2.values()) or 1.0
    shares = {c: float(np.sum(v)) / total for c, v in w2.items()}
    per_sample = np.mean(np.column_stack(list(w2.values())), axis=1)
    mean_all = float(np.mean(per_sample)) or 1.0
    tc = {k: float(np.mean(per_sample[m[:n]]) / mean_all) if np.any(m[:n]) else None
          for k, m in time_classes(rec).items()}
    fs = 1.0 / rec.dt
    peaks = {}
    for c in res:
        f, p = welch(res[c], fs=fs, nperseg=min(len(res[c]), 1024))
        peaks[c] = float(f[1:][np.argmax(p[1:])])
    worst = max(shares, key=shares.get)
    corr = {}
    for i in range(rec.n_joints):
        c = f"tau{i + 1}"
        if c in res and np.std(res[c]) > 0:
            corr[c] = float(np.corrcoef(res[c], rec.channels[c][:n])[0, 1])
    return {"channel_shares": shares, "worst_channel": worst, "time_classes": tc,
            "spectral_peak_hz": peaks, "lag1_autocorrelation": {c: lag1(r)
                                                                for c, r in res.items()},
            "residual_input_correlation": corr}
