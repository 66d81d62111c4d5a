"""Closed-loop replay of a measured experiment through a twin (issue 8, step 1).

The twin runs with the recorded reference and the same sampled controller as the arm
(:mod:`flex_twin.diagnosis.controller`): at every control instant t_k the law reads the
twin's measured channels, its output (the recorded command ``tau<i>``) is held
(zero-order hold) and, with an
``actuator_delay`` effect on joint j, applied d_j = ceil(delay_j / period) periods later
(0 before the first command is old enough), exactly as :func:`flex_model.simulate.simulate`
with a ``policy`` and ``method='fixed'`` does. The whole loop is compiled (numba), calling
the generalized-alpha loop (flex_model.solvers.loop.fixed_step on
flex_model.integrators.PlanarModel) between control instants, so a 20 s run costs a
fraction of a second. A control period whose Newton iterations stall (the rounded
corners of a backlash or of friction crossed within one step) is integrated again with
:data:`SUBSTEPS` steps per step. Open-loop replay of measured torques through the
rigid-body modes drifts and is not offered. Joints with
``stick_slip_friction`` carry their bristle deflections z in the state, x = [q; v; z]
(the integrator advances them, flex_model.effects.stick_slip); a replay starts with them
unloaded.

A continuous law (``timing: continuous``, :mod:`.controller`) is the compiled joint PD of
:mod:`flex_model.integrators` (E.kp, E.kd: its stiffness and damping are in the
generalized-alpha Newton matrix, so a D term on an arm without hub inertia is implicit and
stable at the replay's step); the part of the law that depends on time only,
ff + kp (qset - encoder bias), is the held input E.u, updated at the recording's samples
(:func:`_continuous_loop`; the integrator restarts with a consistent acceleration only
where that input changes). Its recorded command is the law at the sampled state.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from flex_model.dynamics import FlexArmModel
from flex_model.integrators import PlanarModel, consistent_acceleration
from flex_model.iteration_matrix import empty_factor
from flex_model.kernels import link_origins
from flex_model.inputs import JointPD, input_data
from flex_model.simulate import SimulationDivergedError
from flex_model.solvers.loop import fixed_step
from flex_model.solvers.status import REFINEMENTS, newton_settings
from flex_model.statics import StaticConvergenceError, static_equilibrium
from .controller import ControllerDescription
from flex_model.kernels import P_MODE

DEFAULT_STEP = 1e-3
#: steps per step of a control period retried after a Newton failure (the first refinement)
SUBSTEPS = REFINEMENTS[0]
#: replays on second-order kinematics by simplified Newton (_closed_loop, _continuous_loop)
SIMPLIFIED = True
# (the compiled loops pass their integer constants to the loop as np.int64: a bare
# literal is its own numba type, and each one compiled fixed_step once more)


@njit(cache=True)
def _closed_loop(x0, P, E, h, per_period, n_periods, rho_inf, C, Kp, Kd, ref, ff, bias,
                 delay, sdelay, out_stride, simplified):
    """Run n_periods control periods of per_period steps; return the states every
    out_stride steps, the commands at the n_periods + 1 instants (the last one at the
    final state) and a status (0 ok, 1 diverged, 2 Newton failed). ``simplified``
    (second-order kinematics): each period's first attempt by simplified Newton
    (flex_model.solvers.loop.simplified_newton, the same results to the Newton tolerance),
    the retry of a stalled period by full Newton."""
    nx = x0.shape[0]
    n = E.K.shape[0]   # x = [q; v; z]: z the bristle deflections of stick-slip joints
    md, opts = PlanarModel(P, E), newton_settings(rho_inf, 1e-10, 1e6)
    nj = Kp.shape[0]
    nc = C.shape[0]
    n_steps = n_periods * per_period
    n_out = n_steps // out_stride + 1
    X = np.full((n_out, nx), np.nan)
    cmd = np.zeros((n_periods + 1, nj))
    Y = np.zeros((n_periods + 1, nc))
    YD = np.zeros((n_periods + 1, nc))
    u = E.u
    x = x0.copy()
    X[0] = x
    for k in range(n_periods + 1):
        Y[k] = C @ x[:n] + bias
        YD[k] = C @ x[n:2 * n]
        y = np.empty(nc)
        yd = np.empty(nc)
        for c in range(nc):
            kk = max(k - sdelay[c], 0)
            y[c] = Y[kk, c]
            yd[c] = YD[kk, c]
        cmd[k] = ff[min(k, ff.shape[0] - 1)] + Kp @ (ref[min(k, ref.shape[0] - 1)] - y) \
            - Kd @ yd
        if k == n_periods:
            break
        for j in range(nj):
            u[j] = cmd[k - delay[j], j] if k >= delay[j] else 0.0
        t = k * per_period * h
        a0 = consistent_acceleration(t, x, P, E)
        if simplified:
            Xs, status, t_stop, x_stop, a, abar, it = fixed_step(
                md, n, t, x, a0, a0.copy(), h, per_period, np.int64(1), opts, empty_factor())
        else:
            Xs, status, t_stop, x_stop, a, abar, it = fixed_step(
                md, n, t, x, a0, a0.copy(), h, per_period, np.int64(1), opts, None)
        if status == 2:   # Newton stalled (a sharp corner: backlash, friction): the period
            # again in SUBSTEPS steps per step from the last accepted state x and its
            # consistent acceleration a0, not the failed attempt's (bit-identical runs
            # where it converges)
            Xs, status, t_stop, x_stop, a, abar, it = fixed_step(
                md, n, t, x, a0, a0.copy(), h / SUBSTEPS, per_period * SUBSTEPS,
                np.int64(SUBSTEPS), opts, None)
        if status != 0:
            return X, cmd, status, t_stop
        for s in range(1, per_period + 1):
            g = k * per_period + s
            if g % out_stride == 0:
                X[g // out_stride] = Xs[s]
        x = x_stop
    return X, cmd, 0, n_steps * h


@njit(cache=True)
def _continuous_periods(x, a, abar, k, m, P, E, h, per_period, rho_inf, U, out_stride, X):
    """Periods k .. k + m - 1 of :func:`_continuous_loop` one by one by full Newton (the
    held input E.u = U[k] on period k; a period whose Newton iterations stall again in
    SUBSTEPS steps per step, from the last accepted state and its consistent acceleration).
    Writes the states into X; returns (status, time reached, x, a, abar)."""
    u = E.u
    md, opts, n = PlanarModel(P, E), newton_settings(rho_inf, 1e-10, 1e6), E.K.shape[0]
    for kk in range(k, k + m):
        t = kk * per_period * h
        restart = kk == 0
        for j in range(u.shape[0]):
            if u[j] != U[kk, j]:
                restart = True
            u[j] = U[kk, j]
        if restart:
            a = consistent_acceleration(t, x, P, E)
            abar = a.copy()
        Xs, status, t_stop, x_stop, a1, abar1, it = fixed_step(
            md, n, t, x, a, abar, h, per_period, np.int64(1), opts, None)
        if status == 2:   # Newton stalled on a sharp corner: the period in substeps
            a0 = consistent_acceleration(t, x, P, E)
            Xs, status, t_stop, x_stop, a1, abar1, it = fixed_step(
                md, n, t, x, a0, a0.copy(), h / SUBSTEPS, per_period * SUBSTEPS,
                np.int64(SUBSTEPS), opts, None)
        if status != 0:
            return status, t_stop, x, a, abar
        a = a1
        abar = abar1
        for s in range(1, per_period + 1):
            g = kk * per_period + s
            if g % out_stride == 0:
                X[g // out_stride] = Xs[s]
        x = x_stop
    return 0, (k + m) * per_period * h, x, a, abar


@njit(cache=True)
def _continuous_loop(x0, P, E, h, per_period, n_periods, rho_inf, U, out_stride,
                     simplified):
    """Run n_periods sample periods of per_period steps under the compiled joint PD of E
    with the held input E.u = U[k] on period k; return the states every out_stride steps,
    a status (0 ok, 1 diverged, 2 Newton failed) and the time reached. The method runs on
    through the periods (bit-identical to one call) and restarts with a consistent
    acceleration where the held input changes (a set-point step).

    ``simplified`` (second-order kinematics): each stretch of periods with one held input
    is one call of simplified Newton (flex_model.solvers.loop.simplified_newton:
    its iteration matrix kept across the stretch, the same results to the Newton
    tolerance, a fraction of the cost); a stretch it does not finish is integrated again
    period by period by full Newton (:func:`_continuous_periods`), as without it."""
    nx = x0.shape[0]
    n_steps = n_periods * per_period
    n_out = n_steps // out_stride + 1
    X = np.full((n_out, nx), np.nan)
    u = E.u
    x = x0.copy()
    X[0] = x
    a = np.zeros(E.K.shape[0])
    abar = a.copy()
    if not simplified:
        status, t_stop, x, a, abar = _continuous_periods(
            x, a, abar, np.int64(0), n_periods, P, E, h, per_period, rho_inf, U, out_stride, X)
        return X, status, t_stop
    k = 0
    md, opts, n = PlanarModel(P, E), newton_settings(rho_inf, 1e-10, 1e6), a.shape[0]
    while k < n_periods:
        m = 1   # the stretch of periods with the held input of period k
        while k + m < n_periods and np.all(U[k + m] == U[k]):
            m += 1
        t = k * per_period * h
        u[:] = U[k]
        a = consistent_acceleration(t, x, P, E)
        abar = a.copy()
        Xs, status, t_stop, x_stop, a1, abar1, it = fixed_step(
            md, n, t, x, a, abar, h, m * per_period, np.int64(1), opts, empty_factor())
        if status == 0:
            for s in range(1, m * per_period + 1):
                g = k * per_period + s
                if g % out_stride == 0:
                    X[g // out_stride] = Xs[s]
            x = x_stop
        else:   # period by period, by full Newton (E.u as before this stretch)
            if k > 0:
                u[:] = U[k - 1]
            status, t_stop, x, a1, abar1 = _continuous_periods(
                x, a, abar, k, m, P, E, h, per_period, rho_inf, U, out_stride, X)
            if status != 0:
                return X, status, t_stop
        k += m
    return X, 0, n_steps * h


@njit(cache=True)
def _tips(Q, P):
    """(n, 2): the arm's end for every row of Q (kernels.link_origins)."""
    out = np.empty((Q.shape[0], 2))
    for k in range(Q.shape[0]):
        out[k] = link_origins(Q[k], P)[-1]
    return out


