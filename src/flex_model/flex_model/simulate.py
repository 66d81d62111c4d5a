"""Time simulation of the arm: variable-step (analysis) and fixed-step (real-time) modes.

The joint law built into the compiled integrator is a PD with set-points (thesis Eq. 95
without feed-forward, or the "PD-held" joints of §II.6), plus torque and tip-load pulses on
time windows. Any other controller is a ``policy(t, x) -> tau`` callable, sampled with a
zero-order hold every ``control_period`` (a digital controller), as ``solve_ivp`` takes
``fun(t, y)``.

Accuracy
--------
- ``method='variable'``: Dormand-Prince 5(4) with local error control (``rtol``, and
  ``atol`` per state: 1e-3 rtol in m or rad for q, 1e-2 rtol for v by default); steps land
  on pulse edges and control instants.
- ``method='fixed'``: generalized-alpha with a constant step ``dt`` (default 1 ms, the
  model node's rate; rounded down to divide the sample period), spectral radius
  ``rho_inf`` (default 0.9): implicit, second order (global error O(dt^2)),
  unconditionally stable, so the stiff flexible modes do not limit the step. The method
  restarts at pulse edges and at policy instants (rounded to the step grid). ``newton``:
  each step's equations are solved to 1e-10 m or rad by full Newton (``'full'``) or by
  simplified Newton (``'simplified'``: the iteration matrix kept across steps, refreshed
  when the iterations contract slowly; solvers.loop.simplified_newton, about a
  third of the cost); the default takes simplified Newton for ``second_order``
  kinematics and full Newton (results as before it existed) for the thesis kinematics.

With ``kinematics: exact`` (flex_model.exact_kinematics, compiled in its own module) the
variable mode is DOP853 (scipy) on the exact equations, ``rtol`` and ``atol`` as above, and
the fixed mode that module's generalized-alpha (full Newton, the same parameters); the
model's compiled data ``P`` is refused (Stepper, control loop, node, replays).

Joints with ``stick_slip_friction`` add one bristle state each: the integrated state is
``x = [q; v; z]`` (flex_model.effects.stick_slip); ``SimulationResult.bristles`` holds z.
"""
from __future__ import annotations

import copy
from typing import Callable

import numpy as np

from .dynamics import FlexArmModel
from .errors import SimulationDivergedError  # noqa: F401 (raised here; public here)
from .inputs import JointPD, Pulse, input_data  # noqa: F401 (JointPD, Pulse: public here)
from .integrators import (PlanarModel, consistent_acceleration, dopri5, restart_acceleration,
                          sampled_joint_torques)
from .iteration_matrix import empty_factor
from .solvers import loop
from .solvers.status import newton_settings
from .result import SimulationResult
from .kernels import P_MODE

#: a state component beyond this magnitude (rad, m, rad/s, m/s) counts as diverged
DIVERGENCE_LIMIT = 1e6


def diverged(model: FlexArmModel, t: float, x: np.ndarray) -> SimulationDivergedError:
    names = model.coordinate_names()
    names = names + [n + "_rate" for n in names] + [
        f"{model.arm.joint_names[i]}/bristle" for i in model.stick_slip_joints]
    bad = ~np.isfinite(x) | (np.abs(x) > DIVERGENCE_LIMIT)
    i = int(np.flatnonzero(bad)[0]) if np.any(bad) else int(np.argmax(np.abs(x)))
    return SimulationDivergedError(
        f"simulation diverged at t = {t:.6g} s: state variable {names[i]} = {x[i]!r} "
        f"(non-finite or beyond {DIVERGENCE_LIMIT:g}); reduce the step or check the inputs")


#: why Newton fails in a loop driven by commands (Stepper, ControlLoop)
RUNAWAY = ("the state ran away, most often under an implausible joint command or payload or "
           "an unstable control loop")


def newton_failed(t: float, h: float, hint: str) -> SimulationDivergedError:
    """The error of a fixed step whose Newton iterations did not converge."""
    return SimulationDivergedError(
        f"Newton iterations did not converge at t = {t:.6g} s with step {h:.3g} s: {hint}")


