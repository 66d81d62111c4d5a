"""Settings and status of a time integration (issue 43's one settings object and one
status with a message, after scipy's OdeSolver and Exudyn's SolveDynamic settings)."""
from __future__ import annotations

from typing import NamedTuple

#: status codes returned by the compiled loops (0, 1, 2 as the planar loops always did)
FINISHED = 0
DIVERGED = 1
NO_CONVERGENCE = 2

MESSAGES = {FINISHED: "finished",
            DIVERGED: "the state became non-finite or diverged",
            NO_CONVERGENCE: "the step's Newton iteration did not converge"}


class Settings(NamedTuple):
    """Settings of the fixed-step generalized-alpha solver. ``tol``: the Newton
    correction's bound (planar: position correction beta' |da|, m or rad; spatial:
    |da| relative to max(1, |a|)); ``max_iter`` Newton iterations a step; ``backtrack``:
    halvings of the backtracking line search (planar full Newton); ``line_search_from``,
    ``halvings``, ``stagnation``: the spatial loop's halving line search and
    stagnation test (:func:`flex_model.solvers.newton.spatial_converged`); ``limit``: a
    state component beyond it is a divergence; ``substeps``: a failed step is tried
    again as that many shorter steps (0: fail)."""
    rho_inf: float = 0.9
    tol: float = 1e-10
    max_iter: int = 50
    backtrack: int = 30
    line_search_from: int = 20
    halvings: int = 8
    stagnation: float = 1e3
    limit: float = 1e6
    substeps: int = 4


def message(status: int, t: float | None = None) -> str:
    """One line for a run's status code, with the time reached."""
    text = MESSAGES.get(int(status), f"unknown status {status}")
    return text if t is None or status == FINISHED else f"{text} at t = {t:.6g} s"
