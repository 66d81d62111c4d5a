"""The steel cantilever on a shaker (USC data set, Chowdhury et al., CC BY-SA 4.0): data
reader, force-to-acceleration FRF, peak identification, and the Euler-Bernoulli model.

Data (``../shared/data/real/cantilever_beam_shaker_usc_chowdhury``, see its PROVENANCE.md):
LabVIEW ``.lvm`` text files, columns time (s), shaker drive voltage (V), load-cell force
(lbf), acceleration near the free edge (g), 3200 Hz. The modes reported by the source
(impulse test, not in the stored data): 6.62, 41.4, 117.5 Hz.

Model: the clamped-free Euler-Bernoulli beam, f_n = (beta_n L)^2 / (2 pi L^2)
sqrt(EI / m) with cos(beta L) cosh(beta L) = -1 (thesis Eq. 31 with a clamped root), and the
wavelet model of flex_model (preset ``usc_cantilever``).
"""
from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.signal as sig
from scipy.optimize import brentq

from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from flex_model.plots import finish_figure, plt
from .modal_diagnosis import (ModalSetup, change_text, diagnose, fmt_value, link_totals,
                              modal_frequencies, say_for, shift_pattern,
                              standard_candidates, tolerance_text)

LBF = 4.4482216152605          # N per lbf
G0 = 9.80665                   # m/s^2 per g
DATA_SET = "cantilever_beam_shaker_usc_chowdhury"
#: ../shared beside the checkout
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "real"
#: modal frequencies reported by the source (impulse test, modal_analysis/README.md)
REPORTED_MODES_HZ = (6.62, 41.4, 117.5)
#: frequency bands searched for modes 1-3 (around the reported values)
MODE_BANDS_HZ = ((3.0, 12.0), (30.0, 55.0), (95.0, 140.0))


@dataclass
class ShakerRecord:
    """One test: time (s), drive voltage (V), force (N), acceleration (m/s^2)."""

    name: str
    t: np.ndarray
    voltage: np.ndarray
    force: np.ndarray
    acceleration: np.ndarray

    @property
    def rate(self) -> float:
        return float(1.0 / np.median(np.diff(self.t)))


def read_lvm(path) -> ShakerRecord:
    """Read a LabVIEW .lvm file of this data set (data after the ``X_Value`` line)."""
    path = Path(path)
    lines = path.read_text().splitlines()
    try:
        start = next(i for i, ln in enumerate(lines) if ln.startswith("X_Value")) + 1
    except StopIteration:
        raise ValueError(f"{path}: no 'X_Value' header line; expected a LabVIEW .lvm file "
                         "with columns time, voltage, force, acceleration") from None
    data = np.loadtxt(lines[start:], dtype=float)
    if data.ndim != 2 or data.shape[1] < 4:
        raise ValueError(f"{path}: got {data.shape} data; expected 4 columns (time, voltage, "
                         "force [lbf], acceleration [g])")
    t, v, f, a = data[:, :4].T
    return ShakerRecord(path.stem, t, v, f * LBF, a * G0)


def read_data_set(directory) -> list[ShakerRecord]:
    """All ``data_set_*.lvm`` records of the data set directory, in name order."""
    directory = Path(directory)
    files = sorted(directory.glob("data_set_*.lvm"))
    if not files:
        raise FileNotFoundError(f"{directory}: no data_set_*.lvm files (the shaker data set "
                                f"{DATA_SET}, see its PROVENANCE.md)")
    return [read_lvm(p) for p in files]


@dataclass
class FRF:
    """H1 estimate H = S_fa / S_ff ((m/s^2)/N) and the coherence, per frequency (Hz)."""

    frequency: np.ndarray
    H: np.ndarray
    coherence: np.ndarray


def frf_h1(record: ShakerRecord, nperseg: int = 8192) -> FRF:
    """Force-to-acceleration FRF by Welch averaging (Hann windows, 50 % overlap, linear
    detrend: the load cell has a static offset)."""
    fs = record.rate
    kw = dict(fs=fs, nperseg=nperseg, detrend="linear")
    fr, sff = sig.welch(record.force, **kw)
    _, saa = sig.welch(record.acceleration, **kw)
    _, sfa = sig.csd(record.force, record.acceleration, **kw)
    with np.errstate(divide="ignore", invalid="ignore"):
        coh = np.abs(sfa) ** 2 / (sff * saa)
    return FRF(fr, sfa / sff, np.nan_to_num(coh))