def simulate(model: FlexArmModel, q0, v0=None, *, t_final: float, sample_period: float,
             pd: JointPD | None = None, pulses=(), policy: Callable | None = None,
             control_period: float | None = None, method: str = "variable",
             rtol: float = 1e-8, atol=None, dt: float | None = None, rho_inf: float = 0.9,
             payload_changes=(), progress: Callable | None = None,
             bristles0=None, newton: str | None = None) -> SimulationResult:
    """Integrate the arm from (q0, v0) over [0, t_final], sampling every ``sample_period``.

    ``policy(t, x) -> tau`` (N m per joint) adds to the built-in PD and pulses, held for
    ``control_period`` (default: ``sample_period``), and delayed per joint by the arm's
    ``actuator_delay`` effects. ``payload_changes``: (time, mass, inertia) triples, a pick
    (the payload's momentum, zero, joins the arm's: B v is conserved) or a place (the arm
    keeps its velocity). ``progress(t, t_final)`` is called as the run advances.
    ``bristles0``: initial bristle deflections (rad) of the stick_slip_friction joints
    (default 0: unloaded). ``newton``: 'full' or 'simplified' Newton in the fixed mode
    (default: simplified with second_order kinematics; the module's docstring). Raises
    :class:`SimulationDivergedError` naming the time and
    variable.
    """
    if method not in ("variable", "fixed"):
        raise ValueError(f"method: got {method!r}; expected 'variable' or 'fixed'")
    if newton not in (None, "full", "simplified"):
        raise ValueError(f"newton: got {newton!r}; expected 'full', 'simplified' or None "
                         "(simplified for second_order kinematics)")
    exact = model.arm.kinematics == "exact"
    if exact:
        if model.n_bristles:
            from .exact_kinematics import ExactKinematicsUnsupported
            raise ExactKinematicsUnsupported(
                f"{model.arm.source}: kinematics: exact does not take stick_slip_friction "
                "yet; use kinematics: second_order")
        if newton == "simplified":
            raise ValueError("newton: 'simplified' is not implemented for kinematics: "
                             "exact; use 'full' or None")
        newton = "full"
    if newton is None:
        newton = "simplified" if model.P[P_MODE] == 1 else "full"
    if not (t_final > 0 and sample_period > 0):
        raise ValueError(f"t_final and sample_period must be > 0 (got {t_final}, "
                         f"{sample_period})")
    nq, nl = model.nq, model.n_links
    if payload_changes:
        model = copy.copy(model)  # the caller's model keeps its payload
    delays = np.array([getattr(model.arm.effect("actuator_delay", j), "values", (0.0,))[0]
                       for j in model.arm.joint_names])
    if policy is not None and np.any(delays > 0):
        policy = _delayed(policy, delays, nl)
    q0 = np.asarray(q0, float)
    v0 = np.zeros(nq) if v0 is None else np.asarray(v0, float)
    nz = model.n_bristles
    z0 = np.zeros(nz) if bristles0 is None else np.asarray(bristles0, float).reshape(nz)
    x0 = np.concatenate([q0, v0, z0])
    u = np.zeros(nl)
    E = input_data(model, pd, pulses, u)
    n_samples = int(round(t_final / sample_period)) + 1
    t_samples = np.arange(n_samples) * sample_period
    control_period = (control_period or sample_period) if policy is not None else None
    run = _run_fixed if method == "fixed" else _run_exact if exact else _run_variable
    changes = sorted((float(t), float(m), float(j)) for t, m, j in payload_changes)
    X, U, stats = run(model, x0, E, u, t_samples, policy, control_period, pulses,
                      rtol=rtol, atol=atol, dt=dt, rho_inf=rho_inf, progress=progress,
                      changes=changes, newton=newton)
    q = X[:, :nq]
    v = X[:, nq:2 * nq]
    tau = sampled_joint_torques(t_samples, np.ascontiguousarray(X), np.asarray(U, float), E)
    stats["method"] = method
    return SimulationResult(model=model, t=t_samples, q=q, v=v, tau=tau, stats=stats, u=U,
                            inputs=E, bristles=X[:, 2 * nq:])


