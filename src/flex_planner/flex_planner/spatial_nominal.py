"""Nominal input of a spatial arm along a prescribed joint motion (thesis Ch. V.1 in 3D;
issue 25): the scheme of :mod:`flex_planner.nominal_input` on a
:class:`flex_model.spatial.SpatialArmModel`.

With the joint values theta(t), rates and accelerations prescribed, the deformation
variables q_f obey the rows of the equations of motion that carry no joint torque,

    [M a + c + K q + D v - Q_e]_f = 0                                      (1)

(seed 002's Eq. 16 in 3D: flexible links, rigid joints under a prescribed motion), which
are integrated by the generalized-alpha method with theta exact at every sample; the joint
rows then give the torques

    tau = [M a + c + K q + D v - Q_e]_j                                      (2)

M a + c comes from the compiled inverse dynamics (compiled.spatial_eval), Q_e is the
model's effect force (friction, contact, stops, ...). Same parameters as the planar solver
(rho_inf 1 by default, Newton on the accelerations to a position tolerance of 1e-13, the
iteration matrix M_ff + gamma' h D_ff + beta' h^2 K_ff refreshed every 25 steps or after a
slow step), so a planar arm embedded by ``from_planar`` gives the planar solver's result.
Joints with an elastic gear (a motor coordinate) or a locked motor are refused: the
prescribed joint is the link side of a rigid joint.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.solvers.galpha import galpha_abar, galpha_coefficients

from .nominal_input import REFRESH_EVERY, STEP_TOLERANCE
from .trajectories import SampledTrajectory


class NotDrivenError(ValueError):
    """An arm whose joints the nominal input cannot prescribe (elastic gear, locked)."""


@dataclass
class SpatialNominalInput:
    """Samples: t (n,), the full states q, v, a (n, nq), joint torques tau (n, n_joints),
    the tip (n, 3, base frame) and the largest residual of Eq. (1) over the samples."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    tip: np.ndarray
    balance_residual: float


def _check_rigid_joints(model) -> None:
    bad = [lk.joint.name for i, lk in enumerate(model.arm.links)
           if model.motor_index[i] >= 0 or lk.joint.motor == "locked"]
    if bad:
        raise NotDrivenError(f"{model.arm.name}: joints {', '.join(bad)} have an elastic gear "
                             "or a locked motor; the nominal input prescribes rigid, driven "
                             "joints")


def spatial_nominal_input(model, traj: SampledTrajectory, flex0=None, flex_rate0=None, *,
                          rho_inf: float = 1.0) -> SpatialNominalInput:
    """Integrate Eq. (1) along ``traj`` (joint values, rates, accelerations at its samples)
    from ``flex0`` (default: the static equilibrium at theta(0), joints held) and
    ``flex_rate0`` (default 0); Eq. (2) at every sample (module docstring)."""
    from flex_model.spatial.analysis import static_equilibrium
    from flex_model.spatial.compiled import pack, spatial_eval
    _check_rigid_joints(model)
    if not 0.0 <= rho_inf <= 1.0:
        raise ValueError(f"rho_inf: got {rho_inf!r}; expected 0 <= rho_inf <= 1")
    data = getattr(model, "_compiled_data", None)
    if data is None:
        data = model._compiled_data = pack(model)
    off = np.asarray(model.off)
    free = np.setdiff1d(np.arange(model.nq), off)
    K, D = model.K, model.D
    Kff, Dff = K[np.ix_(free, free)], D[np.ix_(free, free)]
    t = np.asarray(traj.t, float)
    th, thd, thdd = (np.asarray(x, float) for x in (traj.p, traj.v, traj.a))
    zf = static_equilibrium(model, th[0]).q[free] if flex0 is None else \
        np.asarray(flex0, float).copy()
    vf = np.zeros(len(free)) if flex_rate0 is None else np.asarray(flex_rate0, float).copy()
    n_s, nq = len(t), model.nq
    Q, V, A = np.zeros((n_s, nq)), np.zeros((n_s, nq)), np.zeros((n_s, nq))

    def state(k, zf_, vf_, af_):
        q, v, a = np.zeros(nq), np.zeros(nq), np.zeros(nq)
        q[off], v[off], a[off] = th[k], thd[k], thdd[k]
        q[free], v[free], a[free] = zf_, vf_, af_
        return q, v, a

    def force(q, v, a):
        return spatial_eval(data, q, v, a, False)[1] + K @ q + D @ v - \
            model.effect_force(v, q)

    q0, v0, a0 = state(0, zf, vf, np.zeros(len(free)))
    r0 = force(q0, v0, a0)[free]
    M0 = spatial_eval(data, q0, v0, a0, True)[0]
    acc = -np.linalg.solve(M0[np.ix_(free, free)], r0)
    Q[0], V[0], A[0] = state(0, zf, vf, acc)
    abar = acc.copy()
    inv = None
    h_used, age = -1.0, REFRESH_EVERY
    for k in range(1, n_s):
        h = t[k] - t[k - 1]
        c = galpha_coefficients(rho_inf, h)
        bp, gp, beta, gam = c.bp, c.gp, c.beta, c.gam
        if h != h_used or age >= REFRESH_EVERY:
            M = spatial_eval(data, Q[k - 1], V[k - 1], A[k - 1], True)[0]
            inv = np.linalg.inv(M[np.ix_(free, free)] + gp * Dff + bp * Kff)
            h_used, age = h, 0
        age += 1
        zf_pred = zf + h * vf + h * h * (0.5 - beta) * abar
        vf_pred = vf + h * (1.0 - gam) * abar
        a1 = acc.copy()
        for it in range(40):
            abar1 = galpha_abar(a1, acc, abar, c)
            q1, v1, a_full = state(k, zf_pred + h * h * beta * abar1,
                                   vf_pred + h * gam * abar1, a1)
            da = -(inv @ force(q1, v1, a_full)[free])
            a1 = a1 + da
            if bp * np.max(np.abs(da)) <= STEP_TOLERANCE:
                break
        else:
            raise RuntimeError(f"nominal input: Newton did not converge at t = {t[k]:.6g} s "
                               f"(step {h:.3g} s); reduce the integration step")
        if it > 2:
            age = REFRESH_EVERY
        abar1 = galpha_abar(a1, acc, abar, c)
        zf = zf_pred + h * h * beta * abar1
        vf = vf_pred + h * gam * abar1
        acc, abar = a1, abar1
        Q[k], V[k], A[k] = state(k, zf, vf, acc)
    tau = np.zeros((n_s, model.n_links))
    tip = np.zeros((n_s, 3))
    worst = 0.0
    for k in range(n_s):
        r = force(Q[k], V[k], A[k])
        tau[k] = r[off]
        worst = max(worst, float(np.max(np.abs(r[free]))))
        tip[k] = model.tip_position(Q[k])
    return SpatialNominalInput(t=t.copy(), q=Q, v=V, a=A, tau=tau, tip=tip,
                               balance_residual=worst)