@dataclass
class IdentifiedPeak:
    """A resonance picked in a band: frequency, half-power damping ratio, or why not."""

    band: tuple
    identified: bool
    frequency_hz: float = float("nan")
    damping_ratio: float = float("nan")
    coherence: float = float("nan")
    reason: str = ""

    def as_dict(self) -> dict:
        return {"band_hz": list(self.band), "identified": self.identified,
                "frequency_hz": self.frequency_hz, "damping_ratio": self.damping_ratio,
                "coherence": self.coherence, "reason": self.reason}


def pick_peak(frf: FRF, band, min_coherence: float = 0.8, min_bins: int = 3,
              band_coherence: float = 0.5) -> IdentifiedPeak:
    """The largest |H| in ``band`` among coherent bins; a resonance only if it is interior
    and its half-power band (|H| >= peak / sqrt 2, interpolated) spans ``min_bins`` bins,
    with coherence >= ``band_coherence`` (the bias of Welch averaging lowers the coherence
    at a sharp resonance). Frequency and damping ratio then come from a single-mode fit
    (:func:`fit_sdof`) to the coherent bins within two half-power widths of the peak."""
    f, mag, coh = frf.frequency, np.abs(frf.H), frf.coherence
    inside = np.flatnonzero((f >= band[0]) & (f <= band[1]))
    good = inside[coh[inside] >= min_coherence]
    if len(good) == 0:
        return IdentifiedPeak(tuple(band), False, coherence=float(coh[inside].max()),
                              reason=f"coherence below {min_coherence} in the whole band "
                                     "(no broadband excitation there)")
    k = good[np.argmax(mag[good])]
    if k in (inside[0], inside[-1]):
        return IdentifiedPeak(tuple(band), False, coherence=float(coh[k]),
                              reason=f"largest coherent |H| at the band edge ({f[k]:.1f} Hz)")
    half = mag[k] / np.sqrt(2.0)
    lo = k
    while lo > inside[0] and mag[lo - 1] >= half:
        lo -= 1
    hi = k
    while hi < inside[-1] and mag[hi + 1] >= half:
        hi += 1
    if lo == inside[0] or hi == inside[-1] or np.any(coh[lo - 1:hi + 2] < band_coherence):
        return IdentifiedPeak(tuple(band), False, coherence=float(coh[k]),
                              reason=f"half-power band of the {f[k]:.1f} Hz peak not coherent "
                                     "or not inside the band")
    fa = np.interp(half, [mag[lo - 1], mag[lo]], [f[lo - 1], f[lo]])
    fb = np.interp(half, [mag[hi + 1], mag[hi]], [f[hi + 1], f[hi]])
    if (fb - fa) < min_bins * (f[1] - f[0]):
        return IdentifiedPeak(tuple(band), False, coherence=float(coh[k]),
                              reason=f"{f[k]:.1f} Hz peak narrower than {min_bins} bins "
                                     "(a forced line, not a resonance)")
    width = max(fb - fa, 3 * (f[1] - f[0]))
    near = inside[(np.abs(f[inside] - f[k]) <= 2.0 * width) & (coh[inside] >= min_coherence)]
    fn, zeta = fit_sdof(f[near], frf.H[near], coh[near])
    if not (band[0] < fn < band[1] and 0 < zeta < 0.5):
        return IdentifiedPeak(tuple(band), False, coherence=float(coh[k]),
                              reason=f"no single-mode fit near the {f[k]:.1f} Hz peak")
    return IdentifiedPeak(tuple(band), True, fn, zeta, float(coh[k]))


