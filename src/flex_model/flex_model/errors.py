"""The failures of the solvers, planar and spatial alike: one family that every entry point
reports as one line (:func:`flex_model.command.run_command`, exit code 1)."""


class SolverError(RuntimeError):
    """A computation that did not reach its answer; the message says where and why."""


class SimulationDivergedError(SolverError):
    """The state became non-finite or diverged, or a step's Newton iteration did not
    converge; the message says when and which variable."""


class StaticConvergenceError(SolverError):
    """Newton's method did not converge to a static equilibrium."""
