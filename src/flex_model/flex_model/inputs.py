"""What drives the compiled integrators besides the state: the built-in joint PD, torque
and tip-load pulses, the held command, packed with the model's matrices into the input data
``E`` of :mod:`flex_model.integrators` (used by simulate, the stepper, modes and the
diagnosis replay)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

#: the columns of the joint data (FlexArmModel.joint_data, InputData.joint_data), one row a
#: joint: spring (k, b, backlash, smoothing), friction (F_v, F_c, F_s, w_s, eps), DC motor
#: (on, R, K_t, K_e, i_max, V_max), gear ratio n, cogging (A, N, phase), stick-slip friction
#: (from JD_SS on, flex_model.effects.stick_slip.COLUMNS). The compiled kernels read them
#: by the JD_ constants below (numba takes module constants as literals).
JOINT_DATA = ("k", "b", "backlash", "smoothing", "fv", "fc", "fs", "ws", "eps", "motor",
              "R", "Kt", "Ke", "imax", "vmax", "ratio", "cog_A", "cog_N", "cog_phase",
              "ss_on", "ss_fv", "ss_fc", "ss_fs", "ss_ws", "ss_k", "ss_d", "ss_frac")
(JD_K, JD_B, JD_BACKLASH, JD_SMOOTHING, JD_FV, JD_FC, JD_FS, JD_WS, JD_EPS, JD_MOTOR, JD_R,
 JD_KT, JD_KE, JD_IMAX, JD_VMAX, JD_RATIO, JD_COG_A, JD_COG_N, JD_COG_PHASE,
 JD_SS) = range(20)


class InputData(NamedTuple):
    """The input data ``E`` of the compiled planar kernels (flex_model.integrators, the
    exact kinematics, the control kernel, the replays): the model's stiffness K and
    damping D, the joint map G (theta = G q) and the actuator map Ga, gravity (gx, gy),
    the built-in joint PD (kp, kd, theta_set), the held input u (written in place by the
    callers), the pulses (pulse_t0, pulse_t1, pulse_tau, pulse_force, pulse_torque),
    torque_limit, the contact surface (effects.contact_surface.kernel_data) and the joint
    data (columns JD_ above)."""
    K: np.ndarray
    D: np.ndarray
    G: np.ndarray
    gx: float
    gy: float
    kp: np.ndarray
    kd: np.ndarray
    theta_set: np.ndarray
    u: np.ndarray
    pulse_t0: np.ndarray
    pulse_t1: np.ndarray
    pulse_tau: np.ndarray
    pulse_force: np.ndarray
    pulse_torque: np.ndarray
    torque_limit: np.ndarray
    contact: np.ndarray
    Ga: np.ndarray
    joint_data: np.ndarray


@dataclass(frozen=True)
class JointPD:
    """tau = kp (theta_set - theta) - kd theta_dot per joint (N m/rad, N m s/rad, rad)."""

    kp: np.ndarray
    kd: np.ndarray
    setpoints: np.ndarray


def ramp_fraction(t, t0: float, r: float):
    """(y, area): a set-point ramp's fraction y(t) = clip((t - t0) / r, 0, 1) over [t0,
    t0 + r] and its integral from t0 (t a number or an array): the ramps of every
    scenario's set-point schedule."""
    t = np.asarray(t, float)
    y = np.clip((t - t0) / r, 0.0, 1.0)
    area = np.where(t <= t0, 0.0, np.where(t <= t0 + r, (t - t0) ** 2 / (2 * r),
                                           r / 2 + (t - t0 - r)))
    return y, area


@dataclass(frozen=True)
class Pulse:
    """Constant joint torques (N m), tip force (N, base frame) and tip torque (N m) on
    ``start <= t < end`` (s)."""

    start: float
    end: float
    joint_torques: tuple = ()
    tip_force: tuple = (0.0, 0.0)
    tip_torque: float = 0.0


def input_data(model, pd: JointPD | None, pulses, u) -> InputData:
    """The input data ``E`` (:class:`InputData`) of the compiled integrators for
    ``model``: its matrices, gravity, the built-in joint PD, the held command ``u`` and the
    pulses."""
    nl = model.n_links
    if pd is None:
        kp = kd = sp = np.zeros(nl)
    else:
        # fresh C-contiguous, writable copies: a read-only (np.broadcast_to) or strided
        # gain array is another numba type, and every new type of E compiles the whole
        # integrator again (~10 s each on a fresh clone)
        kp, kd, sp = (np.array(a, float).reshape(nl) for a in (pd.kp, pd.kd, pd.setpoints))
    n = len(pulses)
    t0 = np.array([p.start for p in pulses], float)
    t1 = np.array([p.end for p in pulses], float)
    ptau = np.zeros((n, nl))
    pf = np.zeros((n, 2))
    pc = np.zeros(n)
    for k, p in enumerate(pulses):
        if len(p.joint_torques):
            ptau[k] = p.joint_torques
        pf[k] = p.tip_force
        pc[k] = p.tip_torque
    return InputData(model.K, model.D, model.G, float(model.gravity[0]),
                     float(model.gravity[1]), kp, kd, sp, u, t0, t1, ptau, pf, pc,
                     model.torque_limit, model.contact, model.Ga, model.joint_data)