@dataclass
class Prediction:
    """The twin's channels at the recording's samples (same names as the Recording)."""

    t: np.ndarray
    channels: dict
    q: np.ndarray      # model coordinates at the samples
    v: np.ndarray


def initial_state(model: FlexArmModel, theta0, rates0=None, link0=None,
                  link_rates0=None) -> np.ndarray:
    """[q; v; z]: joints at ``theta0`` with the links in static equilibrium under gravity
    (joints clamped), moving with the joint rates ``rates0`` (undeformed velocity field),
    the bristles z of stick-slip joints unloaded (the friction then takes up the held
    torque within the pre-sliding displacement, F_s / sigma_0).

    ``link0``, ``link_rates0`` (per joint, NaN where unknown): the link-side encoder of an
    elastic joint. There the link side starts at link0 / link_rates0 and the motor
    coordinate at theta0 / rates0 (the coupling twisted as measured); elsewhere, and on
    rigid joints, the start is the one above (motor and link side together)."""
    theta0 = np.asarray(theta0, float)
    rates0 = np.zeros(model.n_links) if rates0 is None else np.asarray(rates0, float)
    twisted = []
    if link0 is not None and model.elastic_joints:
        link0 = np.asarray(link0, float)
        link_rates0 = np.asarray(link_rates0, float)
        twisted = [(m, i) for m, i in enumerate(model.elastic_joints)
                   if np.isfinite(link0[i]) and np.isfinite(link_rates0[i])]
    theta, rates = theta0, rates0
    if twisted:
        theta, rates = theta0.copy(), rates0.copy()
        for _, i in twisted:
            theta[i], rates[i] = link0[i], link_rates0[i]
    try:
        q = static_equilibrium(model, theta, joints="clamped").q
    except (StaticConvergenceError, np.linalg.LinAlgError):
        q = static_equilibrium(model, theta, joints="clamped", linear=True).q
    v = model.v_from_joint_rates(rates)
    for m, i in twisted:   # the motor coordinates (after the arm's): the motor encoder
        q[model.nq_arm + m] = theta0[i]
        v[model.nq_arm + m] = rates0[i]
    return np.concatenate([q, v, np.zeros(model.n_bristles)])


