"""The generalized-alpha pieces of flex_model.solvers (galpha_coefficients, galpha_state,
step_status, the backtracking test) on a linear oscillator m a + k q = 0 against closed
forms: second-order accuracy, no numerical dissipation at rho_inf = 1 (the trapezoidal
rule), an unresolved mode damped by rho_inf per step (Chung & Hulbert 1993), and the
status of a step with its message; the one compiled loop on a model given by its hooks."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pytest
from numba import njit

from flex_model.iteration_matrix import empty_factor
from flex_model.kernels import cholesky
from flex_model.solvers.galpha import galpha_coefficients, galpha_state, step_status
from flex_model.solvers.loop import (fixed_step, id_residual, implements, iteration_factor,
                                     residual, tangent)
from flex_model.solvers.newton import backtrack_done, spatial_converged
from flex_model.solvers.status import (DIVERGED, FINISHED, NO_CONVERGENCE, Settings,
                                       message)


def oscillator(h, n, rho_inf=0.9, omega=1.0):
    """q_k of q'' + omega^2 q = 0 from q = 1, v = 0: each step's equation a1 + omega^2
    q1(a1) = 0 is linear, solved in one Newton step on the slope 1 + omega^2 beta'."""
    c = galpha_coefficients(rho_inf, h)
    q, v = np.array([1.0]), np.array([0.0])
    a = -omega ** 2 * q
    abar = a.copy()
    out = [q[0]]
    for _ in range(n):
        q1 = galpha_state(q, v, a, abar, np.zeros(1), c)[0]
        a1 = -(omega ** 2 * q1) / (1.0 + omega ** 2 * c.bp)
        q, v, abar = galpha_state(q, v, a, abar, a1, c)
        a = a1
        out.append(q[0])
    return np.array(out), v


def test_second_order_accurate():
    """q = cos t at t = 2: the error falls 4 times when the step halves."""
    err = [abs(oscillator(h, int(round(2.0 / h)))[0][-1] - np.cos(2.0)) for h in (0.02, 0.01)]
    assert 3.9 < err[0] / err[1] < 4.1
    assert err[1] < 2e-5


def test_no_dissipation_at_rho_inf_one():
    """rho_inf = 1 is the trapezoidal rule: the energy q^2 + v^2 / omega^2 of an undamped
    mode stays 1, even at h omega = 10, over 1000 steps."""
    q, v = oscillator(1.0, 1000, rho_inf=1.0, omega=10.0)
    assert q[-1] ** 2 + v[0] ** 2 / 100.0 == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("rho_inf", [0.5, 0.9])
def test_an_unresolved_mode_decays_by_rho_inf_per_step(rho_inf):
    """At h omega = 1e4 the amplitude ratio of successive steps tends to rho_inf, the
    scheme's spectral radius at infinite frequency."""
    q = oscillator(1.0, 400, rho_inf=rho_inf, omega=1e4)[0]
    assert abs(q[-1] / q[-2]) == pytest.approx(rho_inf, rel=0.01)


def test_the_status_of_a_step_and_its_message():
    assert step_status(np.array([1.0, 2.0]), 1e6, True) == FINISHED
    assert step_status(np.array([1.0, 2.0]), 1e6, False) == NO_CONVERGENCE
    assert step_status(np.array([np.nan, 2.0]), 1e6, False) == DIVERGED
    assert step_status(np.array([1.0, 2e6]), 1e6, True) == DIVERGED
    assert message(NO_CONVERGENCE, 0.1) == \
        "the step's Newton iteration did not converge at t = 0.1 s"
    assert message(DIVERGED) == "the state became non-finite or diverged"
    assert Settings().rho_inf == 0.9 and Settings().max_iter == 50