def fit_sdof(frequency_hz, H, weight=None) -> tuple[float, float]:
    """Natural frequency (Hz) and damping ratio of one mode fitted to accelerance samples
    by Levy's linearized rational fraction: H (w_n^2 + 2 zeta w_n i w - w^2) =
    b0 + b1 i w + b2 (i w)^2, least squares in the real and imaginary parts."""
    w = 2 * np.pi * np.asarray(frequency_hz, float)
    H = np.asarray(H, complex)
    wt = np.ones_like(w) if weight is None else np.sqrt(np.asarray(weight, float))
    iw = 1j * w
    # unknowns a0 = w_n^2, a1 = 2 zeta w_n, b0, b1, b2:  H a0 + H iw a1 - b(iw) = H w^2
    A = np.column_stack([H, H * iw, -np.ones_like(H), -iw, -iw ** 2]) * wt[:, None]
    rhs = H * w ** 2 * wt
    sol = np.linalg.lstsq(np.vstack([A.real, A.imag]), np.concatenate([rhs.real, rhs.imag]),
                          rcond=None)[0]
    a0, a1 = sol[0], sol[1]
    if a0 <= 0:
        return float("nan"), float("nan")
    wn = np.sqrt(a0)
    return float(wn / (2 * np.pi)), float(a1 / (2 * wn))


def clamped_free_roots(count: int) -> np.ndarray:
    """beta_n L of the clamped-free beam: cos x cosh x = -1 (1.8751, 4.6941, 7.8548, ...)."""
    g = lambda x: np.cos(x) * np.cosh(x) + 1.0  # noqa: E731
    return np.array([brentq(g, (n - 0.5) * np.pi - 1.0, (n - 0.5) * np.pi + 1.0, xtol=1e-14)
                     for n in range(1, count + 1)])


def euler_bernoulli_clamped_free_hz(EI: float, m: float, length: float,
                                    count: int = 3) -> np.ndarray:
    """f_n = (beta_n L)^2 / (2 pi L^2) sqrt(EI / m) (Hz) of a uniform cantilever."""
    return clamped_free_roots(count) ** 2 / (2 * np.pi * length ** 2) * np.sqrt(EI / m)


def tip_accelerance(arm, frequency_hz, damping=0.01, count: int = 6) -> np.ndarray:
    """Model FRF tip force -> tip acceleration ((m/s^2)/N) of the clamped arm, modal sum
    H = sum_n -omega^2 phi_n(L)^2 / (omega_n^2 - omega^2 + 2 i zeta omega_n omega) with
    mass-normalized modes (an undamped model with modal damping ``damping``)."""
    model = FlexArmModel(arm)
    res = natural_modes(model, joints="clamped")
    tip = res.shapes_q[model.tip_deflection_index(model.n_links - 1), :count]
    wn = res.omega[:count]
    w = 2 * np.pi * np.asarray(frequency_hz, float)[:, None]
    zeta = np.broadcast_to(np.asarray(damping, float), wn.shape)
    return np.sum(-w ** 2 * tip ** 2 / (wn ** 2 - w ** 2 + 2j * zeta * wn * w), axis=1)


def identify_modes(record: ShakerRecord, bands=MODE_BANDS_HZ, npersegs=(4096, 8192, 16384),
                   min_coherence: float = 0.8) -> list[IdentifiedPeak]:
    """:func:`pick_peak` in each band at several Welch resolutions; a resonance keeps its
    half-power width as the resolution refines, a forced (harmonic) line narrows with it.
    Identified only if at least two resolutions resolve the peak, with frequencies within
    one coarse bin and damping ratios within 30 % of each other; the finest estimate is
    returned."""
    frfs = [frf_h1(record, n) for n in npersegs]
    return [_consistent([pick_peak(frf, band, min_coherence) for frf in frfs], band,
                        record.rate / npersegs[0]) for band in bands]


def _consistent(peaks, band, coarse_bin: float) -> IdentifiedPeak:
    """The finest of the resolutions' peaks if at least two agree (see identify_modes)."""
    found = [p for p in peaks if p.identified]
    if len(found) < 2:
        last = next(p for p in reversed(peaks) if not p.identified)
        return IdentifiedPeak(tuple(band), False, coherence=peaks[-1].coherence,
                              reason=f"not resolved at two resolutions ({last.reason})")
    f = np.array([p.frequency_hz for p in found])
    z = np.array([p.damping_ratio for p in found])
    if np.ptp(f) > coarse_bin or z.max() > 1.3 * z.min():
        return IdentifiedPeak(tuple(band), False, coherence=found[-1].coherence,
                              reason=f"peak near {f[-1]:.1f} Hz changes with the resolution "
                                     f"(zeta {z.max():.4f} -> {z.min():.4f}): a forced line, "
                                     "not a resonance")
    return found[-1]