#: default window of :func:`measured_start` (s)
START_WINDOW = 0.05


def _start_fit(rec, names, window: float):
    n = max(3, min(len(rec.t), int(round(window / rec.dt)) + 1))
    t = rec.t[:n] - rec.t[0]
    A = np.column_stack([np.ones(n), t, t * t])
    coef, *_ = np.linalg.lstsq(A, np.column_stack([rec.channels[c][:n] for c in names]),
                               rcond=None)
    return coef[0]


def measured_start(rec, window: float = START_WINDOW):
    """Joint angles and rates at the first sample, from a quadratic fit over the first
    ``window`` seconds (averages the sensor noise out of the replay's initial state; at
    most 2 samples: the first sample itself, the fit then passing through 3 points)."""
    n = max(3, min(len(rec.t), int(round(window / rec.dt)) + 1))
    t = rec.t[:n] - rec.t[0]
    A = np.column_stack([np.ones(n), t, t * t])
    out = []
    for kind in ("q", "v"):
        coef, *_ = np.linalg.lstsq(A, rec.stack(kind)[:n], rcond=None)
        out.append(coef[0])
    return out


def measured_link_start(rec, window: float = START_WINDOW):
    """Link-side angles and rates (per joint, NaN without a ``ql<i>``/``vl<i>`` encoder) at
    the first sample, fitted as :func:`measured_start`; None when the recording has none."""
    joints = rec.link_encoders()
    if not joints:
        return None
    ql = np.full(rec.n_joints, np.nan)
    vl = np.full(rec.n_joints, np.nan)
    ql[joints] = _start_fit(rec, [f"ql{i + 1}" for i in joints], window)
    vl[joints] = _start_fit(rec, [f"vl{i + 1}" for i in joints], window)
    return ql, vl


