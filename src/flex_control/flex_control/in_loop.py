"""flex_control's laws as in-loop controllers (:mod:`flex_model.controller_interface`).

Registered as entry points of the group ``flex_twin.controllers`` (setup.py):

- ``eq95``: the decentralized PD of thesis Eq. (95) with the trajectory's nominal torque as
  feed-forward; with ``schedule_file`` the gain-scheduled design of thesis Ch. V;
- ``eq45``: seed 000's PD-like cascade, Eq. (45);
- ``state_feedback``: ``u = K1 (r - theta) - K2 d - K3 theta_dot - K4 d_dot`` per joint
  (the Quanser lab's law, :mod:`.state_feedback`, for any number of joints).

Parameters are those of the controller node (:class:`flex_control.params.ControllerParams`:
h, a, schedule_file, feedforward, kpp, kpv, gear_ratio, torque_limits), without the node's
own (rate_hz, state_timeout, stale_action), or ``gains`` (4 per joint) and ``limit`` for
``state_feedback``. Until a trajectory arrives the controller holds the joint angles it
senses at its first update, as the controller node does.

After that first update each law also offers ``compiled_law()`` (a
:class:`flex_model.control_kernel.LinearLaw`), with which ControlLoop runs its periods in
one compiled call; the gain-scheduled Eq. (95) stays in Python.
"""
from __future__ import annotations

import numpy as np

from flex_model import control_kernel as ck
from flex_model.trajectory import JointTrajectoryData

from .laws import hold_reference, joint_vector
from .params import ControllerParams, build_controller

NODE_ONLY = ("rate_hz", "state_timeout", "stale_action")


class InLoopLaw:
    """A law of :mod:`.laws` behind ``update(time, period, state)``."""

    def __init__(self, law: str, joint_names, parameters: dict):
        extra = sorted(set(parameters) & set(NODE_ONLY + ("law", "joint_names")))
        if extra:
            raise ValueError(f"{extra[0]}: got a parameter of the controller node; an "
                             "in-loop controller runs at the model's control period")
        self.params = ControllerParams.from_mapping(
            dict(parameters, law=law, joint_names=tuple(joint_names)))
        self.joint_names = list(self.params.joint_names)
        self.controller = None
        self.pending = None
        self._compiled = None

    def set_trajectory(self, trajectory: JointTrajectoryData) -> None:
        if list(trajectory.joint_names) != self.joint_names:
            raise ValueError(f"trajectory joint_names: got {list(trajectory.joint_names)}; "
                             f"expected {self.joint_names}")
        self._compiled = None
        if self.controller is None:
            self.pending = trajectory
        else:
            self.controller.set_reference(trajectory)

    def compiled_law(self):
        """This law for flex_model's compiled loop (None before the first update, which
        fixes the held reference, and for a gain schedule)."""
        c = self.controller
        if c is None or getattr(c, "schedule", None) is not None:
            return None
        if self._compiled is None:
            if self.params.law == "eq45":
                self._compiled = ck.linear_law(
                    ck.EQ45, ck.SAMPLER, c.reference, [c.kpp, c.kpv, c.gear_ratio], False,
                    c.torque_limits)
            else:
                self._compiled = ck.linear_law(ck.EQ95, ck.SAMPLER, c.reference, [c.h, c.a],
                                               c.feedforward, c.torque_limits)
        return self._compiled

    def update(self, time: float, period: float, state) -> np.ndarray:
        if self.controller is None:
            self.controller = build_controller(self.params, self.pending,
                                               hold_positions=state.positions)
        d = state.deflections if self.params.use_deflections else None
        return self.controller.torque(time, state.positions, state.velocities, d)


class JointStateFeedback:
    """``u_i = K1 (r_i - theta_i) - K2 d_i - K3 theta_dot_i - K4 d_dot_i`` (+ the
    trajectory's effort as feed-forward), clipped to ``limit``; d_i the tip deflection of
    link i (m). Torque (N m) or voltage (V), whatever the joint takes."""

    def __init__(self, joint_names, parameters: dict):
        p = dict(parameters)
        self.joint_names = list(joint_names)
        n = len(self.joint_names)
        unknown = sorted(set(p) - {"gains", "limit", "feedforward"})
        if unknown:
            raise ValueError(f"{unknown[0]}: got an unknown parameter; expected gains, limit, "
                             "feedforward")
        if "gains" not in p:
            raise ValueError("gains: missing; expected 4 gains K1..K4 per joint")
        self.K = joint_vector("gains", p["gains"], 4 * n).reshape(n, 4)
        self.limit = float(p.get("limit", np.inf))
        if not self.limit > 0:
            raise ValueError(f"limit: got {self.limit!r}; expected > 0")
        self.feedforward = bool(p.get("feedforward", True))
        self.reference = None
        self._compiled = None

    def set_trajectory(self, trajectory: JointTrajectoryData) -> None:
        if list(trajectory.joint_names) != self.joint_names:
            raise ValueError(f"trajectory joint_names: got {list(trajectory.joint_names)}; "
                             f"expected {self.joint_names}")
        self.reference = trajectory
        self._compiled = None

    def compiled_law(self):
        """This law for flex_model's compiled loop (None before the first update)."""
        if self.reference is None:
            return None
        if self._compiled is None:
            self._compiled = ck.linear_law(ck.STATE_FEEDBACK, ck.TRAJECTORY_SAMPLE,
                                           self.reference, self.K.T, self.feedforward,
                                           self.limit)
        return self._compiled

    def update(self, time: float, period: float, state) -> np.ndarray:
        if self.reference is None:
            self.reference = hold_reference(self.joint_names, state.positions)
        r, dr, _, ff = self.reference.sample(time)
        K = self.K
        u = K[:, 0] * (r - state.positions) - K[:, 1] * state.deflections \
            - K[:, 2] * (state.velocities - dr) - K[:, 3] * state.deflection_rates
        if self.feedforward:
            u = u + ff
        return np.clip(u, -self.limit, self.limit)


def eq95(joint_names, parameters: dict) -> InLoopLaw:
    return InLoopLaw("eq95", joint_names, parameters)


def eq45(joint_names, parameters: dict) -> InLoopLaw:
    return InLoopLaw("eq45", joint_names, parameters)


def state_feedback(joint_names, parameters: dict) -> JointStateFeedback:
    return JointStateFeedback(joint_names, parameters)
