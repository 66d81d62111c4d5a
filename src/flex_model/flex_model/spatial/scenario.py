"""Spatial simulation scenarios (issue 25): a YAML file, validated on load, run by the
compiled generalized-alpha loop (integrate.simulate_fixed_compiled).

The file format is the one of every scenario (:mod:`flex_model.scenario`, one loader:
``load_scenario``); its arm here is a spatial arm (a DH table, a URDF side file or a
spatial preset).

``pd45`` is seed 000's PD-like cascade, Eq. (45), in continuous time (as the seed's runs
and flex_control.step_response): on the motor angle n theta_a it is the joint PD
kp = n^2 K_pv K_pp, kd = n^2 K_pv (:func:`eq45_joint_gains`, n the ratio of the joint's
``gear`` effect), run as below. The PD law is thesis Eq. 95 with constant gains,
tau_i = kp_i (s_i(t) - theta_a) -
kd_i theta_a', evaluated inside the integrator: its -kp theta_a - kd theta_a' part is
stiffness and damping on the actuator coordinate theta_a (the joint, or the motor
coordinate behind an elastic gear: collocated), kp s(t) a joint torque. A set-point step
of delta is the torque step kp delta (as the planar scenario). With effort limits (URDF
``<limit effort>`` or a DH joint's ``effort``) the whole actuator torque (PD, holding
torques and pulses) is clipped to them inside the loop (integrate.simulate_fixed_compiled
``pd_clip``; without a PD the torques are). Pulses and set-point steps
are evaluated at mid-step, and the method restarts where one switches, as the planar
fixed-step mode does (simulate._run_fixed; integrators.restart_choice: the consistent
acceleration, or the part of the jump the step follows where the rest would kick modes
it cannot follow), so that a planar arm embedded in 3D follows the planar run.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import SimulationDivergedError, StaticConvergenceError
from ..inputs import ramp_fraction
from ..result import SimulationResult
from ..simulate import fixed_step
from .description import SpatialArm
from .dynamics import SpatialArmModel
from .limits import joint_limits


def eq45_joint_gains(arm: SpatialArm, kpp, kpv) -> tuple:
    """Seed 000's PD-like cascade, Eq. (45), tau_cmd = K_pv (K_pp (p_cmd - p) - p'), on the
    motor angle p = n theta_a with n the ratio of the joint's ``gear`` effect (1 without)
    and the joint torque n tau_cmd: at the joint the PD kp = n^2 K_pv K_pp, kd = n^2 K_pv
    (flex_control.laws.PDLikeCascade.joint_gains). Returns (kp, kd) per joint."""
    n = np.array([1.0 if arm.effect("gear", nm) is None else arm.effect("gear", nm)["ratio"]
                  for nm in arm.joint_names])
    kpp, kpv = np.asarray(kpp, float), np.asarray(kpv, float)
    return n * n * kpv * kpp, n * n * kpv


def grid(sc):
    """(h, steps per sample, samples) of scenario ``sc`` (flex_model.scenario.Scenario):
    the step divides the sample period (simulate.fixed_step, as the planar fixed mode)."""
    h, per = fixed_step(sc.sample_period, sc.step)
    return h, per, int(round(sc.duration / sc.sample_period))


def pd_matrices(sc, model: SpatialArmModel):
    """(K_pd, D_pd): the PD's stiffness and damping on the actuator coordinates."""
    Kp, Dp = np.zeros((model.nq, model.nq)), np.zeros((model.nq, model.nq))
    if sc.pd is not None:
        for i, a in enumerate(model.actuator_index):
            if a >= 0:
                Kp[a, a] += sc.pd.kp[i]
                Dp[a, a] += sc.pd.kd[i]
    return Kp, Dp


def holding_torques(joint_values, model: SpatialArmModel) -> np.ndarray:
    """Joint torques that hold the arm at ``joint_values`` under gravity: the joint rows of
    K q + dU_g/dq - Q_const at the equilibrium with the joints held
    (analysis.static_equilibrium)."""
    from .analysis import static_equilibrium
    q = static_equilibrium(model, joint_values).q
    r = model.K @ q + model.gravity_force(q) - model.Q_const - model.contact_load(q)
    return np.where(model.actuator_index >= 0, r[model.off], 0.0)


def _coordinates(model: SpatialArmModel, joint) -> np.ndarray:
    """Coordinates (nq) with the joint values at the joints and their motors."""
    x = np.zeros(model.nq)
    x[model.off] = joint
    for i, m in enumerate(model.motor_index):
        if m >= 0:
            x[m] = joint[i]
    return x


