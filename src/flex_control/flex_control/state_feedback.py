"""The Quanser rotary flexible link lab's state feedback (voltage output, issue 9).

    V = K1 (theta_ref - theta) + K2 (0 - d) - K3 theta_dot - K4 d_dot + V_0

with theta the hub angle (rad), d the strain-gauge tip deflection (m, as the lab logs
it: ``gauge_sign`` times the twin's deflection plus ``gauge_bias``) and V the motor
voltage (V), optionally clipped to ``voltage_limit``. V_0 (``voltage_offset``, default 0)
is a constant the motor receives on top of the law: an amplifier offset, or any constant
torque at the hub (K_g K_m V_0 / R_m), such as a cable's pull. The reference is a recorded square
wave held between its samples (zero-order hold, as the lab's 1 kHz loop). The gauge's
reading may lag the tip by ``gauge_delay`` (s): the law then acts on d(t - gauge_delay)
and its rate, as the lab's loop received them (the CU Boulder logs: about 60 ms, python -m
studies.link_response).
"""
from __future__ import annotations

from collections import deque
from typing import Callable

import numpy as np


class TipStateFeedback:
    """V = K1 (r - theta) - K2 d - K3 theta_dot - K4 d_dot for one joint."""

    def __init__(self, gains, reference_t, reference, gauge_sign: float = 1.0,
                 gauge_bias: float = 0.0, voltage_limit: float = np.inf,
                 voltage_offset: float = 0.0, gauge_gain: float = 1.0,
                 gauge_delay: float = 0.0):
        k = np.asarray(gains, float).reshape(-1)
        if k.shape != (4,) or not np.all(np.isfinite(k)):
            raise ValueError(f"gains: got {np.asarray(gains).tolist()}; expected 4 finite "
                             "values K1..K4")
        if gauge_sign not in (1.0, -1.0):
            raise ValueError(f"gauge_sign: got {gauge_sign!r}; expected +1 or -1")
        if not voltage_limit > 0:
            raise ValueError(f"voltage_limit: got {voltage_limit!r}; expected > 0 V")
        if not (np.isfinite(gauge_gain) and gauge_gain > 0):
            raise ValueError(f"gauge_gain: got {gauge_gain!r}; expected a finite number > 0 "
                             "(the gauge reads gain x the tip deflection)")
        if not (np.isfinite(gauge_delay) and gauge_delay >= 0):
            raise ValueError(f"gauge_delay: got {gauge_delay!r}; expected a finite time >= 0 "
                             "s (the gauge's lag)")
        if not np.isfinite(voltage_offset):
            raise ValueError(f"voltage_offset: got {voltage_offset!r}; expected a finite "
                             "voltage (V)")
        self.gains = k
        self.t_ref = np.asarray(reference_t, float)
        self.ref = np.asarray(reference, float)
        if self.t_ref.shape != self.ref.shape or self.t_ref.size < 1:
            raise ValueError("reference: times and values must be equal-length arrays")
        self.gauge_sign = float(gauge_sign)
        self.gauge_bias = float(gauge_bias)
        self.voltage_limit = float(voltage_limit)
        self.voltage_offset = float(voltage_offset)
        self.gauge_gain = float(gauge_gain)
        self.gauge_delay = float(gauge_delay)

    def reference_at(self, t: float) -> float:
        """The held reference sample at t (rad)."""
        k = int(np.searchsorted(self.t_ref, t + 1e-9, side="right")) - 1
        return float(self.ref[max(k, 0)])

    def voltage(self, t: float, theta: float, theta_rate: float, deflection: float,
                deflection_rate: float) -> float:
        """The motor voltage (V) for the twin's state (deflection in the twin's sign)."""
        k1, k2, k3, k4 = self.gains
        d = self.gauge_gain * self.gauge_sign * deflection + self.gauge_bias
        dd = self.gauge_gain * self.gauge_sign * deflection_rate
        v = (k1 * (self.reference_at(t) - theta) - k2 * d - k3 * theta_rate - k4 * dd
             + self.voltage_offset)
        return float(np.clip(v, -self.voltage_limit, self.voltage_limit))

    def policy(self, model) -> Callable:
        """``policy(t, x) -> [V]`` for :func:`flex_model.simulate.simulate` (single link).
        With a ``gauge_delay`` it keeps the tip's recent history (called at increasing
        times; a call at an earlier time starts a new run) and reads it that much late,
        linearly interpolated, the first sample held before it."""
        nq = model.nq
        g = model.G[0]
        i = model.tip_deflection_index(0)
        lag = self.gauge_delay
        history = deque()   # (t, d, d_dot), the oldest one at or before t - lag

        def gauge(t, d, dd):
            if history and t < history[-1][0]:
                history.clear()
            history.append((t, d, dd))
            while len(history) > 1 and history[1][0] <= t - lag:
                history.popleft()
            (t0, d0, dd0), (t1, d1, dd1) = history[0], history[min(1, len(history) - 1)]
            s = 0.0 if t1 <= t0 else min(max((t - lag - t0) / (t1 - t0), 0.0), 1.0)
            return d0 + s * (d1 - d0), dd0 + s * (dd1 - dd0)

        def policy(t, x):
            q, v = x[:nq], x[nq:2 * nq]   # a stick-slip joint appends bristle states
            d, dd = (q[i], v[i]) if lag == 0 else gauge(t, q[i], v[i])
            return [self.voltage(t, g @ q, g @ v, d, dd)]

        return policy


def lab_controller(run, voltage_limit: float = np.inf, voltage_offset: float = 0.0,
                   gauge_gain: float = 1.0, gauge_delay: float = 0.0) -> TipStateFeedback:
    """The lab's law of a recorded run (flex_twin.real_arms.quanser_data.LabRun): its
    gains, its reference, its gauge sign and bias; the gauge reads ``gauge_gain`` times
    the twin's tip deflection ``gauge_delay`` (s) ago."""
    return TipStateFeedback(run.gains, run.t, run.reference, run.gauge_sign(),
                            run.gauge_bias(), voltage_limit, voltage_offset, gauge_gain,
                            gauge_delay)


def lab_policy_factory(run, model, voltage_offset: float = 0.0) -> Callable:
    """The closed-loop policy of a run on a twin (the replay's ``make_policy`` hook); the
    gauge's gain and delay are the twin's first link's ``tip_deflection`` sensor's
    (flex_model.sensors; its other fields are not used: the run gives sign and bias)."""
    from flex_model.sensors import tip_gauge
    gauge = tip_gauge(model.arm, model.arm.links[0].name)
    return lab_controller(run, voltage_offset=voltage_offset, gauge_gain=gauge.gain,
                          gauge_delay=gauge.delay).policy(model)
