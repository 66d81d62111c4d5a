"""Do the chosen step and variables resolve the arm? One line of advice before a simulation.

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

The modal rule misleads both ways (issue 47: 21 of 23 settings of a tapered arm with
payload warned though within 0.35 %; a link sagging on a heavy hub, 2-16 % off, never
warned), so in the fixed mode the warning is a-posteriori (:func:`estimate_error`, planar
and spatial scenarios alike): the run's distance to a run with a quarter of the step and
twice the variables per link over :func:`probe_window`, as a share of each link's largest
tip deflection (:func:`tip_error`). Above :data:`WARN_ABOVE` (1.5 %: the estimate was
0.64-1.06 x the measured error on 66 settings of four arms, bench/bench_step_advice.py) it
warns with the estimate and the step and variables
that meet 2 % (:func:`error_warning`). Its cost: the window (0.5 s or up to 0.3 s past
the first input jump, at most 1 s) run three times, at h, h/4 and h/4 with twice the variables,
about 10-15 times the window's own run (bench/bench_step_advice.py prints it).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import SolverError

#: Dormand-Prince 5(4): stability interval on the imaginary axis, |h omega| <= ~3.3
DOPRI_STABILITY = 3.3
#: variable mode: warn above this many stability-bound steps per simulated second
MAX_VARIABLE_STEPS = 1e4
#: the tolerated error of a tip deflection, share of its largest value (issue 47)
TOLERANCE = 0.02
#: warn above this estimated error (the estimate's own uncertainty below TOLERANCE)
WARN_ABOVE = 0.015
#: the stand-in for the converged run has the step divided by this
STEP_DIVISOR = 4
#: error ratio of a run with twice the variables per link to the run (the suggestion)
VARS_GAIN = 4.0
#: a link whose largest tip deflection is below this share of the largest link's is
#: measured against that share (its own relative error would not matter)
PEAK_FLOOR = 0.05
#: the estimate runs the whole run up to this long (s), else up to PROBE_AFTER_JUMP s past
#: the first input jump (at least that long), at most PROBE_MAX s
PROBE_WHOLE_RUN = 0.5
PROBE_AFTER_JUMP = 0.3
PROBE_MAX = 1.0
#: failures of a refined run that the estimate counts as an infinite error
REFINED_FAILURES = (SolverError, np.linalg.LinAlgError)


@dataclass(frozen=True)
class StepAdvice:
    highest_mode_hz: float          # the arm's highest mode (linearized, joints as run)
    highest_excited_mode_hz: float  # the highest a joint torque step excites (>= share)
    step_needed_s: float            # 1 / (steps_per_period f_x)
    variable_steps_per_s: float     # stability-bound steps of the explicit mode per s
    warning: str | None
    #: fixed mode: the a-posteriori estimate (estimate_error) the warning comes from
    estimate: "ErrorEstimate | None" = None


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


def probe_window(duration: float, sample_period: float, jumps) -> float:
    """The time the estimate runs (a whole number of samples): the whole run up to
    PROBE_WHOLE_RUN s, else PROBE_WHOLE_RUN s or up to PROBE_AFTER_JUMP s past the first
    input jump (set-point step, pulse), whichever is longer, but at most PROBE_MAX s (a
    later first jump is not checked: its cost)."""
    first = min((t for t in jumps if 0 <= t < duration), default=0.0)
    window = min(duration, PROBE_MAX, max(PROBE_WHOLE_RUN, first + PROBE_AFTER_JUMP))
    return sample_period * max(1, round(window / sample_period))


def tip_error(tips, ref) -> float:
    """Largest error of the links' tip deflections against ``ref``, as a share of each
    link's largest |deflection| in ``ref``: arrays (samples, links) or (samples, links,
    components: a spatial link's y and z, compared as a vector)."""
    a, b = np.asarray(tips, float), np.asarray(ref, float)
    if a.ndim == 2:
        a, b = a[..., None], b[..., None]
    dist = np.linalg.norm(a - b, axis=2).max(axis=0)
    peak = np.linalg.norm(b, axis=2).max(axis=0)
    floor = PEAK_FLOOR * max(float(peak.max(initial=0.0)), 1e-300)
    return float(np.max(dist / np.maximum(peak, floor), initial=0.0))