def initial_state(sc, model: SpatialArmModel):
    """(q0, v0, u_hold): the start of scenario ``sc`` and the constant holding torques
    (zero without ``gravity_hold``)."""
    hold = holding_torques(sc.joint_values, model) if sc.gravity_hold else \
        np.zeros(model.n_links)
    v0 = _coordinates(model, sc.joint_rates)
    if not sc.start_static:
        return _coordinates(model, sc.joint_values), v0, hold
    if sc.pd is not None:
        u = hold + sc.pd.kp * sc.pd.setpoints
        q0 = pd_static_equilibrium(model, pd_matrices(sc, model)[0], u, start=sc.pd.setpoints)
        act = model.actuator_index
        need = np.where(act >= 0, u - sc.pd.kp * q0[np.maximum(act, 0)], 0.0)
        effort = joint_limits(model.arm)["effort"]
        over = np.flatnonzero(np.abs(need) > effort)
        if len(over):       # the loop clips the PD: that start would not be at rest
            j = int(over[0])
            raise ValueError(
                f"{sc.name}: the PD's static start needs {need[j]:.6g} N m (or N) on "
                f"{sc.arm.joint_names[j]}, beyond its effort limit {effort[j]:.6g}; "
                "start undeformed, or change the set-points or the gains")
        return q0, v0, hold
    from .analysis import static_equilibrium
    q0 = static_equilibrium(model, sc.joint_values).q
    gaps = {qi: (half, smooth) for qi, _, _, _, half, smooth, _ in model.backlash}
    for i, m in enumerate(model.motor_index):   # elastic gears: the spring carries
        if m >= 0:                               # the holding torque
            e = sc.arm.effect("joint_elasticity", sc.arm.links[i].joint.name)
            x = hold[i] / e["stiffness"]
            if model.off[i] in gaps:             # backlash: k dz(x) = hold
                x = _dead_zone_inverse(x, *gaps[model.off[i]])
            q0[m] = q0[model.off[i]] + x
    return q0, v0, hold


def _joint_pulses(sc):
    return [p for p in sc.pulses if len(p.joint_torques)]


def _tip_loads(sc):
    return [p for p in sc.pulses if not len(p.joint_torques)]


def open_loop(sc, t, hold, t_sample=None) -> np.ndarray:
    """The joint torques at times t (n,) that are not the PD's feedback: holding
    torques, pulses and kp s(t) (n, n_joints); a ramp of the set-point schedule is
    kp (s - s0) + kd s' averaged over the sample period that starts at ``t_sample``
    (default t) and held over it, as the planar scenario's ramps
    (flex_model.scenario.Scenario.setpoint_inputs)."""
    t = np.asarray(t, float)
    tk = t if t_sample is None else np.asarray(t_sample, float)
    u = np.broadcast_to(np.asarray(hold, float), (len(t), sc.arm.n_links)).copy()
    for p in _joint_pulses(sc):
        u[(p.start <= t) & (t < p.end)] += p.joint_torques
    if sc.pd is not None:
        u += sc.pd.kp * sc.pd.setpoints
        prev = sc.pd.setpoints
        T = sc.sample_period
        for ts, sp, ramp in sc.setpoint_schedule:
            delta = np.asarray(sp, float) - prev
            prev = np.asarray(sp, float)
            if ramp <= 0.0:
                u[t >= ts] += sc.pd.kp * delta
                continue
            (y0, a0), (y1, a1) = ramp_fraction(tk, ts, ramp), ramp_fraction(tk + T, ts, ramp)
            u += np.outer((a1 - a0) / T, sc.pd.kp * delta) + \
                np.outer((y1 - y0) / T, sc.pd.kd * delta)
    return u


def switch_steps(sc, h: float, n_total: int) -> list[int]:
    """Step indices where an input switches (the method restarts there): pulse and tip
    load edges, set-point steps, payload changes and, with ramps, every sample instant
    (as the planar fixed mode restarts at its policy instants)."""
    times = [t for p in sc.pulses for t in (p.start, p.end)] + \
        [e[0] for e in sc.setpoint_schedule] + [c[0] for c in sc.payload_changes]
    steps = {int(round(t / h)) for t in times if math.isfinite(t) and
             0 < round(t / h) < n_total}
    if any(ramp > 0.0 for _, _, ramp in sc.setpoint_schedule):
        per = max(1, int(round(sc.sample_period / h)))
        steps |= set(range(per, n_total, per))
    return sorted(steps)


