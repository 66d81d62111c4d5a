"""Compiled time integration of the arm: a variable-step and a fixed-step scheme.

State ``x = [q; v]``. The applied generalized force is (thesis Eqs. 27-30)

    Q = H_c tau + J_tip^T F + e_tip C - K q - D v,
    tau = Kp (theta_set - theta) + Kd (theta_dot_set - theta_dot) + u + pulses(t),

with joint angles ``theta = G q`` (relative angle between the tip tangent of link i-1 and
the root tangent of link i, so ``H_c = G^T``), a held input torque ``u`` (set by a policy
between calls) and torque/force pulses on time windows.

The input data ``E`` is :class:`flex_model.inputs.InputData` (inputs.input_data), read by
name: the joint torques are clipped to ``E.torque_limit`` (actuator saturation),
``E.contact`` = (on, x, y, nx, ny, k, c) is a one-sided spring-damper surface at the tip
(flex_model.effects.contact), ``E.Ga`` maps q to the actuator coordinates (the joint
angle, or the motor angle of an elastic joint) and ``E.joint_data`` holds the joint
effects (columns inputs.JD_K ...: springs with backlash, friction, DC motor, gear ratio,
cogging, stick-slip friction).

Schemes
-------
- ``dopri5``: Dormand-Prince 5(4), error per step controlled in the weighted RMS norm
  ``|err_i| / (atol_i + rtol |x_i|)``; lands exactly on the output times.
- generalized-alpha: fixed step, implicit, second order, unconditionally stable for
  the linear part; it steps over the stiff flexible modes (damping the unresolved ones)
  at a cost of a few equation evaluations per step: the real-time mode. The loop is
  solvers.loop.fixed_step on :class:`PlanarModel` (its hooks below), called as
  ``fixed_step(PlanarModel(P, E), n, t0, x0, a0, abar0, h, n_steps, every,
  newton_settings(rho_inf, tol, limit), F0)``: F0 None for full Newton (backtracking),
  ``empty_factor()`` for simplified Newton (solvers.loop.simplified_newton).
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .effects.contact import CT_C, CT_K, CT_NX, CT_NY, CT_ON, CT_X, CT_Y
from .effects.friction import friction_law_compiled
from .effects.stick_slip import SS_D, SS_FV, SS_K, bristle_rate, bristle_step
from .iteration_matrix import structured_factor
from .solvers.galpha import finite_within, galpha_parameters, galpha_state, restart_choice
from .solvers.loop import id_residual, implements, iteration_factor, residual, tangent
from .kernels import (P_BAND, P_LAM, P_MODE, P_NF, P_OFF, P_V, band_matvec, cholesky,
                      inverse_dynamics, link_origins, mass_matrix, solve_spd, tip_jacobian)
from .inputs import (JD_B, JD_BACKLASH, JD_COG_A, JD_COG_N, JD_COG_PHASE, JD_EPS, JD_FC, JD_FS,
                     JD_FV, JD_IMAX, JD_K, JD_KE, JD_KT, JD_MOTOR, JD_R, JD_RATIO, JD_SMOOTHING,
                     JD_SS, JD_VMAX, JD_WS)

_CACHE = True


@njit(cache=_CACHE)
def joint_torques(t, q, v, E):
    """Actuator torques (nl) at time t: PD + held input (a voltage for a DC motor joint),
    through the motor model, clipped to the torque limit, plus torque pulses."""
    kp, kd, theta_set, u, pt0, pt1, ptau, lim, Ga, jd = E.kp, E.kd, E.theta_set, E.u, E.pulse_t0, \
        E.pulse_t1, E.pulse_tau, E.torque_limit, E.Ga, E.joint_data
    nl = Ga.shape[0]
    th = np.zeros(nl)
    dth = np.zeros(nl)
    for i in range(nl):     # loops, not BLAS: a call's overhead exceeds these small products
        for j in range(q.shape[0]):
            th[i] += Ga[i, j] * q[j]
            dth[i] += Ga[i, j] * v[j]
    tau = kp * (theta_set - th) - kd * dth + u
    for i in range(tau.shape[0]):
        if jd[i, JD_MOTOR] > 0.0:  # DC motor: tau is the voltage (seed 003 Eq. 48, L neglected)
            n = jd[i, JD_RATIO]
            volt = min(max(tau[i], -jd[i, JD_VMAX]), jd[i, JD_VMAX])
            cur = (volt - jd[i, JD_KE] * n * dth[i]) / jd[i, JD_R]
            cur = min(max(cur, -jd[i, JD_IMAX]), jd[i, JD_IMAX])
            tau[i] = n * jd[i, JD_KT] * cur
    tau = np.minimum(np.maximum(tau, -lim), lim)
    for p in range(pt0.shape[0]):
        if pt0[p] <= t < pt1[p]:
            tau += ptau[p]
    return tau


@njit(cache=_CACHE)
def sampled_joint_torques(t, X, U, E):
    """:func:`joint_torques` at every sample t[j] of a run (X[j] = [q, v, ...], the held
    inputs U[j] written into E's input u), in one compiled loop (a Python loop of
    single calls cost about a sixth of a fast run: unboxing E per call)."""
    n = E.K.shape[0]
    u = E.u
    out = np.empty((t.shape[0], u.shape[0]))
    for j in range(t.shape[0]):
        u[:] = U[j]
        out[j] = joint_torques(t[j], X[j, :n], X[j, n:2 * n], E)
    return out


@njit(cache=_CACHE)
def dead_zone(x, b, s):
    """C-infinity dead zone of half-width b (corners rounded over s) and its slope."""
    xp = x - b
    xm = x + b
    rp = np.sqrt(xp * xp + s * s)
    rm = np.sqrt(xm * xm + s * s)
    return 0.5 * (xp + rp) + 0.5 * (xm - rm), 0.5 * (1.0 + xp / rp) + 0.5 * (1.0 - xm / rm)


@njit(cache=_CACHE)
def dead_zone_energy(x, b, s):
    """int_0^x dead_zone(y) dy, the potential of a spring with backlash / k:
    P(x - b) - P(-b) + P2(x + b) - P2(b), P(z) = (z^2 + z r + s^2 ln(z + r)) / 4,
    P2(z) = (z^2 - z r + s^2 ln(r - z)) / 4, r = sqrt(z^2 + s^2), the logarithms in the
    form without cancellation (ln(z + r) = ln(s^2 / (r - z)) for z < 0)."""
    return (_dead_zone_prim(x - b, s, 1.0) - _dead_zone_prim(-b, s, 1.0)
            + _dead_zone_prim(x + b, s, -1.0) - _dead_zone_prim(b, s, -1.0))


@njit(cache=_CACHE)
def _dead_zone_prim(z, s, sign):
    """(z^2 + sign z r + s^2 ln(sign z + r)) / 4: P (sign 1) and P2 (sign -1) above."""
    r = np.sqrt(z * z + s * s)
    w = sign * z
    if s == 0.0:
        lg = 0.0
    elif w >= 0.0:
        lg = np.log(w + r)
    else:
        lg = np.log(s * s / (r - w))
    return 0.25 * (z * z + w * r + s * s * lg)


@njit(cache=_CACHE)
def joint_passive_forces(q, v, E):
    """Generalized forces of the joint springs (with backlash), friction and cogging."""
    G, Ga, jd = E.G, E.Ga, E.joint_data
    Q = np.zeros(q.shape[0])
    for i in range(jd.shape[0]):
        if np.isfinite(jd[i, JD_K]):  # elastic joint: spring between motor and link side
            x = 0.0
            xd = 0.0
            for j in range(q.shape[0]):
                d = Ga[i, j] - G[i, j]
                x += d * q[j]
                xd += d * v[j]
            if jd[i, JD_BACKLASH] > 0.0:
                dz, slope = dead_zone(x, jd[i, JD_BACKLASH], jd[i, JD_SMOOTHING])
                ts = jd[i, JD_K] * dz + jd[i, JD_B] * slope * xd
            else:
                ts = jd[i, JD_K] * x + jd[i, JD_B] * xd
            for j in range(q.shape[0]):
                Q[j] -= (Ga[i, j] - G[i, j]) * ts
        tf = 0.0
        if jd[i, JD_FV] > 0.0 or jd[i, JD_FC] > 0.0 or jd[i, JD_FS] > 0.0:
            w = Ga[i] @ v
            tf += friction_law_compiled(w, jd[i, JD_FV], jd[i, JD_FC], jd[i, JD_FS],
                                        jd[i, JD_WS], jd[i, JD_EPS])[0]
        if jd[i, JD_COG_A] != 0.0:
            wn = jd[i, JD_COG_N] * jd[i, JD_RATIO]
            tf += jd[i, JD_COG_A] * np.sin(wn * (Ga[i] @ q) + jd[i, JD_COG_PHASE])
        if tf != 0.0:
            for j in range(q.shape[0]):
                Q[j] += Ga[i, j] * tf
    return Q


@njit(cache=_CACHE)
def bristle_count(E):
    """Number of bristle states z: one per joint with a stick_slip_friction effect."""
    jd = E.joint_data
    n = 0
    for i in range(jd.shape[0]):
        if jd[i, JD_SS] > 0.0:
            n += 1
    return n


@njit(cache=_CACHE)
def _check_state(x, E):
    if x.shape[0] != 2 * E.K.shape[0] + bristle_count(E):
        raise ValueError("state: expected [q, v, z], z one bristle deflection per joint "
                         "with a stick_slip_friction effect (flex_model.effects.stick_slip)")


@njit(cache=_CACHE)
def stick_slip_forces(q, v, z, zd, E):
    """Generalized forces of the stick_slip_friction joints at bristle deflections z and
    rates zd: F = sigma_0 z + sigma_1 zd + sigma_2 w, the damping only while zd w > 0
    (flex_model.effects.stick_slip.friction_magnitude for zd = z'(z, w))."""
    Ga, jd = E.Ga, E.joint_data
    Q = np.zeros(q.shape[0])
    k = 0
    for i in range(jd.shape[0]):
        if jd[i, JD_SS] > 0.0:
            p = jd[i, JD_SS:]
            w = Ga[i] @ v
            f = p[SS_K] * z[k] + p[SS_FV] * w
            if zd[k] * w > 0.0:
                f += p[SS_D] * zd[k]
            for j in range(q.shape[0]):
                Q[j] -= Ga[i, j] * f
            k += 1
    return Q


@njit(cache=_CACHE)
def bristle_rates(v, z, E):
    """z' of the stick_slip_friction joints (Dupont et al. 2002)."""
    Ga, jd = E.Ga, E.joint_data
    out = np.zeros(z.shape[0])
    k = 0
    for i in range(jd.shape[0]):
        if jd[i, JD_SS] > 0.0:
            out[k] = bristle_rate(z[k], Ga[i] @ v, jd[i, JD_SS:])[0]
            k += 1
    return out


@njit(cache=_CACHE)
def bristle_update(h, v0, v1, z0, E):
    """Bristle deflections after a fixed step h from speed v0 to v1, by backward Euler
    (z1 = z0 + h z'(z1, w1)) with the Stribeck level z_m of the step's start speed (a
    steep Stribeck drop, -dF_ss/dw > J / h, would make the step's equations
    non-monotone), and their slopes dz1/d(h w1)."""
    Ga, jd = E.Ga, E.joint_data
    z1 = np.empty(z0.shape[0])
    g = np.empty(z0.shape[0])
    k = 0
    for i in range(jd.shape[0]):
        if jd[i, JD_SS] > 0.0:
            z1[k], g[k] = bristle_step(z0[k], h * (Ga[i] @ v1), Ga[i] @ v0, jd[i, JD_SS:])
            k += 1
    return z1, g


@njit(cache=_CACHE)
def applied_force(t, q, v, z, zd, P, E):
    """Generalized applied force Q (joint torques, joint effects, tip loads, contact,
    elastic and damping forces); z, zd: bristle deflections of stick-slip joints and their
    rates."""
    K, D, pt0, pt1, pF, pC = E.K, E.D, E.pulse_t0, E.pulse_t1, E.pulse_force, E.pulse_torque
    ct, Ga = E.contact, E.Ga
    tau = joint_torques(t, q, v, E)
    if P[P_MODE] == 1 and P[P_BAND][1] == 1:  # banded K, D (dynamics._band_structure): linear
        Q = (Ga.T @ tau - band_matvec(K, q, P[P_BAND][0], P[P_V], P[P_LAM][2])
             - band_matvec(D, v, P[P_BAND][0], P[P_V], P[P_LAM][1])
             + joint_passive_forces(q, v, E))
    else:   # Ga^T tau - K q - D v by loops (BLAS calls cost more at these sizes)
        Q = joint_passive_forces(q, v, E)
        for a in range(q.shape[0]):
            f = 0.0
            for i in range(tau.shape[0]):
                f += Ga[i, a] * tau[i]
            for b in range(q.shape[0]):
                f -= K[a, b] * q[b] + D[a, b] * v[b]
            Q[a] += f
    if z.shape[0] > 0:
        Q += stick_slip_forces(q, v, z, zd, E)
    fx = 0.0
    fy = 0.0
    c = 0.0
    for p in range(pt0.shape[0]):
        if pt0[p] <= t < pt1[p]:
            fx += pF[p, 0]
            fy += pF[p, 1]
            c += pC[p]
    if ct[CT_ON] > 0.0:
        org = link_origins(q, P)
        Jt = tip_jacobian(q, P)
        nx, ny = ct[CT_NX], ct[CT_NY]
        pen = -(nx * (org[-1, 0] - ct[CT_X]) + ny * (org[-1, 1] - ct[CT_Y]))
        if pen > 0.0:
            vn = 0.0
            for j in range(q.shape[0]):
                vn += (nx * Jt[0, j] + ny * Jt[1, j]) * v[j]
            fn = ct[CT_K] * pen - ct[CT_C] * vn
            if fn > 0.0:
                fx += fn * nx
                fy += fn * ny
    if fx != 0.0 or fy != 0.0:
        Jt = tip_jacobian(q, P)
        Q += Jt[0] * fx + Jt[1] * fy
    if c != 0.0:
        off, nf = P[P_OFF], P[P_NF]
        last = off.shape[0] - 1
        Q[off[last]] += c
        Q[off[last] + nf[last]] += c
    return Q


@njit(cache=_CACHE)
def joint_tangent(v, E):
    """Stiffness and damping of the joint laws and effects for the Newton matrix."""
    G, kp, kd, Ga, jd = E.G, E.kp, E.kd, E.Ga, E.joint_data
    n = G.shape[1]
    Kj = np.zeros((n, n))
    Cj = np.zeros((n, n))
    for i in range(jd.shape[0]):
        gain = 1.0
        cd = 0.0
        if jd[i, JD_MOTOR] > 0.0:
            gain = jd[i, JD_RATIO] * jd[i, JD_KT] / jd[i, JD_R]
            cd = gain * jd[i, JD_KE] * jd[i, JD_RATIO]
        w = Ga[i] @ v
        if jd[i, JD_FC] > 0.0 or jd[i, JD_FS] > 0.0:
            cd += jd[i, JD_FS] / jd[i, JD_EPS] / np.cosh(min(abs(w / jd[i, JD_EPS]), 300.0)) ** 2
        cd += jd[i, JD_FV] + gain * kd[i]
        kk = gain * kp[i]
        for a in range(n):
            for b in range(n):
                Kj[a, b] += kk * Ga[i, a] * Ga[i, b]
                Cj[a, b] += cd * Ga[i, a] * Ga[i, b]
        if np.isfinite(jd[i, JD_K]):
            for a in range(n):
                for b in range(n):
                    dd = (Ga[i, a] - G[i, a]) * (Ga[i, b] - G[i, b])
                    Kj[a, b] += jd[i, JD_K] * dd
                    Cj[a, b] += jd[i, JD_B] * dd
    return Kj, Cj


@njit(cache=_CACHE)
def _stick_slip_tangent(Kj, Cj, v1, z0, z1, g, h, E):
    """Adds the bristle force's slope to the iteration matrix, on the velocity
    (z1 = z0 + h z'(z1, w1)): sigma_0 dz1/dw1 = sigma_0 h g, sigma_1 g, sigma_2."""
    Ga, jd = E.Ga, E.joint_data
    n = Kj.shape[0]
    k = 0
    for i in range(jd.shape[0]):
        if jd[i, JD_SS] > 0.0:
            p = jd[i, JD_SS:]
            kk = 0.0
            cd = p[SS_K] * h * g[k] + p[SS_FV]
            if (z1[k] - z0[k]) * (Ga[i] @ v1) > 0.0:
                cd += p[SS_D] * g[k]
            for a in range(n):
                for b in range(n):
                    Kj[a, b] += kk * Ga[i, a] * Ga[i, b]
                    Cj[a, b] += cd * Ga[i, a] * Ga[i, b]
            k += 1


@njit(cache=_CACHE)
def _balance(t, q, v, z, zd, P, E):
    """Mass matrix and right-hand side of B(q) a = Q - c(q, v)."""
    n = q.shape[0]
    rhs = applied_force(t, q, v, z, zd, P, E) - \
        inverse_dynamics(q, v, np.zeros(n), E.gx, E.gy, P)
    return mass_matrix(q, P), rhs


@njit(cache=_CACHE)
def _derivative(t, x, P, E):
    n = E.K.shape[0]
    z = x[2 * n:]
    zd = z
    if z.shape[0] > 0:
        zd = bristle_rates(x[n:2 * n], z, E)
    B, rhs = _balance(t, x[:n], x[n:2 * n], z, zd, P, E)
    out = np.empty(x.shape[0])
    out[:n] = x[n:2 * n]
    out[n:2 * n] = solve_spd(B, rhs)
    if z.shape[0] > 0:
        out[2 * n:] = zd
    return out


@njit(cache=_CACHE)
def derivative(t, x, P, E):
    """dx/dt = [v; B(q)^-1 (Q - c(q, v) - dU_g/dq); z'] for x = [q; v; z] (z: the bristle
    deflections of stick_slip_friction joints, none without them)."""
    _check_state(x, E)
    return _derivative(t, x, P, E)


@njit(cache=_CACHE)
def dopri5(t0, x0, t_out, rtol, atol, h0, hmax, max_steps, limit, P, E):
    """Integrate from t0 through the increasing output times ``t_out``.

    Returns ``(X, status, t_end, x_end, h, n_steps, n_rejected)``; status 0 = done,
    1 = non-finite or diverging state (beyond ``limit``; X rows after it are NaN),
    2 = step size underflow, 3 = too many steps. ``h`` is the next step size.
    """
    a21 = 1 / 5
    a31, a32 = 3 / 40, 9 / 40
    a41, a42, a43 = 44 / 45, -56 / 15, 32 / 9
    a51, a52, a53, a54 = 19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729
    a61, a62, a63, a64, a65 = 9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656
    b1, b3, b4, b5, b6 = 35 / 384, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84
    e1, e3, e4, e5, e6, e7 = (71 / 57600, -71 / 16695, 71 / 1920, -17253 / 339200,
                              22 / 525, -1 / 40)
    c2, c3, c4, c5 = 1 / 5, 3 / 10, 4 / 5, 8 / 9
    _check_state(x0, E)
    nx = x0.shape[0]
    nout = t_out.shape[0]
    X = np.full((nout, nx), np.nan)
    t = t0
    x = x0.copy()
    k1 = _derivative(t, x, P, E)
    h = h0
    steps = 0
    rejected = 0
    j = 0
    while j < nout and t_out[j] <= t:
        X[j] = x
        j += 1
    while j < nout:
        if steps >= max_steps:
            return X, 3, t, x, h, steps, rejected
        hh = min(h, hmax, t_out[j] - t)
        land = hh == t_out[j] - t
        k2 = _derivative(t + c2 * hh, x + hh * a21 * k1, P, E)
        k3 = _derivative(t + c3 * hh, x + hh * (a31 * k1 + a32 * k2), P, E)
        k4 = _derivative(t + c4 * hh, x + hh * (a41 * k1 + a42 * k2 + a43 * k3), P, E)
        k5 = _derivative(t + c5 * hh,
                         x + hh * (a51 * k1 + a52 * k2 + a53 * k3 + a54 * k4), P, E)
        k6 = _derivative(t + hh,
                         x + hh * (a61 * k1 + a62 * k2 + a63 * k3 + a64 * k4 + a65 * k5),
                         P, E)
        xn = x + hh * (b1 * k1 + b3 * k3 + b4 * k4 + b5 * k5 + b6 * k6)
        k7 = _derivative(t + hh, xn, P, E)
        err = hh * (e1 * k1 + e3 * k3 + e4 * k4 + e5 * k5 + e6 * k6 + e7 * k7)
        s = 0.0
        for i in range(nx):
            sc = atol[i] + rtol * max(abs(x[i]), abs(xn[i]))
            s += (err[i] / sc) ** 2
        en = np.sqrt(s / nx)
        steps += 1
        if not np.isfinite(en):
            if hh < 1e-14 * max(1.0, abs(t)):
                return X, 1, t, xn, h, steps, rejected
            h = 0.25 * hh
            rejected += 1
            continue
        if en <= 1.0:
            t = t_out[j] if land else t + hh
            x = xn
            k1 = k7
            if not finite_within(x, limit):
                return X, 1, t, x, h, steps, rejected
            while j < nout and t_out[j] <= t:
                X[j] = x
                j += 1
            fac = 5.0 if en == 0.0 else min(5.0, max(0.2, 0.9 * en ** -0.2))
            if not land or fac < 1.0:
                h = hh * fac
        else:
            rejected += 1
            h = hh * max(0.2, 0.9 * en ** -0.2)
            if h < 1e-14 * max(1.0, abs(t)):
                return X, 2, t, x, h, steps, rejected
    return X, 0, t, x, h, steps, rejected


@njit(cache=_CACHE)
def consistent_acceleration(t, x, P, E):
    _check_state(x, E)
    n = E.K.shape[0]
    return _derivative(t, x, P, E)[n:2 * n]


@njit(cache=_CACHE)
def restart_acceleration(t, x, a, abar, h, rho_inf, P, E):
    """Start values (a, abar, share, overshoot) of the fixed step after a jump of the
    applied forces at state x (a pulse edge, a new held command), a and abar the step's
    values before it.

    The consistent restart a = abar = B^-1 (Q - c) (thesis Eq. 27) puts the whole jump
    dA of the acceleration into the first step's position update, h^2 (1/2 - beta) abar.
    On a beam root without hub inertia a joint torque jump accelerates modes the step does
    not resolve (h omega >> 1), and that term moves them by about (h omega)^2 / 4 times
    their static deflection: issue 24's hub-less arm, 16 variables per link at 0.125 ms,
    tip deflections 685 % off. The step itself follows a force jump B dA with
    da = S^-1 B dA, S = B + gamma' (D + C_j) + beta' (K + K_j) its iteration matrix
    (Arnold-Bruls form of generalized-alpha): all of dA in the modes with
    gamma' omega, beta' omega^2 << 1, next to nothing in the unresolved ones.
    ``share`` = |dA - da|_B / |dA|_B, the part of the jump the step does not follow (kinetic
    norm); ``overshoot`` = k h^2 max|dA - da|, the position (m or rad) the consistent
    restart would add to it, k = :func:`restart_kick` (1/2 - beta from rho_inf = 0.721 up;
    issue 47: 1/2 - beta everywhere was <= 0 below rho_inf = sqrt(2) - 1, which never
    filtered: tip deflections 1588 % off at 0.5 ms, rho_inf 0). When both exceed
    solvers.galpha.RESTART_SHARE and RESTART_OVERSHOOT the restart filters the jump,
    a = abar = a + da; otherwise it is the consistent one (results as before: smooth
    commands, arms with hub or rotor inertia, bristle states).
    """
    ac = consistent_acceleration(t, x, P, E)
    n = E.K.shape[0]
    if x.shape[0] > 2 * n:
        return ac, ac.copy(), 0.0, 0.0
    B = mass_matrix(x[:n], P)
    am, af, gam, beta = galpha_parameters(rho_inf)
    ratio = (1.0 - af) / (1.0 - am)
    Kj, Cj = joint_tangent(x[n:2 * n], E)
    S = B + h * gam * ratio * (E.D + Cj) + h * h * beta * ratio * (E.K + Kj)
    a1, share, overshoot = restart_choice(a, ac, B, S, h, rho_inf)
    return a1, a1.copy(), share, overshoot


class PlanarModel(NamedTuple):
    """The planar arm's compiled data for solvers.loop: P (kernels) and E (module
    docstring)."""
    P: tuple
    E: tuple


@njit(cache=_CACHE)
def _residual(md, a1, st, c, first):
    """Residual B(q1) a1 - (Q - c) of a generalized-alpha step (solvers.galpha.Step st,
    coefficients c) for the guess a1 (``first`` unused), with (B, v1, the bristle
    deflections z1 at the step's end, their slopes g) (stick-slip joints)."""
    P, E = md
    q1, v1, _ = galpha_state(st.q, st.v, st.a, st.abar, a1, c)
    z1 = st.z
    g = st.z
    zd = st.z
    if st.z.shape[0] > 0:
        z1, g = bristle_update(c.h, st.v, v1, st.z, E)
        zd = (z1 - st.z) / c.h
    B, rhs = _balance(st.t, q1, v1, z1, zd, P, E)
    return B @ a1 - rhs, (B, v1, z1, g)


@njit(cache=_CACHE)
def _tangent(md, ctx, st, c):
    """Cholesky factor of the Newton iteration matrix B + gamma' (D + C_j) + beta' (K +
    K_j) of :func:`_residual` (PD gains, joint springs, friction slope and back-EMF at v1;
    the bristles' slope and damping)."""
    E = md.E
    B, v1, z1, g = ctx
    Kj, Cj = joint_tangent(v1, E)
    if st.z.shape[0] > 0:
        _stick_slip_tangent(Kj, Cj, v1, st.z, z1, g, c.h, E)
    return cholesky(B + c.gp * (E.D + Cj) + c.bp * (E.K + Kj))


@njit(cache=_CACHE)
def _id_residual(md, a1, st, c):
    """Residual of :func:`_residual` without the mass matrix (no bristles): one
    inverse-dynamics pass gives B(q1) a1 + c(q1, v1) (thesis Eq. 27) directly."""
    P, E = md
    q1, v1, _ = galpha_state(st.q, st.v, st.a, st.abar, a1, c)
    z = np.zeros(0)
    return (inverse_dynamics(q1, v1, a1, E.gx, E.gy, P)
            - applied_force(st.t, q1, v1, z, z, P, E)), q1, v1


@njit(cache=_CACHE)
def _iteration_factor(md, q1, v1, c):
    """Factor of the Newton iteration matrix B + gamma' (D + C_j) + beta' (K + K_j) at
    (q1, v1): banded plus low rank, linear in the variables, for second-order kinematics
    from dynamics.STRUCTURED_MIN_VARS variables per link (flex_model.iteration_matrix),
    else dense Cholesky (an empty factor when it is not positive definite)."""
    P, E = md
    if P[P_MODE] == 1 and P[P_BAND][1] == 1:
        F = structured_factor(q1, v1, c.gp, c.bp, P, E)
        if F[0].shape[0] > 0:
            return F
    Kj, Cj = joint_tangent(v1, E)
    Lc = cholesky(mass_matrix(q1, P) + c.gp * (E.D + Cj) + c.bp * (E.K + Kj))
    z2 = np.zeros((0, 0))
    return Lc, z2, z2, z2, np.zeros(0, dtype=np.int64), z2, 0


for _hook, _fn in ((residual, _residual), (tangent, _tangent), (id_residual, _id_residual),
                   (iteration_factor, _iteration_factor)):
    implements(_hook, PlanarModel, _fn)


# numba re-compiles a cached function when its own file changes, not when a compiled
# function it calls from kernels.py (or effects/stick_slip.py, effects/friction.py) does:
# flush these caches when they change.
def _guard_caches():
    from . import iteration_matrix, kernels
    from .numba_cache import guard
    from .effects import friction, stick_slip
    from .solvers import galpha, loop, newton
    guard([obj for obj in globals().values() if hasattr(obj, "py_func")
           and obj.py_func.__module__ == __name__],
          [kernels.__file__, stick_slip.__file__, friction.__file__, iteration_matrix.__file__,
           galpha.__file__, newton.__file__, loop.__file__])


_guard_caches()
