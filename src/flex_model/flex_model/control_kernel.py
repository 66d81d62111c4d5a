"""Compiled control loop: many control periods of the arm and a built-in law in one call.

What :class:`flex_model.control_loop.ControlLoop` does per control period (sense, evaluate
the law, hold its command, restart the method when the command changed, integrate the
period with generalized-alpha), in one numba loop over the periods: no Python and no
dispatch per period. It serves the laws that are a fixed formula of the sensed state and
a piecewise-linear reference (``LinearLaw``: thesis Eq. 95 with constant gains, seed 000's
Eq. 45, the joint state-feedback law), with the same arithmetic in the same order as their
Python versions in flex_control, so the trajectories agree to rounding (tested to 1e-12).
Users' own controllers keep the Python path.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .integrators import PlanarModel, restart_acceleration
from .solvers.loop import fixed_step
from .solvers.status import newton_settings

_CACHE = True

#: law codes (LinearLaw.law)
EQ95, EQ45, STATE_FEEDBACK = 0, 1, 2
#: reference interpolation (LinearLaw.interpolation): flex_control.laws.ReferenceSampler,
#: flex_model.trajectory.JointTrajectoryData.sample
SAMPLER, TRAJECTORY_SAMPLE = 0, 1

SQRT2 = float(np.sqrt(2.0))


class LinearLaw(NamedTuple):
    """A built-in law in the compiled loop's terms (what a controller's ``compiled_law()``
    returns). ``gains`` (4, n): eq95 h, a; eq45 kpp, kpv, gear ratio; state feedback
    K1..K4. ``reference`` (m, 3n): angles, rates and feed-forward torques at ``times``."""

    law: int
    interpolation: int
    times: np.ndarray
    reference: np.ndarray
    gains: np.ndarray
    feedforward: bool
    limits: np.ndarray


def linear_law(law: int, interpolation: int, trajectory, gains, feedforward: bool,
               limits) -> LinearLaw:
    """A :class:`LinearLaw` tracking ``trajectory`` (a JointTrajectoryData)."""
    n = len(trajectory.joint_names)
    G = np.zeros((4, n))
    g = np.asarray(gains, float)
    G[:g.shape[0]] = g
    ref = np.ascontiguousarray(np.hstack([trajectory.positions, trajectory.velocities,
                                          trajectory.efforts]), dtype=float)
    return LinearLaw(int(law), int(interpolation), np.ascontiguousarray(trajectory.t, float),
                     ref, G, bool(feedforward),
                     np.array(np.broadcast_to(np.asarray(limits, float), (n,)), dtype=float))


@njit(cache=_CACHE)
def sample_reference(interp, T, R, t):
    """The reference row at time t, held outside [T[0], T[-1]]: linear interpolation as
    ReferenceSampler (interp 0) or JointTrajectoryData.sample (interp 1) computes it."""
    m = T.shape[0]
    if interp == 0:
        if t <= T[0]:
            return R[0].copy()
        if t >= T[m - 1]:
            return R[m - 1].copy()
        k = np.searchsorted(T, t, side="right") - 1
        return R[k] + ((t - T[k]) / (T[k + 1] - T[k])) * (R[k + 1] - R[k])
    tc = min(max(t, T[0]), T[m - 1])
    k = np.searchsorted(T, tc, side="right") - 1
    k = min(max(k, 0), m - 1)
    if k == m - 1:
        return R[k].copy()
    w = (tc - T[k]) / (T[k + 1] - T[k])
    return (1 - w) * R[k] + w * R[k + 1]


@njit(cache=_CACHE)
def law_command(law, interp, T, R, gains, ff, lim, t, th, dth, d, dd):
    """The command of a built-in law at time t for the sensed state (th, dth, d, dd)."""
    n = th.shape[0]
    y = sample_reference(interp, T, R, t)
    u = np.empty(n)
    for i in range(n):
        r, dr, tn = y[i], y[n + i], y[2 * n + i]
        if law == 0:  # thesis Eq. 95 (flex_control.laws.DecentralizedPD)
            h, a = gains[0, i], gains[1, i]
            tau = h * (a * a * (r - th[i]) + SQRT2 * a * (dr - dth[i]))
            if ff:
                tau = tau + tn
            u[i] = min(max(tau, -lim[i]), lim[i])
        elif law == 1:  # seed 000 Eq. 45 (flex_control.laws.PDLikeCascade)
            kpp, kpv, g = gains[0, i], gains[1, i], gains[2, i]
            tau = g * (kpv * (kpp * (g * r - g * th[i]) - g * dth[i]))
            u[i] = min(max(tau, -lim[i]), lim[i])
        else:  # joint state feedback (flex_control.in_loop.JointStateFeedback)
            tau = gains[0, i] * (r - th[i]) - gains[1, i] * d[i] \
                - gains[2, i] * (dth[i] - dr) - gains[3, i] * dd[i]
            if ff:
                tau = tau + tn
            u[i] = min(max(tau, -lim[i]), lim[i])
    return u


@njit(cache=_CACHE)
def run_periods(t, x, a, abar, n_periods, period, max_step, rho_inf, t_ref0, G, defl,
                law, interp, T, R, gains, ff, lim, tol, limit, P, E):
    """``n_periods`` control periods from (t, x, a, abar): sense, command (held in E.u,
    the stepper's command array), restart if it changed, integrate the period.

    Returns ``(status, periods_done, t, x, a, abar, t_fail, x_fail)``: status 0 ok, 1
    diverged, 2 Newton failed, 3 non-finite command; on failure (t, x, a, abar) is the
    state at the start of the failing period and (t_fail, x_fail) where it failed.
    """
    u = E.u
    n = G.shape[1]
    ns = max(1, int(np.ceil(period / max_step - 1e-9)))
    h = period / ns
    md, s = PlanarModel(P, E), newton_settings(rho_inf, tol, limit)   # full Newton
    for k in range(n_periods):
        q = x[:n]
        v = x[n:2 * n]
        th = G @ q
        dth = G @ v
        d = q[defl]
        dd = v[defl]
        un = law_command(law, interp, T, R, gains, ff, lim, t - t_ref0, th, dth, d, dd)
        for i in range(un.shape[0]):
            if not np.isfinite(un[i]):
                return 3, k, t, x, a, abar, t, un
        changed = False
        for i in range(un.shape[0]):
            if un[i] != u[i]:
                changed = True
        if changed:
            u[:] = un
            a, abar, _, _ = restart_acceleration(t, x, a, abar, h, rho_inf, P, E)
        _, status, t_end, x_end, a1, abar1, _ = fixed_step(
            md, n, t, x, a, abar, h, ns, ns, s, None)
        if status != 0:
            return status, k, t, x, a, abar, t_end, x_end
        t, x, a, abar = t + period, x_end, a1, abar1
    return 0, n_periods, t, x, a, abar, t, x


def _guard_caches():
    from . import integrators, iteration_matrix, kernels
    from .effects import friction, stick_slip
    from .numba_cache import guard
    from .solvers import galpha, loop, newton
    # this module's own dispatchers only: the imported integrators ones have their guard
    # (run_periods holds the machine code of solvers.loop.fixed_step: its files too)
    guard([obj for obj in globals().values() if hasattr(obj, "py_func")
           and obj.py_func.__module__ == __name__],
          [integrators.__file__, kernels.__file__, stick_slip.__file__, friction.__file__,
           iteration_matrix.__file__, galpha.__file__, newton.__file__, loop.__file__])


_guard_caches()