def run_spatial(sc, model: SpatialArmModel, progress=None) -> SimulationResult:
    """Integrate scenario ``sc`` (compiled generalized-alpha, a restart at every input
    switch): :meth:`flex_model.scenario.Scenario.run` on a spatial arm."""
    h, per, n_samples = grid(sc)
    n_total = n_samples * per
    q, v, hold = initial_state(sc, model)
    Kp, Dp = pd_matrices(sc, model)
    t_mid = h * (np.arange(n_total) + 0.5)
    u = open_loop(sc, t_mid, hold, t_sample=h * per * (np.arange(n_total) // per))
    tipf = None
    if _tip_loads(sc):
        tipf = np.zeros((n_total, 3))
        for p in _tip_loads(sc):
            tipf[(p.start <= t_mid) & (t_mid < p.end)] += p.tip_force
    bounds = switch_steps(sc, h, n_total) + [n_total]
    Q, V, iters = _segments(sc, model, (q, v), h, bounds, u, tipf, Kp, Dp, progress)
    Q, V = Q[::per], V[::per]
    t = h * per * np.arange(len(Q))
    a_idx = np.maximum(model.actuator_index, 0)
    tau = open_loop(sc, t, hold)
    if sc.pd is not None:
        act = model.actuator_index >= 0
        tau -= np.where(act, sc.pd.kp * Q[:, a_idx] + sc.pd.kd * V[:, a_idx], 0.0)
    effort = joint_limits(model.arm)["effort"]
    tau = np.where(model.actuator_index >= 0, np.clip(tau, -effort, effort), 0.0)
    return SimulationResult(model=model, t=t, q=Q, v=V, tau=tau,
                            stats={"dt": h, "steps": n_total, "newton_iterations": iters,
                                   "restarts": len(bounds) - 1, "method": "fixed"})


def _segments(sc, model, x0, h, bounds, u, tipf, Kp, Dp, progress):
    """(q, v at every step, Newton iterations): the compiled loop between the switches,
    the model of each payload change (a shallow copy with the end body replaced)."""
    from .integrate import simulate_fixed_compiled
    from .payload import model_with_payload
    changes = [(int(round(tc / h)), model_with_payload(model, sc.arm, m, inertia))
               for tc, m, inertia in sc.payload_changes]
    (q, v), K0, n_total = x0, model.K, bounds[-1]
    qs, vs, iters, start, acc = [q[None]], [v[None]], 0, 0, None
    try:
        model.K = K0 + Kp     # the PD's stiffness, for this run only
        for _, m in changes:
            m.K = model.K
        for stop in bounds:   # a restart at every switch (integrators.restart_choice)
            cur = model
            for step_c, m in changes:
                if step_c <= start:
                    cur = m
            try:
                run = simulate_fixed_compiled(
                    cur, q, v, h, stop - start, joint_torques=u[start:stop],
                    rho_inf=sc.rho_inf, tol=sc.tol, damping=Dp,
                    pd_clip=None if sc.pd is None else (sc.pd.kp, sc.pd.kd),
                    tip_force=None if tipf is None else tipf[start:stop],
                    restart_from=acc)
            except SimulationDivergedError as exc:   # the segment's time -> the run's
                raise SimulationDivergedError(
                    f"{sc.name}: Newton did not converge in the step after t = "
                    f"{start * h:.6g} s + ({exc}); reduce the step or the input") from None
            qs.append(run.q[1:])
            vs.append(run.v[1:])
            iters += run.newton_iterations
            q, v = run.q[-1].copy(), run.v[-1].copy()
            acc = run.acceleration   # the restart at the next switch starts from it
            start = stop
            if progress is not None:
                progress(stop * h, n_total * h)
    finally:
        model.K = K0
    return np.concatenate(qs), np.concatenate(vs), iters


def _dead_zone_inverse(y: float, half: float, smooth: float) -> float:
    """x with integrators.dead_zone(x, half, smooth) = y (Newton from y + sign(y) half;
    dz is increasing)."""
    from ..integrators import dead_zone
    if y == 0.0:
        return 0.0
    x = y + np.sign(y) * half
    for _ in range(100):
        dz, slope = dead_zone(x, half, smooth)
        dx = (dz - y) / max(slope, 1e-300)
        x -= dx
        if abs(dx) <= 1e-15 * max(1.0, abs(x)):
            break
    return float(x)


def pd_static_equilibrium(model: SpatialArmModel, K_pd, u, start=None, tol: float = 1e-13,
                          max_iter: int = 40) -> np.ndarray:
    """q with (K + K_pd) q + dU_g/dq - Q_const - J^T F_c = H u (all free coordinates; the
    spring balance of the PD, thesis Eq. 95 at rest; F_c the force of a contact surface
    at the tip): Newton with the tangent K + K_pd + d^2 U_g/dq^2 (+ k J^T n n^T J in
    contact) from joint values ``start``."""
    from .integrate import joint_input_matrix
    q = np.zeros(model.nq)
    if start is not None:
        q[model.off] = start
        for i, m in enumerate(model.motor_index):
            if m >= 0:
                q[m] = start[i]
    free = model.free_indices
    Kt0 = model.K + K_pd
    f = joint_input_matrix(model) @ np.asarray(u, float) + model.Q_const
    for _ in range(max_iter):
        r = (f - Kt0 @ q - model.gravity_force(q) + model.contact_load(q)
             + model.stop_load(q) + model.curvature_load(q))[free]
        Kt = (Kt0 + model.gravity_stiffness(q) + model.contact_tangent(q)[0]
              + model.stop_tangent(q)[0] + model.curvature_tangent(q))[np.ix_(free, free)]
        dq = np.linalg.solve(Kt, r)
        q[free] += dq
        if np.max(np.abs(dq)) < tol * max(1.0, np.max(np.abs(q))):
            return q
    raise StaticConvergenceError(f"no PD equilibrium after {max_iter} Newton steps")
