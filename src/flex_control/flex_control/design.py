"""Gain-scheduled design of the Eq. (95) PD by cyclic coordinate ascent (thesis V.2).

"The nominal nonlinear model of the flexible robot is unstable, therefore it is locally
stabilized in the neighbourhood of a sufficiently high number of the trajectory points with
a linear decentralized controller of PD type [Eq. 95] ... The stabilization is numerically
obtained through the ascendant cyclic coordinates technique so to optimize the parameters
zeta_min (as high as possible) and tau_max (as small as possible)."

At each of ``n_points`` times equally spaced along the nominal trajectory the closed loop is
linearized (:func:`flex_control.closed_loop.open_loop_jacobian`) and the gains
``x = (h_1, a_1, ..., h_n, a_n)`` maximize the cost

    J(x) = ln zeta_min(x) - w ln(tau_max(x) / 1 s)          if the frozen loop is stable,
    J(x) = -1000 + (-max Re lambda(x))                      otherwise,

i.e. the ratio ``zeta_min / tau_max^w`` (with ``w = tau_weight``, 1 by default: equal weight
to relative improvements of the two figures, no units to tune); the unstable branch lies
below every stable value and increases towards stability, so the ascent can start from an
unstable guess. The search runs in ``ln x`` within bounds: each coordinate in turn is
multiplied or divided by ``step`` while that improves ``J``; after a cycle without
improvement the step is square-rooted, down to ``min_step``. Start: the best common
``(h, a)`` of a coarse log grid, or the previous point's optimum if that is better.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.trajectory import JointTrajectoryData

from .closed_loop import (EigenSummary, NominalTrajectory, closed_loop_matrix, eigen_summary,
                          open_loop_jacobian, pd_gains)
from .gain_schedule import GainSchedule

UNSTABLE_OFFSET = -1000.0


@dataclass(frozen=True)
class DesignSettings:
    """Settings of :func:`design_schedule` (see module doc).

    ``h_bounds`` (kg m^2) and ``a_bounds`` (rad/s): search box; ``grid``: points per axis
    of the initial common-gain grid; ``per_joint``: one (h, a) per joint (else shared);
    ``deflection_weight`` (rad/m): stored in the schedule for run-time interpolation.
    """

    n_points: int = 16
    h_bounds: tuple = (0.01, 100.0)
    a_bounds: tuple = (0.1, 20.0)
    tau_weight: float = 1.0
    initial_step: float = 2.0
    min_step: float = 1.01
    max_evaluations: int = 3000
    grid: int = 7
    per_joint: bool = True
    deflection_weight: float = 0.0

    def __post_init__(self):
        if not (isinstance(self.n_points, int) and self.n_points >= 1):
            raise ValueError(f"n_points: got {self.n_points!r}; expected an integer >= 1")
        for name in ("h_bounds", "a_bounds"):
            lo, hi = getattr(self, name)
            if not (0 < lo < hi < np.inf):
                raise ValueError(f"{name}: got {(lo, hi)!r}; expected 0 < low < high")
        if not self.tau_weight >= 0:
            raise ValueError(f"tau_weight: got {self.tau_weight!r}; expected a number >= 0")
        if not (self.initial_step > self.min_step > 1):
            raise ValueError(f"initial_step, min_step: got {self.initial_step!r}, "
                             f"{self.min_step!r}; expected initial_step > min_step > 1")
        if not (isinstance(self.grid, int) and self.grid >= 2):
            raise ValueError(f"grid: got {self.grid!r}; expected an integer >= 2")
        if not self.max_evaluations >= 1:
            raise ValueError(f"max_evaluations: got {self.max_evaluations!r}; expected >= 1")


def design_cost(summary: EigenSummary, tau_weight: float = 1.0) -> float:
    """``J = ln zeta_min - w ln tau_max`` when stable, else ``-1000 - max Re lambda``."""
    if not summary.stable or summary.zeta_min <= 0:
        return UNSTABLE_OFFSET + min(summary.decay_rate, 0.0)
    return float(np.log(summary.zeta_min) - tau_weight * np.log(summary.tau_max))


@dataclass
class AscentResult:
    x: np.ndarray
    value: float
    evaluations: int
    cycles: int


def cyclic_coordinate_ascent(objective: Callable, x0, lower, upper, *, step: float = 2.0,
                             min_step: float = 1.01, max_evaluations: int = 3000
                             ) -> AscentResult:
    """Maximize ``objective(x)`` over ``lower <= x <= upper`` (all > 0), one coordinate at a
    time with multiplicative steps (a line search per coordinate and direction), refining
    the step by its square root after a cycle without improvement."""
    lower = np.asarray(lower, float)
    upper = np.asarray(upper, float)
    x = np.clip(np.asarray(x0, float), lower, upper)
    best = objective(x)
    evals, cycles = 1, 0
    while step >= min_step and evals < max_evaluations:
        cycles += 1
        improved = False
        for i in range(len(x)):
            for factor in (step, 1.0 / step):
                moved = False
                while evals < max_evaluations:
                    trial = x.copy()
                    trial[i] = np.clip(x[i] * factor, lower[i], upper[i])
                    if trial[i] == x[i]:
                        break
                    value = objective(trial)
                    evals += 1
                    if value > best + 1e-12 * max(1.0, abs(best)):
                        x, best, moved = trial, value, True
                    else:
                        break
                if moved:
                    improved = True
                    break
        if not improved:
            step = np.sqrt(step)
    return AscentResult(x=x, value=float(best), evaluations=evals, cycles=cycles)


@dataclass
class PointDesign:
    """The design at one trajectory point."""

    t: float
    theta: np.ndarray
    h: np.ndarray
    a: np.ndarray
    zeta_min: float
    tau_max: float
    cost: float
    evaluations: int

    def as_dict(self) -> dict:
        return {"t_s": self.t, "theta_deg": np.degrees(self.theta).tolist(),
                "h": self.h.tolist(), "a": self.a.tolist(), "zeta_min": self.zeta_min,
                "tau_max_s": self.tau_max, "cost": self.cost, "evaluations": self.evaluations}


@dataclass
class DesignResult:
    schedule: GainSchedule
    points: list = field(default_factory=list)
    settings: DesignSettings = field(default_factory=DesignSettings)

    @property
    def stabilizing(self) -> bool:
        """Every frozen-time closed loop at the design points is stable."""
        return all(np.isfinite(p.tau_max) and p.zeta_min > 0 for p in self.points)

    def as_dict(self) -> dict:
        h_max, a_max = self.schedule.max_gains()
        return {"stabilizing": self.stabilizing, "n_points": len(self.points),
                "cost": "J = ln(zeta_min) - tau_weight * ln(tau_max / 1 s); "
                        "-1000 - max Re(lambda) if unstable",
                "tau_weight": self.settings.tau_weight,
                "zeta_min": min(p.zeta_min for p in self.points),
                "tau_max_s": max(p.tau_max for p in self.points),
                "h_max": h_max.tolist(), "a_max": a_max.tolist(),
                "points": [p.as_dict() for p in self.points]}


def _evaluate(A0, Bu, G, x, nj, tau_weight):
    h, a = _unpack(x, nj)
    kp, kd = pd_gains(h, a)
    s = eigen_summary(closed_loop_matrix(A0, Bu, G, kp, kd))
    return design_cost(s, tau_weight), s


def _unpack(x, nj):
    x = np.asarray(x, float)
    if len(x) == 2:
        return np.full(nj, x[0]), np.full(nj, x[1])
    return x[0::2].copy(), x[1::2].copy()


def design_point(model: FlexArmModel, A0, Bu, settings: DesignSettings, x_prev=None):
    """Gains at one point: ``(x, summary, value, evaluations)`` (module doc)."""
    nj = model.n_links
    G = model.G

    def f(x):
        return _evaluate(A0, Bu, G, x, nj, settings.tau_weight)[0]

    hs = np.geomspace(*settings.h_bounds, settings.grid)
    as_ = np.geomspace(*settings.a_bounds, settings.grid)
    grid = [(f([h, a]), h, a) for h in hs for a in as_]
    _, h0, a0 = max(grid)
    evals = len(grid)
    n_var = 2 * nj if settings.per_joint else 2
    x0 = np.tile([h0, a0], n_var // 2)
    if x_prev is not None and f(x_prev) > f(x0):
        x0 = np.asarray(x_prev, float)
    lower = np.tile([settings.h_bounds[0], settings.a_bounds[0]], n_var // 2)
    upper = np.tile([settings.h_bounds[1], settings.a_bounds[1]], n_var // 2)
    res = cyclic_coordinate_ascent(f, x0, lower, upper, step=settings.initial_step,
                                   min_step=settings.min_step,
                                   max_evaluations=settings.max_evaluations)
    value, summary = _evaluate(A0, Bu, G, res.x, nj, settings.tau_weight)
    return res.x, summary, value, evals + res.evaluations


def design_schedule(model: FlexArmModel, trajectory: JointTrajectoryData,
                    settings: DesignSettings = DesignSettings()) -> DesignResult:
    """Design the gain schedule along ``trajectory`` (which must carry ``q_nominal``)."""
    nominal = NominalTrajectory.from_data(model, trajectory)
    times = np.linspace(nominal.t[0], nominal.t[-1], settings.n_points) \
        if settings.n_points > 1 else np.array([nominal.t[0]])
    points = []
    x_prev = None
    for t in times:
        q, v, tau, theta, _ = nominal.at(t)
        A0, Bu = open_loop_jacobian(model, q, v, tau)
        x, s, value, evals = design_point(model, A0, Bu, settings, x_prev)
        x_prev = x
        h, a = _unpack(x, model.n_links)
        points.append(PointDesign(t=float(t), theta=np.asarray(theta, float).copy(), h=h, a=a,
                                  zeta_min=s.zeta_min, tau_max=s.tau_max, cost=value,
                                  evaluations=evals))
    deflections = np.array([model.tip_deflections(nominal.at(p.t)[0]) for p in points])
    info = {"arm": model.arm.name, "law": "thesis Eq. (95)",
            "cost": "ln(zeta_min) - tau_weight ln(tau_max / 1 s)",
            "tau_weight": settings.tau_weight,
            "zeta_min": [p.zeta_min for p in points],
            "tau_max_s": [p.tau_max for p in points]}
    schedule = GainSchedule(joint_names=tuple(model.arm.joint_names),
                            theta=np.array([p.theta for p in points]),
                            h=np.array([p.h for p in points]),
                            a=np.array([p.a for p in points]),
                            t=times, deflections=deflections,
                            deflection_weight=settings.deflection_weight, info=info)
    return DesignResult(schedule=schedule, points=points, settings=settings)
