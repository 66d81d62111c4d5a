"""Evaluating a twin on a recording: the weighted residual vector, noise levels, costs,
and the executor interface for running many evaluations in parallel.

A twin is the nominal arm with baseline scales (:mod:`.baseline`) and accepted or
candidate effects (:mod:`.hypotheses`). Residuals are weighted per channel by the
channel's white-noise level sigma_c, estimated from the data by the second difference
(sigma^2 = var(y[k+1] - 2 y[k] + y[k-1]) / 6, exact for white noise on a smooth signal),
times the ratio kappa_c of a healthy twin's residual to that white noise (coloured sensor
noise, quantisation and the drives' torque ripple, which the closed loop turns into
motion no replay can predict): sigma_eff = kappa_c sigma_c. kappa is calibrated on healthy
runs (:data:`HEALTHY_RATIO`: the synthetic two-link cases of :mod:`.synthetic` at nominal
noise, seeds 1-3, baseline twin, fit and held-out recordings), so the cost
J = mean_c mean_k (r_c,k / sigma_eff_c)^2 is about 1 for a healthy unit at the data's noise
level and the excess J - 1 is the model error in units of that noise power. Another arm or
controller recalibrates with ``noise_ratios`` (a mapping channel -> kappa).

Long logs: with ``segment`` the replay restarts every ``segment`` seconds from the measured
joint angles and rates (links in static equilibrium; the link side of an elastic joint at
its link-side encoder ``ql<i>``, ``vl<i>`` where the recording has one): multiple
shooting, the k-step prediction of each window, which bounds the drift of a long
closed-loop replay and the cost of a divergent candidate.

Executor: anything with ``map(fn, iterable)`` returning results in order
(``concurrent.futures`` executors, ``dask.distributed.Client`` via its
``concurrent.futures``-compatible executor, Ray's ``ray.util.multiprocessing.Pool``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..cluster import SerialExecutor  # noqa: F401 (the executors: flex_twin.cluster)
from ..cluster import local_executor as default_executor  # noqa: F401
from flex_model.arm import ArmDescription
from flex_model.dynamics import FlexArmModel
from flex_model.sensors import tip_gauge
from flex_model.simulate import SimulationDivergedError
from flex_model.statics import StaticConvergenceError
from .baseline import apply_scales
from .controller import ControllerDescription
from . import spatial_loop
from .replay import (START_WINDOW, initial_state, measured_link_start, measured_start,
                     replay, zero_order_hold)

#: absolute noise floors per channel kind (rad, rad/s, N m, m)
FLOORS = {"q": 1e-6, "v": 1e-5, "tau": 1e-4, "w": 1e-6, "tip": 1e-6}
#: residual RMS of healthy baseline twins / white-noise estimate, per channel (see above)
HEALTHY_RATIO = {"q1": 9.3, "q2": 22.1, "v1": 1.07, "v2": 1.47, "tau1": 1.28, "tau2": 1.88,
                 "w1": 2.86, "w2": 2.14, "tip_x": 2.42, "tip_y": 1.75}
#: the same by channel kind, for channels not in the table
HEALTHY_RATIO_KIND = {"q": 15.0, "v": 1.3, "tau": 1.6, "w": 2.5, "tip": 2.1}
#: a diverged candidate costs this much (it is not a plausible twin)
DIVERGED_COST = 1e12


def _floor(name: str) -> float:
    for k in ("tau", "tip", "q", "v", "w"):
        if name.startswith(k):
            return FLOORS[k]
    return 1e-6


def healthy_ratio(name: str, table=None) -> float:
    table = HEALTHY_RATIO if table is None else table
    if name in table:
        return float(table[name])
    kind = "tip" if name.startswith("tip") else name.rstrip("0123456789")
    return HEALTHY_RATIO_KIND.get(kind, 1.0)


def quantisation_step(y: np.ndarray) -> float:
    """The step of a quantised signal (every nonzero sample difference a multiple of the
    smallest one, to 0.1 % of it, in 99 % of the samples), or 0."""
    d = np.abs(np.diff(np.asarray(y, float)))
    d = d[d > 0]
    if len(d) < 10:
        return 0.0
    q = float(np.min(d))
    on_grid = np.abs(d / q - np.round(d / q)) < 1e-3
    return q if np.mean(on_grid) >= 0.99 else 0.0


def noise_levels(rec, noise_ratios=None) -> dict:
    """Effective noise level per residual channel: the white-noise standard deviation
    (second-difference estimate, at least the step / sqrt(12) of a quantised channel,
    whose second difference is mostly 0) times the healthy ratio kappa."""
    out = {}
    for name in rec.residual_channels:
        y = rec.channels[name]
        d2 = y[2:] - 2 * y[1:-1] + y[:-2]
        # a robust scale (median absolute deviation) ignores the rare steps of a move
        s = 1.4826 * np.median(np.abs(d2 - np.median(d2))) / np.sqrt(6.0)
        s = max(s, quantisation_step(y) / np.sqrt(12.0))
        out[name] = float(max(s, _floor(name), 1e-6 * np.std(y))
                          * healthy_ratio(name, noise_ratios))
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
    score_from: float = -np.inf   # residuals count from this time on (a held-out segment)
    segment: float | None = None  # multiple shooting: restart every `segment` s (long logs)
    start_window: float | None = None  # measured_start's window (s); None: the recording's
    # `# start_window:` setting, else replay.START_WINDOW

    @classmethod
    def build(cls, nominal, controller, rec, baseline_params, sigma=None, dt=2e-3,
              score_from=-np.inf, segment=None):
        period = controller.instant_period(rec.dt)
        t_rel = rec.t - rec.t[0]
        instants = np.arange(int(round(t_rel[-1] / period)) + 1) * period
        if spatial_loop.is_spatial(nominal):   # the spatial replay (spatial_loop.py)
            ff = spatial_loop.feedforward(controller, rec, len(instants))
            return cls(nominal, controller, rec, sigma or noise_levels(rec), ff,
                       list(baseline_params), dt, score_from, segment)
        model = FlexArmModel(nominal)
        qset = zero_order_hold(t_rel, rec.stack("qset"), instants)
        recorded = zero_order_hold(t_rel, rec.stack("tau_ff"), instants) \
            if controller.feedforward_mode == "recorded" else None
        ff = controller.feedforward(model, qset, recorded)
        return cls(nominal, controller, rec, sigma or noise_levels(rec), ff,
                   list(baseline_params), dt, score_from, segment)


def twin_arm(ctx: Context, scales, effects=()) -> ArmDescription:
    """Nominal + baseline scales + [(hypothesis, x), ...]."""
    arm = apply_scales(ctx.nominal, ctx.baseline_params, scales)
    for hyp, x in effects:
        arm, _ = hyp.apply(arm, x)
    return arm


def encoder_faults(arm: ArmDescription) -> tuple[np.ndarray, np.ndarray]:
    """Per joint: bias (rad) and delay (s) of the arm's joint_encoder sensors."""
    b = np.zeros(arm.n_links)
    d = np.zeros(arm.n_links)
    for s in arm.sensors:
        if s.kind == "joint_encoder":
            j = arm.joint_names.index(s.target)
            b[j] += s.bias
            d[j] = max(d[j], s.delay)
    return b, d


