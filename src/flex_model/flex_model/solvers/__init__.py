"""The one solver layer of flex_model (issue 43): generalized-alpha stepping, Newton, the
settings and the status of a run, for the planar and the spatial arms alike.

- :mod:`.galpha`: Chung-Hulbert's parameters from rho_inf (the only copy of that formula),
  the Arnold-Bruls update of (q, v, abar) from an acceleration iterate, the restart after
  an input discontinuity and the status of a step;
- :mod:`.newton`: the pieces of the Newton iterations (the backtracking test on the
  residual norm, the relative and stagnation test of the spatial arm);
- :mod:`.status`: the settings (rho_inf, tolerances, iteration limits, the
  refinements of a failed step and :func:`.status.refine`, the retry) and the status
  of a run (finished / diverged / no convergence) with its one-line message;
- :mod:`.loop`: the one compiled fixed-step loop and its full and simplified Newton,
  generic over the model (its hooks chosen at compile time by the type of the model's
  data: the planar arm's, the exact kinematics' and the spatial arm's).
"""