def _delay_periods(model: FlexArmModel, period: float) -> np.ndarray:
    d = [getattr(model.arm.effect("actuator_delay", j), "values", (0.0,))[0]
         for j in model.arm.joint_names]
    return np.array([int(np.ceil(x / period - 1e-9)) if x > 0 else 0 for x in d], np.int64)


def simulate_closed_loop(model: FlexArmModel, controller: ControllerDescription, x0,
                         t_final: float, qset_at_instants, ff_at_instants, *,
                         sample_period: float, dt: float = DEFAULT_STEP, rho_inf: float = 0.9,
                         sensor_bias=None, sensor_delay=None):
    """(X, CMD) every ``sample_period`` over [0, t_final]: the states [q; v; z] of the arm
    (z: bristle deflections of stick-slip joints, flex_model.effects.stick_slip) under the
    sampled law and the command issued at the latest control instant (a continuous law:
    its command at the sample).

    ``qset_at_instants``/``ff_at_instants``: (n_periods + 1, n_joints) reference and
    feed-forward at the control instants k * period (a continuous law: the samples k *
    sample_period, held between them); ``sensor_bias`` (per controller channel) is added
    to what the controller reads, ``sensor_delay`` (per channel, whole control periods)
    delays it (the first reading before the record starts).
    """
    if controller.continuous:
        return _continuous_closed_loop(model, controller, x0, t_final, qset_at_instants,
                                       ff_at_instants, sample_period=sample_period, dt=dt,
                                       rho_inf=rho_inf, sensor_bias=sensor_bias,
                                       sensor_delay=sensor_delay)
    period = controller.period
    per_period = max(1, int(np.ceil(period / dt - 1e-9)))
    h = period / per_period
    stride = int(round(sample_period / h))
    if stride < 1 or abs(stride * h - sample_period) > 1e-9 * sample_period:
        raise ValueError(f"sample period {sample_period:g} s is not a multiple of the "
                         f"integration step {h:g} s (controller period {period:g} s)")
    n_periods = int(round(t_final / period))
    E = input_data(model, None, (), np.zeros(model.n_links))
    C = controller.channel_matrix(model)
    nc = len(controller.channels)
    ref = controller.reference(qset_at_instants[:n_periods + 1])
    bias = np.zeros(nc) if sensor_bias is None else np.asarray(sensor_bias, float)
    sdelay = np.zeros(nc, np.int64) if sensor_delay is None else \
        np.asarray(sensor_delay, np.int64)
    X, cmd, status, t_stop = _closed_loop(
        np.asarray(x0, float), model.P, E, h, per_period, n_periods, rho_inf, C,
        np.ascontiguousarray(controller.gains), np.ascontiguousarray(controller.rate_gains),
        np.ascontiguousarray(ref), np.ascontiguousarray(ff_at_instants[:n_periods + 1]),
        bias, _delay_periods(model, period), sdelay, stride,
        bool(SIMPLIFIED and model.P[P_MODE] == 1))
    if status != 0:
        raise SimulationDivergedError(f"closed-loop replay failed at t = {t_stop:.6g} s "
                                      f"(status {status}: diverged or Newton failed)")
    k = np.floor(np.arange(len(X)) * sample_period / period + 1e-9).astype(int)
    return X, cmd[np.minimum(k, n_periods)]