def gauge_delays(arm: ArmDescription) -> np.ndarray:
    """Per link: the delay (s) of its tip gauge (flex_model.sensors.tip_gauge: 0 without
    one)."""
    return np.array([tip_gauge(arm, lk.name).delay for lk in arm.links])


def _late(y, n: int):
    """y read n samples late, its first value held."""
    return np.concatenate([np.full(n, y[0]), y[:-n]]) if n else y


def _segments(ctx: Context) -> list[tuple[int, int]]:
    """Sample ranges [k0, k1) of the replay: the whole record, or windows of
    ``ctx.segment`` seconds sharing their boundary sample (multiple shooting)."""
    n = len(ctx.rec.t)
    if not ctx.segment or ctx.segment >= ctx.rec.t[-1] - ctx.rec.t[0]:
        return [(0, n)]
    per = max(2, int(round(ctx.segment / ctx.rec.dt)))
    per -= per % max(1, int(round(ctx.controller.instant_period(ctx.rec.dt) / ctx.rec.dt)))
    return [(k, min(k + per + 1, n)) for k in range(0, n - 1, per)]


def start_window(ctx: Context) -> float:
    """The window (s) of the (re)starts' state fit (:func:`.replay.measured_start`)."""
    if ctx.start_window is not None:
        return float(ctx.start_window)
    return float(ctx.rec.meta.get("start_window", START_WINDOW))


