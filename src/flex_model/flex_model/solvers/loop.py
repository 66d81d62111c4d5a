"""The one compiled fixed-step generalized-alpha loop (issue 43) and its Newton iterations,
generic over the model.

The model is the first argument ``md``, a NamedTuple of its compiled data (the planar arm's
integrators.PlanarModel, the exact kinematics' exact_kinematics.ExactModel, the spatial
arm's spatial.compiled.SpatialModel). The loop calls the model's equations through four
hooks whose implementation numba picks at compile time by the TYPE of ``md``
(:func:`implements`, numba.extending.overload): one machine code per model, cached on disk
like any njit function (a first-class residual function is not cached: solvers.newton). A
model module registers its hooks when imported:

- ``residual(md, a1, st, c, first)`` -> (r, ctx): the residual of a step (solvers.galpha.
  Step st, coefficients c) at the acceleration iterate a1 (``first``: the step's first,
  where the spatial arm takes M); ctx what ``tangent`` needs, ctx[2] the bristle
  deflections at the step's end (st.z without bristles);
- ``tangent(md, ctx, st, c)``: the Cholesky factor (kernels.cholesky) of the iteration
  matrix B + gamma' (D + C_j) + beta' (K + K_j), empty when it is not positive definite;
- ``id_residual(md, a1, st, c)`` -> (r, q1, v1): the residual of simplified Newton
  (no bristles);
- ``iteration_factor(md, q1, v1, c)``: a factor of the iteration matrix at (q1, v1)
  (iteration_matrix's factor tuple; empty when it is not positive definite).
"""
from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np
from numba import njit, types
from numba.extending import overload

from ..iteration_matrix import empty_factor, factor_solve
from ..kernels import solve_chol
from .galpha import Step, galpha_coefficients, galpha_state, step_status
from .newton import backtrack_done, max_abs, residual_norm, spatial_converged
from .status import FINISHED

_CACHE = True
#: simplified Newton: a contraction rate above this refreshes the iteration matrix for the
#: next step (section E: 2.2 iterations per step, as with a fresh matrix every step; 2.9
#: when refreshed only on divergence)
THETA_REFRESH = 0.003
#: the same for the banded-plus-low-rank matrix (flex_model.iteration_matrix), itself an
#: approximation (contraction about 0.002 on the hub-less arm): a fresh one would not
#: contract faster
THETA_REFRESH_STRUCTURED = 0.03


def residual(md, a1, st, c, first):
    """Hook: (r, ctx) of a step at the iterate a1 (module docstring)."""


def tangent(md, ctx, st, c):
    """Hook: the factor of the iteration matrix at ctx (module docstring)."""


def id_residual(md, a1, st, c):
    """Hook: (r, q1, v1) of simplified Newton at the iterate a1 (module docstring)."""


def iteration_factor(md, q1, v1, c):
    """Hook: the factor of the iteration matrix at (q1, v1) (module docstring)."""


def implements(hook, model_type, fn):
    """Register the njit function ``fn`` (the hook's argument names) as ``hook`` for model
    data of the NamedTuple class ``model_type``."""
    def typer(*args):
        md = args[0]
        if isinstance(md, types.BaseNamedTuple) and md.instance_class is model_type:
            return fn.py_func
    typer.__signature__ = inspect.signature(hook)
    overload(hook, jit_options={"cache": _CACHE})(typer)


