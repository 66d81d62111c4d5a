"""Reading a spatial arm: a DH table (:mod:`.description`) or a URDF side file (:mod:`.urdf`),
by path, preset name or parsed mapping."""
from __future__ import annotations

from ..config import read_yaml
from .description import SPATIAL_PRESET_DIR, SpatialArm, dh_arm_from_dict
from .urdf import spatial_arm_from_side_file


def spatial_arm_from_dict(data: dict, source: str = "<memory>") -> SpatialArm:
    """Validate a parsed spatial arm description; errors name ``source`` and the field.
    A description with a ``urdf`` key is a URDF side file, any other a DH table."""
    if isinstance(data, dict) and "urdf" in data:
        return spatial_arm_from_side_file(data, source)
    return dh_arm_from_dict(data, source)


def load_spatial_arm(name_or_path) -> SpatialArm:
    """Load a spatial arm by path or preset name (flex_model/presets/spatial/<name>.yaml)."""
    from ..arm import resolve_preset
    path = resolve_preset(name_or_path, SPATIAL_PRESET_DIR)
    return spatial_arm_from_dict(read_yaml(path), str(path))
