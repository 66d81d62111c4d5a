"""Validation of a design on the linear time-varying closed loop (thesis V.3).

For the closed loop linearized along the whole nominal trajectory, ``dx' = A(t) dx`` (see
:mod:`flex_control.closed_loop`), the state transition matrix ``Phi(t, t0)`` is built with
the exponential midpoint rule ``Phi_{k+1} = expm(A(t_k + dt/2) dt) Phi_k`` (second order,
exact for constant ``A``, stable for the stiff flexible modes at any step). Then

- free responses: ``dx(t) = Phi(t, t0) dx0_i`` from ``n = 2 nq`` independent initial
  conditions ``dx0_i = s m_i e_i`` (each coordinate at ``s`` = 80, 90, 100 % of its maximum
  ``m_i``). "For a linear time variant system of order n, if n free responses converging to
  zero are found, which correspond to n independent initial conditions, the system is
  internally stable" (thesis V.3). Converged means: over the last ``tail`` fraction of the
  horizon the weighted norm ``|dx / m|_inf`` stays below ``tolerance`` times its peak
  (the peak, not the initial value, because a flexible arm first transfers an initial
  deflection into large rates).
- impulse response matrix: ``H(t, t0) = C Phi(t, t0) Bu(t0)`` for unit torque impulses
  (1 N m s) on every joint at ``t0``, outputs the joint angles (rad) and link tip
  deflections (m); converged when its largest entry over the tail is below ``tolerance``
  times its peak.

On a linear system the 80 % and 90 % responses are exactly 0.8 and 0.9 times the 100 %
ones; the thesis repeats them on the nonlinear model to confirm linearity near the
trajectory, which :func:`flex_control.tracking.nonlinear_free_responses` does (the full
model in closed loop).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .closed_loop import LinearizedTrajectory, eigen_summary, pd_gains

DEFAULT_SCALES = (0.8, 0.9, 1.0)


@dataclass(frozen=True)
class LTVSettings:
    """Settings of the LTV check (SI units).

    ``angle_max`` (rad) for the link angles, ``deflection_max`` (m) for the deflection
    variables delta, ``rotation_max`` (rad) for the rotation variables gamma,
    ``rate_factor`` (1/s) times those for the velocities; ``step`` (s) of the transition
    matrix; ``hold`` (s) of the final pose appended after the trajectory; ``tolerance`` and
    ``tail`` of the convergence test (see module doc).
    """

    angle_max: float = np.radians(5.0)
    deflection_max: float = 0.01
    rotation_max: float = 0.01
    rate_factor: float = 1.0
    step: float = 0.01
    hold: float = 0.0
    tolerance: float = 0.05
    tail: float = 0.1
    scales: tuple = DEFAULT_SCALES
    impulse_times: tuple = ()

    def __post_init__(self):
        for name in ("angle_max", "deflection_max", "rotation_max", "rate_factor", "step",
                     "tolerance"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name}: got {value!r}; expected a finite number > 0")
        if not (0 <= self.hold and np.isfinite(self.hold)):
            raise ValueError(f"hold: got {self.hold!r}; expected a time >= 0 s")
        if not 0 < self.tail < 1:
            raise ValueError(f"tail: got {self.tail!r}; expected a fraction in (0, 1)")
        if not self.scales or any(not 0 < s <= 1 for s in self.scales):
            raise ValueError(f"scales: got {self.scales!r}; expected fractions in (0, 1]")


def initial_condition_maxima(model, settings: LTVSettings) -> np.ndarray:
    """Maximum ``m_i`` of every state component (angles, deflections, rotations, rates)."""
    m = np.empty(model.nq)
    for i in range(model.n_links):
        m[model.alpha_index(i)] = settings.angle_max
        s = model.flex_slice(i)
        idx = np.arange(s.start, s.stop)
        m[idx[0::2]] = settings.deflection_max
        m[idx[1::2]] = settings.rotation_max
    return np.concatenate([m, settings.rate_factor * m])


class GainFunction:
    """Gains of the LTV loop at time t: constant (h, a) or a schedule of the rigid
    coordinates (and deflections) evaluated on the nominal trajectory."""

    def __init__(self, h=None, a=None, schedule=None, n_joints: int | None = None):
        if schedule is None and (h is None or a is None):
            raise ValueError("gains: got neither (h, a) nor a schedule; expected one of them")
        self.schedule = schedule
        if schedule is None:
            self.h = np.broadcast_to(np.asarray(h, float), (n_joints,)).copy()
            self.a = np.broadcast_to(np.asarray(a, float), (n_joints,)).copy()

    def __call__(self, lin: LinearizedTrajectory, t: float):
        if self.schedule is None:
            return pd_gains(self.h, self.a)
        q, _, _, theta, _ = lin.nominal.at(t)
        h, a = self.schedule.gains(theta, lin.model.tip_deflections(q))
        return pd_gains(h, a)


def _grid(lin: LinearizedTrajectory, settings: LTVSettings) -> np.ndarray:
    t0 = float(lin.t[0])
    t1 = float(lin.t[-1]) + settings.hold
    n = max(1, int(np.ceil((t1 - t0) / settings.step - 1e-9)))
    return np.linspace(t0, t1, n + 1)


#: Pade [13/13] coefficients and the scaling threshold theta_13 of Higham (2005)
_PADE13 = (64764752532480000., 32382376266240000., 7771770303897600., 1187353796428800.,
           129060195264000., 10559470521600., 670442572800., 33522128640., 1323241920.,
           40840800., 960960., 16380., 182., 1.)
_THETA13 = 5.371920351148152


def expm_batch(A: np.ndarray) -> np.ndarray:
    """Matrix exponentials of a stack ``A`` (..., n, n): scaling and squaring with the
    [13/13] Pade approximant (Higham 2005, the algorithm of scipy.linalg.expm), in numpy
    so that a stack costs a few vectorized products (scipy's expm is per matrix)."""
    A = np.asarray(A, float)
    norm = np.max(np.sum(np.abs(A), axis=-2), axis=-1)
    s = np.maximum(0, np.ceil(np.log2(np.maximum(norm, 1e-300) / _THETA13))).astype(int)
    As = A / (2.0 ** s)[..., None, None]
    b = _PADE13
    eye = np.broadcast_to(np.eye(A.shape[-1]), A.shape)
    A2 = As @ As
    A4 = A2 @ A2
    A6 = A4 @ A2
    U = As @ (A6 @ (b[13] * A6 + b[11] * A4 + b[9] * A2) + b[7] * A6 + b[5] * A4
              + b[3] * A2 + b[1] * eye)
    V = A6 @ (b[12] * A6 + b[10] * A4 + b[8] * A2) + b[6] * A6 + b[4] * A4 + b[2] * A2 \
        + b[0] * eye
    R = np.linalg.solve(V - U, V + U)
    for k in range(int(s.max()) if s.size else 0):
        sel = s > k
        R[sel] = R[sel] @ R[sel]
    return R


def propagate(lin: LinearizedTrajectory, gains: GainFunction, X0: np.ndarray,
              t_grid: np.ndarray) -> np.ndarray:
    """``Phi(t_k, t_grid[0]) X0`` for every grid time: array (len(t_grid), 2 nq, cols)."""
    steps = []
    for k in range(len(t_grid) - 1):
        tm = 0.5 * (t_grid[k] + t_grid[k + 1])
        kp, kd = gains(lin, tm)
        steps.append(lin.closed_loop(tm, kp, kd) * (t_grid[k + 1] - t_grid[k]))
    E = expm_batch(np.array(steps)) if steps else np.zeros((0,) + (X0.shape[0],) * 2)
    out = np.empty((len(t_grid),) + X0.shape)
    out[0] = X0
    X = X0.copy()
    for k in range(len(E)):
        X = E[k] @ X
        out[k + 1] = X
    return out


@dataclass
class LTVReport:
    """Outcome of :func:`ltv_check`; ``converged`` is the verdict of thesis V.3."""

    t: np.ndarray
    free_norms: np.ndarray          # (len(t), n): |dx/m|_inf of the 100 % free responses
    free_end_ratio: np.ndarray      # (n,): end norm / initial norm
    free_tail_ratio: np.ndarray     # (n,): max norm over the tail / peak norm
    free_converged: bool
    impulse_t0: list
    impulse_peak: np.ndarray        # (len(t0),): max |H| over time
    impulse_end_ratio: np.ndarray   # (len(t0),): max |H(t_end)| / peak
    impulse_converged: bool
    outputs: list
    free_responses: np.ndarray = field(repr=False, default=None)   # (len(t), 2nq, n), 100 %
    impulse_responses: list = field(repr=False, default_factory=list)  # (len(t), ny, nj)
    maxima: np.ndarray = field(repr=False, default=None)
    scales: tuple = DEFAULT_SCALES
    tolerance: float = 0.05

    @property
    def converged(self) -> bool:
        return bool(self.free_converged and self.impulse_converged)

    def as_dict(self) -> dict:
        return {"converged": self.converged,
                "free_responses": {
                    "count": int(len(self.free_end_ratio)),
                    "scales": list(self.scales),
                    "converged": bool(self.free_converged),
                    "worst_end_ratio": float(np.max(self.free_end_ratio)),
                    "worst_tail_ratio": float(np.max(self.free_tail_ratio)),
                    "tolerance": self.tolerance},
                "impulse_responses": {
                    "t0_s": [float(t) for t in self.impulse_t0],
                    "outputs": self.outputs,
                    "converged": bool(self.impulse_converged),
                    "peak": [float(p) for p in self.impulse_peak],
                    "end_ratio": [float(r) for r in self.impulse_end_ratio]},
                "horizon_s": [float(self.t[0]), float(self.t[-1])]}


def output_matrix(model) -> tuple[np.ndarray, list]:
    """C (joint angles and link tip deflections from the state) and the output names."""
    nq = model.nq
    rows = [model.G, np.eye(nq)[[model.tip_deflection_index(i) for i in range(model.n_links)]]]
    Cq = np.vstack(rows)
    C = np.hstack([Cq, np.zeros_like(Cq)])
    names = ([f"{j}/angle_rad" for j in model.arm.joint_names]
             + [f"{lk.name}/tip_deflection_m" for lk in model.arm.links])
    return C, names


def ltv_check(lin: LinearizedTrajectory, gains: GainFunction,
              settings: LTVSettings = LTVSettings(), keep_responses: bool = True) -> LTVReport:
    """Free responses and impulse response matrix of the LTV closed loop (module doc)."""
    model = lin.model
    t = _grid(lin, settings)
    m = initial_condition_maxima(model, settings)
    X = propagate(lin, gains, np.diag(m), t)
    norms = np.max(np.abs(X / m[None, :, None]), axis=1)          # (len(t), n)
    n_tail = max(1, int(np.ceil(settings.tail * len(t))))
    peak = np.max(norms, axis=0)
    end_ratio = norms[-1] / norms[0]
    tail_ratio = np.max(norms[-n_tail:], axis=0) / peak
    free_ok = bool(np.all(np.isfinite(norms)) and np.all(tail_ratio < settings.tolerance))
    C, names = output_matrix(model)
    t0s = list(settings.impulse_times) or [float(t[0])]
    peaks, ends, responses = [], [], []
    for t0 in t0s:
        if not t[0] <= t0 < t[-1]:
            raise ValueError(f"impulse_times: got {t0!r} s; expected times in "
                             f"[{t[0]:g}, {t[-1]:g}) s")
        tt = np.concatenate([[t0], t[t > t0 + 1e-12]])
        _, Bu = lin.matrices(t0)
        H = np.einsum("yx,kxj->kyj", C, propagate(lin, gains, Bu, tt))
        mag = np.max(np.abs(H), axis=(1, 2))
        peaks.append(float(np.max(mag)))
        ends.append(float(np.max(mag[-n_tail:]) / max(np.max(mag), 1e-300)))
        responses.append(H)
    imp_ok = bool(np.all(np.isfinite(ends)) and np.all(np.array(ends) < settings.tolerance))
    return LTVReport(t=t, free_norms=norms, free_end_ratio=end_ratio,
                     free_tail_ratio=tail_ratio, free_converged=free_ok, impulse_t0=t0s,
                     impulse_peak=np.array(peaks), impulse_end_ratio=np.array(ends),
                     impulse_converged=imp_ok, outputs=names,
                     free_responses=X if keep_responses else None,
                     impulse_responses=responses if keep_responses else [], maxima=m,
                     scales=tuple(settings.scales), tolerance=settings.tolerance)


@dataclass
class FrozenPoint:
    """Frozen-time eigen-analysis of the closed loop at one time."""

    t: float
    zeta_min: float
    tau_max: float
    decay_rate: float
    gain_margin_low: float    # h may be divided by this factor before instability
    gain_margin_high: float   # h may be multiplied by this factor (capped at max_factor)

    def as_dict(self) -> dict:
        return {"t_s": self.t, "zeta_min": self.zeta_min, "tau_max_s": self.tau_max,
                "decay_rate_1_s": self.decay_rate, "gain_margin_low": self.gain_margin_low,
                "gain_margin_high": self.gain_margin_high}


def _stable_with_scale(lin, t, kp, kd, k) -> bool:
    return eigen_summary(lin.closed_loop(t, k * kp, k * kd)).stable


def _margin(lin, t, kp, kd, towards: float, max_factor: float) -> float:
    """Largest factor f <= max_factor with the loop stable for every h scale between 1 and
    f (towards > 1) or 1/f (towards < 1); bisection on log f over a geometric scan."""
    if not _stable_with_scale(lin, t, kp, kd, 1.0):
        return 0.0
    lo = 1.0
    f = 2.0
    while f <= max_factor:
        if not _stable_with_scale(lin, t, kp, kd, f if towards > 1 else 1.0 / f):
            hi = f
            for _ in range(30):
                mid = np.sqrt(lo * hi)
                if _stable_with_scale(lin, t, kp, kd, mid if towards > 1 else 1.0 / mid):
                    lo = mid
                else:
                    hi = mid
                if hi / lo < 1.001:
                    break
            return float(lo)
        lo = f
        f *= 2.0
    return float(max_factor)


def frozen_time_report(lin: LinearizedTrajectory, gains: GainFunction, times,
                       max_factor: float = 1e3) -> list[FrozenPoint]:
    """ζ_min, τ_max and the decay rate of ``A(t)`` at each time, with the gain margins:
    the factors by which every ``h`` (hence ``Kp`` and ``Kd``) can be divided or multiplied
    before the frozen-time loop has an eigenvalue with ``Re >= 0``."""
    out = []
    for t in times:
        kp, kd = gains(lin, float(t))
        s = eigen_summary(lin.closed_loop(float(t), kp, kd))
        out.append(FrozenPoint(t=float(t), zeta_min=s.zeta_min, tau_max=s.tau_max,
                               decay_rate=s.decay_rate,
                               gain_margin_low=_margin(lin, t, kp, kd, 0.5, max_factor),
                               gain_margin_high=_margin(lin, t, kp, kd, 2.0, max_factor)))
    return out
