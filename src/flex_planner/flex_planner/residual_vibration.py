"""Path deviation and residual vibration at the end of a given path (seed 002).

The joint motion is prescribed over [0, t_f] and held at its final value afterwards. The
tip of the flexible arm is compared with the rigid tip of the planned joint motion
(seed 002 Eqs. 20-22):

    e = r_f - r_r(theta(t))     t <= t_f   (path deviation)
    e = r_f - (x_f, y_f)        t >  t_f   (residual vibration about the goal point)
    P_e = |e|

with r_f the tip of the flexible arm (Eq. 19) and (x_f, y_f) = r_r(theta(t_f)) the goal
point. The radius of the residual vibration (seed 002 Fig. 5) is max P_e over t > t_f.

Two joint models:

- rigid joints (flexible links, seed 002 Eqs. 9-10, 16): the joint angles follow the
  plan exactly; the deformation variables obey Eq. (10), which is Eq. (1) of
  :mod:`.nominal_input`, integrated by the same solver (thesis V.1); the joint torques
  are Eq. (9).
- flexible joints (seed 002 Eqs. 11-13): a torsional spring k_t between motor and link,
  the motor angle q_ac(t) being the planned motion (the input, as in the paper). With
  q_ac prescribed, Eqs. (11)-(12) are the arm with joint torque k_t (q_ac - theta),
  simulated by flex_model (``JointPD`` with kp = k_t, zero set-point, plus the held input
  k_t q_ac(t)); the motor inertia I_r enters only the motor torque of Eq. (13),
  tau = I_r q_ac'' + k_t (q_ac - theta).

The arm of VALIDATION.md section H is flex_model's preset ``seed002_two_link`` (joint
springs and motor inertias given here). Units: s, m, rad, N m.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.simulate import JointPD, simulate
from flex_model.statics import static_equilibrium

from .nominal_input import NominalInputSolver
from .rigid_kinematics import elbow_bend, forward_kinematics, rigid_path_inverse
from .trajectories import (SampledTrajectory, polynomial_fourier, trapezoidal_duration,
                           trapezoidal_line)

#: seed 002 Table 1 / VALIDATION.md section H: joint springs (N m/rad), motor inertia
SECTION_H_JOINT_STIFFNESS = 1.0e4
SECTION_H_MOTOR_INERTIA = 0.1
#: hold period of the spring input k_t q_ac(t) in the flexible-joint simulation (s); with
#: mid-interval sampling the error is second order in it (0.2 mm on the section H radii)
SPRING_INPUT_PERIOD = 2.5e-4
#: Path 1 (Eqs. 27-29): joint angles (rad) at start and goal, motion time, observation
SECTION_H_PATH1 = {"theta0": np.radians([60.0, -120.0]), "theta_f": np.radians([-45.0, -90.0]),
                   "t_f": 1.5, "hold": 1.5}
#: Path 2 (Eq. 30): straight tip line, trapezoidal speed, observation after the motion
SECTION_H_PATH2 = {"start": (0.0, 1.0), "end": (0.75, 1.5), "v_max": 0.75, "accel": 3.0,
                   "hold": 1.0}


@dataclass
class ResidualVibration:
    """Seed 002 Eqs. (19)-(22) along one run (m, s)."""

    t: np.ndarray
    t_final: float
    tip: np.ndarray            # (N, 2) tip of the flexible arm
    desired: np.ndarray        # (N, 2) rigid tip of the plan, the goal point after t_f
    deviation: np.ndarray      # (N,) P_e of Eq. (22)
    joint_torques: np.ndarray  # (N, n) Eq. (9) (rigid joints) or Eq. (13) (motor torque)

    @property
    def path_deviation(self) -> float:
        """Largest deviation from the rigid path while moving (t <= t_f), m."""
        return float(np.max(self.deviation[self.t <= self.t_final + 1e-12]))

    @property
    def radius(self) -> float:
        """Radius of the residual vibration about the goal point (t > t_f), m."""
        return float(np.max(self.deviation[self.t > self.t_final + 1e-12]))

    @property
    def centre_offset(self) -> float:
        """Distance of the mean tip after t_f from the goal (the gravity sag), m."""
        after = self.t > self.t_final + 1e-12
        return float(np.linalg.norm(np.mean(self.tip[after], axis=0) - self.desired[-1]))


def section_h_motion(model: FlexArmModel, path: int, sample_period: float = 1e-3):
    """The planned joint motion of seed 002's Path 1 or Path 2, with its observation
    time, as ``(SampledTrajectory, t_f)``. Path 2 is inverted with the rigid kinematics,
    as in the paper (its Step 2), on the elbow-up branch."""
    if path == 1:
        p = SECTION_H_PATH1
        return (polynomial_fourier(p["theta0"], p["theta_f"], p["t_f"], sample_period,
                                   hold=p["hold"]), p["t_f"])
    if path == 2:
        p = SECTION_H_PATH2
        line = trapezoidal_line(p["start"], p["end"], p["v_max"], p["accel"], sample_period,
                                hold=p["hold"])
        lengths = [lk.length for lk in model.arm.links]
        bend = elbow_bend(lengths[0], lengths[1], p["start"], "up")
        th, thd, thdd = rigid_path_inverse(lengths, line.p, line.v, line.a, bend)
        distance = float(np.linalg.norm(np.subtract(p["end"], p["start"])))
        t_f = trapezoidal_duration(distance, p["v_max"], p["accel"])
        return SampledTrajectory(line.t, th, thd, thdd), t_f
    raise ValueError(f"path: got {path!r}; expected 1 (joint motion, Eqs. 27-29) or 2 "
                     "(straight tip line, Eq. 30)")


def _result(model, motion, t_final, t, tip, torques) -> ResidualVibration:
    lengths = [lk.length for lk in model.arm.links]
    theta = np.array([np.interp(t, motion.t, motion.p[:, i]) for i in
                      range(motion.p.shape[1])]).T
    desired = forward_kinematics(lengths, theta)
    k_f = int(np.searchsorted(motion.t, t_final + 1e-12) - 1)
    desired[t > t_final + 1e-12] = forward_kinematics(lengths, motion.p[k_f])
    return ResidualVibration(t=t, t_final=float(t_final), tip=tip, desired=desired,
                             deviation=np.linalg.norm(tip - desired, axis=1),
                             joint_torques=torques)


def residual_vibration(model: FlexArmModel, motion: SampledTrajectory, t_final: float, *,
                       joint_stiffness=None, motor_inertia=0.0,
                       sample_period: float = 1e-3) -> ResidualVibration:
    """Deviation and residual vibration of ``model`` under the planned joint motion
    ``motion`` (prescribed through ``t_final``, held afterwards, starting at rest in the
    static equilibrium). ``joint_stiffness`` (N m/rad, scalar or per joint) switches to
    flexible joints driven by the motor angles q_ac = motion (module docstring)."""
    if not motion.t[0] < t_final <= motion.t[-1]:
        raise ValueError(f"t_final: got {t_final!r} s; expected a time inside the motion "
                         f"({motion.t[0]!r}, {motion.t[-1]!r}] s")
    if joint_stiffness is None:
        nominal = NominalInputSolver(model).solve(motion)
        return _result(model, motion, t_final, nominal.t, nominal.tip, nominal.tau)
    n = model.n_links
    kt = np.broadcast_to(np.asarray(joint_stiffness, float), (n,)).copy()
    if np.any(~np.isfinite(kt)) or np.any(kt <= 0):
        raise ValueError(f"joint_stiffness: got {kt.tolist()}; expected springs > 0 N m/rad")
    q0 = static_equilibrium(model, motion.p[0], joints="pd", kp=kt).q
    pd = JointPD(kp=kt, kd=np.zeros(n), setpoints=np.zeros(n))

    def motor_angle(t):
        return np.array([np.interp(t, motion.t, motion.p[:, i]) for i in range(n)])

    hold = min(sample_period, SPRING_INPUT_PERIOD)

    def spring_input(t, x):  # k_t q_ac at mid-interval of the held input
        return kt * motor_angle(t + 0.5 * hold)

    duration = float(motion.t[-1] - motion.t[0])
    sim = simulate(model, q0, t_final=duration, sample_period=sample_period, pd=pd,
                   policy=spring_input, control_period=hold, method="fixed", dt=hold)
    t = sim.t + motion.t[0]
    q_ac = np.array([motor_angle(tk) for tk in t])
    q_ac_dd = np.array([np.interp(t, motion.t, motion.a[:, i]) for i in range(n)]).T
    torques = motor_inertia * q_ac_dd + kt * (q_ac - sim.joint_angles)
    return _result(model, motion, t_final, t, sim.tip_positions, torques)


def payload_sweep(model: FlexArmModel, payloads, path: int = 1, *, joint_stiffness=None,
                  sample_period: float = 1e-3) -> list[ResidualVibration]:
    """Residual vibration for each tip payload (kg) on seed 002's Path 1 or 2 (section H).

    The payload is a point mass (no rotary inertia); the model's payload is restored.
    """
    saved = model.payload
    motion, t_f = section_h_motion(model, path, sample_period)
    out = []
    try:
        for mass in payloads:
            model.set_payload(float(mass), 0.0)
            out.append(residual_vibration(model, motion, t_f, joint_stiffness=joint_stiffness,
                                          motor_inertia=SECTION_H_MOTOR_INERTIA,
                                          sample_period=sample_period))
    finally:
        model.set_payload(*saved)
    return out
