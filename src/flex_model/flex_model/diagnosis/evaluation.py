"""Evaluating a twin on a recording: the weighted residual vector, noise levels, costs,
and the executor interface for running many evaluations in parallel.

A twin is the nominal arm with baseline scales (:mod:`.baseline`) and accepted or
candidate effects (:mod:`.hypotheses`). Residuals are weighted per channel by the
channel's white-noise level sigma_c, estimated from the data by the second difference
(sigma^2 = var(y[k+1] - 2 y[k] + y[k-1]) / 6, exact for white noise on a smooth signal),
so the cost J = mean_c mean_k (r_c,k / sigma_c)^2 is about 1 for a perfect twin under
white noise; its excess J - 1 is the model error in units of the noise power.

Executor: anything with ``map(fn, iterable)`` returning results in order
(``concurrent.futures`` executors, ``dask.distributed.Client`` via its
``concurrent.futures``-compatible executor, Ray's ``ray.util.multiprocessing.Pool``).
"""
from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np

from ..arm import ArmDescription
from ..dynamics import FlexArmModel
from ..simulate import SimulationDivergedError
from ..statics import StaticConvergenceError
from .baseline import apply_scales
from .controller import ControllerDescription
from .replay import _held, replay

#: absolute noise floors per channel kind (rad, rad/s, N m, m)
FLOORS = {"q": 1e-6, "v": 1e-5, "tau": 1e-4, "w": 1e-6, "tip": 1e-6}
#: a diverged candidate costs this much (it is not a plausible twin)
DIVERGED_COST = 1e12


def _floor(name: str) -> float:
    for k in ("tau", "tip", "q", "v", "w"):
        if name.startswith(k):
            return FLOORS[k]
    return 1e-6


def noise_levels(rec) -> dict:
    """White-noise standard deviation per residual channel (second-difference estimate)."""
    out = {}
    for name in rec.residual_channels:
        y = rec.channels[name]
        d2 = y[2:] - 2 * y[1:-1] + y[:-2]
        # a robust scale (median absolute deviation) ignores the rare steps of a move
        s = 1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0)
        out[name] = float(max(s, _floor(name), 1e-6 * np.std(y)))
    return out


@dataclass
class Context:
    """Everything an evaluation needs (picklable, sent to the workers)."""

    nominal: ArmDescription
    controller: ControllerDescription
    rec: object
    sigma: dict
    ff: np.ndarray          # feed-forward at the control instants (the nominal model's)
    baseline_params: list
    dt: float = 2e-3

    @classmethod
    def build(cls, nominal, controller, rec, baseline_params, sigma=None, dt=2e-3):
        model = FlexArmModel(nominal)
        period = controller.period
        t_rel = rec.t - rec.t[0]
        instants = np.arange(int(round(t_rel[-1] / period))) * period
        qset = _held(t_rel, rec.stack("qset"), instants)
        recorded = _held(t_rel, rec.stack("tau_ff"), instants) \
            if controller.feedforward_mode == "recorded" else None
        ff = controller.feedforward(model, qset, recorded)
        return cls(nominal, controller, rec, sigma or noise_levels(rec), ff,
                   list(baseline_params), dt)


def twin_arm(ctx: Context, scales, effects=()) -> ArmDescription:
    """Nominal + baseline scales + [(hypothesis, x), ...]."""
    arm = apply_scales(ctx.nominal, ctx.baseline_params, scales)
    for hyp, x in effects:
        arm, _ = hyp.apply(arm, x)
    return arm


def _encoder_bias(arm: ArmDescription) -> np.ndarray:
    b = np.zeros(arm.n_links)
    for s in arm.sensors:
        if s.kind == "joint_encoder":
            b[arm.joint_names.index(s.target)] += s.bias
    return b


def predict_channels(ctx: Context, arm: ArmDescription):
    """The twin's channels on the context's recording (encoder biases included)."""
    model = FlexArmModel(arm)
    bias = _encoder_bias(arm)
    cbias = np.array([bias[int(c[1:]) - 1] if c[0] == "q" else 0.0
                      for c in ctx.controller.channels])
    rec = ctx.rec
    x0 = None
    if np.any(bias):
        from .replay import initial_state, measured_start
        q0, v0 = measured_start(rec)
        x0 = initial_state(model, q0 - bias, v0)
    pred = replay(model, ctx.controller, rec, ff=ctx.ff, dt=ctx.dt, sensor_bias=cbias,
                  x0=x0)
    for i in range(arm.n_links):
        if f"q{i + 1}" in pred.channels:
            pred.channels[f"q{i + 1}"] = pred.channels[f"q{i + 1}"] + bias[i]
    return pred


def residual_vector(ctx: Context, arm: ArmDescription) -> np.ndarray:
    """Weighted residuals, channels concatenated in rec.residual_channels order."""
    pred = predict_channels(ctx, arm)
    rec = ctx.rec
    n = len(pred.t)
    return np.concatenate([(rec.channels[c][:n] - pred.channels[c]) / ctx.sigma[c]
                           for c in rec.residual_channels])


def cost(r: np.ndarray) -> float:
    """J = mean squared weighted residual."""
    return float(np.mean(r * r))


def evaluate(task) -> np.ndarray | None:
    """Worker function: (ctx, scales, effects) -> weighted residuals (None if diverged)."""
    ctx, scales, effects = task
    try:
        return residual_vector(ctx, twin_arm(ctx, scales, effects))
    except (SimulationDivergedError, StaticConvergenceError, np.linalg.LinAlgError,
            ValueError):
        return None


class SerialExecutor:
    """The executor interface without parallelism (``map`` in order)."""

    def map(self, fn, *iterables):
        return map(fn, *iterables)

    def submit(self, fn, *args):
        from concurrent.futures import Future
        f = Future()
        f.set_result(fn(*args))
        return f


def default_executor(workers: int | None = None):
    """A process pool on the available cores (serial with one core)."""
    n = workers or len(os.sched_getaffinity(0))
    return SerialExecutor() if n <= 1 else ProcessPoolExecutor(max_workers=n)
