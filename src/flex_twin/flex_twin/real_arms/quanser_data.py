"""Readers of the Quanser rotary flexible link lab files (PROVENANCE.md of each folder).

Three labs, one kind of arm (SRV02 servo + gear + hub driving a flexible link):

- ``cuboulder`` (CU Boulder ASEN 2003 Lab 6): tab-separated, ``%`` header, 1 kHz, 13
  columns: time (ms), hub angle (rad), tip deflection (m, 1 mm steps), hub rate (rad/s),
  tip rate (m/s), reference (rad), voltage (V), gains K1..K4 of
  V = K1 (theta_ref - theta) + K2 (0 - d) - K3 theta_dot - K4 d_dot;
- ``ucmerced`` (UC Merced): .mat files, 500 Hz, hub angle, reference and link deflection
  angle alpha in degrees, motor voltage; no logged gains;
- ``kyoto_frf`` (Kyoto): closed-loop frequency responses, rows omega (rad/s), |G|, phase.

Every reader returns SI units and radians; the data stay in ``../shared`` (never copied).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

CUBOULDER = "quanser_rotary_flexible_link_cuboulder"
UCMERCED = "quanser_rotary_flexible_link_ucmerced"
KYOTO = "quanser_rotary_flexible_link_kyoto_frf"
#: the Kyoto files PROVENANCE.md calls consistent (the others are erratic or another grid)
KYOTO_CONSISTENT = ("07-May-2025_1825", "09-May-2025_1421", "16-Apr-2025_1819",
                    "16-Apr-2025_1824", "18-Apr-2025_1205", "11-Apr-2025_1801",
                    "11-Apr-2025_1445")


@dataclass
class LabRun:
    """One closed-loop recording, uniformly sampled, SI units.

    ``deflection`` is the lab's tip deflection (m); for an arm that logs a deflection
    angle alpha it is L alpha. ``gains`` (K1..K4) are the logged or identified gains.
    ``gauge_sign`` (+1/-1) maps the twin's tip deflection to the lab's sign convention
    (see :func:`gauge_sign`).
    """

    name: str
    lab: str
    kind: str                   # "flexible" or "rigid"
    t: np.ndarray
    theta: np.ndarray
    deflection: np.ndarray
    theta_rate: np.ndarray
    deflection_rate: np.ndarray
    reference: np.ndarray
    voltage: np.ndarray
    gains: np.ndarray
    source: str = ""
    notes: list = field(default_factory=list)

    @property
    def dt(self) -> float:
        return float(self.t[1] - self.t[0])

    @property
    def has_gauge(self) -> bool:
        return self.kind == "flexible" and bool(np.any(self.deflection != 0.0))

    def head(self, seconds: float) -> "LabRun":
        """The first ``seconds`` of the run (same gauge sign and bias as the whole run)."""
        n = int(round(seconds / self.dt)) + 1
        cut = {k: getattr(self, k)[:n] for k in ("t", "theta", "deflection", "theta_rate",
                                                  "deflection_rate", "reference", "voltage")}
        out = dataclasses.replace(self, name=f"{self.name}[:{seconds:g}s]", **cut)
        out._sign, out._bias = self.gauge_sign(), self.gauge_bias()
        return out

    def reference_changes(self) -> np.ndarray:
        """Sample indices where the reference changes (every sample of a ramp)."""
        return np.flatnonzero(np.abs(np.diff(self.reference)) > 1e-6) + 1

    def holds(self) -> list:
        """(start, stop) sample indices of every hold: from a reference step to the next
        step or the end of the run."""
        bounds = list(self.step_indices()) + [len(self.t)]
        return list(zip(bounds[:-1], bounds[1:]))

    def step_indices(self, min_gap: float = 0.1) -> np.ndarray:
        """Sample indices where the square-wave reference steps: the first change of
        each group closer than ``min_gap`` (s) (UC Merced ramps over 20 ms)."""
        k = self.reference_changes()
        if len(k) == 0:
            return k
        keep = np.concatenate([[True], np.diff(k) * self.dt > min_gap])
        return k[keep]

    def gauge_sign(self) -> float:
        """+1 when the lab's deflection has the twin's sign, -1 when it is opposite.

        Physics fixes it: right after a reference step the hub accelerates towards the
        step and the tip lags behind, so the deflection (from the hub's root tangent,
        counter-clockwise positive, as flex_model's) is opposite to the step in the first
        0.3 s. The lab groups wired the gauge both ways (PROVENANCE: two groups).
        """
        if getattr(self, "_sign", None) is not None:
            return self._sign
        if not self.has_gauge:
            return 1.0
        score = 0.0
        n = int(round(0.3 / self.dt))
        for k in self.step_indices():
            jump = self.reference[min(k + n, len(self.t) - 1)] - self.reference[k - 1]
            seg = self.deflection[k:k + n] - self.deflection[k - 1]
            score += -np.sign(jump) * float(np.mean(seg))
        return 1.0 if score >= 0 else -1.0

    def gauge_bias(self) -> float:
        """Offset of the gauge (m): mean deflection over the 0.5 s before each step, when
        the arm has settled (covington_2017 logs about +31 mm at rest)."""
        if getattr(self, "_bias", None) is not None:
            return self._bias
        if not self.has_gauge:
            return 0.0
        n = int(round(0.5 / self.dt))
        segs = [self.deflection[max(k - n, 0):k] for k in self.step_indices() if k > n // 2]
        return float(np.mean(np.concatenate(segs))) if segs else 0.0


def _steps(run: LabRun) -> list:
    """(levels, first sample, window length) of every reference step of a run."""
    k = run.step_indices()
    ends = np.append(k[1:], len(run.t))
    return [((round(float(run.reference[i - 1]), 6), round(float(run.reference[i]), 6)), i,
             e - i) for i, e in zip(k, ends)]


def _same_setup(a: LabRun, b: LabRun) -> bool:
    """Same folder, kind, gauge (a run without one fed no tip back), gains and reference
    levels: runs that should repeat each other step for step."""
    return (bool(a.source) and Path(a.source).parent == Path(b.source).parent
            and a.kind == b.kind and a.has_gauge == b.has_gauge
            and np.allclose(a.gains, b.gains, atol=1e-6)
            and np.array_equal(np.unique(np.round(a.reference, 6)),
                               np.unique(np.round(b.reference, 6))))


def repeatability(run: LabRun, companions=()) -> dict:
    """The lab's own scatter: for every pair of identical steps (same levels), both of
    ``run`` or one of ``run`` and one of a companion run of the same setup (same folder,
    gauge, gains and reference levels: Covington's test_3 and test_4), the RMS of half the
    difference of the responses over the shorter step window (tip deflections sign- and
    bias-corrected as the twin's are): the lab's scatter. A prediction that is the same
    for both steps (their mean is the best one) errs by at least this on one of them; a
    closed-loop twin enters each step from its own state, so this is a scale of the lab's
    scatter, not a strict bound. ``{}`` if no step repeats. Keys: hub_rms_rad, tip_rms_m
    (when both have a gauge), pairs, runs (the companions used)."""
    others = [c for c in companions if c is not run and c.name != run.name
              and _same_setup(run, c)]

    def corrected(r):
        return r.gauge_sign() * (r.deflection - r.gauge_bias()) if r.has_gauge else None

    mine = _steps(run)
    d0 = corrected(run)
    theirs = [(c, corrected(c), s) for c in others for s in _steps(c)]
    hub, tip, used = [], [], set()
    for j, (lev, i, n) in enumerate(mine):
        cands = [(run, d0, s) for s in mine[j + 1:]] + theirs
        for other, d1, (lev1, i1, n1) in cands:
            if lev1 != lev:
                continue
            m = min(n, n1)
            hub.append(0.5 * (run.theta[i:i + m] - other.theta[i1:i1 + m]))
            if d0 is not None and d1 is not None:
                tip.append(0.5 * (d0[i:i + m] - d1[i1:i1 + m]))
            if other is not run:
                used.add(other.name)
    if not hub:
        return {}
    out = {"hub_rms_rad": float(np.sqrt(np.mean(np.square(np.concatenate(hub))))),
           "pairs": len(hub), "runs": sorted(used)}
    if tip:
        out["tip_rms_m"] = float(np.sqrt(np.mean(np.square(np.concatenate(tip)))))
    return out


def _cuboulder_kind(path: Path) -> str:
    return "rigid" if "rigid" in path.parent.name.lower() or "rigid" in path.name.lower() \
        else "flexible"


def read_cuboulder_file(path) -> LabRun:
    """One CU Boulder log (PROVENANCE: time in ms although some headers say s)."""
    path = Path(path)
    try:
        d = np.loadtxt(path, comments="%")
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a Quanser lab log ({exc})") from None
    if d.ndim != 2 or d.shape[1] < 11:
        raise ValueError(f"{path}: got shape {d.shape}; expected 13 tab-separated columns")
    t = (d[:, 0] - d[0, 0]) * 1e-3
    gains = d[0, 7:11].copy()
    run = LabRun(name=path.name, lab="cuboulder", kind=_cuboulder_kind(path), t=t,
                 theta=d[:, 1], deflection=d[:, 2], theta_rate=d[:, 3],
                 deflection_rate=d[:, 4], reference=d[:, 5], voltage=d[:, 6], gains=gains,
                 source=str(path))
    if run.kind == "flexible" and not run.has_gauge:
        run.notes.append("tip deflection identically 0 (gauge not connected): hub only")
    change = np.flatnonzero(np.any(np.diff(d[:, 7:11], axis=0) != 0, axis=1))
    if len(change):
        # three flexible runs start with the previous run's gains and switch to their own
        # (the file name's) 0.3-0.9 s in, before the first step: the last row's are used
        run.gains = d[-1, 7:11].copy()
        steps = run.step_indices()
        t_change = float(t[change[-1] + 1])
        run.notes.append(f"gains change at t = {t_change:.3f} s from {gains.tolist()}; "
                         f"the last ones {run.gains.tolist()} are used"
                         + (" (after a step!)" if len(steps) and t_change > t[steps[0]]
                            else ""))
    return run


def cuboulder_files(root) -> list[Path]:
    """All 23 CU Boulder logs under ``root`` (the lab folder), sorted by group and name."""
    root = Path(root)
    files = sorted(p for p in root.glob("*/**/*") if p.is_file() and p.suffix != ".md")
    return files


def read_cuboulder(root) -> dict[str, LabRun]:
    """All CU Boulder runs by file name."""
    return {p.name: read_cuboulder_file(p) for p in cuboulder_files(root)}


def load_mat_file(path: Path, name: str) -> np.ndarray:
    from scipy.io import loadmat
    try:
        return np.asarray(loadmat(path)[name], float)
    except (OSError, KeyError, ValueError) as exc:
        raise ValueError(f"{path}: variable {name!r} not readable ({exc})") from None


def read_ucmerced(root, link_length: float) -> LabRun:
    """The UC Merced 5 s record (500 Hz): angles in degrees -> rad, alpha -> L alpha.

    The lab's gains are not logged: they are identified from the record by least squares
    (:func:`identify_gains`) and stored in ``gains``; rates are central differences.
    """
    root = Path(root)
    a = load_mat_file(root / "data_alpha.mat", "data_alpha")
    th = load_mat_file(root / "data_theta.mat", "data_theta")
    vm = load_mat_file(root / "data_vm.mat", "data_vm")
    t = th[:, 0] - th[0, 0]
    theta = np.radians(th[:, 2])
    defl = link_length * np.radians(a[:, 1])
    dt = float(t[1] - t[0])
    run = LabRun(name="ucmerced_5s", lab="ucmerced", kind="flexible", t=t, theta=theta,
                 deflection=defl, theta_rate=np.gradient(theta, dt),
                 deflection_rate=np.gradient(defl, dt), reference=np.radians(th[:, 1]),
                 voltage=vm[:, 1], gains=np.zeros(4), source=str(root))
    run.gains, resid = identify_gains(run)
    run.notes.append(f"gains identified from the record (least squares, RMS residual "
                     f"{resid:.3f} V)")
    return run


def law_regressors(run: LabRun, shift: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(X, k): the lab law V = X @ [K1..K4] = K1 (r - theta) - K2 d - K3 theta_dot -
    K4 d_dot on the samples k where the gauge read ``shift`` samples later exists."""
    n = len(run.t)
    k = np.arange(max(0, -shift), min(n, n - shift))
    return np.column_stack([run.reference[k] - run.theta[k], -run.deflection[k + shift],
                            -run.theta_rate[k], -run.deflection_rate[k + shift]]), k


def identify_gains(run: LabRun) -> tuple[np.ndarray, float]:
    """K1..K4 of V = K1 (r - theta) - K2 d - K3 theta_dot - K4 d_dot fitted to a record."""
    X, _ = law_regressors(run)
    k, *_ = np.linalg.lstsq(X, run.voltage, rcond=None)
    resid = float(np.sqrt(np.mean((X @ k - run.voltage) ** 2)))
    return k, resid


@dataclass
class FrequencyResponse:
    """A measured frequency response: f (Hz), |G| (-) and phase (rad), repeats averaged."""

    name: str
    f: np.ndarray
    magnitude: np.ndarray
    phase: np.ndarray
    repeats: int

    def peak(self, f_lo: float, f_hi: float, largest: bool = True) -> float:
        """Frequency (Hz) of the largest (or smallest) |G| within [f_lo, f_hi]."""
        sel = (self.f >= f_lo) & (self.f <= f_hi)
        mag = self.magnitude[sel]
        return float(self.f[sel][np.argmax(mag) if largest else np.argmin(mag)])


def read_kyoto_frf(path) -> FrequencyResponse:
    """A Kyoto .dat file (3 rows: omega, |G|, phase); repeats on one grid are averaged
    (geometric mean of |G|, circular mean of the phase)."""
    path = Path(path)
    try:
        d = np.loadtxt(path, delimiter=",")
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a Kyoto FRF file ({exc})") from None
    if d.ndim != 2 or d.shape[0] != 3:
        raise ValueError(f"{path}: got shape {d.shape}; expected 3 rows (omega, |G|, phase)")
    w, mag, ph = d
    grid = np.unique(np.round(w, 9))
    idx = np.searchsorted(grid, np.round(w, 9))
    logm = np.bincount(idx, np.log(mag)) / np.bincount(idx)
    z = np.bincount(idx, np.cos(ph)) + 1j * np.bincount(idx, np.sin(ph))
    return FrequencyResponse(name=path.stem.replace("SKE2024_data", ""), f=grid / (2 * np.pi),
                             magnitude=np.exp(logm), phase=np.angle(z),
                             repeats=int(round(len(w) / len(grid))))


def read_kyoto(root, consistent_only: bool = True) -> list[FrequencyResponse]:
    """The Kyoto responses (by default only those PROVENANCE.md calls consistent)."""
    out = []
    for p in sorted(Path(root).glob("*.dat")):
        name = p.stem.replace("SKE2024_data", "")
        if consistent_only and name not in KYOTO_CONSISTENT:
            continue
        out.append(read_kyoto_frf(p))
    return out
