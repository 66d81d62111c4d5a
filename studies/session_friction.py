"""A twin that takes its hub's friction, and a constant hub torque, from the run's own
start (issue 22).

The CU Boulder sessions hold different frictions: Hagenau's K1K2 runs stick 59-65 mrad
short at ~0.07 N m where the K1K2K3 runs reach the reference, and the rigid-bar runs of
different sessions want different levels. Within a session the up- and down-steps stop
short by different amounts (flexarm_K1K2_6_-5: 59-65 against 15-28 mrad), as a constant
torque at the hub would make them (a cable's pull, an amplifier offset: the law's
``voltage_offset`` V_0). One fixed twin cannot follow either. Here the stick-slip twin's
F_c (and V_0) are set per run from its start alone on a lattice: from the first step
(``steps=1``: the start to the second step), or from the first period (``steps=2``: to the
third step, one up- and one down-step, which V_0 needs); every twin is then scored on the
rest of the run only, which the choice did not see. What the fixed twin loses against the
session twins is what the sessions' spread costs a twin of fixed levels.
"""
from __future__ import annotations

import dataclasses

import numpy as np

from flex_model.arm import ArmDescription
from flex_model.dynamics import FlexArmModel
from flex_model.effects import StickSlipFriction
from flex_twin.real_arms.replay import rms, replay

#: pre-sliding displacement F_s / sigma_0 at the hub (rad): one encoder count
#: (2 pi / 4096) of the SRV02's output-shaft encoder
PRESLIDING = 2 * np.pi / 4096
STRIBECK_VELOCITY = 0.01     # rad/s, as the calibrated joint_friction
ELASTIC_FRACTION = 0.5


def with_stick_slip(arm: ArmDescription, coulomb=None, static=None, viscous=None,
                    presliding: float = PRESLIDING) -> ArmDescription:
    """The arm with its joint_friction (or given levels) as stick_slip_friction; the
    bristles critically damped for the hub's inertia n^2 J_r + J_hub + link."""
    from flex_twin.diagnosis.hypotheses import joint_inertias
    j = arm.joint_names[0]
    fr = arm.effect("joint_friction", j)
    fv = viscous if viscous is not None else (fr["viscous"] if fr else 0.0)
    fc = coulomb if coulomb is not None else (fr["coulomb"] if fr else 0.0)
    fs = static if static is not None else (fr["static"] if fr else 0.0)
    fs = max(fs, fc)
    base = dataclasses.replace(arm, effects=tuple(e for e in arm.effects
                                                  if e.TYPE != "joint_friction"))
    inertia = float(joint_inertias(base, [0.0])[0])
    sigma0 = max(fs, 1e-6) / presliding
    return base.with_effects(StickSlipFriction(j, (
        fv, fc, fs, STRIBECK_VELOCITY, sigma0, 2.0 * np.sqrt(sigma0 * inertia),
        ELASTIC_FRACTION)))


#: the lattice of Coulomb levels (N m at the hub) the start chooses from
LEVELS = tuple(np.round(np.arange(0.02, 0.105, 0.01), 3))
#: the lattice of voltage offsets V_0 (V; 0.157 N m/V at the hub)
OFFSETS = tuple(np.round(np.arange(-0.25, 0.2505, 0.05), 3) + 0.0)   # + 0.0: no -0.0
#: the least scored time after the choice window (s): one hold of the CU Boulder square wave
MIN_SCORED = 2.5


def choice_end(run, steps: int = 1) -> int:
    """Sample index of the run's reference step number ``steps`` + 1 (the choice window
    ends there); ValueError when the run has no such step or less than :data:`MIN_SCORED`
    after it (10 s runs with two steps 5 s apart leave 0.5-3.4 s after the second)."""
    idx = run.step_indices()
    if len(idx) < steps + 1:
        raise ValueError(f"{run.name}: {len(idx)} reference step(s); choosing on {steps} "
                         "needs a later one to score on")
    left = run.t[-1] - run.t[idx[steps]]
    if left < MIN_SCORED:
        raise ValueError(f"{run.name}: {left:.2f} s after its step {steps + 1}; at least "
                         f"{MIN_SCORED} s needed to score on")
    return int(idx[steps])