def _continuous_closed_loop(model, controller, x0, t_final, qset_at_instants,
                            ff_at_instants, *, sample_period, dt, rho_inf, sensor_bias,
                            sensor_delay):
    """:func:`simulate_closed_loop` of a continuous law (:func:`_continuous_loop`)."""
    if sensor_delay is not None and np.any(np.asarray(sensor_delay) != 0):
        raise ValueError("a continuous controller cannot read a delayed encoder in the "
                         "replay (a delay of a continuous law is not a state function)")
    if np.any(_delay_periods(model, sample_period) > 0):
        raise ValueError("a continuous controller with an actuator_delay: the replay "
                         "cannot delay a continuous law")
    per_period = max(1, int(np.ceil(sample_period / dt - 1e-9)))
    h = sample_period / per_period
    n_periods = int(round(t_final / sample_period))
    nc = len(controller.channels)
    bias = np.zeros(nc) if sensor_bias is None else np.asarray(sensor_bias, float)
    ref = controller.reference(qset_at_instants[:n_periods + 1])
    ff = np.asarray(ff_at_instants[:n_periods + 1], float)
    kp, kd = controller.joint_pd()
    E = input_data(model, JointPD(kp, kd, np.zeros(model.n_links)), (),
                   np.zeros(model.n_links))
    U = np.ascontiguousarray(ff + (ref - bias) @ controller.gains.T)
    X, status, t_stop = _continuous_loop(np.asarray(x0, float), model.P, E, h, per_period,
                                         n_periods, rho_inf, U, per_period,
                                         bool(SIMPLIFIED and model.P[P_MODE] == 1))
    if status != 0:
        raise SimulationDivergedError(f"closed-loop replay failed at t = {t_stop:.6g} s "
                                      f"(status {status}: diverged or Newton failed)")
    return X, controller.command(model, X, ref, ff, bias)


def zero_order_hold(t_rec, values, instants):
    """Zero-order hold of sampled values at the given instants (latest sample <= t)."""
    k = np.clip(np.searchsorted(t_rec, instants + 1e-9, side="right") - 1, 0, len(t_rec) - 1)
    return values[k]


