"""ControlLoop: the arm and an in-loop controller advanced together (ros2_control's update
loop: read the sensors, update the controller, write the command, integrate).

Every control ``period`` the controller (:mod:`flex_model.controller_interface`) reads the
sensed state of the arm, its command is held (zero-order hold) while the model integrates
the period in steps of at most the stepper's ``max_step``. No message crosses a process or
an executor inside the loop; the model node publishes the state at its own rates.
"""
from __future__ import annotations

import numpy as np

from .controller_interface import SensedState
from .stepper import Stepper


class ControlLoop:
    """A :class:`~flex_model.stepper.Stepper` driven by an in-loop controller."""

    def __init__(self, stepper: Stepper, controller, period: float):
        if not period > 0:
            raise ValueError(f"control period: got {period!r}; expected > 0 s")
        self.stepper, self.controller, self.period = stepper, controller, float(period)
        m = stepper.model
        self._G = m.G
        self._defl = np.array([m.tip_deflection_index(i) for i in range(m.n_links)])
        self.n_updates = 0
        self.t0 = 0.0  # the trajectory's start (simulation time, s)

    def set_trajectory(self, trajectory, start: float = 0.0) -> None:
        """Track ``trajectory`` (a JointTrajectoryData) from the simulation time ``start``:
        the controller sees the time since then."""
        self.controller.set_trajectory(trajectory)
        self.t0 = float(start)

    def sense(self) -> SensedState:
        """Joint angles and rates, link tip deflections and their rates, now."""
        q, v = self.stepper.q, self.stepper.v
        return SensedState(self._G @ q, self._G @ v, q[self._defl], v[self._defl])

    def update(self) -> np.ndarray:
        """One controller update at the current time; the command is held from now on."""
        st = self.stepper
        u = np.asarray(self.controller.update(st.t - self.t0, self.period, self.sense()),
                       float)
        if u.shape != (st.model.n_links,) or not np.all(np.isfinite(u)):
            raise ValueError(f"in-loop controller: got the command {u.tolist()}; expected "
                             f"{st.model.n_links} finite values")
        st.set_command(u)
        self.n_updates += 1
        return u

    def advance(self, n_periods: int = 1) -> None:
        """``n_periods`` control periods: update, then integrate one period, each."""
        for _ in range(int(n_periods)):
            self.update()
            self.stepper.advance(self.period)
