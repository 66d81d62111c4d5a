"""JointTrajectoryData: a sampled joint trajectory with its nominal deflections and torques.

The planner (thesis Ch. IV-V.1) produces it and the controller (thesis Eq. 95) consumes it
as data, so neither package imports the other. Units: s, rad, rad/s, rad/s^2, N m, m.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class JointTrajectoryData:
    """Samples at times ``t`` (strictly increasing, s).

    ``positions``/``velocities``/``accelerations`` are joint (encoder) angles and their
    derivatives, shape (N, n_joints); ``efforts`` the nominal joint torques (N, n_joints);
    ``q_nominal`` (N, nq), optional, the nominal generalized coordinates of the model
    (joint angles and deflections); ``tip`` (N, 2), optional, the nominal tip path (m).
    """

    joint_names: list
    t: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray
    efforts: np.ndarray = field(default=None)
    q_nominal: np.ndarray = field(default=None)
    tip: np.ndarray = field(default=None)

    def __post_init__(self):
        self.t = np.asarray(self.t, float)
        n, j = len(self.t), len(self.joint_names)
        if n < 1 or np.any(np.diff(self.t) <= 0) or not np.all(np.isfinite(self.t)):
            raise ValueError(f"t: got {n} times; expected strictly increasing finite times")
        for name in ("positions", "velocities", "accelerations", "efforts"):
            value = getattr(self, name)
            if value is None and name == "efforts":
                value = np.zeros((n, j))
            value = np.asarray(value, float)
            if value.shape != (n, j) or not np.all(np.isfinite(value)):
                raise ValueError(f"{name}: got shape {value.shape}; expected ({n}, {j}) "
                                 "finite values")
            setattr(self, name, value)

    @property
    def duration(self) -> float:
        return float(self.t[-1] - self.t[0])

    def sample(self, t: float):
        """(position, velocity, acceleration, effort) at time t, linear interpolation,
        held constant outside [t0, t_end]."""
        t = float(np.clip(t, self.t[0], self.t[-1]))
        k = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 1))
        if k == len(self.t) - 1:
            return (self.positions[k], self.velocities[k], self.accelerations[k],
                    self.efforts[k])
        w = (t - self.t[k]) / (self.t[k + 1] - self.t[k])
        out = []
        for arr in (self.positions, self.velocities, self.accelerations, self.efforts):
            out.append((1 - w) * arr[k] + w * arr[k + 1])
        return tuple(out)
