"""Does the chosen time step resolve the arm? One line of advice before a simulation.

The modes that matter are those a joint torque excites: for mode k (mass-normalized shape
phi_k, circular frequency omega_k) the static tip of a unit torque step at joint j holds the
share ``(G phi_k)_j^2 / omega_k^2`` of the joint's static compliance (modal expansion of
K^-1). The highest mode with at least ``share`` (1 %) of some joint's compliance is the
highest *excited* mode f_x. Generalized-alpha at step h follows a mode of period T with
a phase error growing with h/T and damps it the more the closer h/T gets to 1; below
``steps_per_period`` (4) steps per period of f_x the fixed step misses the response to
torque and set-point jumps: the advice names f_x and the step it needs, 1 / (4 f_x).
Calibrated on the hub-less two-link arm of issue 24 (bench/bench_stiff_hubless.py: f_x
1706 Hz, 1 / (4 f_x) = 0.15 ms; tip deflections 1.8 % off at 0.25 ms, 0.36 % at
0.125 ms, Newton fails at 1 ms after the 15 deg set-point step). The explicit variable-step mode
(Dormand-Prince) is bounded by stability at about 3.3 / omega_max per step whatever the
tolerance: with the highest mode of the arm above 10^4 x 3.3 / (2 pi) = 5.3 kHz that is
> 10^4 steps per simulated second, and the advice suggests the fixed mode.

The modal rule is necessary, not sufficient: on hub-less arms whose excited modes are
resolved (2 variables per link, f_x 143-317 Hz, 5-7 steps per period at 1 ms) or whose
root mode is left to the filtered restart (integrators.restart_acceleration, 4 variables
per link and more) the fixed step was 1.0-3.9 % off while the rule was quiet
(bench/bench_stiff_hubless.py with --kp/--kd/--joint/--deg). Where fewer than
``PROBE_STEPS_PER_PERIOD`` steps fall in a period of f_x, :func:`step_halving_error`
measures instead: the run's first jump at the step and at half of it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Dormand-Prince 5(4): stability interval on the imaginary axis, |h omega| <= ~3.3
DOPRI_STABILITY = 3.3
#: variable mode: warn above this many stability-bound steps per simulated second
MAX_VARIABLE_STEPS = 1e4
#: fixed mode: with fewer steps per period of the highest excited mode, a quiet modal rule
#: is checked by halving the step (step_halving_error)
PROBE_STEPS_PER_PERIOD = 20.0
#: fixed mode: the tolerated error of a tip deflection, share of its largest value
TIP_TOLERANCE = 0.01


@dataclass(frozen=True)
class StepAdvice:
    highest_mode_hz: float          # the arm's highest mode (linearized, joints as run)
    highest_excited_mode_hz: float  # the highest a joint torque step excites (>= share)
    step_needed_s: float            # 1 / (steps_per_period f_x)
    variable_steps_per_s: float     # stability-bound steps of the explicit mode per s
    warning: str | None
    #: fixed mode, where measured (step_halving_error): estimated error of each link's tip
    #: deflection, share of its largest value
    tip_error: tuple | None = None


def step_advice(model, joint_angles, *, method: str, step: float | None = None,
                kp=None, share: float = 0.01, steps_per_period: float = 4.0) -> StepAdvice:
    """Advice for integrating ``model`` near ``joint_angles`` (rad) with ``method``
    (fixed: ``step`` s, default 1 ms); ``kp`` the joint PD gains (N m/rad; none: clamped
    joints for the frequencies, a torque then acts on the flexible links alone)."""
    from .modes import natural_modes
    joints = "pd" if kp is not None and np.any(np.asarray(kp) > 0) else "clamped"
    res = natural_modes(model, joint_angles, joints=joints,
                        kp=None if joints == "clamped" else np.asarray(kp, float))
    omega = np.asarray(res.omega, float)
    G = model.G
    gphi = G @ np.asarray(res.shapes_q)  # (joints, modes): modal force of a unit torque
    flexible = omega > 1e-6 * max(omega.max(), 1.0)
    comp = np.zeros_like(gphi)
    comp[:, flexible] = gphi[:, flexible] ** 2 / omega[flexible] ** 2
    total = comp.sum(axis=1, keepdims=True)
    frac = np.divide(comp, total, out=np.zeros_like(comp), where=total > 0)
    excited = np.any(frac >= share, axis=0)
    f_max = float(omega.max() / (2 * np.pi))
    f_x = float(omega[excited].max() / (2 * np.pi)) if np.any(excited) else 0.0
    needed = 1.0 / (steps_per_period * f_x) if f_x > 0 else np.inf
    n_var = float(omega.max() / DOPRI_STABILITY)
    warning = None
    if method == "fixed":
        h = step or 1e-3
        if h > needed * (1 + 1e-9):
            warning = (f"step {h:.3g} s cannot resolve the arm: a joint torque excites its "
                       f"mode at {f_x:.4g} Hz ({1 / (f_x * h):.1f} steps per period); it needs "
                       f"a step of {needed:.2g} s or less (numerical damping does not help: "
                       "the mode is part of the response; hub inertia at the joints would)")
    elif n_var > MAX_VARIABLE_STEPS:
        warning = (f"the variable-step mode is explicit: the arm's highest mode at "
                   f"{f_max:.4g} Hz bounds its step to {DOPRI_STABILITY / omega.max():.2g} s "
                   f"(>= {n_var:.3g} steps per simulated second, whatever rtol); the fixed "
                   f"mode (integrator: {{method: fixed}}, or --method fixed) steps over it")
    return StepAdvice(f_max, f_x, needed, n_var, warning)


def step_halving_error(run_at, step: float) -> np.ndarray:
    """Estimated error of the fixed ``step`` for each link's tip deflection, as a share of
    its largest value: ``run_at(h)`` returns the tip deflections (samples x links) of one
    run at step h; the runs at ``step`` and ``step / 2`` differ by d and the estimate is
    2 d (Richardson extrapolation with order 1: generalized-alpha is second order between
    force jumps, first order across one; for an order-2 error it overestimates by 1.5)."""
    coarse, fine = np.asarray(run_at(step), float), np.asarray(run_at(step / 2), float)
    scale = np.abs(fine).max(axis=0)
    diff = np.abs(coarse - fine).max(axis=0)
    return 2.0 * np.divide(diff, scale, out=np.zeros_like(diff), where=scale > 0)


def halving_warning(step: float, tip_error, window: float) -> str | None:
    """The fixed step's warning from :func:`step_halving_error` (None within
    :data:`TIP_TOLERANCE`); the step it suggests scales the error linearly."""
    err = np.asarray(tip_error, float)
    if err.size == 0 or err.max() <= TIP_TOLERANCE:
        return None
    link = int(np.argmax(err))
    return (f"step {step:.3g} s cannot resolve the arm: halving it moves the tip deflection "
            f"of link {link + 1} by {50 * err[link]:.2g} % of its largest in the first "
            f"{window:.3g} s (estimated error {100 * err[link]:.2g} %); it needs a step of "
            f"about {step * TIP_TOLERANCE / err[link]:.2g} s or less")
