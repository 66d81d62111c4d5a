"""The FdiTools two-mass motor bench (drive motor - flexible coupling - load motor): reader
and period-averaged frequency responses (Pintelon & Schoukens 2012, Ch. 2: the FRF of a
periodic excitation as the ratio of period-averaged spectra at the excited lines).

``../shared/data/real/two_mass_motor_bench_fditools/MultisineType{A,B}.mat`` (PROVENANCE.md
there): q-axis current ``iq_adx`` (A) of the drive motor, motor angle ``theta_mx`` and load
angle ``theta_my`` (rad, load sign inverted), 2.5 kHz, 20 periods of 1 s; A a Schroeder-phase
full multisine (11-250 Hz, every 1 Hz line), B a random-phase odd-odd one (every 4th line).
The logged speeds ``omega_ma*`` are low-pass filtered (a first-order lag of ~20 Hz corner
against the angles' derivative), so the speeds here are central differences of the angles
(encoder steps 5-6 urad: 0.015 rad/s at 2.5 kHz).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from flex_twin.real_arms.two_mass_twin import TORQUE_CONSTANT, TwoMassParameters

TWO_MASS = "two_mass_motor_bench_fditools"
RECORDS = {"A": "MultisineTypeA.mat", "B": "MultisineTypeB.mat"}
#: the first period holds the start transient: FRFs average periods 2..20
SKIP_PERIODS = 1


@dataclass
class TwoMassRecord:
    """One record in SI units, time from 0; ``theta_l`` in the motor's sign with its mean
    moved onto the motor's (the encoders' zeros differ; the coupling carries no mean
    torque: the bench does not drift), ``current_offset`` the mean measured current (the
    reference has none: an offset of the current measurement, removed from ``current``)."""

    name: str
    t: np.ndarray
    current: np.ndarray          # iq_adx - offset (A)
    current_reference: np.ndarray
    theta_m: np.ndarray
    theta_l: np.ndarray
    omega_m_logged: np.ndarray
    omega_l_logged: np.ndarray
    fs: float
    period_samples: int
    band: tuple                  # excited band (Hz)
    current_offset: float
    source: str = ""

    @property
    def dt(self) -> float:
        return 1.0 / self.fs

    @property
    def n_periods(self) -> int:
        return len(self.t) // self.period_samples

    @property
    def omega_m(self) -> np.ndarray:
        return np.gradient(self.theta_m, self.dt)

    @property
    def omega_l(self) -> np.ndarray:
        return np.gradient(self.theta_l, self.dt)


def data_dir(root=None) -> Path:
    """The bench's folder: ``root`` (the real-data folder or the bench folder itself), or
    ``../shared/data/real/two_mass_motor_bench_fditools`` beside the cwd."""
    root = Path(root) if root else Path.cwd().parent / "shared" / "data" / "real"
    d = root if (root / RECORDS["A"]).is_file() else root / TWO_MASS
    if not (d / RECORDS["A"]).is_file():
        raise FileNotFoundError(f"{root}: no {TWO_MASS}/{RECORDS['A']} (give --data DIR, the "
                                "folder holding the labs' data)")
    return d


def read_two_mass(record: str = "A", root=None) -> TwoMassRecord:
    """Read record ``A`` or ``B`` (or a path to a .mat file of the same layout)."""
    from scipy.io import loadmat
    path = Path(record) if str(record).endswith(".mat") else data_dir(root) / RECORDS[record]
    d = loadmat(path, squeeze_me=True, struct_as_record=False)
    for key in ("time", "iq_adx", "theta_mx", "theta_my", "fs", "nrofs"):
        if key not in d:
            raise ValueError(f"{path}: no variable {key!r} (expected the FdiTools layout)")
    t = (np.asarray(d["time"], float) - float(d["time"][0])) * 1e-6      # us -> s
    iq = np.asarray(d["iq_adx"], float)
    qm = np.asarray(d["theta_mx"], float)
    ql = -np.asarray(d["theta_my"], float)
    ql = ql - ql.mean() + qm.mean()
    fs = float(d["fs"])
    if not np.allclose(np.diff(t), 1.0 / fs, rtol=1e-6, atol=1e-9):
        raise ValueError(f"{path}: time is not uniform at fs = {fs} Hz")
    offset = float(iq.mean())
    name = path.stem.replace("MultisineType", "")
    return TwoMassRecord(name=name, t=t, current=iq - offset,
                         current_reference=np.asarray(d["iq_refx"], float), theta_m=qm,
                         theta_l=ql, omega_m_logged=np.asarray(d["omega_max"], float),
                         omega_l_logged=-np.asarray(d["omega_may"], float), fs=fs,
                         period_samples=int(d["nrofs"]),
                         band=(float(d["fl"]), float(d["fh"])), current_offset=offset,
                         source=str(path))


@dataclass
class PeriodFRF:
    """theta / i at the excited lines (rad/A), periods averaged; ``*_std`` the standard
    deviation of the mean over periods (noise)."""

    f: np.ndarray
    motor: np.ndarray
    load: np.ndarray
    motor_std: np.ndarray
    load_std: np.ndarray


def excited_lines(rec: TwoMassRecord, current=None) -> np.ndarray:
    """Indices of the lines in the excited band where the reference carries power."""
    n = rec.period_samples
    ref = rec.current_reference[:n * rec.n_periods].reshape(rec.n_periods, n)
    amp = np.abs(np.fft.rfft(ref, axis=1).mean(0))
    f = np.fft.rfftfreq(n, rec.dt)
    band = (f >= rec.band[0] - 1e-9) & (f <= rec.band[1] + 1e-9)
    return np.flatnonzero(band & (amp > 0.1 * amp[band].max()))


def period_frf(rec: TwoMassRecord, theta_m=None, theta_l=None, current=None) -> PeriodFRF:
    """The FRFs theta_m / i and theta_l / i (measured, or of given signals on the record's
    grid: a twin's response), periods SKIP_PERIODS.. averaged (Pintelon & Schoukens Eq.
    2-42: ratio of the mean spectra)."""
    n, p = rec.period_samples, rec.n_periods
    use = slice(SKIP_PERIODS * n, p * n)

    def spec(x):
        return np.fft.rfft(np.asarray(x)[use].reshape(p - SKIP_PERIODS, n), axis=1)

    k = excited_lines(rec)
    i = spec(rec.current if current is None else current)[:, k]
    out = []
    for x in (rec.theta_m if theta_m is None else theta_m,
              rec.theta_l if theta_l is None else theta_l):
        X = spec(x)[:, k]
        H = X.mean(0) / i.mean(0)
        per = X / i
        out += [H, np.abs(per - H).std(0) / np.sqrt(p - SKIP_PERIODS)]
    f = np.fft.rfftfreq(n, rec.dt)[k]
    return PeriodFRF(f=f, motor=out[0], load=out[2], motor_std=out[1], load_std=out[3])


def frf(p: TwoMassParameters, f) -> tuple[np.ndarray, np.ndarray]:
    """theta_m / i and theta_l / i (rad/A) of the two-inertia model at f (Hz)."""
    s = 2j * np.pi * np.asarray(f, float)
    a11 = p.J_m * s * s + (p.b_m + p.c) * s + p.k
    a22 = p.J_l * s * s + (p.b_l + p.c) * s + p.k
    a12 = -(p.c * s + p.k)
    g = TORQUE_CONSTANT * np.exp(-s * p.delay) / (a11 * a22 - a12 * a12)
    return a22 * g, -a12 * g


def fit_frf(meas: PeriodFRF, load_friction: bool = False, delay: bool = True
            ) -> tuple[TwoMassParameters, float]:
    """Least squares of log(H_model / H_measured) (complex: log magnitude and phase) on both
    FRFs' excited lines; starts from the mass lines. Returns the parameters and the RMS of
    the log residual (0.1 ~ 10 % / 6 deg)."""
    f = meas.f
    w2 = (2 * np.pi * f) ** 2
    low = np.median(np.abs(meas.motor[f < 25]) * w2[f < 25])     # K_t / (J_m + J_l)
    high = np.median(np.abs(meas.motor[f > 150]) * w2[f > 150])  # K_t / J_m
    jm0 = TORQUE_CONSTANT / high
    jl0 = max(TORQUE_CONSTANT / low - jm0, 0.2 * jm0)
    k0 = jl0 * (2 * np.pi * f[np.argmin(np.abs(meas.motor) * w2)]) ** 2

    def unpack(x):
        return TwoMassParameters(J_m=float(np.exp(x[0])), J_l=float(np.exp(x[1])),
                                 k=float(np.exp(x[2])), c=float(x[3]), b_m=float(x[4]),
                                 b_l=float(x[5]) if load_friction else 0.0,
                                 delay=float(x[6]) if delay else 0.0)

    def res(x):
        m, lo = frf(unpack(x), f)
        return np.concatenate([np.log(m / meas.motor).view(float),
                               np.log(lo / meas.load).view(float)])

    x0 = [np.log(jm0), np.log(jl0), np.log(k0), 0.01, 0.01, 0.0, 0.0]
    lb = [-20, -20, -10, 0.0, 0.0, 0.0, 0.0]
    ub = [5, 5, 20, 100.0, 100.0, 100.0, 2e-3]
    r = least_squares(res, x0, bounds=(lb, ub))
    return unpack(r.x), float(np.sqrt(np.mean(r.fun ** 2)))
