"""The one solver layer of flex_model (issue 43): generalized-alpha stepping, Newton, the
settings and the status of a run, for the planar and the spatial arms alike.

- :mod:`.galpha`: Chung-Hulbert's parameters from rho_inf (the only copy of that formula),
  the Arnold-Bruls update of (q, v, abar) from an acceleration iterate, the restart after
  an input discontinuity and the fixed-step loop with full Newton;
- :mod:`.newton`: the Newton iterations (backtracking on the residual norm, the halving
  line search and the stagnation test of the spatial loop);
- :mod:`.status`: the settings (rho_inf, tolerances, iteration limits) and the status of a
  run (finished / diverged / no convergence) with its one-line message.

Compiled loops take the model's residual and iteration matrix as first-class numba
functions; each model module wraps them in its own cached entry point.
"""
