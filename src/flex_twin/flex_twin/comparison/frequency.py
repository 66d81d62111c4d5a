"""Frequency responses tip torque -> tip rotation (thesis Figs. 20-25, 28-29 style).

Each method is linearized about the straight horizontal arm with clamped joints (the
"very strong PD" of thesis Example 2 and the clamped joints of Example 4), gravity as an
input (thesis §II.6), and compared with the 20-variable wavelet model as reference: the
frequency range over which a model is reliable widens from zero frequency as the
variables per link increase (thesis Figs. 20-21, 28-29).
"""
from __future__ import annotations

import numpy as np

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.modes import linearize, natural_modes
from .methods import METHODS, with_discretization

#: the arms (VALIDATION.md C and D) and the variables per link compared
ARMS = {"C": "thesis_example2", "D": "thesis_example4"}
REFERENCE_VARS = 20


def tip_torque_response(model: FlexArmModel, freqs_hz: np.ndarray) -> np.ndarray:
    """Complex H(j w) from the tip torque (N m) to the tip rotation (rad), clamped joints."""
    lin = linearize(model, joints="clamped")
    b = lin.B[:, lin.input_names.index("tip/torque")]
    c = lin.C[lin.output_names.index("tip/angle")]
    n = lin.A.shape[0]
    out = np.empty(len(freqs_hz), dtype=complex)
    for k, f in enumerate(freqs_hz):
        out[k] = c @ np.linalg.solve(2j * np.pi * f * np.eye(n) - lin.A, b)
    return out


def reliable_up_to(freqs_hz, h, h_ref, tol_db: float = 1.0) -> float:
    """Highest frequency (Hz) below which |h| stays within ``tol_db`` of |h_ref|."""
    err = np.abs(20 * np.log10(np.abs(h) / np.abs(h_ref)))
    bad = np.flatnonzero(~(err <= tol_db))
    return float(freqs_hz[-1] if len(bad) == 0 else freqs_hz[max(bad[0] - 1, 0)])


def frequency_responses(section: str, vars_per_link=(2, 10), freqs_hz=None,
                        progress=None) -> dict:
    """Responses of every method on the section's arm, against the 20-variable wavelet
    reference (the lumped link: one variable per link, n masses)."""
    arm = load_arm(ARMS[section])
    if freqs_hz is None:
        freqs_hz = np.logspace(-1, np.log10(200.0), 500)
    ref_model = FlexArmModel(with_discretization(arm, "wavelet", REFERENCE_VARS))
    ref = tip_torque_response(ref_model, freqs_hz)
    ref_f = natural_modes(ref_model, joints="clamped").frequencies_hz[:3]
    curves = []
    for n in vars_per_link:
        for label, disc, opt in METHODS:
            if progress:
                progress(f"frequency response {section}: {label}, {n} variables per link")
            model = FlexArmModel(with_discretization(arm, disc, n, **opt))
            h = tip_torque_response(model, freqs_hz)
            f = natural_modes(model, joints="clamped").frequencies_hz[:3]
            curves.append({"method": label, "n_vars": n, "h": h,
                           "reliable_up_to_hz": reliable_up_to(freqs_hz, h, ref),
                           "static_gain_error_pct": float(100 * (abs(h[0]) / abs(ref[0]) - 1)),
                           "frequencies_hz": [float(x) for x in f]})
    return {"section": section, "arm": ARMS[section], "freqs_hz": freqs_hz, "reference": ref,
            "reference_frequencies_hz": [float(x) for x in ref_f], "curves": curves}


def plot_frequency_responses(result: dict, path) -> None:
    """Magnitude (dB) of every method against the reference, one panel per variable count."""
    from flex_model.plots import finish_figure, plt
    counts = sorted({c["n_vars"] for c in result["curves"]})
    fig, ax = plt.subplots(1, len(counts), figsize=(6.5 * len(counts), 4.8), squeeze=False)
    f = result["freqs_hz"]
    for a, n in zip(ax[0], counts):
        a.semilogx(f, 20 * np.log10(np.abs(result["reference"])), "k", lw=2.2,
                   label=f"wavelet {REFERENCE_VARS} (reference)")
        for c in result["curves"]:
            if c["n_vars"] == n:
                a.semilogx(f, 20 * np.log10(np.abs(c["h"])), lw=0.9, label=c["method"])
        a.set(xlabel="frequency [Hz]", ylabel="|tip rotation / tip torque| [dB rad/(N m)]",
              title=f"{n} variables per link")
    finish_figure(fig, ax, path, f"section {result['section']} ({result['arm']}): tip torque "
                  "-> tip rotation, clamped joints")
