"""The one solver layer of flex_model (issue 43): generalized-alpha stepping, Newton, the
settings and the status of a run, for the planar and the spatial arms alike.

- :mod:`.galpha`: Chung-Hulbert's parameters from rho_inf (the only copy of that formula),
  the Arnold-Bruls update of (q, v, abar) from an acceleration iterate, the restart after
  an input discontinuity and the status of a step;
- :mod:`.newton`: the pieces of the Newton iterations (the backtracking test on the
  residual norm, the stagnation test of the spatial loop);
- :mod:`.status`: the settings (rho_inf, tolerances, iteration limits) and the status of a
  run (finished / diverged / no convergence) with its one-line message.

Each model keeps its compiled fixed-step entry point (integrators.generalized_alpha and
generalized_alpha_simplified, exact_kinematics.generalized_alpha,
spatial.compiled.galpha_loop) built from these pieces (solvers.newton says why the loop
itself is not passed the residual as a function).
"""