def predict_channels(ctx: Context, arm: ArmDescription):
    """The twin's channels on the context's recording. Encoder bias and delay (sensors of
    the arm) act on what the controller reads and on the recorded q<i>, v<i>. Each
    (re)start takes the state of :func:`.replay.measured_start` over
    :func:`start_window`; with link-side encoders ``ql<i>``, ``vl<i>`` an elastic joint
    starts twisted as measured (:func:`.replay.initial_state`). A spatial arm:
    :func:`.spatial_loop.predict` (no encoder faults, no multiple shooting)."""
    if spatial_loop.is_spatial(arm):
        return spatial_loop.predict(ctx, arm, start_window(ctx))
    model = FlexArmModel(arm)
    bias, delay = encoder_faults(arm)
    rec = ctx.rec
    joint_of = [int(c[1:]) - 1 if c[0] == "q" else None for c in ctx.controller.channels]
    cbias = np.array([bias[j] if j is not None else 0.0 for j in joint_of])
    period = ctx.controller.instant_period(rec.dt)
    periods = np.rint(delay / period).astype(np.int64)
    cdelay = np.array([periods[j] if j is not None else 0 for j in joint_of], np.int64)
    gauges = gauge_delays(arm)   # a lagging tip gauge: the law reads w<i> late too
    for c, name in enumerate(ctx.controller.channels):
        if name[0] == "w":
            cdelay[c] = int(np.rint(gauges[int(name[1:]) - 1] / period))
    window = start_window(ctx)
    pred = None
    for k0, k1 in _segments(ctx):
        part = rec if (k0, k1) == (0, len(rec.t)) else rec.window(rec.t[k0], rec.t[k1 - 1])
        q0, v0 = measured_start(part, window)
        link = measured_link_start(part, window) if model.elastic_joints else None
        i0 = int(round((rec.t[k0] - rec.t[0]) / period))
        seg = replay(model, ctx.controller, part, ff=ctx.ff[i0:], dt=ctx.dt,
                     sensor_bias=cbias, sensor_delay=cdelay,
                     x0=initial_state(model, q0 - bias, v0, *(link or ())))
        if pred is None:
            pred = seg
        else:   # the segment's first sample is the previous one's last: keep the new one
            pred.t = np.concatenate([pred.t[:-1], seg.t])
            for c in pred.channels:
                pred.channels[c] = np.concatenate([pred.channels[c][:-1], seg.channels[c]])
    samples = np.rint(delay / rec.dt).astype(int)
    w_samples = np.rint(gauges / rec.dt).astype(int)
    for i in range(arm.n_links):
        for kind, n, add in (("q", samples[i], bias[i]), ("v", samples[i], 0.0),
                             ("w", w_samples[i], 0.0)):
            name = f"{kind}{i + 1}"
            if name in pred.channels:
                pred.channels[name] = _late(pred.channels[name], n) + add
    return pred


def residual_vector(ctx: Context, arm: ArmDescription) -> np.ndarray:
    """Weighted residuals, channels concatenated in rec.residual_channels order."""
    pred = predict_channels(ctx, arm)
    rec = ctx.rec
    n = len(pred.t)
    k0 = int(np.searchsorted(pred.t, ctx.score_from - 1e-9))
    return np.concatenate([(rec.channels[c][k0:n] - pred.channels[c][k0:])
                           / channel_sigma(ctx, c, k0, n) for c in rec.residual_channels])


def channel_sigma(ctx: Context, c: str, k0: int = 0, n: int | None = None):
    """The noise level of channel c over samples [k0, n): a number, or the per-sample
    levels of a run whose transients the model-form floor down-weights (:mod:`.floor`)."""
    s = ctx.sigma[c]
    return s[k0:n] if np.ndim(s) else s


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
