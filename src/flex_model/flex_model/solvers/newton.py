"""Newton's method for an implicit step (issue 43: one Newton): full Newton with
backtracking on the residual norm (the planar loops, solvers.galpha.galpha_fixed) and the
convergence tests of the spatial loop (a correction relative to the accelerations, the
stagnation at their round-off floor)."""
from __future__ import annotations

import numpy as np
from numba import njit

from ..kernels import solve_spd

_CACHE = True


@njit
def newton_backtracking(residual, tangent, x, step, c, tol, max_iter, backtrack, M, E):
    """Solve residual(x) = 0 by Newton on the matrix tangent(...) (symmetric positive
    definite), each correction dx shortened by halving until the residual norm falls
    (Armijo, 1e-4; at most ``backtrack`` halvings: regularized friction is nearly flat
    outside its narrow zone, where full steps overshoot across it), until the position
    correction c.bp |dx| lam is below ``tol``. ``residual(x, step, c, M, E)`` -> (r, B,
    v1, z1, g), ``tangent(B, v1, z1, g, step, c, M, E)``. Returns (x, z1, iterations,
    converged)."""
    res, B, v1, z1, g = residual(x, step, c, M, E)
    norm = np.sqrt(np.sum(res * res))
    for it in range(max_iter):
        dx = solve_spd(tangent(B, v1, z1, g, step, c, M, E), -res)
        lam = 1.0
        for ls in range(backtrack):
            x_try = x + lam * dx
            r_try, B_try, v_try, z_try, g_try = residual(x_try, step, c, M, E)
            n_try = np.sqrt(np.sum(r_try * r_try))
            if n_try <= (1.0 - 1e-4 * lam) * norm or n_try < 1e-300 or ls == backtrack - 1:
                break
            lam *= 0.5
        x, res, B, v1, norm, z1, g = x_try, r_try, B_try, v_try, n_try, z_try, g_try
        if np.max(np.abs(dx)) * lam * c.bp <= tol:
            return x, z1, it + 1, True
    return x, z1, max_iter, False


@njit(cache=_CACHE)
def spatial_converged(it, dmax, amax, dprev, tol, line_search_from, stagnation):
    """(converged, stagnated): the correction dmax within tol x amax (amax = max(1,
    |a|)), or, from iteration ``line_search_from`` on, a correction that no longer halves
    (dmax >= dprev / 2) within ``stagnation`` x tol x amax: the round-off floor of the
    accelerations of light deformation variables (spatial.integrate.STAGNATION)."""
    if it >= line_search_from and dmax <= stagnation * tol * amax and dmax >= 0.5 * dprev:
        return True, True
    return dmax <= tol * amax, False
