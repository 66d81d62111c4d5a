"""Planner parameters and waypoint files: one source of truth for the node and the CLI.

``PlannerConfig`` holds the node's parameters with their defaults, descriptions and
validation (errors name the field, the value and what is allowed). A waypoint file is
YAML::

    # tip waypoints (m, in the arm's plane) and their times from the start (s)
    frame_id: arm_plane            # optional; must match the planner's frame
    elbow: up                      # optional: up | down
    tip_load: {force: [0.0, 0.0], torque: 0.0}   # optional known tip load (N, N m)
    waypoints:
      - {t: 0.0, x: -1.0, y: -1.0}
      - {t: 5.0, x: -2.0, y: -1.0}             # add phi (rad) for arms with >= 3 links
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flex_model.arm import load_arm
from flex_model.config import Fields, read_yaml
from flex_model.dynamics import FlexArmModel
from flex_model.statics import TipLoad

from .planning import SECTION_F_TIMES, SECTION_F_WAYPOINTS
from .rigid_kinematics import ELBOWS

#: descriptions of the PlannerConfig fields (ROS parameter descriptors, CLI help)
DESCRIPTIONS = {
    "arm": "arm preset name or arm YAML path (flex_model)",
    "vars_per_link": "deformation variables per link (even >= 2; 0 = as in the arm file)",
    "sample_period": "sample period of the published trajectory (s)",
    "elbow": "elbow branch at the first waypoint: up | down",
    "frame_id": "frame of the waypoints and of the published paths: the arm's plane "
                "(the model node's arm_plane frame, with its frame_prefix; REP 103)",
}

#: named tasks: (default arm, waypoints, times)
TASKS = {"thesis_ch5": ("thesis_example1", SECTION_F_WAYPOINTS, SECTION_F_TIMES)}


@dataclass(frozen=True)
class PlannerConfig:
    """Parameters of the planner node (and the defaults of ``flex-twin plan``)."""

    arm: str = "thesis_example1_motors"
    vars_per_link: int = 0
    sample_period: float = 1e-3
    elbow: str = "up"
    frame_id: str = "arm_plane"

    def __post_init__(self):
        if not isinstance(self.arm, str) or not self.arm:
            raise ValueError(f"arm: got {self.arm!r}; expected a preset name or a YAML path")
        if (isinstance(self.vars_per_link, bool) or not isinstance(self.vars_per_link, int)
                or self.vars_per_link < 0 or self.vars_per_link % 2):
            raise ValueError(f"vars_per_link: got {self.vars_per_link!r}; expected 0 (as in "
                             "the arm file) or an even integer >= 2")
        if not (isinstance(self.sample_period, (int, float)) and np.isfinite(self.sample_period)
                and 1e-5 <= self.sample_period <= 1.0):
            raise ValueError(f"sample_period: got {self.sample_period!r}; expected a time in "
                             "[1e-5, 1] s")
        if self.elbow not in ELBOWS:
            raise ValueError(f"elbow: got {self.elbow!r}; expected one of {', '.join(ELBOWS)}")
        if not isinstance(self.frame_id, str) or not self.frame_id:
            raise ValueError(f"frame_id: got {self.frame_id!r}; expected a non-empty frame name")

    def model(self) -> FlexArmModel:
        """The arm model these parameters name."""
        arm = load_arm(self.arm, self.vars_per_link or None)
        return FlexArmModel(arm)


@dataclass
class WaypointTask:
    """Tip waypoints (N, 2) m, times (N,) s, optional orientations (N,) rad and options."""

    name: str
    waypoints: np.ndarray
    times: np.ndarray
    orientations: np.ndarray | None = None
    elbow: str | None = None
    frame_id: str | None = None
    tip_load: TipLoad | None = None
    arm: str | None = None


def named_task(name: str) -> WaypointTask:
    """A built-in task (``thesis_ch5``: VALIDATION.md section F)."""
    if name not in TASKS:
        raise ValueError(f"task: got {name!r}; expected one of {', '.join(TASKS)}")
    arm, pts, times = TASKS[name]
    return WaypointTask(name=name, waypoints=np.array(pts), times=np.array(times), arm=arm)


def load_waypoint_file(path) -> WaypointTask:
    """Read and validate a waypoint YAML file (module docstring); errors name the file
    and the field."""
    source = str(path)
    f = Fields(read_yaml(path), source, "")
    frame_id = f.string("frame_id", None) if f.has("frame_id") else None
    elbow = f.string("elbow", choices=list(ELBOWS)) if f.has("elbow") else None
    load = None
    if f.has("tip_load"):
        lf = f.mapping("tip_load")
        load = TipLoad(tuple(lf.vector("force", 2, [0.0, 0.0], unit="N")),
                       lf.number("torque", 0.0, unit="N m"))
        lf.done()
    rows = f.items("waypoints", min_len=2)
    f.done()
    pts, times, phis = [], [], []
    for i, raw in enumerate(rows):
        wf = Fields(raw, source, f"waypoints[{i}]")
        times.append(wf.number("t", unit="s"))
        pts.append([wf.number("x", unit="m"), wf.number("y", unit="m")])
        phis.append(wf.number("phi", unit="rad") if wf.has("phi") else None)
        wf.done()
    given = [p is not None for p in phis]
    if any(given) and not all(given):
        k = given.index(False)
        raise f.error(f"waypoints[{k}].phi", "<missing>",
                      "a tip orientation (rad) on every waypoint or on none")
    orientations = np.array(phis, float) if all(given) else None
    return WaypointTask(name=getattr(path, "stem", None) or source, waypoints=np.array(pts),
                        times=np.array(times), orientations=orientations, elbow=elbow,
                        frame_id=frame_id, tip_load=load)
