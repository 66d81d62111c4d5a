"""flex_planner: trajectory planning for the flex-twin flexible-link arm models.

The planning chain of the thesis (Ch. IV static-flexible kinematic inversion, V.1
admissible nominal input, V.3 splines) and the trajectories and residual-vibration
analysis of seed 002, as a ROS-free library; ``planner_node`` wraps it for ROS 2.
"""
import flex_model as _flex_model  # noqa: F401  (the ROS environment first)

from .inverse_statics import UnreachableError, invert_tip_pose, invert_waypoints
from .planning import SECTION_F_TIMES, SECTION_F_WAYPOINTS, plan, plan_tip_path

__all__ = ["SECTION_F_TIMES", "SECTION_F_WAYPOINTS", "UnreachableError", "invert_tip_pose",
           "invert_waypoints", "plan", "plan_tip_path"]