@dataclass(frozen=True)
class ErrorEstimate:
    """A-posteriori error of a run's tip deflections (share of each link's largest value;
    :func:`tip_error`) over its first ``window`` s: ``total`` against the run with a
    quarter of the step and twice the variables per link (the stand-in for the converged
    run), ``step_error`` against the run with a quarter of the step, ``vars_error``
    between that run and the stand-in (nan: not refined); ``cost_s`` the wall-clock
    seconds of the three runs."""

    total: float
    step_error: float
    vars_error: float
    window: float
    cost_s: float


def estimate_error(run, window: float, refine_vars: bool = True) -> ErrorEstimate:
    """The run's distance to a refined run (planar and spatial alike): ``run(divisor,
    factor)`` returns the tip deflections of the setting with its step divided by
    ``divisor`` and its variables per link multiplied by ``factor``. The stand-in has a
    quarter of the step (generalized-alpha: order 2 between input jumps, 1 across one, so
    its step error is a quarter or less of the run's) and twice the variables (their
    error shrinks about as fast): the estimate is near the run's true error (0.64-1.06 x
    in bench/bench_step_advice.py). A refined run that fails (Newton) counts as an
    infinite error; the run's own failure is raised."""
    import time
    t0 = time.perf_counter()
    base = run(1, 1)    # fails as the run itself would (the caller reports it)
    try:
        fine = run(STEP_DIVISOR, 1)
        ref = run(STEP_DIVISOR, 2) if refine_vars else fine
    except REFINED_FAILURES:
        return ErrorEstimate(np.inf, np.inf, np.nan, window, time.perf_counter() - t0)
    return ErrorEstimate(tip_error(base, ref), tip_error(base, fine),
                         tip_error(fine, ref) if refine_vars else np.nan, window,
                         time.perf_counter() - t0)


def error_warning(est: ErrorEstimate, step: float, variables: str | None,
                  rtol: float | None = None) -> str | None:
    """The one-line warning of an :class:`ErrorEstimate` above :data:`WARN_ABOVE` (None
    below): the estimated error and the setting that meets :data:`TOLERANCE` (half of it
    for each part; the step scaled with order 1, the variables doubled at VARS_GAIN per
    doubling); ``variables`` names the current ones (e.g. "8 variables per link").
    ``rtol``: the variable-step mode (its refined run had rtol / STEP_DIVISOR^2)."""
    if not est.total > WARN_ABOVE:
        return None
    half = TOLERANCE / 2
    at = f"rtol {rtol:.3g}" if rtol else f"step {step:.3g} s"
    finer = (f"rtol / {STEP_DIVISOR ** 2}" if rtol else "a quarter of the step")
    if not np.isfinite(est.total):
        return (f"the run with {finer} (at {at}" + (
            f" and {variables}, or twice them" if variables else "") + ") fails (Newton): "
            "the run cannot be checked; use a smaller step")
    fixes = []
    if est.step_error > half:
        scale = half / est.step_error
        fixes.append(f"rtol {rtol * scale:.2g} or less" if rtol else
                     f"a step of {step * scale:.2g} s or less")
    vars_off = np.nan_to_num(est.vars_error)
    if vars_off > half and variables is not None:
        times = 2 ** max(1, int(np.ceil(np.log(vars_off / half) / np.log(VARS_GAIN))))
        fixes.append(f"{times}x the variables")
    parts = ("rtol" if rtol else "step") + f" {100 * est.step_error:.2g} %" + (
        f", variables {100 * est.vars_error:.2g} %" if np.isfinite(est.vars_error) else "")
    return (f"the tip deflections are about {100 * est.total:.2g} % off the converged run "
            f"(against a run with {finer} and twice the variables over the first "
            f"{est.window:.3g} s, at {at}" + (f" and {variables}" if variables else "")
            + f": {parts}); for {100 * TOLERANCE:.0f} % use "
            + (" and ".join(fixes) or "a finer setting")
            + f" (this check took {est.cost_s:.2g} s)")