def window_errors(result, start: int) -> tuple:
    """Hub RMS (rad) and tip RMS (m, None without a gauge) of a replay from ``start`` on."""
    run, n = result.run, len(result.t)
    hub = rms(result.twin_theta[start:] - run.theta[start:n])
    if not run.has_gauge:
        return hub, None
    return hub, rms(result.twin_deflection[start:] - run.deflection[start:n])


def lab_policy(voltage_offset: float = 0.0):
    """The replay's ``make_policy``: the run's lab law with a voltage offset V_0."""
    from flex_control.state_feedback import lab_policy_factory

    def make(run, model):
        return lab_policy_factory(run, model, voltage_offset=voltage_offset)
    return make


def session_levels(arm, run, static: float, steps: int = 1, levels=LEVELS,
                   offsets=(0.0,)) -> tuple:
    """The (F_c, V_0) of ``levels`` x ``offsets`` whose stick-slip twin (F_s = max(F_c,
    ``static``)) follows the hub best over the choice window (least hub RMS up to
    :func:`choice_end`). Returns ((F_c, V_0), {(F_c, V_0): hub RMS})."""
    end = choice_end(run, steps)
    table = {}
    for fc in levels:
        model = FlexArmModel(with_stick_slip(arm, coulomb=float(fc),
                                             static=max(float(fc), static)))
        for v0 in offsets:
            r = replay(model, run, lab_policy(float(v0)), t_final=float(run.t[end]))
            table[(float(fc), float(v0))] = window_errors(r, 0)[0]
    return min(table, key=table.get), table


def compare(arm, run, coulomb: float, static: float, steps: int = 1,
            offsets=(0.0,), levels=LEVELS) -> dict:
    """Scored after the choice window (:func:`choice_end`): the calibrated twin ``arm``, its
    stick-slip twin of fixed levels (``coulomb``, ``static``), the session twin (F_c chosen
    on the window) and, with more than one offset, the session twin with F_c and V_0
    chosen together."""
    end = choice_end(run, steps)
    (fo, v0), table = session_levels(arm, run, static, steps, levels,
                                     tuple(offsets) + (() if 0.0 in offsets else (0.0,)))
    alone = {k: v for k, v in table.items() if k[1] == 0.0}
    fc = min(alone, key=alone.get)[0]
    row = {"run": run.name, "steps_chosen_on": steps, "scored_from_s": float(run.t[end]),
           "session_coulomb": fc, "choice_table": {f"{k[0]:g}": v for k, v in alone.items()}}
    twins = [("calibrated", arm, 0.0),
             ("fixed", with_stick_slip(arm, coulomb=coulomb, static=static), 0.0),
             ("session", with_stick_slip(arm, coulomb=fc, static=max(fc, static)), 0.0)]
    if len(offsets) > 1:
        row.update(session_offset_coulomb=fo, session_offset_V=v0)
        twins.append(("session_offset", with_stick_slip(arm, coulomb=fo,
                                                        static=max(fo, static)), v0))
    for label, twin, v in twins:
        hub, tip = window_errors(replay(FlexArmModel(twin), run, lab_policy(v)), end)
        row[label] = {"hub_rms_rad": hub, "tip_rms_m": tip}
    return row


def summarize(rows) -> dict:
    """Medians over the rows (hub over all, tip over those with a gauge) per twin, and how
    many rows have the hub under the 0.01 rad aim."""
    out = {"runs": len(rows)}
    for label in ("calibrated", "fixed", "session", "session_offset"):
        have = [r[label] for r in rows if label in r]
        if not have:
            continue
        hub = np.array([m["hub_rms_rad"] for m in have])
        tips = [m["tip_rms_m"] for m in have if m["tip_rms_m"] is not None]
        out[label] = {"hub_rms_median_rad": float(np.median(hub)),
                      "hub_under_aim": int(np.sum(hub < 0.01)),
                      "tip_rms_median_m": float(np.median(tips)) if tips else float("nan")}
    return out