@dataclass
class CantileverStudy:
    """Model vs measured modes of the cantilever, the identification from the shaker
    records, the single-effect diagnosis and each effect's signature."""

    arm: object
    closed_form_hz: np.ndarray
    model_hz: np.ndarray
    measured_hz: np.ndarray
    frfs: dict                      # record name -> FRF (nperseg 8192)
    identified: dict                # record name -> [IdentifiedPeak per band]
    diagnosis: object               # modal_diagnosis.Diagnosis
    signatures: dict                # effect -> EffectFit sized to move mode 1 to measured
    first_order: dict               # effect -> EffectFit for a 1 % drop of mode 1 (root
    #                                 compliance and tip mass: uniform at first order)

    @property
    def ratio(self) -> np.ndarray:
        return self.model_hz[:len(self.measured_hz)] / self.measured_hz

    def as_dict(self) -> dict:
        def shifts(fits):
            return {k: (f.predicted_hz / self.model_hz[:len(f.predicted_hz)] - 1.0).tolist()
                    for k, f in fits.items()}
        return {"arm": self.arm.name, "closed_form_hz": self.closed_form_hz.tolist(),
                "model_hz": self.model_hz.tolist(), "measured_hz": self.measured_hz.tolist(),
                "model_over_measured": self.ratio.tolist(),
                "identified": {k: [p.as_dict() for p in v] for k, v in self.identified.items()},
                "diagnosis": self.diagnosis.as_dict(),
                "signature_mode1_to_measured": shifts(self.signatures),
                "signature_first_order_1pct": shifts(self.first_order)}


def cantilever_study(arm, records=(), measured_hz=REPORTED_MODES_HZ, *, sigma: float = 0.005,
                     progress=None) -> CantileverStudy:
    """Compare the clamped arm with the measured modes and diagnose the difference.

    ``records``: shaker records to identify the modes from (may be empty); ``sigma``:
    relative uncertainty of each measured frequency; ``progress(text)``: optional callback.
    """
    say = progress or (lambda text: None)
    measured = np.asarray(measured_hz, float)
    n = len(measured)
    length, mass, ei = link_totals(arm)
    closed = euler_bernoulli_clamped_free_hz(ei, mass / length, length, n + 2)
    setup = ModalSetup(arm)
    model_hz = modal_frequencies(setup, n + 2)
    frfs, identified = {}, {}
    for rec in records:
        say(f"identifying {rec.name}")
        frfs[rec.name] = frf_h1(rec)
        identified[rec.name] = identify_modes(rec, MODE_BANDS_HZ[:n])
    cands = standard_candidates(setup)
    say(f"fitting {len(cands)} single effects to {n} frequencies")
    diag = diagnose(setup, cands, measured, sigma=sigma, count=n + 2)
    say("signatures of the effects")
    sigs = {c.name: shift_pattern(setup, c, measured[0], count=n) for c in cands}
    first = {c.name: shift_pattern(setup, c, 0.99 * model_hz[0], count=n) for c in cands
             if c.name in ("root compliance", "tip mass")}
    return CantileverStudy(arm, closed, model_hz, measured, frfs, identified, diag, sigs,
                           first)


# ----------------------------------------------------------------------------- command
def cmd_cantilever(args) -> int:
    from flex_model.arm import load_arm
    from flex_model.command import run_dir
    say = say_for(args)
    measured = np.asarray(args.measured_hz, float)
    if not (np.all(measured > 0) and np.all(np.diff(measured) > 0)):
        raise ValueError(f"--measured-hz: got {args.measured_hz}; expected increasing "
                         "frequencies > 0 Hz (modes 1, 2, ...)")
    if not args.sigma > 0:
        raise ValueError(f"--sigma: got {args.sigma}; expected a relative uncertainty > 0")
    arm = load_arm(args.arm, args.vars)
    data = Path(args.data) if args.data else SHARED_DATA / DATA_SET
    if args.data and not data.is_dir():
        raise FileNotFoundError(f"--data: {data} is not a directory")
    records = read_data_set(data) if data.is_dir() else []
    if not records:
        say(f"no shaker data at {data}: identification skipped")
    study = cantilever_study(arm, records, measured, sigma=args.sigma, progress=say)
    out = run_dir(args.out, "cantilever")
    result = study.as_dict()
    result["data"] = str(data) if records else None
    plot_cantilever(study, out / "cantilever.png")
    (out / "report.md").write_text(cantilever_report(study, data if records else None))
    (out / "result.json").write_text(json.dumps(result, indent=1))
    if args.json:
        print(json.dumps(result))
    else:
        print((out / "report.md").read_text())
        print(f"written: {out}/report.md, cantilever.png, result.json")
    return 0


