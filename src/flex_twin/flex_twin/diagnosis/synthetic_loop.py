"""Closed-loop recording of a synthetic diagnosis case: the true arm under the sampled
controller, read through noisy, quantised, possibly biased or delayed sensors.

The controller reads the measured joint angles and rates at its instants (every
``period`` s, a multiple of the sample period) and commands

    tau_k = tau_ff(qset_k) + kp (qset_k - q_k) - kd v_k             (held for one period)

the ``law: pd`` of :mod:`flex_twin.diagnosis.controller` with ``feedforward: gravity``
(the gravity torque of the *nominal*, undeformed arm at the reference), q_k and v_k the
measured actuator coordinates (the link-side joint angle, or the motor angle / n of an
elastic joint: the encoder sits on the motor) and their rates. The drives add process
noise (torque ripple) to the command; the arm's ``actuator_delay`` and
``torque_saturation`` effects act on what arrives. The recording holds the measured
channels and the command, never the true state.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.simulate import simulate
from flex_model.statics import StaticConvergenceError, static_equilibrium
from .controller import ControllerDescription
from flex_model.sensors import quantise
from .synthetic_signals import channel_noise


@dataclass(frozen=True)
class SensorFaults:
    """Per-joint encoder bias (rad) and delay (samples) of the true unit."""

    bias: np.ndarray
    delay: np.ndarray


@dataclass
class SyntheticRecording:
    """Measured channels (the CSV columns) and, for tests only, the true signals."""

    columns: list
    data: np.ndarray
    true: dict

    def to_csv(self, path) -> None:
        np.savetxt(path, self.data, delimiter=",", header=",".join(self.columns),
                   comments="", fmt="%.10g")


def record(true_model: FlexArmModel, nominal: FlexArmModel, law: ControllerDescription, t,
           qset, noise: dict, faults: SensorFaults, rng: np.random.Generator,
           dt: float = 1e-3) -> SyntheticRecording:
    """Run the closed loop of the true arm from rest under the controller holding qset[0]
    and return the measured recording (rate = 1 / (t[1] - t[0])); ``nominal`` is the
    model the controller's feed-forward knows."""
    n, nl = qset.shape
    h = float(t[1] - t[0])
    step = int(round(law.period / h))
    if step < 1 or abs(step * h - law.period) > 1e-9:
        raise ValueError(f"controller period {law.period} s is not a multiple of the sample "
                         f"period {h} s")
    G = true_model.Ga
    ff = law.feedforward(nominal, qset)
    n_q = channel_noise(rng, (n, nl), noise["q"], h)
    n_v = channel_noise(rng, (n, nl), noise["v"], h)
    n_w = channel_noise(rng, (n, nl), noise["w"], h)
    n_tip = channel_noise(rng, (n, 2), noise["tip"], h)
    n_tau = channel_noise(rng, (n, nl), noise["torque"], law.period)  # per control instant
    hist = np.zeros((n, 2, nl))      # true joint angles and rates at the control instants
    cmd = np.zeros((n, nl))
    cols = np.arange(nl)
    res_q = noise["q"].resolution

    def measured(k, angles, rates):
        kd = np.maximum(np.asarray(k)[..., None] - faults.delay, 0)
        qm = quantise(angles[kd, cols] + faults.bias + n_q[k], res_q)
        return qm, rates[kd, cols] + n_v[k]

    def policy(time, x):
        k = int(round(time / h))
        hist[k] = G @ x[:true_model.nq], G @ x[true_model.nq:2 * true_model.nq]
        qm, vm = measured(k, hist[:, 0], hist[:, 1])
        cmd[k:k + step] = ff[k] + law.gains @ (qset[k] - qm) - law.rate_gains @ vm
        return cmd[k] + n_tau[k // step]

    q0, v0 = _initial_state(true_model, law, ff[0], qset[0], faults.bias)
    result = simulate(true_model, q0, v0, t_final=float(t[-1]), sample_period=h, policy=policy,
                      control_period=law.period, method="fixed", dt=min(dt, h))
    angles, rates = result.q @ G.T, result.v @ G.T
    qm, vm = measured(np.arange(n), angles, rates)
    w = result.tip_deflections
    tip = result.tip_positions
    columns = (["t"] + [f"q{i + 1}" for i in range(nl)] + [f"v{i + 1}" for i in range(nl)]
               + [f"tau{i + 1}" for i in range(nl)] + [f"qset{i + 1}" for i in range(nl)]
               + [f"w{i + 1}" for i in range(nl)] + ["tip_x", "tip_y"])
    data = np.column_stack([t, qm, vm, cmd, qset, quantise(w + n_w, noise["w"].resolution),
                            quantise(tip + n_tip, noise["tip"].resolution)])
    true = {"joint_angles": angles, "joint_rates": rates, "tip_deflections": w, "tip": tip,
            "applied_torque": result.tau, "noise": {"q": n_q, "v": n_v, "w": n_w,
                                                    "tip": n_tip, "torque": n_tau}}
    return SyntheticRecording(columns=columns, data=data, true=true)


def _initial_state(model: FlexArmModel, law: ControllerDescription, ff0, theta_set, bias,
                   settle: float = 3.0):
    """(q0, v0): at rest under the controller holding theta_set: the static equilibrium of
    the true arm under a PD on the actuator coordinates, then ``settle`` s of noiseless
    closed loop (elastic joints, friction and backlash settle where the law puts them;
    twice as long from the undeformed pose where Newton's method finds no equilibrium, as
    on a contact surface)."""
    kp = np.diag(law.gains)
    try:
        q0 = static_equilibrium(model, np.asarray(theta_set) - bias, joints="pd", kp=kp,
                                joint_torques=ff0).q
    except StaticConvergenceError:  # e.g. resting on a contact surface: let it settle
        q0 = model.q_from_joint_angles(np.asarray(theta_set) - bias)
        settle *= 2
    nq = model.nq
    G = model.Ga

    def hold(time, x):
        return (ff0 + law.gains @ (theta_set - G @ x[:nq] - bias)
                - law.rate_gains @ (G @ x[nq:2 * nq]))

    pre = simulate(model, q0, t_final=settle, sample_period=law.period, policy=hold,
                   control_period=law.period, method="fixed")
    return pre.q[-1], pre.v[-1]
