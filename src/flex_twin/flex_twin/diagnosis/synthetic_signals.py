"""Signals of the synthetic diagnosis cases: the excitation a user runs and sensor noise.

- :func:`reference`: a joint reference made of the pieces a user runs on an arm: holds,
  quintic point-to-point moves (fast and slow), and reversals (a sine back and forth about
  the current pose, whose velocity changes sign twice per cycle).
- :class:`NoiseSpec` / :func:`channel_noise`: white Gaussian noise plus coloured noise, a
  first-order autoregressive process AR(1) ``c_k = phi c_{k-1} + e_k`` of stationary
  standard deviation ``coloured`` and correlation time ``corr_time`` (``phi =
  exp(-dt / corr_time)`` at the sample period dt), and quantisation to ``resolution``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

#: joint workspace of the synthetic runs (rad): the two-link arm moves about the hanging
#: pose in the vertical plane, link 1 within +-0.9 rad of straight down
WORKSPACE = ((-np.pi / 2 - 0.9, -np.pi / 2 + 0.9), (-1.2, 1.2))


def _quintic(s):
    """Minimum-jerk blend 0 -> 1 (zero velocity and acceleration at both ends)."""
    return s**3 * (10 - 15 * s + 6 * s**2)


def reference(rng: np.random.Generator, duration: float, rate: float,
              workspace=WORKSPACE) -> tuple[np.ndarray, np.ndarray]:
    """(t, qset): a joint reference (rad) at ``rate`` Hz over ``duration`` s.

    Starts with a hold of 0.5-1 s at a random pose, then a random sequence of moves by up
    to 0.8 rad per joint (1.5-3 s, or slow ones of 3.5-5 s), jogs (0.3-0.5 s moves by up
    to 0.15 rad and a 1.5 s hold: the arm rings out), holds (0.5-3 s) and
    reversals (1-2 cycles of a sine of 0.2-0.5 Hz and 0.1-0.3 rad per joint). Every joint
    stays in ``workspace``. The arm's first flexible mode is near 1 Hz: faster moves
    than these leave tracking errors of tenths of a radian with a joint PD.
    """
    n = int(round(duration * rate)) + 1
    t = np.arange(n) / rate
    lo = np.array([w[0] for w in workspace])
    hi = np.array([w[1] for w in workspace])
    nj = len(lo)
    qset = np.empty((n, nj))
    pose = lo + (hi - lo) * rng.uniform(0.25, 0.75, nj)
    k = int(round(rng.uniform(0.5, 1.0) * rate))
    qset[:k] = pose
    kinds = ("move", "move", "slow_move", "hold", "reversal", "jog")
    while k < n:
        kind = kinds[rng.integers(len(kinds))]
        if kind == "hold":
            m = int(round(rng.uniform(0.5, 3.0) * rate))
            seg = np.broadcast_to(pose, (m, nj))
        elif kind in ("move", "slow_move", "jog"):
            T, step = {"move": (rng.uniform(1.5, 3.0), 0.8), "jog": (rng.uniform(0.3, 0.5), 0.15),
                       "slow_move": (rng.uniform(3.5, 5.0), 0.8)}[kind]
            m = int(round(T * rate))
            target = np.clip(pose + rng.uniform(-step, step, nj), lo, hi)
            s = _quintic(np.arange(1, m + 1) / m)[:, None]
            seg = pose + s * (target - pose)
            if kind == "jog":  # a quick small move and a hold to watch the arm ring out
                seg = np.vstack([seg, np.broadcast_to(target, (int(1.5 * rate), nj))])
                m = len(seg)
        else:
            f = rng.uniform(0.2, 0.5)
            cycles = int(rng.integers(1, 3))
            m = int(round(cycles / f * rate))
            amp = rng.uniform(0.1, 0.3, nj) * rng.choice([-1.0, 1.0], nj)
            amp = np.clip(pose + amp, lo, hi) - pose
            tau = np.arange(1, m + 1) / rate
            seg = pose + np.sin(2 * np.pi * f * tau)[:, None] * amp
        take = min(m, n - k)
        qset[k:k + take] = seg[:take]
        pose = qset[k + take - 1].copy()
        k += take
    return t, qset


@dataclass(frozen=True)
class NoiseSpec:
    """Noise of one measured channel (its SI unit): white std, AR(1) std and correlation
    time (s), quantisation step (0: none)."""

    white: float = 0.0
    coloured: float = 0.0
    corr_time: float = 0.1
    resolution: float = 0.0

    def scaled(self, factor: float) -> "NoiseSpec":
        """The same channel with both noise levels times ``factor`` (resolution kept)."""
        return NoiseSpec(self.white * factor, self.coloured * factor, self.corr_time,
                         self.resolution)

    def phi(self, dt: float) -> float:
        """AR(1) coefficient per sample of period dt."""
        return float(np.exp(-dt / self.corr_time))

    def as_dict(self) -> dict:
        return {"white": self.white, "coloured": self.coloured, "corr_time": self.corr_time,
                "resolution": self.resolution}


def ar1(rng: np.random.Generator, shape, std: float, phi: float) -> np.ndarray:
    """Stationary AR(1) noise along axis 0, stationary standard deviation ``std``."""
    shape = (shape,) if np.isscalar(shape) else tuple(shape)
    if std <= 0:
        return np.zeros(shape)
    e = rng.normal(0.0, std * np.sqrt(1.0 - phi**2), size=shape)
    e[0] = rng.normal(0.0, std, size=shape[1:])  # start in the stationary distribution
    return lfilter([1.0], [1.0, -phi], e, axis=0)


def channel_noise(rng: np.random.Generator, shape, spec: NoiseSpec, dt: float) -> np.ndarray:
    """Additive noise (white + AR(1)) of a channel sampled every ``dt`` s."""
    shape = (shape,) if np.isscalar(shape) else tuple(shape)
    white = rng.normal(0.0, spec.white, size=shape) if spec.white > 0 else np.zeros(shape)
    return white + ar1(rng, shape, spec.coloured, spec.phi(dt))


#: the nominal noise of the synthetic recordings: a 17-bit link-side encoder with a little
#: electrical noise and a slowly drifting mount, a tachometer, strain-gauge tip deflection
#: (thermal drift), a camera tip position, and torque ripple of the drives (process noise)
NOMINAL_NOISE = {
    "q": NoiseSpec(white=3e-5, coloured=3e-5, corr_time=0.1, resolution=2 * np.pi / 2**17),
    "v": NoiseSpec(white=3e-3, coloured=2e-3, corr_time=0.02),
    "w": NoiseSpec(white=2e-4, coloured=3e-4, corr_time=0.5),
    "tip": NoiseSpec(white=1e-3, coloured=1e-3, corr_time=0.1),
    "torque": NoiseSpec(white=0.05, coloured=0.1, corr_time=0.2),
}

#: noise levels by name: factors on NOMINAL_NOISE
NOISE_LEVELS = {"none": 0.0, "low": 0.3, "nominal": 1.0, "high": 3.0}


def noise_model(level) -> dict:
    """NOMINAL_NOISE scaled by a level name (NOISE_LEVELS) or a factor >= 0."""
    if isinstance(level, str):
        if level not in NOISE_LEVELS:
            raise ValueError(f"noise: got {level!r}; expected one of "
                             f"{', '.join(NOISE_LEVELS)} or a factor >= 0")
        factor = NOISE_LEVELS[level]
    else:
        factor = float(level)
        if not factor >= 0:
            raise ValueError(f"noise: got {level!r}; expected a factor >= 0")
    return {k: s.scaled(factor) for k, s in NOMINAL_NOISE.items()}