@njit(cache=_CACHE)
def newton(md, st, c, a1, s):
    """(a1, z1, iterations, converged) of full Newton on the step's residual from a1, at
    most ``s.max_iter`` iterations (solvers.status.Settings s), by one of two tests and
    line searches. Planar (not ``s.relative``): backtracking on the residual norm, up to
    ``s.backtrack`` halvings (solvers.newton.backtrack_done), until beta' |da| <= ``s.tol``
    (m or rad). Spatial: from iteration ``s.line_search_from`` on, a correction that raised
    the largest residual is halved (half of it taken back: an iteration), up to
    ``s.halvings`` times in a row, until |da| <= ``s.tol`` max(1, |a1|) or stagnates
    (solvers.newton.spatial_converged); a tangent not positive definite fails the step."""
    n = a1.shape[0]
    res, ctx = residual(md, a1, st, c, True)
    norm = max_abs(res) if s.relative else residual_norm(res)
    prev, dprev, back, it = np.inf, np.inf, 0, 0
    da = np.zeros(n)
    while it < s.max_iter:
        if s.relative and it >= s.line_search_from and norm > prev and back < s.halvings:
            da *= 0.5
            a1, back = a1 - da, back + 1
        else:
            prev, back = norm, 0
            L = tangent(md, ctx, st, c)
            if L.shape[0] < n and s.relative:
                break
            da = solve_chol(L, -res) if L.shape[0] == n else np.full(n, np.nan)
            if not s.relative:
                lam = 1.0
                for ls in range(s.backtrack):
                    a_try = a1 + lam * da
                    r_try, c_try = residual(md, a_try, st, c, False)
                    n_try = residual_norm(r_try)
                    if backtrack_done(n_try, norm, lam, ls, s.backtrack):
                        break
                    lam *= 0.5
                a1, res, ctx, norm = a_try, r_try, c_try, n_try
                it += 1
                if np.max(np.abs(da)) * lam * c.bp <= s.tol:
                    return a1, ctx[2], it, True
                continue
            a1 = a1 + da
            if not np.all(np.isfinite(a1)):
                return a1, ctx[2], it + 1, False
            dmax = max_abs(da)
            if spatial_converged(it, dmax, max(1.0, max_abs(a1)), dprev, s.tol,
                                 s.line_search_from, s.stagnation)[0]:
                return a1, ctx[2], it + 1, True
            dprev = dmax
        it += 1
        res, ctx = residual(md, a1, st, c, False)
        norm = max_abs(res)
    return a1, ctx[2], it, False


@njit(cache=_CACHE)
def simplified_newton(md, a1, st, c, tol, F):
    """One step by simplified Newton (Hairer-Wanner IV.8): the factor F of the iteration
    matrix is kept from earlier steps, refreshed here (at the predictor) when the
    corrections contract by less than half per iteration. The iterations stop, without
    evaluating the next residual, when the position correction ``|da| beta'`` is below
    ``tol`` (as full Newton's; the error left is theta times that, theta the contraction
    rate). Returns (a1, F, theta, iterations, ok); ok False when even a fresh factor does
    not converge (the caller then takes full Newton)."""
    iters = 0
    theta = 0.0
    for attempt in range(2):
        x1 = a1.copy()
        res = id_residual(md, x1, st, c)[0]
        prev = 0.0
        for it in range(12):
            da = factor_solve(F, -res)
            nd = 0.0
            for i in range(da.shape[0]):
                x1[i] += da[i]
                nd = max(nd, abs(da[i]))
            nd *= c.bp
            iters += 1
            if not np.isfinite(nd):
                break
            if it > 0:
                theta = nd / prev if prev > 0.0 else 0.0
                if theta >= 0.5:
                    break
            if nd <= tol:
                return x1, F, theta, iters, True
            prev = nd
            res = id_residual(md, x1, st, c)[0]
        # slow or diverging: a fresh factor at the predictor's state, once
        _, q1, v1 = id_residual(md, a1, st, c)
        F = iteration_factor(md, q1, v1, c)
        theta = 0.0
        if F[0].shape[0] == 0:
            break
    return a1, F, theta, iters, False


