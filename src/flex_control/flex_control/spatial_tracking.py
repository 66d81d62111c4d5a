"""Eq. (95) tracking on spatial arms (thesis V.3 in 3D; issue 25).

The run of :func:`flex_control.tracking.simulate_tracking` with constant gains on a
:class:`flex_model.spatial.SpatialArmModel`: the PD's feedback ``-Kp theta_a - Kd
theta_a'`` is stiffness and damping inside the compiled generalized-alpha loop (continuous,
implicit: the joint loop of a flexible arm is stiff), and the reference part
``tau_nom(t) + Kp theta_hat(t) + Kd theta_hat_dot(t)`` is sampled every ``control_period``
and held, the method restarting (consistent acceleration) at each instant, as the planar
run's policy is. The start is the static equilibrium under gravity at the reference's
first joint values (joints held), at rest, unless ``q0``/``v0`` are given. Gains per joint
from ``h``, ``a`` (``Kp = h a^2``, ``Kd = sqrt(2) h a``, :func:`.closed_loop.pd_gains``);
effort limits clip the whole PD torque (spatial ``pd_clip``).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.trajectory import JointTrajectoryData

from .closed_loop import pd_gains


@dataclass
class SpatialTrackingRun:
    """Samples of a spatial tracking run: t (n,), q, v (n, nq), the joint torques tau
    (n, n_joints: the reference part held over the period minus the PD feedback)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    newton_iterations: int


def simulate_tracking_spatial(model, trajectory: JointTrajectoryData, *, h, a, q0=None,
                              v0=None, t_final: float | None = None,
                              control_period: float = 5e-3, dt: float = 1e-3,
                              sample_period: float = 0.01) -> SpatialTrackingRun:
    """The spatial arm under Eq. (95) + feed-forward along ``trajectory`` (module doc)."""
    from flex_model.spatial.analysis import static_equilibrium
    from flex_model.spatial.integrate import simulate_fixed_compiled
    nj = model.n_links
    if len(trajectory.joint_names) != nj:
        raise ValueError(f"trajectory: got {len(trajectory.joint_names)} joints; expected "
                         f"{nj} (the arm's)")
    kp, kd = pd_gains(np.broadcast_to(np.asarray(h, float), (nj,)),
                      np.broadcast_to(np.asarray(a, float), (nj,)))
    t0 = float(trajectory.t[0])
    t_final = trajectory.duration if t_final is None else float(t_final)
    per_ctl = int(round(control_period / dt))
    per_out = int(round(sample_period / dt))
    if per_ctl < 1 or abs(per_ctl * dt - control_period) > 1e-9 * control_period or \
            per_out < 1 or abs(per_out * dt - sample_period) > 1e-9 * sample_period:
        raise ValueError(f"dt: got {dt!r}; expected a step dividing control_period "
                         f"({control_period!r}) and sample_period ({sample_period!r})")
    n_ctl = int(np.ceil(t_final / control_period - 1e-9))
    if q0 is None:
        q0 = static_equilibrium(model, trajectory.sample(t0)[0]).q
    q = np.asarray(q0, float).copy()
    v = np.zeros(model.nq) if v0 is None else np.asarray(v0, float).copy()
    Kp, Dp = np.zeros((2, model.nq, model.nq))
    act = model.actuator_index
    for i, k in enumerate(act):
        if k >= 0:
            Kp[k, k], Dp[k, k] = kp[i], kd[i]
    Q, V, U, iters = [q[None]], [v[None]], [], 0
    K0 = model.K
    try:
        model.K = K0 + Kp
        for c in range(n_ctl):
            p, dp, _, tau_nom = trajectory.sample(t0 + c * control_period)
            u = tau_nom + kp * p + kd * dp
            run = simulate_fixed_compiled(model, q, v, dt, per_ctl, joint_torques=u,
                                          damping=Dp, pd_clip=(kp, kd))
            Q.append(run.q[1:])
            V.append(run.v[1:])
            U.append(np.broadcast_to(u, (per_ctl, nj)))
            iters += run.newton_iterations
            q, v = run.q[-1].copy(), run.v[-1].copy()
    finally:
        model.K = K0
    Q, V = np.concatenate(Q)[::per_out], np.concatenate(V)[::per_out]
    U = np.concatenate([U[0][:1]] + U)[::per_out]
    from flex_model.spatial.limits import joint_limits
    a_idx = np.maximum(act, 0)
    effort = joint_limits(model.arm)["effort"]          # the loop clips the PD torque
    tau = np.where(act >= 0, np.clip(U - kp * Q[:, a_idx] - kd * V[:, a_idx], -effort,
                                     effort), 0.0)
    return SpatialTrackingRun(t=t0 + dt * per_out * np.arange(len(Q)), q=Q, v=V, tau=tau,
                              newton_iterations=iters)
