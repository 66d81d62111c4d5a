"""Time integration of a spatial arm: M(q) a + c(q, v) + K q = Q(t, q, v).

- ``simulate_variable``: Dormand-Prince 8(5,3) with error control (scipy DOP853), for
  analysis and energy checks.
- ``simulate_fixed``: generalized-alpha (Chung-Hulbert; Arnold-Bruels form for the
  accelerations), fixed step, Newton on the accelerations with the iteration matrix
  M + beta' h^2 K frozen per step. rho_inf = 1 is the trapezoidal rule (no numerical
  dissipation), rho_inf < 1 damps the unresolved high modes like the planar ``fixed`` mode.
- ``simulate_fixed_compiled``: the same scheme compiled (the planar arms'
  solvers.loop.fixed_step on compiled.SpatialModel; analytic velocity terms), joint
  torques as an array, clipped to the URDF effort limits.

``force(t, q, v)`` returns the generalized applied force Q (nq), e.g. ``H tau`` with
``H = joint_input_matrix(model)``. ``joint_commands`` are joint torques/forces, or
voltages on ``dc_motor`` joints, put through the motor model and the effort limits by
``model.actuator_force`` (velocity dependent: its slope enters the Newton matrix). The
joint effects (dynamics.py) are always in: the springs and dampers of elastic gears
(model.K, model.D; structural damping in model.D), friction and the locked motors'
preload (model.effect_force, its slope in the Newton matrix), the backlash of gears and
the contact surface at the tip and the end stops at the joint limits (model.effect_force
with q; their tangents in the Newton matrix), held joints (zero acceleration: their rows
and columns of the Newton matrix are the identity).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import SimulationDivergedError
from ..solvers.galpha import galpha_coefficients, galpha_state
from ..solvers.newton import spatial_converged
from ..solvers.status import FINISHED, NO_CONVERGENCE, REFINEMENTS, Settings, message
from .dynamics import SpatialArmModel


@dataclass
class SpatialRun:
    t: np.ndarray
    q: np.ndarray     # (len(t), nq)
    v: np.ndarray
    newton_iterations: int = 0
    #: (2, nq): the method's accelerations (a, abar) after the last step (compiled loop);
    #: hand it back as ``acceleration`` to continue the run without a restart
    acceleration: np.ndarray | None = None


def joint_input_matrix(model: SpatialArmModel) -> np.ndarray:
    """H (nq x n_joints): joint torques/forces to generalized forces."""
    H = np.zeros((model.nq, model.n_links))
    for i, a in enumerate(model.actuator_index):
        if a >= 0:    # the motor coordinate of an elastic gear; none for a locked motor
            H[a, i] = 1.0
    return H


def _solve_free(model, M, rhs):
    a = np.zeros(model.nq)
    free = model.free_indices
    a[free] = np.linalg.solve(M[np.ix_(free, free)], rhs[free])
    return a


def simulate_variable(model: SpatialArmModel, q0, v0, t_out, force=None, rtol: float = 1e-11,
                      atol: float = 1e-13, compiled: bool = False,
                      joint_commands=None) -> SpatialRun:
    """Integrate with DOP853 and report at the times ``t_out`` (s); ``compiled``: M, c
    from the compiled kernels (compiled.py, equal to the Python reference to 1e-10).
    ``joint_commands(t)``: the joint commands (n_joints; voltages on dc_motor joints)
    through ``model.actuator_force`` (URDF effort limits applied)."""
    nq = model.nq
    t_out = np.asarray(t_out, float)
    terms = model.terms
    if compiled:
        from .compiled import CompiledSpatialModel
        terms = CompiledSpatialModel(model).terms

    def rhs(t, x):
        q, v = x[:nq], x[nq:]
        M, c = terms(q, v)
        Q = -model.K @ q - c - model.D @ v + model.effect_force(v, q)
        if force is not None:
            Q = Q + force(t, q, v)
        if joint_commands is not None:
            Q = Q + model.actuator_force(joint_commands(t), v, effort)[0]
        return np.concatenate([v, _solve_free(model, M, Q)])

    if joint_commands is not None:
        from .limits import joint_limits
        effort = joint_limits(model.arm)["effort"]

    sol = solve_ivp(rhs, (t_out[0], t_out[-1]), np.concatenate([q0, v0]), method="DOP853",
                    t_eval=t_out, rtol=rtol, atol=atol)
    if not sol.success:
        raise SimulationDivergedError(f"DOP853 failed: {sol.message}")
    return SpatialRun(sol.t, sol.y[:nq].T.copy(), sol.y[nq:].T.copy())


#: the Newton of both spatial loops: its line search with the nonlinear joint effects and
#: the stagnation acceptance (solvers.loop.newton, solvers.newton.spatial_converged)
SETTINGS = Settings()


def simulate_fixed(model: SpatialArmModel, q0, v0, h: float, n_steps: int, force=None,
                   rho_inf: float = 0.9, tol: float = 1e-10, max_iter: int = 50,
                   damping=None, joint_commands=None,
                   clip_to_effort: bool = True) -> SpatialRun:
    """Generalized-alpha with step ``h`` (s) for ``n_steps`` steps (at most ``max_iter``
    Newton iterations a step: 50, since a Coulomb joint starting to slide under gravity
    takes ~25 in its first step with a 1 mrad/s regularization); ``damping`` an optional
    constant matrix D (force -D v), added to the model's joint dampers.
    ``joint_commands``: None or (n_steps, n_joints) joint commands (torques, forces;
    voltages on dc_motor joints), row n held over step n (row 0 also at t = 0), as
    :func:`simulate_fixed_compiled`'s ``joint_torques``, through ``model.actuator_force``
    (clipped to the URDF effort limits when ``clip_to_effort``)."""
    D = model.D + (0.0 if damping is None else np.asarray(damping, float))
    K = model.K
    held = model.held
    cmd = None
    if joint_commands is not None:
        from .limits import joint_limits
        cmd = np.broadcast_to(np.asarray(joint_commands, float), (n_steps, model.n_links))
        effort = joint_limits(model.arm)["effort"] if clip_to_effort else None
    contact = model.contact is not None
    nonlinear = bool(model.friction) or bool(model.motors) or \
        bool(model.backlash) or contact or bool(model.stops)     # as the compiled loop
    gaps = bool(model.backlash) or contact or bool(model.stops) or model.coupled

    def residual(t, q, v, a, n):
        M, c = model.terms(q, v)
        r = M @ a + c + K @ q + D @ v - model.effect_force(v, q if gaps else None)
        if force is not None:
            r -= force(t, q, v)
        slope = model.effect_force_slope(v)
        if cmd is not None:
            Qu, s_u = model.actuator_force(cmd[n], v, effort)
            r -= Qu
            slope = slope + s_u
        r[held] = 0.0
        return r, M, slope

    q, v = np.array(q0, float), np.array(v0, float)
    M, c = model.terms(q, v)
    Q0 = -c - K @ q - D @ v + model.effect_force(v, q if gaps else None) + \
        (force(0.0, q, v) if force is not None else 0.0)
    if cmd is not None:
        Q0 = Q0 + model.actuator_force(cmd[0], v, effort)[0]
    a = _solve_free(model, M, Q0)
    abar = a.copy()
    ts, qs, vs = [0.0], [q.copy()], [v.copy()]
    ga = galpha_coefficients(float(rho_inf), float(h))
    cq, cv, st = ga.bp, ga.gp, SETTINGS
    iters = 0
    for n in range(n_steps):
        t1 = (n + 1) * h
        a1 = a.copy()
        lu = None
        rprev, back, da, dprev = np.inf, 0, np.zeros(model.nq), np.inf
        for it in range(max_iter):
            q1, v1, _ = galpha_state(q, v, a, abar, a1, ga)
            r, M1, slope = residual(t1, q1, v1, a1, n)
            rn = np.max(np.abs(r))
            if nonlinear and it >= st.line_search_from and rn > rprev and \
                    back < st.halvings:
                da *= 0.5       # the step raised the residual: take half of it back
                a1 -= da
                back += 1
                iters += 1
                continue
            rprev, back = rn, 0
            if lu is None:     # (the curvature coupling's tangent at the first iterate)
                S0 = M1 + cq * (K + model.curvature_tangent(q1)) + cv * D
            if lu is None or nonlinear:  # iteration matrix, frozen for the step but
                # for the friction and motor slopes (steep tanh: from the current iterate)
                S = S0 - cv * np.diag(slope)
                if model.backlash:
                    Kb, Db = model.backlash_tangent(q1, v1)
                    S = S + cq * Kb + cv * Db
                if contact:
                    Kc, Dc = model.contact_tangent(q1, v1)
                    S = S + cq * Kc + cv * Dc
                if model.stops:
                    Ks, Ds = model.stop_tangent(q1, v1)
                    S = S + cq * Ks + cv * Ds
                S[held, :] = 0.0
                S[:, held] = 0.0
                S[held, held] = 1.0
                try:
                    lu = np.linalg.cholesky(S)
                except np.linalg.LinAlgError:     # a Stribeck slope's negative damping
                    pos = np.maximum(slope, 0.0)
                    pos[held] = 0.0
                    lu = np.linalg.cholesky(S + cv * np.diag(pos))
            da = -np.linalg.solve(lu.T, np.linalg.solve(lu, r))
            a1 += da
            iters += 1
            dmax, amax = np.max(np.abs(da)), max(1.0, np.max(np.abs(a1)))
            if spatial_converged(it, dmax, amax, dprev, tol, st.line_search_from,
                                 st.stagnation)[0]:
                break
            dprev = dmax
        else:
            raise SimulationDivergedError(f"generalized-alpha: {message(NO_CONVERGENCE, t1)}")
        q, v, abar = galpha_state(q, v, a, abar, a1, ga)
        a = a1
        ts.append(t1)
        qs.append(q.copy())
        vs.append(v.copy())
    return SpatialRun(np.array(ts), np.array(qs), np.array(vs), iters)


def simulate_fixed_compiled(model: SpatialArmModel, q0, v0, h: float, n_steps: int,
                            joint_torques=None, rho_inf: float = 0.9, tol: float = 1e-10,
                            max_iter: int = 50, damping=None,
                            clip_to_effort: bool = True, acceleration=None,
                            pd_clip=None, substeps: int = REFINEMENTS[0], tip_force=None,
                            restart_from=None) -> SpatialRun:
    """The generalized-alpha scheme of :func:`simulate_fixed`, compiled (numba, the
    analytic velocity terms of compiled.py). ``joint_torques``: None, a constant
    (n_joints) or an (n_steps, n_joints) array, row n held over step n (applied at
    t_{n+1}, as simulate_fixed's ``force(t_{n+1})``); clipped to the URDF effort limits
    when ``clip_to_effort`` (inside the compiled loop, as limits.clip_efforts does)).
    On ``dc_motor`` joints the command is a voltage (the motor model of
    ``model.actuator_force``, then the effort clip). ``acceleration``: the (a, abar) of a
    previous run's ``acceleration`` to continue it from its last state (q0, v0) without
    a restart: two runs chained this way equal one run over both; None restarts with
    the consistent acceleration. ``pd_clip``: None or the gains (kp, kd) (n_joints each)
    of a PD inside the loop (thesis Eq. 95: kp, kd on the actuator coordinates already in
    the model's K and ``damping``, kp s(t) in ``joint_torques``): the PD's whole actuator
    torque kp (s - theta_a) - kd theta_a' + u is then clipped to the effort limits
    (compiled._pd_clip), not only the torques. A step whose Newton iteration fails is
    integrated again as ``substeps`` steps of h / substeps from a restart (a consistent
    acceleration), and the run goes on with a restart after it (0: raise instead; the first of
    solvers.status.REFINEMENTS, as the planar replay's); the Newton count includes the failed
    attempts' iterations and ``acceleration`` is None when the run ends with such a step (a
    continuation then restarts). The PD clip leaves ``dc_motor`` joints to the motor model's
    own clip and is off with ``clip_to_effort=False``. ``tip_force``: None, a constant (3) or
    an (n_steps, 3) array of forces (N, base frame) at the tip (the origin of the last link's
    end frame), row n over step n, as J_tip^T F (``simulate_fixed``'s ``force`` does the same
    with a callback). ``restart_from``: the ``acceleration`` of the run before an input jump at
    (q0, v0): the restart then takes the part of the jump the step can follow where the rest
    would kick modes it cannot (integrators.restart_choice, as the planar fixed step), instead
    of the consistent acceleration."""
    from ..solvers.loop import fixed_step
    from .compiled import LoopInputs, pack, spatial_model, start_acceleration
    from .limits import joint_limits
    data = getattr(model, "_compiled_data", None)
    if data is None:
        data = pack(model)
        model._compiled_data = data
    nj = model.n_links
    tau = np.zeros((n_steps, nj)) if joint_torques is None else \
        np.broadcast_to(np.asarray(joint_torques, float), (n_steps, nj))
    tau = np.array(tau, dtype=float, order="C")   # a writable copy: one compiled signature
    effort = joint_limits(model.arm)["effort"] if clip_to_effort else np.full(nj, np.inf)
    D = model.D + (0.0 if damping is None else np.asarray(damping, float))
    fric = np.array([[a, *f.values] for a, f in model.friction], float).reshape(-1, 6)
    motors = np.array([[j, a, n, *e.values] for j, a, n, e in model.motors],
                      float).reshape(-1, 8)
    blash = np.array(model.backlash, float).reshape(-1, 7)
    contact = np.zeros(0) if model.contact is None else \
        np.concatenate([model.contact[0], model.contact[1], model.contact[2:]]).astype(float)
    stops = np.array(model.stops, float).reshape(-1, 6)
    pdc = np.zeros((0, 5))
    if pd_clip is not None and clip_to_effort:
        kp, kd = (np.broadcast_to(np.asarray(g, float), (nj,)) for g in pd_clip)
        volts = {j for j, *_ in model.motors}        # dc_motor joints: their own clip
        rows = [(j, a, kp[j], kd[j], effort[j]) for j, a in enumerate(model.actuator_index)
                if a >= 0 and np.isfinite(effort[j]) and j not in volts]
        pdc = np.array(rows, float).reshape(-1, 5)
        effort = effort.copy()
        effort[pdc[:, 0].astype(int)] = np.inf     # the whole PD torque is clipped instead
    held = np.zeros(model.nq, np.int64)
    held[model.held] = 1
    warm = 1 if acceleration is not None else 2 if restart_from is not None else 0
    acc = np.array(acceleration if warm == 1 else restart_from, float).reshape(
        2, model.nq) if warm else np.zeros((2, model.nq))
    K, H = np.ascontiguousarray(model.K), joint_input_matrix(model)
    tipf = np.zeros((0, 3)) if tip_force is None else np.array(np.broadcast_to(
        np.asarray(tip_force, float), (n_steps, 3)), order="C")

    settings = Settings(rho_inf=float(rho_inf), tol=float(tol), max_iter=int(max_iter),
                        limit=np.inf)     # no bound (motor angles wind up): only non-finite

    def loop(q, v, hh, rows, acc, warm, forces):
        """(q, v) at every step done, the Newton iterations and the status (not
        FINISHED: that of the failed step) of len(rows) steps of hh from (q, v); acc
        overwritten with the last step's (a, abar) when FINISHED."""
        inputs = LoopInputs(K, np.ascontiguousarray(D), model.Q_const.copy(), fric, motors,
                            blash, contact, stops, pdc, forces, held, H, effort)
        q, v, nq = np.asarray(q, float).copy(), np.asarray(v, float).copy(), model.nq
        md = spatial_model(data, inputs, rows)
        a, abar, ok = start_acceleration(md, q, v, float(hh), acc, warm, settings.rho_inf)
        if not ok:
            return q.reshape((1, nq)), v.reshape((1, nq)), 0, NO_CONVERGENCE
        s = settings._replace(relative=True, halvings=settings.halvings if md.nonlinear else 0)
        X, code, t, _, a, abar, iters = fixed_step(md, nq, 0.0, np.concatenate((q, v)), a,
                                                   abar, float(hh), len(rows), 1, s, None)
        if code == FINISHED:
            acc[0], acc[1] = a, abar
        done = len(X) if code == FINISHED else int(np.rint(t / hh))   # the steps before
        return X[:done, :nq].copy(), X[:done, nq:].copy(), iters, code

    def forces(a, b, repeat=1):
        return tipf if not len(tipf) else np.array(np.repeat(tipf[a:b], repeat, axis=0),
                                                   order="C")

    qs, vs, iters, status = loop(q0, v0, h, tau, acc, warm, tipf)
    if status == FINISHED:
        return SpatialRun(h * np.arange(len(qs)), qs, vs, int(iters), acc)
    # a step whose Newton iteration failed: again as `substeps` steps from a restart
    # (consistent acceleration), then on with a restart (runs that never fail: unchanged)
    out_q, out_v, pos, total = [qs[:1]], [vs[:1]], 0, 0
    while True:
        k = len(qs) - 1     # steps done by this call
        out_q.append(qs[1:k + 1])
        out_v.append(vs[1:k + 1])
        pos += k
        total += iters
        if status == FINISHED:
            break
        if not substeps:
            raise SimulationDivergedError(
                f"generalized-alpha: {message(status, (pos + 1) * h)}")
        sub = np.array(np.repeat(tau[pos:pos + 1], substeps, axis=0), order="C")
        acc = np.zeros((2, model.nq))
        qs2, vs2, it2, status = loop(qs[k], vs[k], h / substeps, sub, acc, 0,
                                     forces(pos, pos + 1, substeps))
        if status != FINISHED:
            raise SimulationDivergedError(
                f"generalized-alpha: {message(status, (pos + 1) * h)}, nor in "
                f"{substeps} substeps")
        out_q.append(qs2[-1:])
        out_v.append(vs2[-1:])
        total += it2
        pos += 1
        if pos == n_steps:        # (a, abar) of h / substeps: a continuation restarts
            acc = None
            break
        acc = np.zeros((2, model.nq))
        qs, vs, iters, status = loop(qs2[-1], vs2[-1], h, np.array(tau[pos:], order="C"),
                                     acc, 0, forces(pos, n_steps))
    qs, vs = np.vstack(out_q), np.vstack(out_v)
    return SpatialRun(h * np.arange(len(qs)), qs, vs, int(total), acc)