def cantilever_report(st, data) -> str:
    d = st.diagnosis
    n = len(st.measured_hz)
    lines = [f"# Cantilever: Euler-Bernoulli model of `{st.arm.name}` against measured modes",
             "", f"{st.arm.description}", "",
             "| mode | closed form (Hz) | flex_model (Hz) | measured (Hz) | model / measured |",
             "|---|---|---|---|---|"]
    for k in range(n):
        lines.append(f"| {k + 1} | {st.closed_form_hz[k]:.4f} | {st.model_hz[k]:.4f} | "
                     f"{st.measured_hz[k]:.4g} | {st.ratio[k]:.4f} |")
    lines += ["", "## Modes identified from the shaker records (H1 force -> acceleration)", ""]
    if data is None:
        lines.append("No shaker data found: identification skipped.")
    for name, peaks in st.identified.items():
        for k, p in enumerate(peaks):
            txt = (f"{p.frequency_hz:.3f} Hz, zeta {p.damping_ratio:.4f}" if p.identified
                   else f"not identified: {p.reason}")
            lines.append(f"- {name}, mode {k + 1} ({p.band[0]:g}-{p.band[1]:g} Hz): {txt}")
    if st.identified and not any(p.identified for v in st.identified.values() for p in v):
        lines += ["", "No record holds a resolved, coherent resonance: the shaker drove sines "
                  "at 100, 120 and 150 Hz (PROVENANCE.md), the broadband content is weak, and "
                  "the coherent |H1| has no peak at the reported modes (it is also 10-100 "
                  "times below the model's tip accelerance: the force does not enter as a "
                  "tip force into a free cantilever, the shaker position is not documented). "
                  "The diagnosis therefore uses the reported frequencies (impulse test)."]
    lines += ["", "## Single-effect diagnosis (each effect fitted alone, bounded least squares)",
              "", f"Relative uncertainty of each measured frequency: {d.sigma:.2%}; "
              "chi^2 with 2 degrees of freedom; one-sigma intervals.", "",
              "| rank | effect | class | fitted value | interval | change | within tolerance "
              "| predicted (Hz) | rms residual | chi^2 |", "|---" * 10 + "|"]
    for k, f in enumerate(d.fits):
        c = f.candidates[0]
        lines.append(f"| {k + 1} | {c.name} ({c.parameter}) | {d.class_of(k) + 1} | "
                     f"{fmt_value(f.values[0], c.unit)} | {fmt_value(f.intervals[0, 0])} - "
                     f"{fmt_value(f.intervals[0, 1])} | {change_text(f)} | {tolerance_text(f)} | "
                     f"{', '.join(f'{x:.2f}' for x in f.predicted_hz[:n])} | "
                     f"{100 * f.rms_relative:.2f} % | {f.chi2:.2f} |")
    lines += ["", "Signatures: relative shift of modes 1-3 when the effect alone moves mode 1 to "
              "the measured value (and, first order, when it lowers mode 1 by 1 %):", ""]
    for name, f in st.signatures.items():
        s = 100 * (f.predicted_hz / st.model_hz[:n] - 1)
        first = st.first_order.get(name)
        s1 = "" if first is None else " (first order: " + ", ".join(
            f"{x:+.3f}" for x in 100 * (first.predicted_hz / st.model_hz[:n] - 1)) + " %)"
        lines.append(f"- {name}: {', '.join(f'{x:+.2f}' for x in s)} %{s1}")
    lines += ["", "## Verdict", ""] + verdict(st)
    return "\n".join(lines) + "\n"