@njit(cache=_CACHE)
def _simplified(md, st, c, tol, F, a_old, extrapolate):
    """(a1, F, iterations, ok) of a step by :func:`simplified_newton` from the
    acceleration extrapolated linearly (``extrapolate``), a factor made at the step's
    start when F is empty, F emptied when the iterations contract slowly."""
    a1 = st.a.copy()
    if F[0].shape[0] == 0:
        _, q1, v1 = id_residual(md, a1, st, c)
        F = iteration_factor(md, q1, v1, c)
    if extrapolate:
        a1 = 2.0 * st.a - a_old
    if F[0].shape[0] == 0:
        return a1, F, 0, False
    a1, F, theta, it, ok = simplified_newton(md, a1, st, c, tol, F)
    if ok and theta > (THETA_REFRESH_STRUCTURED if F[6] == 1 else THETA_REFRESH):
        F = empty_factor()  # contracting slowly: a fresh factor next step
    return a1, F, it, ok


@njit(cache=_CACHE)
def fixed_step(md, n, t0, x0, a0, abar0, h, n_steps, every, s, F0):
    """Fixed-step generalized-alpha (Chung-Hulbert, in the Arnold-Bruls form: solvers.
    galpha) on the model ``md`` with n coordinates, x = [q; v; z] (z: bristle
    deflections, advanced inside the residual). Each step solves the residual at the
    mid-step time (a pulse edge on the step grid is resolved exactly) by :func:`newton`
    (``F0`` None: numba compiles no other path) or, with ``F0`` an empty factor and no
    bristles, by :func:`simplified_newton` (factor kept across steps, acceleration
    extrapolated; a step it cannot solve takes full Newton). ``s``: solvers.status.Settings
    (rho_inf, tol, max_iter, backtrack, limit).

    Returns ``(X, status, t_end, x_end, a_end, abar_end, iterations)``; X holds every
    ``every``-th state, X[0] = x0; status of solvers.status (DIVERGED: non-finite or
    beyond ``s.limit``; NO_CONVERGENCE: Newton did not converge)."""
    simplified = x0.shape[0] == 2 * n
    c = galpha_coefficients(s.rho_inf, h)
    X = np.full((n_steps // every + 1, x0.shape[0]), np.nan)
    X[0] = x0
    q, v, z = x0[:n].copy(), x0[n:2 * n].copy(), x0[2 * n:].copy()
    a, abar, a_old = a0.copy(), abar0.copy(), a0.copy()
    t = t0
    r = 1
    iters = 0
    F = empty_factor()
    for k in range(1, n_steps + 1):
        t1 = t0 + k * h
        st = Step(q, v, z, a, abar, t1 - 0.5 * h, k - 1)
        ok = False
        z1 = z
        if F0 is not None:
            if simplified:
                a1, F, it, ok = _simplified(md, st, c, s.tol, F, a_old, k > 1)
                iters += it
        if not ok:  # full Newton for this step, a fresh factor for the next
            if F0 is not None:
                F = empty_factor()
            a1, z1, it, ok = newton(md, st, c, a.copy(), s)
            iters += it
        q, v, abar = galpha_state(q, v, a, abar, a1, c)
        a_old, a, z, t = a, a1, z1, t1
        x = np.concatenate((q, v, z))
        status = step_status(x, s.limit, ok)
        if status != FINISHED:
            return X, status, t, x, a, abar, iters
        if k % every == 0:
            X[r] = x
            r += 1
    return X, FINISHED, t, np.concatenate((q, v, z)), a, abar, iters


# numba re-compiles a cached function when its own file changes, not when a function it
# calls does: the loop inlines the models' hooks, so flush its caches when they change
def _guard_caches():
    from ..numba_cache import guard
    root = Path(__file__).resolve().parent.parent
    files = ["kernels.py", "iteration_matrix.py", "integrators.py", "exact_kinematics.py",
             "effects/friction.py", "effects/stick_slip.py", "solvers/galpha.py",
             "solvers/newton.py", "spatial/compiled.py", "spatial/exact.py"]
    guard([obj for obj in globals().values() if hasattr(obj, "py_func")
           and obj.py_func.__module__ == __name__], [root / f for f in files])


_guard_caches()