def _delayed(policy, delays, nl):
    """Wrap a policy so that joint j applies the command issued delays[j] earlier."""
    history = []

    def delayed(t, x):
        history.append((t, np.asarray(policy(t, x), float).reshape(nl)))
        out = np.zeros(nl)
        for j in range(nl):
            for tk, cmd in reversed(history):
                if tk <= t - delays[j] + 1e-12:
                    out[j] = cmd[j]
                    break
        return out
    return delayed


def apply_payload_change(model, x, mass, inertia):
    """Change the payload at state x; a heavier payload is picked up at rest (B v kept)."""
    n = model.nq
    q, v = x[:n], x[n:2 * n]
    B_old = model.mass_matrix(q)
    old = model.payload
    model.set_payload(mass, inertia)
    if mass > old[0] or inertia > old[1]:
        v = np.linalg.solve(model.mass_matrix(q), B_old @ v)
    return np.concatenate([q, v, x[2 * n:]])


def _run_variable(model, x, E, u, t_samples, policy, control_period, pulses, *, rtol, atol,
                  progress, changes, **_):
    """Dormand-Prince between breakpoints (pulse edges, control instants, progress marks)."""
    nq = model.nq
    t_final = t_samples[-1]
    if policy is not None:
        instants = np.arange(0.0, t_final, control_period)
    else:
        instants = np.arange(0.0, t_final, 1.0)  # progress marks
    edges = _breakpoints(t_final, instants, pulses, changes)
    nz = len(x) - 2 * nq
    if atol is None:
        atol = _default_atol(nq, rtol)
    atol = np.asarray(atol, float)
    if atol.ndim == 0:
        atol = np.full(len(x), float(atol))
    if len(atol) == 2 * nq and nz:  # bristle deflections: as the coordinates, in rad
        atol = np.concatenate([atol, np.full(nz, 1e-3 * rtol)])
    X = np.full((len(t_samples), len(x)), np.nan)
    U = np.zeros((len(t_samples), len(u)))
    X[0] = x
    h = min(t_samples[1] - t_samples[0], 1e-3)
    stats = {"steps": 0, "rejected": 0}
    t = 0.0
    for t_end in edges:
        if t_end <= t:
            continue
        for c in changes:
            if abs(c[0] - t) < 1e-12:
                x = apply_payload_change(model, x, c[1], c[2])
        if policy is not None and np.any(np.isclose(instants, t)):
            u[:] = np.asarray(policy(t, x.copy()), float).reshape(len(u))
            if t == 0.0:
                U[0] = u
        sel = (t_samples > t + 1e-12) & (t_samples <= t_end + 1e-12)
        outs = t_samples[sel]
        if len(outs) == 0 or not np.isclose(outs[-1], t_end):
            outs = np.append(outs, t_end)
        Xs, status, t_stop, x_stop, h, steps, rej = dopri5(
            t, x, outs, rtol, atol, h, np.inf, 10_000_000, DIVERGENCE_LIMIT, model.P, E)
        stats["steps"] += steps
        stats["rejected"] += rej
        if status == 1:
            raise diverged(model, t_stop, x_stop)
        if status != 0:
            raise SimulationDivergedError(
                f"integration stopped at t = {t_stop:.6g} s (step size underflow or step "
                f"limit, status {status}); the system may be too stiff for rtol={rtol}")
        X[sel] = Xs[:int(sel.sum())]
        U[sel] = u
        x = Xs[-1].copy()
        t = t_end
        if progress is not None:
            progress(t, t_final)
    return X, U, stats


def _breakpoints(t_final, instants, pulses, changes) -> np.ndarray:
    """Sorted times where the variable-step modes stop and restart: the control instants
    (or progress marks), the pulse edges, the payload changes and the end."""
    edges = {float(t) for t in instants}
    for p in pulses:
        edges.update(t for t in (p.start, p.end) if 0.0 < t < t_final)
    edges.update(c[0] for c in changes if 0.0 <= c[0] < t_final)
    return np.array(sorted(edges | {float(t_final)}))


def _default_atol(nq: int, rtol: float) -> np.ndarray:
    """Absolute tolerances of the variable-step modes: 1e-3 rtol on the coordinates (rad,
    m), 1e-2 rtol on the rates."""
    return np.concatenate([np.full(nq, 1e-3 * rtol), np.full(nq, 1e-2 * rtol)])


