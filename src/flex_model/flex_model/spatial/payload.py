"""A payload on a spatial arm (issue 25): a rigid body at the origin of the last link's
end frame, lumped into that link's ``end_body`` (parallel axes, as the URDF reader lumps
fixed links; the planar payload M+, J+ of thesis Eq. 7 is the same addition in the
plane: ``from_planar`` maps J+ to the end frame's z axis).

The payload vector of ``flex/payload`` (spatial model node) is one of

- ``[m]``: a point mass (kg);
- ``[m, J]``: mass and inertia about the end frame's z axis (kg m^2; the planar
  node's ``[mass, inertia]``, the same on an embedded planar arm);
- ``[m, Ixx, Iyy, Izz]``: principal inertias in the end frame;
- ``[m, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]``: the full inertia in the end frame,

about the payload's centre, which is the end frame's origin.
"""
from __future__ import annotations

import copy
from dataclasses import replace

import numpy as np

from .description import SpatialArm, lump_bodies

#: accepted lengths of a payload vector and their meaning
LAYOUTS = {1: "[mass]", 2: "[mass, J_z]", 4: "[mass, Ixx, Iyy, Izz]",
           7: "[mass, Ixx, Iyy, Izz, Ixy, Ixz, Iyz]"}


def payload_inertia(values) -> tuple[float, np.ndarray]:
    """(mass kg, 3 x 3 inertia kg m^2 in the end frame) of a payload vector (LAYOUTS);
    ValueError naming what is wrong (length, NaN, negative mass, inertia not positive
    semi-definite)."""
    x = np.asarray(values, float).ravel()
    if len(x) not in LAYOUTS:
        raise ValueError(f"got {len(x)} values; expected one of " + ", ".join(
            LAYOUTS.values()) + " (kg, kg m^2 in the last link's end frame)")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"got {[float(v) for v in x]}; expected finite values")
    m = float(x[0])
    if m < 0:
        raise ValueError(f"payload mass: got {m:g} kg; expected >= 0")
    I = np.zeros((3, 3))
    if len(x) == 2:
        I[2, 2] = x[1]
    elif len(x) >= 4:
        I[np.diag_indices(3)] = x[1:4]
    if len(x) == 7:
        I[0, 1] = I[1, 0] = x[4]
        I[0, 2] = I[2, 0] = x[5]
        I[1, 2] = I[2, 1] = x[6]
    scale = max(1e-30, float(np.max(np.abs(I))))
    if np.min(np.linalg.eigvalsh(I)) < -1e-12 * scale:
        raise ValueError(f"payload inertia: got {[float(v) for v in x[1:]]} kg m^2; "
                         "expected a positive semi-definite inertia")
    return m, I


def with_payload(arm: SpatialArm, mass: float, inertia=None) -> SpatialArm:
    """``arm`` with a payload (mass kg, 3 x 3 inertia about its centre, end frame) at the
    origin of the last link's end frame, lumped into its end body: on top of the arm
    file's own ``payload`` (a tool, say), which the model lumps there too. Mass 0 and no
    inertia returns ``arm`` itself (bit-identical runs)."""
    I = np.zeros((3, 3)) if inertia is None else np.asarray(inertia, float)
    if mass == 0.0 and not np.any(I):
        return arm
    last = arm.links[-1]
    e = last.end_body
    parts = [] if e.is_empty else [(e.mass, e.offset, e.inertia)]
    parts.append((float(mass), (0.0, 0.0, 0.0), I))
    links = arm.links[:-1] + (replace(last, end_body=lump_bodies(parts)),)
    return replace(arm, links=links)


def model_with_payload(model, arm: SpatialArm, mass: float, inertia=None):
    """A SpatialArmModel of ``with_payload(arm, mass, inertia)`` made from ``model`` (the
    model of ``arm`` or of ``arm`` with another payload) without rebuilding its beams:
    only the last link's end body differs (the bases, K and the joint effects are the
    same), so this is a shallow copy with that body replaced and the compiled data
    dropped (repacked on the next run, 0.3 ms). 60-100 ms less than a new model per
    payload change; equal to ``SpatialArmModel(with_payload(...))`` (test_spatial_node).
    Falls back to a new model when the model's body layout is not the expected one."""
    from .dynamics import SpatialArmModel
    new_arm = with_payload(arm, mass, inertia)
    consts = getattr(model, "_consts", None)
    if not isinstance(consts, list) or len(consts) != arm.n_links or \
            len(consts[-1]) != 3 or len(consts[-1][2]) != 2:
        return SpatialArmModel(new_arm)
    from .dynamics import combine_bodies
    pre, dh_rest, (root, _) = consts[-1]
    end = None
    for body in (new_arm.links[-1].end_body, new_arm.payload):   # as SpatialArmModel does
        if not body.is_empty:
            end = combine_bodies(end, (body.mass, np.asarray(body.offset, float),
                                       np.asarray(body.inertia, float)))
    new = copy.copy(model)
    new.arm = new_arm
    new._consts = consts[:-1] + [(pre, dh_rest, [root, end])]
    new._compiled_data = None
    return new
