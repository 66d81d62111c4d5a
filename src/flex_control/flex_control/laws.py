"""Joint control laws: seed 000's PD-like cascade (Eq. 45) and the thesis PD (Eq. 95).

Every controller exposes ``torque(t, positions, velocities, deflections=None) -> tau``:
joint angles (rad) and rates (rad/s) in the controller's joint order, optional link tip
deflections (m), the joint torques (N m) out. The same call serves a simulation
(:func:`as_policy`) and the controller node. References are
:class:`flex_model.trajectory.JointTrajectoryData` (``sample(t)`` gives the reference
angles, rates, accelerations and the nominal torques); :func:`hold_reference` makes a
constant one.
"""
from __future__ import annotations

from bisect import bisect_right
from typing import Callable

import numpy as np

from flex_model.trajectory import JointTrajectoryData

from .closed_loop import SQRT2


def joint_vector(name: str, value, n: int) -> np.ndarray:
    """``value`` as a float array of ``n`` finite entries; ``ValueError`` names the field."""
    arr = np.asarray(value, dtype=float).reshape(-1)
    if arr.shape != (n,):
        raise ValueError(f"{name}: got {arr.shape[0]} values; expected {n} (one per joint)")
    if not np.isfinite(arr).all():
        raise ValueError(f"{name}: got {arr.tolist()}; expected finite values")
    return arr


def torque_limit_vector(limits, n: int) -> np.ndarray:
    """Per-joint torque limits (N m, > 0; ``None`` or ``inf`` = unlimited)."""
    if limits is None:
        return np.full(n, np.inf)
    arr = np.asarray(limits, float).reshape(-1)
    if arr.size not in (1, n):
        raise ValueError(f"torque_limits: got {arr.size} values; expected 1 or {n}")
    arr = np.broadcast_to(arr, (n,)).copy()
    if np.any(np.isnan(arr)) or np.any(arr <= 0):
        raise ValueError(f"torque_limits: got {arr.tolist()}; expected limits > 0 N m "
                         "(inf for none)")
    return arr


def clamp_torques(tau, limits) -> np.ndarray:
    """``tau`` clipped to ``[-limits, limits]`` per joint."""
    return np.minimum(np.maximum(tau, -limits), limits)


def hold_reference(joint_names, positions) -> JointTrajectoryData:
    """A constant reference: hold ``positions`` (rad) at rest, no feed-forward torque."""
    n = len(joint_names)
    p = joint_vector("positions", positions, n)
    return JointTrajectoryData(joint_names=list(joint_names), t=np.array([0.0]),
                               positions=p[None, :].copy(), velocities=np.zeros((1, n)),
                               accelerations=np.zeros((1, n)), efforts=np.zeros((1, n)))


class ReferenceSampler:
    """``(theta_hat, theta_hat_dot, tau_nom)`` of a reference at time t: linear
    interpolation, held outside its time span (as ``JointTrajectoryData.sample``), with the
    three arrays stacked so that a control cycle costs one bisection and one product."""

    def __init__(self, reference: JointTrajectoryData):
        self.n = len(reference.joint_names)
        self.times = [float(x) for x in reference.t]
        self.Y = np.hstack([reference.positions, reference.velocities, reference.efforts])
        self.dY = np.diff(self.Y, axis=0)
        self.dt = np.diff(reference.t)

    def __call__(self, t: float):
        times = self.times
        if t <= times[0]:
            y = self.Y[0]
        elif t >= times[-1]:
            y = self.Y[-1]
        else:
            k = bisect_right(times, t) - 1
            y = self.Y[k] + ((t - times[k]) / self.dt[k]) * self.dY[k]
        n = self.n
        return y[:n], y[n:2 * n], y[2 * n:]


class _JointController:
    """Reference handling, input checks and torque limits shared by the laws."""

    def __init__(self, reference: JointTrajectoryData, torque_limits=None):
        self.joint_names = list(reference.joint_names)
        self.n = len(self.joint_names)
        self.reference = reference
        self.sample = ReferenceSampler(reference)
        self.torque_limits = torque_limit_vector(torque_limits, self.n)

    def set_reference(self, reference: JointTrajectoryData) -> None:
        """Swap the reference; its joint names must be the controller's, in order."""
        if list(reference.joint_names) != self.joint_names:
            raise ValueError(f"joint_names: got {list(reference.joint_names)}; expected "
                             f"{self.joint_names}")
        self.sample = ReferenceSampler(reference)
        self.reference = reference

    def _inputs(self, positions, velocities):
        return (joint_vector("positions", positions, self.n),
                joint_vector("velocities", velocities, self.n))


