"""A twin that takes its hub's Coulomb friction from the run's own first step (issue 22).

The CU Boulder sessions hold different frictions: Hagenau's K1K2 runs stick 59-65 mrad
short at ~0.07 N m where the K1K2K3 runs reach the reference, and the rigid-bar runs of
different sessions want different levels. One fixed twin cannot follow both. Here the
stick-slip twin's F_c is set per run from the first step alone (the reference's first
square-wave period: from the start to the second step) on a lattice, and every twin is
scored on the rest of the run only, which the choice did not see. The difference between
the fixed and the session twin's score is what the sessions' friction spread costs a twin
of fixed levels.
"""
from __future__ import annotations

import numpy as np

from flex_model.dynamics import FlexArmModel
from .replay import _rms, replay
from .stick_slip_study import with_stick_slip

#: the lattice of Coulomb levels (N m at the hub) the first step chooses from
LEVELS = tuple(np.round(np.arange(0.02, 0.105, 0.01), 3))
#: the least scored time after the second step (s): one hold of the CU Boulder square wave
MIN_SCORED = 2.5


def first_step_end(run) -> int:
    """Sample index of the run's second reference step (the first step's window ends);
    ValueError when the run has no second step or less than :data:`MIN_SCORED` after it
    (10 s runs with two steps 5 s apart leave 0.5-3.4 s)."""
    steps = run.step_indices()
    if len(steps) < 2:
        raise ValueError(f"{run.name}: {len(steps)} reference step(s); the session level "
                         "needs a first step and a later one to score on")
    if run.t[-1] - run.t[steps[1]] < MIN_SCORED:
        raise ValueError(f"{run.name}: {run.t[-1] - run.t[steps[1]]:.2f} s after its second "
                         f"step; at least {MIN_SCORED} s needed to score on")
    return int(steps[1])


def window_errors(result, start: int) -> tuple:
    """Hub RMS (rad) and tip RMS (m, None without a gauge) of a replay from ``start`` on."""
    run, n = result.run, len(result.t)
    hub = _rms(result.twin_theta[start:] - run.theta[start:n])
    if not run.has_gauge:
        return hub, None
    return hub, _rms(result.twin_deflection[start:] - run.deflection[start:n])


def session_coulomb(arm, run, make_policy, static: float, levels=LEVELS) -> tuple:
    """The F_c of ``levels`` whose stick-slip twin (F_s = max(F_c, ``static``)) follows the
    hub over the first step best (least hub RMS up to :func:`first_step_end`).
    Returns (F_c, {F_c: hub RMS})."""
    end = first_step_end(run)
    table = {}
    for fc in levels:
        twin = with_stick_slip(arm, coulomb=float(fc), static=max(float(fc), static))
        r = replay(FlexArmModel(twin), run, make_policy, t_final=float(run.t[end]))
        table[float(fc)] = window_errors(r, 0)[0]
    return min(table, key=table.get), table


def compare(arm, run, make_policy, coulomb: float, static: float) -> dict:
    """The calibrated twin ``arm``, its stick-slip twin of fixed levels (``coulomb``,
    ``static``) and the session twin (F_c from the first step) scored after the first step."""
    end = first_step_end(run)
    fc, table = session_coulomb(arm, run, make_policy, static)
    row = {"run": run.name, "scored_from_s": float(run.t[end]), "session_coulomb": fc,
           "first_step_table": table}
    for label, twin in (("calibrated", arm),
                        ("fixed", with_stick_slip(arm, coulomb=coulomb, static=static)),
                        ("session", with_stick_slip(arm, coulomb=fc, static=max(fc, static)))):
        hub, tip = window_errors(replay(FlexArmModel(twin), run, make_policy), end)
        row[label] = {"hub_rms_rad": hub, "tip_rms_m": tip}
    return row


def summarize(rows) -> dict:
    """Medians over the rows (hub over all, tip over those with a gauge) per twin."""
    out = {"runs": len(rows)}
    for label in ("calibrated", "fixed", "session"):
        tips = [r[label]["tip_rms_m"] for r in rows if r[label]["tip_rms_m"] is not None]
        out[label] = {"hub_rms_median_rad": float(np.median([r[label]["hub_rms_rad"]
                                                             for r in rows])),
                      "tip_rms_median_m": float(np.median(tips)) if tips else float("nan")}
    return out
