"""Newton's method for an implicit step (issue 43): the backtracking line search of the
planar full Newton (integrators.PlanarModel and exact_kinematics.ExactModel) and the
convergence test of the spatial one (a correction relative to the accelerations, the
stagnation at their round-off floor; spatial.compiled.SpatialModel).

solvers.loop holds the one Newton loop, generic over the model through hooks chosen by the
type of the model's data (numba.extending.overload): numba (0.68) does not cache a function
that receives the residual as a first-class function and allocates or does array
arithmetic (measured: "Cannot cache compiled function ... as it uses dynamic globals")."""
from __future__ import annotations

import numpy as np
from numba import njit

_CACHE = True


@njit(cache=_CACHE)
def residual_norm(r):
    """Euclidean norm of a residual (the backtracking's merit)."""
    return np.sqrt(np.sum(r * r))


@njit(cache=_CACHE)
def max_abs(r):
    """Largest |r_i| (0 if empty; a NaN passed over, as by Python's max): the spatial test's."""
    m = 0.0
    for i in range(r.shape[0]):
        m = max(m, abs(r[i]))
    return m


@njit(cache=_CACHE)
def backtrack_done(n_try, norm, lam, ls, halvings):
    """True when a correction shortened to ``lam`` (halving ``ls`` of at most ``halvings``)
    is taken: its residual norm ``n_try`` falls by Armijo's 1e-4 lam below ``norm``, is
    zero, or the halvings are used up (regularized friction is nearly flat outside its
    narrow zone, where full Newton steps overshoot across it)."""
    return n_try <= (1.0 - 1e-4 * lam) * norm or n_try < 1e-300 or ls == halvings - 1


@njit(cache=_CACHE)
def spatial_converged(it, dmax, amax, dprev, tol, line_search_from, stagnation):
    """(converged, stagnated): the correction dmax within tol x amax (amax = max(1,
    |a|)), or, from iteration ``line_search_from`` on, a correction that no longer halves
    (dmax >= dprev / 2) within ``stagnation`` x tol x amax: the round-off floor of the
    accelerations of light deformation variables (spatial.integrate.STAGNATION)."""
    if it >= line_search_from and dmax <= stagnation * tol * amax and dmax >= 0.5 * dprev:
        return True, True
    return dmax <= tol * amax, False
