"""Spatial flexible arms (issue 25): DH or URDF description, kinematics, dynamics (Python
reference and compiled), modes, stepping.

No ROS; the planar model (flex_model.dynamics) is untouched.
"""
from .description import SpatialArm, from_planar
from .loader import load_spatial_arm, spatial_arm_from_dict
from .dynamics import SpatialArmModel
from .urdf import load_urdf_arm, spatial_arm_from_urdf

__all__ = ["SpatialArm", "SpatialArmModel", "from_planar", "load_spatial_arm",
           "load_urdf_arm", "spatial_arm_from_dict", "spatial_arm_from_urdf"]
