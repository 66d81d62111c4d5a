"""Spatial flexible arms (issue 25): DH description, kinematics, dynamics, modes, stepping.

No ROS; the planar model (flex_model.dynamics) is untouched.
"""
from .description import SpatialArm, from_planar, load_spatial_arm, spatial_arm_from_dict
from .dynamics import SpatialArmModel

__all__ = ["SpatialArm", "SpatialArmModel", "from_planar", "load_spatial_arm",
           "spatial_arm_from_dict"]