def verdict(st) -> list:
    d = st.diagnosis
    best = d.fits[0]
    cls = [d.fits[k] for k in d.classes[0]]
    names = " and ".join(f.name for f in cls)
    out = [f"- The model is {100 * (np.mean(st.ratio) - 1):.1f} % high on average "
           f"({', '.join(f'{100 * (r - 1):+.1f}' for r in st.ratio)} % per mode)."]
    if len(cls) > 1:
        out.append(f"- Best explained by **{names}**: one equivalence class. They move every "
                   "mode by the same factor (f ~ sqrt(EI / m)), so natural frequencies alone "
                   "can never tell them apart; they fix only EI / m, here "
                   f"{best.values[0] if 'stiffness' in best.name else 1 / best.values[0]:.4f} "
                   "times nominal (a static stiffness test or a weighing separates them).")
    else:
        out.append(f"- Best explained by **{best.name}**.")
    if len(cls) > 1:
        ratio = best.values[0] if "stiffness" in best.name else 1 / best.values[0]
        arm = st.arm
        tol = float(np.hypot(arm.tolerance("E"), 3 * arm.tolerance("section")))
        out.append(f"- The same factor, f ~ h sqrt(E / rho) / L^2 for a rectangular section, "
                   f"is a thickness x{np.sqrt(ratio):.3f}, an E / rho x{ratio:.3f} or a free "
                   f"length x{ratio ** -0.25:.3f}. EI / m {100 * (ratio - 1):+.1f} % is "
                   f"{'outside' if abs(ratio - 1) > tol else 'within'} the manufacturing "
                   f"tolerances (E ±{100 * arm.tolerance('E'):.0f} %, section "
                   f"±{100 * arm.tolerance('section'):.0f} % so EI ±{100 * tol:.1f} %, rho "
                   f"±{100 * arm.tolerance('rho'):.0f} %): the assumed steel data (E = 200 GPa, "
                   "rho = 7850 kg/m^3 are not given by the source) or the dimensions are "
                   "suspect, not a single small defect.")
    rc = st.signatures.get("root compliance")
    if rc is not None:
        s = 100 * (rc.predicted_hz / st.model_hz[:len(rc.predicted_hz)] - 1)
        s1 = 100 * (st.first_order["root compliance"].predicted_hz
                    / st.model_hz[:len(rc.predicted_hz)] - 1)
        out.append(f"- Root compliance sized to lower mode 1 to the measured value lowers the "
                   f"modes by {', '.join(f'{x:.1f}' for x in s)} %: mode 1 more than modes "
                   "2-3, but only at second order. To first order a root spring shifts all "
                   "modes of a uniform cantilever alike (its share of the strain energy, "
                   "4 EI / (kp L), is the same for every mode, as is a tip mass's share of "
                   f"the kinetic energy): a 1 % drop of mode 1 gives "
                   f"{', '.join(f'{x:.3f}' for x in s1)} %.")
    tip = next((f for f in d.fits if f.name == "tip mass"), None)
    if tip is not None:
        beam = link_totals(st.arm)[1]
        out.append(f"- A tip mass alone would need {1000 * tip.values[0]:.0f} g "
                   f"({100 * tip.values[0] / beam:.1f} % of the {beam:.3f} kg beam); an "
                   "accelerometer of a few grams (e.g. 6 g) lowers every mode by only about "
                   f"{200 * 0.006 / beam:.1f} % (first order, -2 M / (m L)).")
    if d.pair is not None and d.pair_p_value is not None:
        verdict = "not justified" if d.pair_p_value > 0.05 else "justified"
        out.append(f"- Parsimony: adding a second effect ({d.pair.name}) lowers chi^2 from "
                   f"{best.chi2:.2f} to {d.pair.chi2:.2f}; F-test p = {d.pair_p_value:.2f}: "
                   f"{verdict}.")
    if len(d.classes) > 1:
        f = d.fits[d.classes[1][0]]
        k = int(np.argmax(np.abs(f.residual - best.residual)))
        out.append(f"- Next class: {' and '.join(d.fits[j].name for j in d.classes[1])} "
                   f"(rms residual {100 * f.rms_relative:.2f} % against "
                   f"{100 * best.rms_relative:.2f} %). The classes differ most in mode "
                   f"{k + 1} ({100 * np.expm1(f.residual[k]):+.2f} % against "
                   f"{100 * np.expm1(best.residual[k]):+.2f} %): the ranking rests on "
                   f"differences of about 1 % and on the assumed {d.sigma:.1%} uncertainty.")
    return out


