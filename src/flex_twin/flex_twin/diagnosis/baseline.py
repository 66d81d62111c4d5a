"""The tolerance-bounded baseline: the nominal parameters free within their declared
manufacturing tolerance (issue 8, step 2).

The bending dynamics of a link depend on its section and material only through EI(z) and
m(z), so the baseline frees one relative scale of EI and one of m per link, with bounds
from the tolerances of flex_model.effects.NOMINAL_TOLERANCES (or the arm's own
``tolerances:``): for a thin-walled section (A ~ side * wall, I ~ side^3 * wall)

    |dEI / EI| <= tol_E + 4 tol_section,     |dm / m| <= tol_rho + 2 tol_section,

plus every nonzero, finite parameter of the nominal arm's own effects (e.g. the rotor
inertia of a gear) within its declared tolerance, and the payload mass within
tol_payload. A scale vector s (1 = nominal) maps to an arm with :func:`apply_scales`;
:func:`scale_raw` applies the same scales to the raw YAML mapping of the nominal arm (for
the updated arm description).
"""
from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass

import numpy as np

from flex_model.arm import ArmDescription
from . import spatial_loop


@dataclass(frozen=True)
class ScaleParameter:
    """A relative scale of a nominal quantity: ``kind`` is "EI", "m", "payload" or
    "effect"; ``index`` the link index or (effect type, target, parameter name)."""

    name: str
    kind: str
    index: object
    tolerance: float


def baseline_parameters(arm: ArmDescription) -> list[ScaleParameter]:
    """The free scales of the baseline with their relative bounds (a spatial arm:
    :func:`.spatial_loop.baseline_parameters`)."""
    if spatial_loop.is_spatial(arm):
        return spatial_loop.baseline_parameters(arm, ScaleParameter)
    tol_sec = arm.tolerance("section")
    out = []
    for i, lk in enumerate(arm.links):
        out.append(ScaleParameter(f"{lk.name}.EI", "EI", i, float(np.sqrt(
            arm.tolerance("E") ** 2 + 10 * tol_sec ** 2))))
        out.append(ScaleParameter(f"{lk.name}.m", "m", i, float(np.sqrt(
            arm.tolerance("rho") ** 2 + 2 * tol_sec ** 2))))
    for e in arm.effects:
        for p, v in zip(e.PARAMETERS, e.values):
            if p.tolerance > 0 and np.isfinite(v) and v != 0:
                out.append(ScaleParameter(f"{e.TYPE}.{e.target}.{p.name}", "effect",
                                          (e.TYPE, e.target, p.name), p.tolerance))
    if arm.payload_mass > 0:
        out.append(ScaleParameter("payload.mass", "payload", 0, arm.tolerance("payload")))
    return out


def bounds(params) -> tuple[np.ndarray, np.ndarray]:
    tol = np.array([p.tolerance for p in params])
    return 1.0 - tol, 1.0 + tol


#: a scale within this fraction of its tolerance from a bound sits at the bound
AT_BOUND = 0.02


def at_bounds(params, scales) -> list:
    """The scales a fit drove to their tolerance bound (within :data:`AT_BOUND` of the
    tolerance): [(name, scale, bound)]. A scale at its bound is evidence that the quantity
    lies outside its tolerance (issue 44), not a recalibration."""
    out = []
    for p, s in zip(params, scales):
        for b in (1.0 - p.tolerance, 1.0 + p.tolerance):
            if p.tolerance > 0 and abs(float(s) - b) <= AT_BOUND * p.tolerance:
                out.append((p.name, float(s), b))
    return out


def apply_scales(arm: ArmDescription, params, scales) -> ArmDescription:
    """The arm with the baseline scales applied."""
    if spatial_loop.is_spatial(arm):
        return spatial_loop.apply_scales(arm, params, scales)
    links = list(arm.links)
    effects = list(arm.effects)
    payload = arm.payload_mass
    ei = np.ones(len(links))
    m = np.ones(len(links))
    for p, s in zip(params, scales):
        if p.kind == "EI":
            ei[p.index] = s
        elif p.kind == "m":
            m[p.index] = s
        elif p.kind == "payload":
            payload = arm.payload_mass * s
        else:
            kind, target, name = p.index
            for k, e in enumerate(effects):
                if e.TYPE == kind and e.target == target:
                    vals = [v * s if q.name == name else v
                            for q, v in zip(e.PARAMETERS, e.values)]
                    effects[k] = dataclasses.replace(e, values=tuple(vals))
    links = [dataclasses.replace(lk, segments=tuple(sg.scaled(ei[i], m[i])
                                                    for sg in lk.segments))
             for i, lk in enumerate(links)]
    return dataclasses.replace(arm, links=tuple(links), effects=tuple(effects),
                               payload_mass=payload)


def scale_raw(raw: dict, params, scales) -> dict:
    """The raw YAML mapping of the nominal arm with the scales applied (same layout)."""
    raw = copy.deepcopy(raw)
    for p, s in zip(params, scales):
        if p.kind in ("EI", "m"):
            scale_raw_link(raw["links"][p.index], p.kind, s)
        elif p.kind == "payload":
            raw["payload"]["mass"] = float(raw["payload"]["mass"]) * float(s)
        else:
            kind, target, name = p.index
            for e in raw.get("effects", []):
                if e.get("type") == kind and target in (e.get("joint"), e.get("link"), ""):
                    e[name] = float(e.get(name, _default(kind, name))) * float(s)
    return raw


def _default(kind: str, name: str) -> float:
    """The value an effect takes for a parameter its YAML entry leaves out."""
    from flex_model.effects import EFFECT_TYPES
    return next(p.off for p in EFFECT_TYPES[kind].PARAMETERS if p.name == name)


def scale_raw_link(lk: dict, kind: str, s: float) -> None:
    """Scale a raw YAML link in place: ``kind`` "EI" (E of a material, EI of an explicit
    section) or "m" (rho, or m), on the link and on each of its segments."""
    s = float(s)
    for holder in [lk] + list(lk.get("segments", [])):
        mat = holder.get("material")
        if mat is not None:
            key = "E" if kind == "EI" else "rho"
            mat[key] = float(mat[key]) * s
        sec = holder.get("section", {})
        if sec.get("shape") == "explicit":
            key = "EI" if kind == "EI" else "m"
            val = sec[key]
            sec[key] = [float(x) * s for x in val] if isinstance(val, list) \
                else float(val) * s
