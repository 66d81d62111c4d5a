"""Generalized-alpha (Chung & Hulbert 1993, in Arnold & Bruls's 2007 form with the
acceleration-like variable abar): the parameters, the update of a step, the restart after
an input jump and the status of a step (issue 43: one implementation for the planar
kinematics, the exact kinematics, the spatial arms and the planner).

One step solves r(a1) = 0 for the acceleration a1 at t_{n+1}, with

    (1 - alpha_m) abar1 = (1 - alpha_f) a1 + alpha_f a - alpha_m abar,
    q1 = q + h v + h^2 ((1/2 - beta) abar + beta abar1),
    v1 = v + h ((1 - gamma) abar + gamma abar1),

so dq1/da1 = beta' = h^2 beta (1 - alpha_f) / (1 - alpha_m) and dv1/da1 = gamma' =
h gamma (1 - alpha_f) / (1 - alpha_m) (the iteration matrix B + gamma' D + beta' K).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .status import DIVERGED, FINISHED, NO_CONVERGENCE

_CACHE = True

#: restart_choice filters a force jump when more than this share of its acceleration
#: jump lies in modes the step cannot follow (the 26303 restarts of test_simulate,
#: test_simplified_newton, test_linear_cost, test_effects, test_sensors,
#: test_scenario_users_asks, the control laws' and the planner's tests: at most 0.28;
#: issue 24's hub-less arm: 0.97-1.0 at 0.125-1 ms and 2-16 variables per link)
RESTART_SHARE = 0.5
#: ... and when the consistent restart would move those modes by more than this (m or
#: rad; calibrated on issue 24's hub-less arm, 15 deg set-point step, tip deflections of
#: link 2 over 0.3 s off a 1/32 ms run, consistent / filtered: 2 variables per link at
#: 0.5 ms, overshoot 0.011: 0.58 / 1.08 %; 4 at 0.25 ms, 0.016: 0.51 / 0.61 %; 8 at
#: 0.125 ms, 0.033: 0.36 / 0.23 %; 6 at 0.25 ms, 0.055: 0.67 / 0.38 %; 8 at 0.25 ms, 0.13:
#: 1.80 / 0.35 %; 16 at 0.125 ms, 0.27: 685 / 0.16 %). Section F's Eq. (95) policy (new
#: held torques every 1 ms) stays below 6e-6: the consistent restart is the better there
#: (4e-6 against 6e-5 rad of joint angle off a 1/8 ms run)
RESTART_OVERSHOOT = 0.03


class GAlpha(NamedTuple):
    """The coefficients of one step size: h, alpha_m, alpha_f, gamma, beta and the
    derivatives bp = dq1/da1, gp = dv1/da1 (module docstring)."""
    h: float
    am: float
    af: float
    gam: float
    beta: float
    bp: float
    gp: float


class Step(NamedTuple):
    """The state a step starts from: q, v, the bristle deflections z (planar stick-slip
    joints; empty otherwise), the method's accelerations a, abar, the residual's time
    t (mid-step for the planar pulses) and the step's index k in the run (0 first: the
    row of the spatial arm's per-step inputs)."""
    q: np.ndarray
    v: np.ndarray
    z: np.ndarray
    a: np.ndarray
    abar: np.ndarray
    t: float
    k: int


@njit(cache=_CACHE)
def galpha_parameters(rho_inf):
    """(alpha_m, alpha_f, gamma, beta) of generalized-alpha with the spectral radius
    ``rho_inf`` at infinite frequency (Chung-Hulbert: second order, optimal damping of
    the high modes)."""
    am = (2.0 * rho_inf - 1.0) / (rho_inf + 1.0)
    af = rho_inf / (rho_inf + 1.0)
    gam = 0.5 + af - am
    return am, af, gam, 0.25 * (gam + 0.5) ** 2


@njit(cache=_CACHE)
def galpha_coefficients(rho_inf, h):
    """:class:`GAlpha` for the step ``h`` (s)."""
    am, af, gam, beta = galpha_parameters(rho_inf)
    ratio = (1.0 - af) / (1.0 - am)
    return GAlpha(h, am, af, gam, beta, h * h * beta * ratio, h * gam * ratio)


@njit(cache=_CACHE)
def galpha_abar(a1, a, abar, c):
    """abar1 for the iterate a1 (module docstring), as an array expression (the planner's
    prescribed-motion loops, flex_planner.nominal_input and spatial_nominal)."""
    return ((1.0 - c.af) * a1 + c.af * a - c.am * abar) / (1.0 - c.am)


