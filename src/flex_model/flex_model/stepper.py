"""Stepper: the arm advanced in real-time-sized pieces (what the model node runs).

Holds the integration state (q, v, the generalized-alpha acceleration history) of one
arm and advances it by any duration with the fixed-step implicit scheme of
:mod:`flex_model.integrators` (generalized-alpha, default step 1 ms), the held joint
command acting as the policy input. A new command or payload restarts the method
(consistent acceleration), as simulate() does at control instants. The state is
``x = [q; v; z]``, z the bristle deflections of stick_slip_friction joints (none without).
"""
from __future__ import annotations

import copy

import numpy as np

from .dynamics import FlexArmModel
from .inputs import input_data
from .integrators import PlanarModel, consistent_acceleration, joint_torques, restart_acceleration
from .solvers.loop import fixed_step
from .solvers.status import REFINEMENTS, newton_settings, refine
from .simulate import (DIVERGENCE_LIMIT, RUNAWAY, SimulationDivergedError,
                       apply_payload_change, diverged, newton_failed)


class Stepper:
    """Advance a FlexArmModel under a held joint command (N m, or V for DC-motor joints)."""

    def __init__(self, model: FlexArmModel, q0=None, v0=None, *, max_step: float = 1e-3,
                 rho_inf: float = 0.9):
        self.model = copy.copy(model)  # payload changes stay local to this stepper
        self.max_step, self.rho_inf = float(max_step), float(rho_inf)
        self.u = np.zeros(model.n_links)
        self.E = input_data(self.model, None, (), self.u)
        self.q0 = self.model.q_from_joint_angles(np.zeros(model.n_links)) if q0 is None \
            else np.asarray(q0, float)
        self.v0 = np.zeros(model.nq) if v0 is None else np.asarray(v0, float)
        self.reset()

    def reset(self, q0=None, v0=None) -> None:
        """Back to the initial state (or a given one) at t = 0, bristles unloaded."""
        if q0 is not None:
            self.q0 = np.asarray(q0, float)
        if v0 is not None:
            self.v0 = np.asarray(v0, float)
        self.t = 0.0
        self.x = np.concatenate([self.q0, self.v0, np.zeros(self.model.n_bristles)])
        self.u[:] = 0.0
        self._restart()

    def _restart(self, jump: bool = False) -> None:
        """Consistent start values of the method; after a jump of the command those of
        integrators.restart_acceleration (filtered where the step cannot follow it)."""
        if jump:
            self.a, self.abar, _, _ = restart_acceleration(
                self.t, self.x, self.a, self.abar, self.max_step, self.rho_inf, self.model.P,
                self.E)
            return
        self.a = consistent_acceleration(self.t, self.x, self.model.P, self.E)
        self.abar = self.a.copy()

    def set_command(self, u) -> None:
        """Hold a new joint command from now on (restarts the method if it changed)."""
        u = np.asarray(u, float).reshape(self.model.n_links)
        if not np.all(np.isfinite(u)):
            raise ValueError(f"command: got {u.tolist()}; expected finite values")
        if not np.array_equal(u, self.u):
            self.u[:] = u
            self._restart(jump=True)

    def set_payload(self, mass: float, inertia: float) -> None:
        """Change the tip payload now (a pick keeps B v, a place keeps v)."""
        self.x = apply_payload_change(self.model, self.x, mass, inertia)
        self._restart()

    def advance(self, duration: float) -> None:
        """Integrate over ``duration`` (s) in equal steps no longer than max_step."""
        if duration <= 0:
            return
        n = max(1, int(np.ceil(duration / self.max_step - 1e-9)))
        h = duration / n
        X, status, t_end, x_end, a, abar, _ = fixed_step(
            PlanarModel(self.model.P, self.E), self.E.K.shape[0], float(self.t), self.x,
            self.a, self.abar, float(h), n, n,
            newton_settings(float(self.rho_inf), 1e-10, DIVERGENCE_LIMIT), None)
        if status == 1:
            raise diverged(self.model, t_end, x_end)
        if status == 2:
            raise newton_failed(t_end, h, RUNAWAY)
        self.t, self.x, self.a, self.abar = self.t + duration, x_end, a, abar

    def hold(self, duration: float) -> None:
        """Let ``duration`` (s) pass with the state held where it is (the arm's brakes on:
        joints and links do not move)."""
        if duration > 0:
            self.t += duration

    def advance_refining(self, duration: float, refinements=REFINEMENTS) -> int:
        """:meth:`advance`; if it fails (Newton or a run-away state), the same duration
        again from the same state in steps of max_step / k for each k of ``refinements``
        in turn (solvers.status.refine). Returns the k that succeeded (1: none needed);
        raises the first failure if every one fails. A failed attempt leaves the state
        unchanged."""
        step = self.max_step

        def attempt(k):
            self.max_step = step / k
            try:
                self.advance(duration)
            finally:
                self.max_step = step
        return refine(attempt, refinements, SimulationDivergedError)

    # ------------------------------------------------------------------ outputs
    @property
    def q(self) -> np.ndarray:
        return self.x[:self.model.nq]

    @property
    def v(self) -> np.ndarray:
        return self.x[self.model.nq:2 * self.model.nq]

    @property
    def bristles(self) -> np.ndarray:
        """Bristle deflections z (rad) of the stick_slip_friction joints."""
        return self.x[2 * self.model.nq:]

    def joint_state(self):
        """(angles, rates, applied torques) of the joints (rad, rad/s, N m)."""
        m = self.model
        tau = joint_torques(self.t, self.q, self.v, self.E)
        return m.joint_angles(self.q), m.G @ self.v, tau

    def deflections(self):
        """(tip deflections, tip rotations, their rates) of every link."""
        m = self.model
        d = [m.tip_deflection_index(i) for i in range(m.n_links)]
        r = m.tip_rotation_matrix()
        return self.q[d], r @ self.q, self.v[d], r @ self.v

    def tip_pose(self):
        return self.model.tip_pose(self.q)

    def tip_specific_force(self) -> np.ndarray:
        """Specific force a - g at the tip in the tip frame (m/s^2), what an accelerometer
        there measures (flex_model.sensors)."""
        from .integrators import derivative
        nq = self.model.nq
        a = derivative(self.t, self.x, self.model.P, self.E)[nq:2 * nq]
        return self.model.tip_specific_force(self.q, self.v, a)