def _run_exact(model, x, E, u, t_samples, policy, control_period, pulses, *, rtol, atol,
               progress, changes, **_):
    """DOP853 (scipy) between breakpoints (pulse edges, control instants, progress marks)
    on the exact kinematics' equations, as _run_variable does with the compiled ones."""
    from scipy.integrate import solve_ivp
    nq = model.nq
    t_final = t_samples[-1]
    step = control_period if policy is not None else 1.0
    instants = np.arange(0.0, t_final, step)
    edges = _breakpoints(t_final, instants, pulses, changes)
    if atol is None:
        atol = _default_atol(nq, rtol)
    atol = np.broadcast_to(np.asarray(atol, float), (len(x),)).copy()
    X = np.full((len(t_samples), len(x)), np.nan)
    U = np.zeros((len(t_samples), len(u)))
    X[0] = x
    from .exact_kinematics import derivative

    def fun(t, x):
        return derivative(t, x, X_exact, E)
    X_exact = model._exact.data
    stats = {"steps": 0, "evaluations": 0}
    t = 0.0
    for t_end in edges:
        if t_end <= t:
            continue
        for c in changes:
            if abs(c[0] - t) < 1e-12:
                x = apply_payload_change(model, x, c[1], c[2])
                X_exact = model._exact.data
        if policy is not None and np.any(np.isclose(instants, t)):
            u[:] = np.asarray(policy(t, x.copy()), float).reshape(len(u))
            if t == 0.0:
                U[0] = u
        sel = (t_samples > t + 1e-12) & (t_samples <= t_end + 1e-12)
        outs = t_samples[sel]
        if len(outs) == 0 or not np.isclose(outs[-1], t_end):
            outs = np.append(outs, t_end)
        # every accepted step in sol.t (counted); the samples from the dense output
        sol = solve_ivp(fun, (t, t_end), x, method="DOP853", rtol=rtol, atol=atol,
                        dense_output=True)
        stats["steps"] += len(sol.t) - 1
        stats["evaluations"] += sol.nfev
        if sol.status != 0:
            raise SimulationDivergedError(f"integration stopped after t = {t:.6g} s: "
                                          f"{sol.message} (kinematics: exact)")
        x_end = sol.y[:, -1].copy()
        if not np.all(np.isfinite(x_end)) or np.max(np.abs(x_end)) > DIVERGENCE_LIMIT:
            raise diverged(model, t_end, x_end)
        X[sel] = sol.sol(outs[:int(sel.sum())]).T
        U[sel] = u
        x = x_end
        t = t_end
        if progress is not None:
            progress(t, t_final)
    return X, U, stats


def _exact_jump_step(model, t, x, a, h, rho_inf, P, E):
    """The first fixed step after a force jump (a set-point step, a pulse edge) with
    exact kinematics; its restart is exact_kinematics.restart_acceleration. Where that
    filters (a hub-less root: modes the joint damper overdamps far beyond 1 / h) the
    jump's velocity change dv in them is immediate, but one generalized-alpha step puts
    only beta / gamma of h dv (half at rho_inf 0.9) into the position: an O(h) joint angle
    lag the slow PD mode carries for ~0.3 s (issue 47: 0.027 deg at 1 ms, 8 variables).
    The step's position gets the rest in the modes the damping holds over the step,
    S^-1 gamma' (D + C_j) (h v1 - (q1 - q0)) (exact_kinematics.iteration_matrix).
    Returns (x, a, abar, Newton iterations)."""
    from .exact_kinematics import ExactModel
    from .exact_kinematics import iteration_matrix as exact_iteration_matrix
    from .exact_kinematics import restart_acceleration as exact_restart
    a, filtered = exact_restart(t, x, a, h, rho_inf, P, E)
    _, status, t_stop, x1, a, abar, it = loop.fixed_step(
        ExactModel(P, E), E.K.shape[0], float(t), x, a, a.copy(), float(h), 1, 1,
        newton_settings(float(rho_inf), 1e-10, DIVERGENCE_LIMIT), None)
    if status == 1:
        raise diverged(model, t_stop, x1)
    if status == 2:
        raise newton_failed(t_stop, h, "reduce the step")
    if filtered:
        n = model.nq
        S, G = exact_iteration_matrix(x1, h, rho_inf, P, E)
        x1 = x1.copy()
        x1[:n] += np.linalg.solve(S, G @ (h * x1[n:] - (x1[:n] - x[:n])))
    return x1, a, abar, it