@njit(cache=_CACHE)
def galpha_state(q, v, a, abar, a1, c):
    """(q1, v1, abar1) for the iterate a1 (module docstring; explicit loops: numba array
    expressions compile slowly)."""
    n = q.shape[0]
    q1, v1, ab1 = np.empty(n), np.empty(n), np.empty(n)
    for j in range(n):
        b = ((1.0 - c.af) * a1[j] + c.af * a[j] - c.am * abar[j]) / (1.0 - c.am)
        ab1[j] = b
        q1[j] = q[j] + c.h * v[j] + c.h * c.h * ((0.5 - c.beta) * abar[j] + c.beta * b)
        v1[j] = v[j] + c.h * ((1.0 - c.gam) * abar[j] + c.gam * b)
    return q1, v1, ab1


@njit(cache=_CACHE)
def restart_choice(a, ac, B, S, h, rho_inf, overshoot_limit=RESTART_OVERSHOOT):
    """(start acceleration, share, overshoot) after a force jump: a + da, the part
    da = S^-1 B (ac - a) of the jump the step follows (S its iteration matrix), where
    ``share`` > RESTART_SHARE and either ``overshoot`` > ``overshoot_limit`` (default
    RESTART_OVERSHOOT; 0 with exact kinematics, exact_kinematics.restart_acceleration) or the
    consistent restart's kick is mostly the velocity one (:func:`restart_kick`: below
    rho_inf = 0.721; it grows with h omega, not with the jump's size: 2 variables per
    link, 0.25 ms, rho_inf 0: link 2 13 % off consistent, 1.1 % filtered), else the
    consistent ac (integrators.restart_acceleration; the planar and the spatial fixed
    step's restart)."""
    jump = ac - a
    Bj = B @ jump
    full = jump @ Bj
    if not full > 0.0:
        return ac, 0.0, 0.0
    da = np.linalg.solve(S, Bj)
    e = jump - da
    share = np.sqrt(max(e @ (B @ e), 0.0) / full)
    overshoot = h * h * restart_kick(rho_inf) * np.max(np.abs(e))
    am, af, gam, beta = galpha_parameters(rho_inf)
    velocity_kick = gam - 0.5 > 0.5 - beta
    if share > RESTART_SHARE and (overshoot > overshoot_limit or velocity_kick):
        return a + da, share, overshoot
    return ac, share, overshoot


@njit(cache=_CACHE)
def restart_kick(rho_inf):
    """Coefficient k of the position k h^2 |dA - da| a consistent restart adds to the modes
    a step cannot follow (restart_choice's ``overshoot``): max(1/2 - beta, gamma - 1/2)
    of Chung & Hulbert's (1993) parameters for rho_inf.

    1/2 - beta is the share of the old acceleration in the position update (h^2 (1/2 -
    beta) abar_n in Arnold & Bruls's (2007) form); it is 0.223 at rho_inf = 0.9 but 0 at
    rho_inf = sqrt(2) - 1 and negative below, where a consistent restart still kicks
    the unresolved modes, through the velocity update h ((1 - gamma) abar_n + gamma
    abar_n+1): gamma - 1/2 = (1 - rho_inf) / (1 + rho_inf) is the scheme's numerical
    damping, 1 at rho_inf = 0 (single mode h omega = 30: the consistent restart's
    velocity 7.5 times the exact solution's largest at rho_inf = 0, 0.9 times at 0.9).
    From rho_inf = 0.721 up the first term is the larger (decisions as before)."""
    am, af, gam, beta = galpha_parameters(rho_inf)
    return max(0.5 - beta, gam - 0.5)


@njit(cache=_CACHE)
def finite_within(x, limit):
    """False when a component is non-finite or beyond ``limit`` (a diverging state)."""
    for i in range(x.shape[0]):
        if not np.isfinite(x[i]) or abs(x[i]) > limit:
            return False
    return True


@njit(cache=_CACHE)
def step_status(x, limit, converged):
    """The status after a step (solvers.status): DIVERGED when the state x is non-finite
    or beyond ``limit`` (checked first), NO_CONVERGENCE when Newton did not converge,
    else FINISHED (the run goes on)."""
    if not finite_within(x, limit):
        return DIVERGED
    return FINISHED if converged else NO_CONVERGENCE
