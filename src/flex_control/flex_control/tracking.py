"""Nonlinear closed-loop runs of the Eq. (95) PD along a nominal trajectory (thesis V.3).

The joint feedback of Eq. (95) is stiff on a flexible arm: the joint sees only the small
inertia of the link roots, so ``Kd`` times the inverse of that inertia gives real
closed-loop poles far out (about -7e4 1/s for the Ch. V arm with h = 25, a = 5). A digital
zero-order-hold law would need a period below ``2 / 7e4 s``; the thesis's analysis is in
continuous time. The runs here therefore split Eq. (95)::

    tau = [-Kp theta - Kd theta_dot]                      built-in PD of the integrator,
        + [tau_nom(t) + Kp theta_hat(t) + Kd theta_hat_dot(t)]   policy, held for a period,

so the feedback is continuous and implicit (generalized-alpha) and only the smooth
reference part is sampled. With a gain schedule the gains are re-evaluated at the measured
joint angles (and tip deflections) every ``gain_period`` and held in between.

:func:`nonlinear_free_responses` repeats the LTV free responses on this nonlinear loop at
80, 90, 100 % of the initial-condition maxima: the deviations from the unperturbed run must
converge to zero and scale with the initial condition (linearity near the trajectory).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.result import SimulationResult
from flex_model.simulate import JointPD, simulate
from flex_model.trajectory import JointTrajectoryData

from .closed_loop import NominalTrajectory, pd_gains
from .ltv import LTVSettings, initial_condition_maxima


def simulate_tracking(model: FlexArmModel, trajectory: JointTrajectoryData, *, h=None, a=None,
                      schedule=None, q0=None, v0=None, t_final: float | None = None,
                      control_period: float = 5e-3, gain_period: float = 0.05,
                      dt: float = 1e-3, sample_period: float = 0.01) -> SimulationResult:
    """The arm under Eq. (95) + feed-forward tracking ``trajectory`` (module doc), from
    ``(q0, v0)`` (default: the nominal state at the start), fixed-step."""
    nj = model.n_links
    if schedule is None:
        if h is None or a is None:
            raise ValueError("gains: got neither (h, a) nor a schedule; expected one")
        kp, kd = pd_gains(np.broadcast_to(np.asarray(h, float), (nj,)),
                          np.broadcast_to(np.asarray(a, float), (nj,)))
    nominal = NominalTrajectory.from_data(model, trajectory) \
        if trajectory.q_nominal is not None else None
    if q0 is None:
        if nominal is None:
            raise ValueError("q0: got None and the trajectory has no q_nominal; expected "
                             "an initial state")
        q0, v0 = nominal.q[0], nominal.v[0]
    t_final = trajectory.duration if t_final is None else t_final
    if not t_final > 0:
        raise ValueError(f"t_final: got {t_final!r}; expected a time > 0 s")
    t0 = float(trajectory.t[0])
    chunk = t_final if schedule is None else max(gain_period, sample_period)
    n_chunks = int(np.ceil(t_final / chunk - 1e-9))
    q, v = np.asarray(q0, float), (np.zeros(model.nq) if v0 is None else np.asarray(v0, float))
    parts = []
    idx = [model.tip_deflection_index(i) for i in range(nj)]
    for c in range(n_chunks):
        start = c * chunk
        length = min(chunk, t_final - start)
        if schedule is not None:
            hh, aa = schedule.gains(model.G @ q, q[idx])
            kp, kd = pd_gains(hh, aa)

        def policy(t, x, start=start, kp=kp, kd=kd):
            p, dp, _, tau_nom = trajectory.sample(t0 + start + t)
            return tau_nom + kp * p + kd * dp

        res = simulate(model, q, v, t_final=length, sample_period=min(sample_period, length),
                       pd=JointPD(kp=kp, kd=kd, setpoints=np.zeros(nj)), policy=policy,
                       control_period=control_period, method="fixed", dt=dt)
        keep = slice(0 if c == 0 else 1, None)
        parts.append((res.t[keep] + start, res.q[keep], res.v[keep], res.tau[keep]))
        q, v = res.q[-1], res.v[-1]
    t, Q, V, tau = (np.concatenate([p[k] for p in parts]) for k in range(4))
    return SimulationResult(model=model, t=t + t0, q=Q, v=V, tau=tau,
                            stats={"method": "fixed", "chunks": n_chunks})


@dataclass
class NonlinearCheck:
    """Deviations of perturbed nonlinear runs from the unperturbed one."""

    t: np.ndarray
    indices: list             # initial-condition indices (state components) tried
    scales: tuple
    end_ratio: np.ndarray     # (len(indices), len(scales)): |dx/m| over the tail / peak
    linearity_error: np.ndarray   # (len(indices), len(scales)): |dx_s - s dx_1| / |dx_1|
    tolerance: float

    @property
    def converged(self) -> bool:
        return bool(np.all(self.end_ratio < self.tolerance))

    def as_dict(self) -> dict:
        return {"converged": self.converged, "indices": self.indices,
                "scales": list(self.scales),
                "worst_tail_ratio": float(np.max(self.end_ratio)),
                "worst_linearity_error": float(np.max(self.linearity_error)),
                "tolerance": self.tolerance}


def nonlinear_free_responses(model: FlexArmModel, trajectory: JointTrajectoryData, *, h=None,
                             a=None, schedule=None, indices=None,
                             settings: LTVSettings = LTVSettings(),
                             t_final: float | None = None, **run) -> NonlinearCheck:
    """Free responses of the nonlinear closed loop from ``x_nom(0) + s m_i e_i``."""
    nominal = NominalTrajectory.from_data(model, trajectory)
    m = initial_condition_maxima(model, settings)
    x0 = np.concatenate([nominal.q[0], nominal.v[0]])
    nq = model.nq
    indices = list(range(2 * nq)) if indices is None else [int(i) for i in indices]
    gains = dict(h=h, a=a, schedule=schedule, t_final=t_final, **run)
    ref = simulate_tracking(model, trajectory, q0=x0[:nq], v0=x0[nq:], **gains)
    Xref = np.hstack([ref.q, ref.v])
    n_tail = max(1, int(np.ceil(settings.tail * len(ref.t))))
    end = np.zeros((len(indices), len(settings.scales)))
    lin = np.zeros_like(end)
    for r, i in enumerate(indices):
        devs = []
        for s in settings.scales:
            x = x0.copy()
            x[i] += s * m[i]
            res = simulate_tracking(model, trajectory, q0=x[:nq], v0=x[nq:], **gains)
            devs.append((np.hstack([res.q, res.v]) - Xref) / m)
        full = devs[int(np.argmax(settings.scales))]
        s_full = max(settings.scales)
        scale = np.max(np.abs(full))
        for c, (s, d) in enumerate(zip(settings.scales, devs)):
            norm = np.max(np.abs(d), axis=1)
            end[r, c] = np.max(norm[-n_tail:]) / max(np.max(norm), 1e-300)
            lin[r, c] = np.max(np.abs(d - (s / s_full) * full)) / max(scale, 1e-300)
    return NonlinearCheck(t=ref.t, indices=indices, scales=tuple(settings.scales),
                          end_ratio=end, linearity_error=lin, tolerance=settings.tolerance)