def fixed_step(sample_period: float, dt: float | None = None) -> tuple[float, int]:
    """(step, steps per sample) of the fixed mode: the largest step at most ``dt``
    (default 1 ms) that divides the sample period."""
    per_sample = max(1, int(np.ceil(sample_period / (dt or 1e-3) - 1e-9)))
    return sample_period / per_sample, per_sample


def _run_fixed(model, x, E, u, t_samples, policy, control_period, pulses, *, dt, rho_inf,
               progress, changes, newton, **_):
    """Generalized-alpha on a step grid that divides the sample period."""
    sample_period = t_samples[1] - t_samples[0] if len(t_samples) > 1 else t_samples[-1]
    h, per_sample = fixed_step(sample_period, dt)
    n_total = (len(t_samples) - 1) * per_sample
    chunk = max(1, int(round(control_period / h))) if policy is not None else \
        max(1, int(round(1.0 / h)))
    X = np.full((len(t_samples), len(x)), np.nan)
    U = np.zeros((len(t_samples), len(u)))
    X[0] = x
    # the method restarts (consistent acceleration) where a pulse switches, as a load jump
    # inside its acceleration history would cost an O(h) error
    restarts = {int(round(t / h)) for p in pulses for t in (p.start, p.end)
                if 0 < round(t / h) < n_total}
    pick = {int(round(c[0] / h)): c for c in changes if 0 <= round(c[0] / h) < n_total}
    restarts |= set(pick)
    exact = model._exact  # kinematics: exact (flex_model.exact_kinematics)
    if exact is not None:
        from .exact_kinematics import ExactModel
        from .exact_kinematics import derivative as exact_derivative
    step = 0
    iters = 0
    while step < n_total:
        m = min(chunk - step % chunk, n_total - step,
                min([r - step for r in restarts if r > step], default=n_total))
        t = step * h
        if step in pick:
            x = apply_payload_change(model, x, pick[step][1], pick[step][2])
        if step % chunk == 0 and policy is not None:
            u[:] = np.asarray(policy(t, x.copy()), float).reshape(len(u))
            if step == 0:
                U[0] = u
        P = model.P if exact is None else exact.data
        if exact is not None and step == 0:
            a = exact_derivative(t, x, P, E)[model.nq:]
            abar = a.copy()
        elif exact is not None and step in restarts:
            x, a, abar, it = _exact_jump_step(model, t, x, a, h, rho_inf, P, E)
            iters += it
            if (step + 1) % per_sample == 0:
                X[(step + 1) // per_sample] = x
                U[(step + 1) // per_sample] = u
            step += 1
            continue
        elif exact is not None and policy is not None:
            a = exact_derivative(t, x, P, E)[model.nq:]
            abar = a.copy()
        elif step == 0:
            a = consistent_acceleration(t, x, P, E)
            abar = a.copy()
        elif step in restarts or policy is not None:
            a, abar, _, _ = restart_acceleration(t, x, a, abar, h, rho_inf, P, E)
        md = PlanarModel(P, E) if exact is None else ExactModel(P, E)
        Xs, status, t_stop, x_stop, a, abar, it = loop.fixed_step(
            md, E.K.shape[0], float(t), x, a, abar, float(h), m, 1,
            newton_settings(float(rho_inf), 1e-10, DIVERGENCE_LIMIT),
            empty_factor() if newton == "simplified" else None)
        iters += it
        if status == 1:
            raise diverged(model, t_stop, x_stop)
        if status == 2:
            raise newton_failed(t_stop, h, "reduce the step")
        idx = step + np.arange(1, m + 1)
        on_grid = idx % per_sample == 0
        X[idx[on_grid] // per_sample] = Xs[1:][on_grid]
        U[idx[on_grid] // per_sample] = u
        x = x_stop
        step += m
        if progress is not None:
            progress(step * h, t_samples[-1])
    return X, U, {"steps": n_total, "dt": h, "newton_iterations": iters}