def predict(model: FlexArmModel, x: np.ndarray, tau: np.ndarray, t: np.ndarray,
            want) -> Prediction:
    """The channels ``want`` of states x (n, 2 nq) and commands tau (n, n_joints)."""
    nq = model.nq
    q, v = x[:, :nq], x[:, nq:2 * nq]
    ch = {}
    qa, va = q @ model.Ga.T, v @ model.Ga.T
    for i in range(model.n_links):
        ch[f"q{i + 1}"] = qa[:, i]
        ch[f"v{i + 1}"] = va[:, i]
        ch[f"tau{i + 1}"] = tau[:, i]
        ch[f"w{i + 1}"] = q[:, model.tip_deflection_index(i)]
    if any(k[:2] in ("ql", "vl") for k in want):   # link side of the joints
        ql, vl = q @ model.G.T, v @ model.G.T
        for i in range(model.n_links):
            ch[f"ql{i + 1}"], ch[f"vl{i + 1}"] = ql[:, i], vl[:, i]
    if "tip_x" in want or "tip_y" in want:
        tips = _tips(np.ascontiguousarray(q), model.P)
        ch["tip_x"], ch["tip_y"] = tips[:, 0], tips[:, 1]
    return Prediction(t=t, channels={k: ch[k] for k in want}, q=q, v=v)


def replay(model: FlexArmModel, controller: ControllerDescription, rec, *,
           nominal_model: FlexArmModel | None = None, dt: float = DEFAULT_STEP,
           sensor_bias=None, sensor_delay=None, ff=None, x0=None) -> Prediction:
    """Replay the Recording ``rec`` in closed loop through ``model``.

    The reference is the recorded ``qset`` (held at the control instants); the gravity
    feed-forward uses ``nominal_model`` (the controller's model; default ``model``), or
    pass ``ff`` (n_periods + 1, n_joints) precomputed. The twin starts at the measured joint
    angles and rates of the first sample with its links in static equilibrium.
    """
    period = controller.instant_period(rec.dt)
    t_rel = rec.t - rec.t[0]
    t_final = t_rel[-1]
    instants = np.arange(int(round(t_final / period)) + 1) * period
    qset = zero_order_hold(t_rel, rec.stack("qset"), instants)
    if ff is None:
        recorded = zero_order_hold(t_rel, rec.stack("tau_ff"), instants) \
            if controller.feedforward_mode == "recorded" else None
        ff = controller.feedforward(nominal_model or model, qset, recorded)
    if x0 is None:
        window = getattr(rec, "meta", {}).get("start_window", START_WINDOW)
        x0 = initial_state(model, *measured_start(rec, window),
                           *(measured_link_start(rec, window) or ()))
    X, TAU = simulate_closed_loop(model, controller, x0, t_final, qset, ff,
                                  sample_period=rec.dt, dt=dt, sensor_bias=sensor_bias,
                                  sensor_delay=sensor_delay)
    n = min(len(X), len(rec.t))
    return predict(model, X[:n], TAU[:n], rec.t[:n], rec.residual_channels)


def residuals(rec, pred: Prediction) -> dict:
    """Measured minus predicted, per channel (samples the prediction covers)."""
    n = len(pred.t)
    return {k: rec.channels[k][:n] - pred.channels[k] for k in pred.channels}


# numba re-compiles a cached loop when this file changes, not when the integrator or the
# kernels it calls change (flex_model.numba_cache): flush these caches then
def _guard_caches():
    from flex_model import integrators, iteration_matrix, kernels, numba_cache
    from flex_model.effects import friction, stick_slip
    from flex_model.solvers import galpha, loop, newton, status
    numba_cache.guard([_closed_loop, _continuous_periods, _continuous_loop, _tips],
                      [integrators.__file__, kernels.__file__, stick_slip.__file__,
                       friction.__file__, iteration_matrix.__file__, galpha.__file__,
                       loop.__file__, newton.__file__, status.__file__])


_guard_caches()