class PDLikeCascade(_JointController):
    """The PD-like cascade of seed 000, Eq. (45), on the motor side of each joint::

        tau_cmd = K_pv (K_pp (p_cmd - p) - p_dot),   p = n theta,   tau = n tau_cmd

    ``p`` is the motor angle (rad) read by the drive's encoder, ``n`` the gear ratio, so
    that ``p_cmd = n theta_ref``; ``tau_cmd`` is the motor torque (N m) and the joint gets
    ``n tau_cmd`` (the gear's rotor-side kinetic energy ``1/2 I_r n^2 theta_dot^2``,
    seed 000 Eq. 35, is the matching inertia). At the joint this is a PD with
    ``kp = n^2 K_pv K_pp`` and ``kd = n^2 K_pv`` (:attr:`joint_gains`); with the rotor
    dominating the joint inertia ``J = n^2 I_r`` the position loop is first order with time
    constant ``1/K_pp`` (rise time 10-90 % = ln 9 / K_pp) and the velocity loop has the
    bandwidth ``K_pv / I_r``. Defaults: ``K_pp = 70`` 1/s, ``K_pv = 50`` N m s/rad,
    ``n = 50`` (seed 000 Section 5).
    """

    def __init__(self, reference: JointTrajectoryData, kpp=70.0, kpv=50.0, gear_ratio=50.0,
                 torque_limits=None):
        super().__init__(reference, torque_limits)
        self.kpp = self._positive("kpp", kpp)
        self.kpv = self._positive("kpv", kpv)
        self.gear_ratio = self._positive("gear_ratio", gear_ratio)

    def _positive(self, name, value):
        arr = np.broadcast_to(np.asarray(value, float), (self.n,)).copy()
        if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
            raise ValueError(f"{name}: got {arr.tolist()}; expected finite values > 0")
        return arr

    @property
    def joint_gains(self) -> tuple[np.ndarray, np.ndarray]:
        """Equivalent joint-side PD: ``(n^2 K_pv K_pp, n^2 K_pv)`` (N m/rad, N m s/rad)."""
        n2 = self.gear_ratio ** 2
        return n2 * self.kpv * self.kpp, n2 * self.kpv

    def motor_torque(self, t: float, positions, velocities) -> np.ndarray:
        """``tau_cmd`` of Eq. (45) (N m at the motor, before the torque limits)."""
        theta, dtheta = self._inputs(positions, velocities)
        ref = self.sample(t)[0]
        n = self.gear_ratio
        return self.kpv * (self.kpp * (n * ref - n * theta) - n * dtheta)

    def torque(self, t: float, positions, velocities, deflections=None) -> np.ndarray:
        """Joint torques ``n tau_cmd`` (N m), clamped to the limits."""
        return clamp_torques(self.gear_ratio * self.motor_torque(t, positions, velocities),
                             self.torque_limits)


class DecentralizedPD(_JointController):
    """The decentralized PD of thesis Eq. (95) with the nominal torque as feed-forward::

        tau = tau_nom(t) + h (a^2 (theta_hat - theta) + sqrt(2) a (theta_hat_dot - theta_dot))

    per joint, ``theta_hat``, ``theta_hat_dot`` and ``tau_nom`` from the reference (the
    planner's admissible nominal input, thesis V.1). ``h`` (kg m^2) and ``a`` (rad/s) are
    constants or come from a :class:`~flex_control.gain_schedule.GainSchedule` evaluated at
    the measured joint angles (and tip deflections, if the schedule uses them).
    """

    def __init__(self, reference: JointTrajectoryData, h=None, a=None, schedule=None,
                 feedforward: bool = True, torque_limits=None):
        super().__init__(reference, torque_limits)
        if schedule is None:
            if h is None or a is None:
                raise ValueError("gains: got neither (h, a) nor a schedule; expected one")
            self.h = np.broadcast_to(np.asarray(h, float), (self.n,)).copy()
            self.a = np.broadcast_to(np.asarray(a, float), (self.n,)).copy()
            for name, v in (("h", self.h), ("a", self.a)):
                if not np.all(np.isfinite(v)) or np.any(v <= 0):
                    raise ValueError(f"{name}: got {v.tolist()}; expected finite gains > 0")
        elif list(schedule.joint_names) != self.joint_names:
            raise ValueError(f"schedule.joint_names: got {list(schedule.joint_names)}; "
                             f"expected {self.joint_names}")
        self.schedule = schedule
        self.feedforward = bool(feedforward)

    def gains(self, positions, deflections=None) -> tuple[np.ndarray, np.ndarray]:
        """``(h, a)`` per joint at the measured state."""
        if self.schedule is None:
            return self.h, self.a
        return self.schedule.gains(positions, deflections)

    def torque(self, t: float, positions, velocities, deflections=None) -> np.ndarray:
        """Joint torques of Eq. (95) plus feed-forward (N m), clamped to the limits."""
        theta, dtheta = self._inputs(positions, velocities)
        ref, dref, tau_nom = self.sample(t)
        h, a = self.gains(theta, deflections)
        tau = h * (a * a * (ref - theta) + SQRT2 * a * (dref - dtheta))
        if self.feedforward:
            tau = tau + tau_nom
        return clamp_torques(tau, self.torque_limits)


def as_policy(controller, model) -> Callable:
    """``policy(t, x) -> tau`` for :func:`flex_model.simulate.simulate`: the controller fed
    with the model's joint angles ``G q``, rates ``G v`` and link tip deflections."""
    nq = model.nq
    G = model.G
    idx = [model.tip_deflection_index(i) for i in range(model.n_links)]

    def policy(t, x):
        q, v = x[:nq], x[nq:]
        return controller.torque(t, G @ q, G @ v, q[idx])

    return policy