def test_the_line_search_and_stagnation_tests():
    """Armijo's 1e-4 decrease, the last halving taken; the spatial loop's correction
    relative to max(1, |a|) and its stagnation from iteration 20 within 1e3 x tol."""
    assert backtrack_done(0.99989, 1.0, 1.0, 0, 30)
    assert not backtrack_done(0.99991, 1.0, 1.0, 0, 30)
    assert backtrack_done(2.0, 1.0, 1.0, 29, 30)
    assert spatial_converged(3, 9e-11, 1.0, 1.0, 1e-10, 20, 1e3) == (True, False)
    assert spatial_converged(19, 5e-8, 1.0, 6e-8, 1e-10, 20, 1e3) == (False, False)
    assert spatial_converged(20, 5e-8, 1.0, 6e-8, 1e-10, 20, 1e3) == (True, True)
    assert spatial_converged(20, 5e-8, 1.0, 2e-7, 1e-10, 20, 1e3) == (False, False)


class Oscillator(NamedTuple):
    """q'' + w2 q = 0 as a model of the one loop (solvers.loop.implements)."""
    w2: float


@njit(cache=True)
def _osc_residual(md, a1, st, c, first):
    q1, v1, _ = galpha_state(st.q, st.v, st.a, st.abar, a1, c)
    return a1 + md.w2 * q1, (np.eye(1) * (1.0 + md.w2 * c.bp), v1, st.z)


@njit(cache=True)
def _osc_tangent(md, ctx, st, c):
    return cholesky(ctx[0])


@njit(cache=True)
def _osc_id_residual(md, a1, st, c):
    r, ctx = _osc_residual(md, a1, st, c, True)
    return r, galpha_state(st.q, st.v, st.a, st.abar, a1, c)[0], ctx[1]


@njit(cache=True)
def _osc_factor(md, q1, v1, c):
    z2 = np.zeros((0, 0))
    return np.sqrt(np.eye(1) * (1.0 + md.w2 * c.bp)), z2, z2, z2, np.zeros(0, np.int64), z2, 0


for _hook, _fn in ((residual, _osc_residual), (tangent, _osc_tangent),
                   (id_residual, _osc_id_residual), (iteration_factor, _osc_factor)):
    implements(_hook, Oscillator, _fn)


@pytest.mark.parametrize("simplified, relative", [(False, False), (True, False),
                                                  (False, True)])
def test_the_one_loop_runs_any_model_it_is_given(simplified, relative):
    """solvers.loop.fixed_step on a model registered by its hooks (a linear oscillator,
    h omega = 0.2, 50 steps): full Newton (the planar test and the spatial relative one)
    and simplified Newton give the closed-form recurrence of :func:`oscillator` to 1e-12,
    every state recorded, status FINISHED."""
    x0 = np.array([1.0, 0.0])
    X, status, t, x, a, abar, it = fixed_step(Oscillator(4.0), 1, 0.0, x0, -4.0 * x0[:1],
                                              -4.0 * x0[:1], 0.1, 50, 1,
                                              Settings(tol=1e-14, relative=relative),
                                              empty_factor() if simplified else None)
    ref = oscillator(0.1, 50, omega=2.0)[0]
    assert status == FINISHED and t == pytest.approx(5.0)
    np.testing.assert_allclose(X[:, 0], ref, rtol=0, atol=1e-12)
    assert it <= 2 * 50


def test_the_spatial_newton_fails_a_step_on_an_indefinite_tangent():
    """The relative (spatial) Newton stops at a tangent that is not positive definite (the
    oscillator's 1 + w2 beta' < 0): status NO_CONVERGENCE at the first step, no iteration
    counted, the state left finite (the planar test takes the NaN correction: DIVERGED)."""
    x0 = np.array([1.0, 0.0])
    for relative, expected, count in ((True, NO_CONVERGENCE, 0), (False, DIVERGED, 50)):
        X, status, t, x, a, abar, it = fixed_step(Oscillator(-1e4), 1, 0.0, x0, x0[:1],
                                                  x0[:1], 0.1, 50, 1,
                                                  Settings(relative=relative), None)
        assert (status, it) == (expected, count) and t == pytest.approx(0.1)
