"""Settings and status of a time integration (issue 43's one settings object and one
status with a message, after scipy's OdeSolver and Exudyn's SolveDynamic settings)."""
from __future__ import annotations

from typing import NamedTuple

from numba import njit

#: status codes returned by the compiled loops (0, 1, 2 as the planar loops always did)
FINISHED = 0
DIVERGED = 1
NO_CONVERGENCE = 2

MESSAGES = {FINISHED: "finished",
            DIVERGED: "the state became non-finite or diverged",
            NO_CONVERGENCE: "the step's Newton iteration did not converge"}


#: a failed step is tried again as 4, then 16 times shorter steps (Settings.refinements)
REFINEMENTS = (4, 16)


class Settings(NamedTuple):
    """Settings of the fixed-step generalized-alpha solver. ``tol``: the Newton
    correction's bound (planar: position correction beta' |da|, m or rad; spatial:
    |da| relative to max(1, |a|)); ``max_iter`` Newton iterations a step; ``backtrack``:
    halvings of the backtracking line search (planar); ``relative``: the spatial Newton
    (solvers.loop.newton), ``line_search_from``, ``halvings``, ``stagnation``: its line
    search and stagnation test (newton.spatial_converged); ``limit``: a state component
    beyond it is a divergence; ``refinements``: a failed step is tried again as that many
    times shorter steps, in turn (the model node's retry and, with its first entry, the
    spatial loop's; :func:`refine`)."""
    rho_inf: float = 0.9
    tol: float = 1e-10
    max_iter: int = 50
    backtrack: int = 30
    relative: bool = False
    line_search_from: int = 20
    halvings: int = 8
    stagnation: float = 1e3
    limit: float = 1e6
    refinements: tuple = REFINEMENTS


def refine(attempt, refinements=REFINEMENTS, errors=(RuntimeError,)) -> int:
    """The retry policy of a failed step: ``attempt(k)`` (the same span in k times
    shorter steps, from the same state) for k = 1, then each k of ``refinements`` in turn
    until one does not raise ``errors``. Returns that k; raises the first failure if every
    one fails (the model node's stepper and spatial period)."""
    try:
        attempt(1)
        return 1
    except errors as first:
        failure = first
    for k in refinements:
        try:
            attempt(k)
            return k
        except errors:
            continue
    raise failure


def message(status: int, t: float | None = None) -> str:
    """One line for a run's status code, with the time reached."""
    text = MESSAGES.get(int(status), f"unknown status {status}")
    return text if t is None or status == FINISHED else f"{text} at t = {t:.6g} s"


@njit(cache=True)
def newton_settings(rho_inf, tol, limit):
    """:class:`Settings` with these three and the other defaults, in compiled code (numba
    builds a NamedTuple from positional arguments only)."""
    return Settings(rho_inf, tol, 50, 30, False, 20, 8, 1e3, limit, REFINEMENTS)