def plot_cantilever(st, path) -> None:
    fig, ax = plt.subplots(2, 1, figsize=(11, 9))
    fmax = 1.3 * st.measured_hz[-1]
    for name, frf in st.frfs.items():
        m = (frf.frequency > 1.0) & (frf.frequency < fmax)
        good = m & (frf.coherence >= 0.8)
        ax[0].semilogy(frf.frequency[m], np.abs(frf.H[m]), lw=0.6, alpha=0.5,
                       label=f"{name}: |H1| measured")
        ax[0].semilogy(frf.frequency[good], np.abs(frf.H[good]), ".", ms=2)
    f = np.linspace(1.0, fmax, 3000)
    ax[0].semilogy(f, np.abs(tip_accelerance(st.arm, f)), "k", lw=1,
                   label="model: tip force -> tip acceleration (zeta 1 %)")
    best = st.diagnosis.fits[0]
    for k, fm in enumerate(st.measured_hz):
        ax[0].axvline(st.model_hz[k], color="C3", ls="--", label="model modes" if k == 0 else "")
        ax[0].axvline(fm, color="C2", ls=":", label="measured (reported)" if k == 0 else "")
        ax[0].axvline(best.predicted_hz[k], color="C4", ls="-.", lw=0.8,
                      label=f"fitted: {best.name}" if k == 0 else "")
    ax[0].set_xlabel("frequency (Hz)")
    ax[0].set_ylabel("accelerance (m/s^2)/N")
    ax[0].set_title("shaker records (dots: coherence >= 0.8) and the Euler-Bernoulli model")
    n = len(st.measured_hz)
    fits = st.diagnosis.fits
    width = 0.8 / (len(fits) + 1)
    x = np.arange(n)
    ax[1].bar(x, st.ratio - 1, width, label="nominal model", color="0.5")
    for j, fit in enumerate(fits):
        ax[1].bar(x + (j + 1) * width, fit.predicted_hz[:n] / st.measured_hz - 1, width,
                  label=f"{fit.name}: {fmt_value(fit.values[0], fit.candidates[0].unit)} "
                        f"(rms {100 * fit.rms_relative:.2f} %)")
    ax[1].set_xticks(x + 0.4 - width / 2, [f"mode {k + 1}" for k in range(n)])
    ax[1].set_ylabel("model / measured - 1")
    ax[1].set_title("single-effect fits: remaining relative error per mode")
    finish_figure(fig, ax, path, f"{st.arm.name}: measured vs model")


def build_parser():
    """The parser of ``python -m studies.cantilever``."""
    from .command import study_parser
    sp = study_parser("cantilever", "shaker cantilever: measured modes vs the "
                      "Euler-Bernoulli model, single-effect diagnosis (issue 9)")
    sp.add_argument("--data", help="data set directory (default: ../shared/data/real/"
                    "cantilever_beam_shaker_usc_chowdhury beside the checkout)")
    sp.add_argument("--arm", default="usc_cantilever", help="arm preset or YAML")
    sp.add_argument("--vars", type=int, default=None, help="deformation variables per link")
    sp.add_argument("--measured-hz", type=float, nargs="+", default=list(REPORTED_MODES_HZ),
                    help="measured modes 1..n (Hz; default: the reported 6.62 41.4 117.5)")
    sp.add_argument("--sigma", type=float, default=0.005,
                    help="relative uncertainty of each measured frequency (default 0.005)")
    sp.add_argument("--out", help="output directory (default runs/<timestamp>-cantilever)")
    sp.add_argument("--json", action="store_true", help="print the result as JSON")
    sp.set_defaults(func=cmd_cantilever, command="cantilever")
    return sp


def main(argv=None) -> int:
    """``python -m studies.cantilever [--data DIR] [--out DIR] [--json]``."""
    from .command import run_study
    return run_study(build_parser(), argv)


if __name__ == "__main__":
    raise SystemExit(main())
