"""A spatial arm from a URDF (``robot_description``) and a side YAML marking flexible links.

Only the standard library XML parser (xml.etree.ElementTree) is used. The URDF must be a
serial chain (each link has at most one child joint). Mapping:

- ``revolute`` / ``continuous`` / ``prismatic`` joints become spatial joints with their
  ``<origin xyz rpy>`` (fixed transform before the joint motion; rpy = URDF fixed-axis
  roll-pitch-yaw, R = Rz(y) Ry(p) Rx(r)) and their ``<axis>`` (any unit direction, URDF
  default 1 0 0); ``<limit lower upper effort velocity>`` are kept on the joint
  (``continuous``: no position limits; absent values are infinite). Effort limits are
  honoured by the compiled fixed-step loop (it clips the joint torques; the same clip for
  Python callers: ``limits.clip_efforts``), the others reported by ``limit_violations``; the
  position limits become end stops with the side YAML's ``joint_stops: {stiffness,
  damping, transition}`` (description.JointStops), else they are only reported.
- ``fixed`` joints are merged: their origin composes into the next moving joint's origin
  (or, after the last moving joint, into the last link's ``end_transform``, e.g. the tool
  frame), and the child link's inertial is lumped into the moving link it hangs on.
- A rigid link keeps its ``<inertial>`` (mass, origin, 3 x 3 inertia rotated by the origin
  rpy) as a rigid body in the link frame. The root link (no parent) is the fixed base: its
  inertial is ignored.
- A link named under ``flexible_links`` in the side YAML becomes a flexible beam along
  **the link frame's x axis** from the link origin (placement ``link_x``): bending v
  along y (``EI_z``), w along z (``EI_y``), twist about x (``GJ``, ``rhoJ``), the wavelet
  basis of thesis Ch. II. Its length defaults to the x coordinate of the next joint's
  origin. Everything beyond (child joint origins, merged fixed links) is fixed to the tip
  section: the link's end frame is the tip frame E (seed 000 Eq. 19: at (L, v, w), rotated
  by Ry(-w') Rz(v') Rx(phi)) and the URDF's transforms from the link frame are applied
  after Trans_x(-L) (the rigid limit is the URDF's kinematics). ``end_body`` of the side
  YAML is in the tip frame. The URDF
  ``<inertial>`` of a flexible link is **ignored** (the section's rhoA gives the beam's
  mass; ``root_body`` / ``end_body`` in the side YAML add motors, flanges).

- A link carrying a ``<flex:flexible>`` extension element (namespace :data:`FLEX_NS`,
  declared on ``<robot>``: ``xmlns:flex="urn:flex-arm-twin:urdf:1"``; URDF parsers
  ignore unknown link children) is flexible with the same data as the side YAML's
  entry (:func:`flexible_from_element`)::

    <link name="forearm_link">
      <flex:flexible length="0.39225" variables="4" torsion_variables="4">
        <flex:section EI_y="6090" EI_z="6090" GJ="4520" rhoA="0.814" rhoJ="4.7e-4"/>
        <flex:root_body mass="1.2" inertia="0.0018 0.00125 0.0018"/>
        <flex:end_body mass="0.756" offset="0 0 0" inertia="0.0008 0.0008 0.0008"/>
      </flex:flexible>
    </link>

  ``length`` optional as in the YAML; a section value is a number or "root tip" (a
  linear taper); several ``<flex:section length="..">`` are segments, root first;
  ``inertia`` 3 diagonal or 9 row-major values. Errors name the URDF, the element path
  (``robot/link[@name='forearm_link']/flex:flexible/flex:section[1]/@EI_y``), the value
  and what is allowed. A link made flexible both by its element and by the side YAML is
  **refused** (no silent precedence: the error names both files); a ``<flexible>``
  child without the namespace is refused too (it would otherwise be ignored).

Side YAML (a spatial preset with a ``urdf`` key; paths relative to the YAML)::

    name: ur5_like_flexible_forearm
    urdf: ur5_like.urdf
    gravity: [0, 0, -9.81]
    flexible_links:
      forearm_link:
        length: 0.39225          # optional (default: x of the next joint origin)
        section: {EI_y: 1.8e4, EI_z: 1.8e4, GJ: 1.3e4, rhoA: 1.53, rhoJ: 1.4e-3}
        variables: 4             # per bending plane; torsion_variables as in YAML arms
        root_body: {mass: 1.0}
        end_body: {mass: 0.5}
    joint_stops: {stiffness: 1.0e5, damping: 100.0}   # optional: the URDF limits as stops
    effects: [{type: gear, joint: shoulder_pan_joint, ratio: 100, rotor_inertia: 1e-4}]
    payload: {mass: 1.0}          # optional, as in a DH arm file; sensors: [...] too

``effects``, ``payload`` and ``sensors`` are the DH arm file's (description.py: the same
fields, checks and models; an elastic gear is a ``joint_elasticity`` effect on the joint).
"""
from __future__ import annotations

import dataclasses
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from ..config import ConfigError, Fields
from .description import (RigidBody, SpatialArm, SpatialJoint, SpatialLink, rigid_body,
                          joint_effects, flexible_beam, lump_bodies, parse_joint_stops)
from .kinematics import rpy_matrix

#: XML namespace of the flexible-link extension element ``<flex:flexible>`` in a <link>
FLEX_NS = "urn:flex-arm-twin:urdf:1"
MOVING = ("revolute", "continuous", "prismatic")
JOINT_KINDS = MOVING + ("fixed",)


class _Urdf:
    """Error helper: every error names the file and the element (tag and name)."""

    def __init__(self, source: str):
        self.source = source

    def error(self, elem_path: str, value, allowed: str) -> ConfigError:
        return ConfigError(self.source, elem_path, value, allowed)

    def floats(self, el, attr: str, n: int, default, where: str):
        raw = el.get(attr) if el is not None else None
        if raw is None:
            return np.array(default, float)
        try:
            vals = np.array([float(x) for x in raw.split()], float)
        except ValueError:
            raise self.error(f"{where}/@{attr}", raw, f"{n} numbers") from None
        if len(vals) != n or not np.all(np.isfinite(vals)):
            raise self.error(f"{where}/@{attr}", raw, f"{n} finite numbers")
        return vals

    def number(self, el, attr: str, where: str, default=None, nonnegative=False):
        raw = el.get(attr)
        if raw is None:
            if default is None:
                raise self.error(f"{where}/@{attr}", None, "a number")
            return default
        try:
            val = float(raw)
        except ValueError:
            raise self.error(f"{where}/@{attr}", raw, "a number") from None
        if not np.isfinite(val) or (nonnegative and val < 0):
            raise self.error(f"{where}/@{attr}", raw,
                             "a finite number" + (" >= 0" if nonnegative else ""))
        return val

    def origin(self, parent, where: str):
        el = parent.find("origin")
        xyz = self.floats(el, "xyz", 3, [0.0, 0.0, 0.0], f"{where}/origin")
        rpy = self.floats(el, "rpy", 3, [0.0, 0.0, 0.0], f"{where}/origin")
        return rpy_matrix(rpy), xyz


def _compose(A, B):
    return A[0] @ B[0], A[0] @ B[1] + A[1]


def _inverse(A):
    return A[0].T, -A[0].T @ A[1]


def _inertial(u: _Urdf, link, where: str):
    """(m, c, I_c) of a URDF link's <inertial> in the link frame, or None."""
    el = link.find("inertial")
    if el is None:
        return None
    R, c = u.origin(el, f"{where}/inertial")
    mel = el.find("mass")
    m = 0.0 if mel is None else u.number(mel, "value", f"{where}/inertial/mass",
                                         nonnegative=True)
    iel = el.find("inertia")
    I = np.zeros((3, 3))
    if iel is not None:
        w = f"{where}/inertial/inertia"
        ixx, iyy, izz = (u.number(iel, a, w, 0.0) for a in ("ixx", "iyy", "izz"))
        ixy, ixz, iyz = (u.number(iel, a, w, 0.0) for a in ("ixy", "ixz", "iyz"))
        I = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        if np.min(np.linalg.eigvalsh(I)) < -1e-12 * max(1e-30, np.max(np.abs(I))):
            raise u.error(w, [ixx, iyy, izz, ixy, ixz, iyz],
                          "a positive semi-definite inertia (kg m^2)")
    return m, c, R @ I @ R.T


def _flexible(f: Fields, default_length, link_name: str, u: _Urdf):
    if f.has("length"):
        length = f.number("length", positive=True, unit="m")
    else:
        if default_length is None or default_length <= 0:
            raise ConfigError(f.source, f.path + ".length", default_length,
                              f"a beam length > 0 (m): link '{link_name}' has no child joint "
                              "whose origin x gives it")
        length = float(default_length)
    beam = flexible_beam(f, length, "link_x")
    root = rigid_body(f.mapping("root_body")) if f.has("root_body") else RigidBody()
    end = rigid_body(f.mapping("end_body")) if f.has("end_body") else RigidBody()
    f.done(["length", "section", "variables", "torsion_variables", "rotary_inertia",
            "root_body", "end_body"])
    return beam, root, end


_FLEX = f"{{{FLEX_NS}}}"
#: attributes of the extension elements (as the side YAML's keys)
_FLEX_ATTRS = {"flexible": ("length", "variables", "torsion_variables"),
               "section": ("length", "EI_y", "EI_z", "GJ", "rhoA", "rhoJ"),
               "root_body": ("mass", "offset", "inertia"),
               "end_body": ("mass", "offset", "inertia")}


def _xml_path(base: str, path: str) -> str:
    """A Fields path of :func:`flexible_from_element`'s mapping as the element path:
    ``base.section[0].EI_y`` -> ``base/flex:section[1]/@EI_y`` (XPath counts from 1)."""
    rest = path[len(base):] if path.startswith(base) else path
    parts = [x for x in rest.split(".") if x]
    out = []
    for i, part in enumerate(parts):
        m = re.fullmatch(r"(\w+)\[(\d+)\]", part)
        if m:
            out.append(f"flex:{m.group(1)}[{int(m.group(2)) + 1}]")
        elif part == "section" and i < len(parts) - 1:   # the one section
            out.append("flex:section[1]")
        elif part in ("section", "root_body", "end_body"):
            out.append(f"flex:{part}")
        else:
            out.append(f"@{part}")
    return "/".join([base] + out)


def flexible_from_element(u: "_Urdf", link, where: str) -> dict | None:
    """The side-YAML mapping of a link's ``<flex:flexible>`` element (None without one):
    attribute values as numbers (a space-separated list: a list of numbers), sections
    under ``section`` (a mapping, or a list of segments when there are several or one
    has a ``length``), ``root_body`` / ``end_body``."""
    plain = link.find("flexible")
    if plain is not None:
        raise u.error(f"{where}/flexible", "<flexible>", f"<flex:flexible> with "
                      f'xmlns:flex="{FLEX_NS}" declared on <robot> (an element without '
                      "the namespace is not read)")
    els = link.findall(_FLEX + "flexible")
    if not els:
        return None
    base = f"{where}/flex:flexible"
    if len(els) > 1:
        raise u.error(base, len(els), "one <flex:flexible> element per link")
    el = els[0]

    def attrs(e, kind: str, path: str) -> dict:
        unknown = sorted(set(e.attrib) - set(_FLEX_ATTRS[kind]))
        if unknown:
            raise u.error(f"{path}/@{unknown[0]}", e.get(unknown[0]),
                          "one of the attributes " + ", ".join(_FLEX_ATTRS[kind]))
        out = {}
        for key, raw in e.attrib.items():
            try:
                vals = [float(x) for x in raw.split()]
            except ValueError:
                raise u.error(f"{path}/@{key}", raw, "a number or space-separated numbers") \
                    from None
            if not vals:
                raise u.error(f"{path}/@{key}", raw, "a number or space-separated numbers")
            if key in ("variables", "torsion_variables"):
                if len(vals) != 1 or not vals[0].is_integer():
                    raise u.error(f"{path}/@{key}", raw, "an integer")
                out[key] = int(vals[0])
            elif key in ("offset", "inertia"):
                out[key] = vals if key == "offset" or len(vals) == 3 else \
                    [vals[0:3], vals[3:6], vals[6:9]] if len(vals) == 9 else vals
            else:
                out[key] = vals[0] if len(vals) == 1 else vals
        return out

    data = attrs(el, "flexible", base)
    sections = []
    for child in el:
        tag = child.tag[len(_FLEX):] if child.tag.startswith(_FLEX) else None
        if tag not in ("section", "root_body", "end_body"):
            shown = child.tag.replace(_FLEX, "flex:")
            raise u.error(f"{base}/{shown}", shown, "<flex:section>, "
                          "<flex:root_body> or <flex:end_body> children")
        if tag == "section":
            sections.append(attrs(child, tag, f"{base}/flex:section[{len(sections) + 1}]"))
        elif tag in data:
            raise u.error(f"{base}/flex:{tag}", tag, f"at most one <flex:{tag}>")
        else:
            data[tag] = attrs(child, tag, f"{base}/flex:{tag}")
    if not sections:
        raise u.error(f"{base}/flex:section", None, "a <flex:section EI_y EI_z GJ rhoA "
                      "[rhoJ]> child (several with a length each: segments, root first)")
    data["section"] = sections if len(sections) > 1 or "length" in sections[0] \
        else sections[0]
    return data


def _serial_tree(u: _Urdf, robot) -> tuple:
    """The URDF's links by name, its joints, each link's child joint and the root link;
    refuses anything but one serial chain."""
    links = {}
    for el in robot.findall("link"):
        nm = el.get("name")
        if not nm:
            raise u.error("robot/link", None, "a link with a name attribute")
        if nm in links:
            raise u.error(f"robot/link[@name='{nm}']", nm, "unique link names")
        links[nm] = el
    joints, child_of = [], {}
    for el in robot.findall("joint"):
        nm = el.get("name")
        where = f"robot/joint[@name='{nm}']"
        if not nm:
            raise u.error("robot/joint", None, "a joint with a name attribute")
        kind = el.get("type")
        if kind not in JOINT_KINDS:
            raise u.error(f"{where}/@type", kind, " | ".join(JOINT_KINDS) +
                          " (the spatial core has no floating or planar joints)")
        parent, child = el.find("parent"), el.find("child")
        pl = parent.get("link") if parent is not None else None
        cl = child.get("link") if child is not None else None
        for tag, ln in (("parent", pl), ("child", cl)):
            if ln not in links:
                raise u.error(f"{where}/{tag}/@link", ln,
                              "the name of a <link> of this robot: " + ", ".join(links))
        if cl in child_of:
            raise u.error(f"{where}/child/@link", cl, "a link that is the child of one joint")
        child_of[cl] = el
        joints.append(el)
    roots = [ln for ln in links if ln not in child_of]
    if len(roots) != 1:
        raise u.error("robot", roots, "exactly one root link (a connected serial chain)")
    children = {}
    for el in joints:
        pl = el.find("parent").get("link")
        if pl in children:
            raise u.error(f"robot/joint[@name='{el.get('name')}']/parent/@link", pl,
                          f"a serial chain: link '{pl}' already has the child joint "
                          f"'{children[pl].get('name')}'")
        children[pl] = el
    return links, joints, children, roots[0]


def _flexible_links(u: _Urdf, links: dict, flexible_links: dict | None, side: str) -> tuple:
    """The flexible data per link name, from the side file and the <flex:flexible> elements
    (a link in both is refused), and the element path of those given in the URDF."""
    source = u.source
    flex = dict(flexible_links or {})
    for ln in flex:
        if ln not in links:
            raise ConfigError(side, f"flexible_links.{ln}", ln,
                              "the name of a <link> of the URDF: " + ", ".join(links))
    # <flex:flexible> extension elements: the same mapping, errors named in the URDF
    from_element = {}     # link name -> element path
    for ln, el in links.items():
        where = f"robot/link[@name='{ln}']"
        data = flexible_from_element(u, el, where)
        if data is None:
            continue
        if ln in flex:
            raise ConfigError(side, f"flexible_links.{ln}", ln,
                              f"a link not also made flexible by its <flex:flexible> "
                              f"element in {source} (conflicts are refused: keep one)")
        flex[ln] = data
        from_element[ln] = f"{where}/flex:flexible"

    return flex, from_element


def _moving_links(u: _Urdf, links: dict, children: dict, root: str, joints: list,
                  flex: dict, from_element: dict, side: str) -> tuple:
    """Walk the chain from the root: per moving joint its joint, origin (fixed joints folded
    in), bodies and flexible data; and the fixed transform after the last one (or None)."""
    source = u.source
    eye = (np.eye(3), np.zeros(3))
    acc = eye                 # fixed transform from the current moving link's end frame
    out = []                  # per moving link: dict of its data
    link = root
    while link in children:
        el = children[link]
        jn, kind = el.get("name"), el.get("type")
        where = f"robot/joint[@name='{jn}']"
        origin = u.origin(el, where)
        child = el.find("child").get("link")
        cwhere = f"robot/link[@name='{child}']"
        if kind == "fixed":
            acc = _compose(acc, origin)
            if out:
                inert = _inertial(u, links[child], cwhere)
                if inert is not None:
                    m, c, I = inert
                    out[-1]["bodies"].append((m, acc[0] @ c + acc[1], acc[0] @ I @ acc[0].T))
            if child in flex:
                raise ConfigError(source if child in from_element else side,
                                  from_element.get(child, f"flexible_links.{child}"), child,
                                  "a link moved by a revolute, continuous or prismatic joint "
                                  f"(it hangs on the fixed joint '{jn}')")
            link = child
            continue
        if out and out[-1]["flex"] is not None and out[-1]["default_length"] is None:
            out[-1]["default_length"] = float((_compose(acc, origin))[1][0])
        axis = u.floats(el.find("axis"), "xyz", 3, [1.0, 0.0, 0.0], f"{where}/axis")
        nrm = float(np.linalg.norm(axis))
        if nrm < 1e-12:
            raise u.error(f"{where}/axis/@xyz", el.find("axis").get("xyz"), "a non-zero axis")
        lim = el.find("limit")
        lower, upper, effort, velocity = -np.inf, np.inf, np.inf, np.inf
        if lim is not None:
            lw = f"{where}/limit"
            effort = u.number(lim, "effort", lw, np.inf, nonnegative=True)
            velocity = u.number(lim, "velocity", lw, np.inf, nonnegative=True)
            if kind != "continuous":
                lower = u.number(lim, "lower", lw, -np.inf)
                upper = u.number(lim, "upper", lw, np.inf)
                if lower > upper:
                    raise u.error(f"{lw}/@lower", lower, f"lower <= upper ({upper})")
        joint = SpatialJoint(name=jn, type="prismatic" if kind == "prismatic" else "revolute",
                             axis=tuple(axis / nrm), lower=lower, upper=upper, effort=effort,
                             velocity=velocity)
        origin = _compose(acc, origin)
        acc = eye
        bodies = []
        if child not in flex:
            inert = _inertial(u, links[child], cwhere)
            if inert is not None:
                bodies.append(inert)
        out.append({"name": child, "joint": joint, "origin": origin, "bodies": bodies,
                    "flex": flex.get(child), "default_length": None})
        link = child
    if not out:
        raise u.error("robot", [j.get("name") for j in joints],
                      "at least one revolute, continuous or prismatic joint")
    end_last = None if np.allclose(acc[0], np.eye(3), atol=0) and not np.any(acc[1]) else acc

    return out, end_last


def _spatial_links(u: _Urdf, out: list, end_last, from_element: dict, side: str) -> list:
    """The SpatialLinks: a flexible link's end frame is its tip section frame, so what the
    URDF places in the link frame moves by Trans_x(-L) (into the next origin)."""
    source, eye = u.source, (np.eye(3), np.zeros(3))
    result = []
    shift_next = None         # Trans_x(-L) of a flexible link, moved into the next origin
    for i, d in enumerate(out):
        end_tf = end_last if i == len(out) - 1 else None
        origin = d["origin"] if shift_next is None else _compose(shift_next, d["origin"])
        shift_next = None
        if d["flex"] is not None:
            elem = from_element.get(d["name"])
            f = Fields(d["flex"], side, f"flexible_links.{d['name']}") if elem is None \
                else Fields(d["flex"], source, elem)
            dl = d["default_length"]
            if dl is None and end_tf is not None:
                dl = float(end_tf[1][0])
            try:
                beam, root, end = _flexible(f, dl, d["name"], u)
            except ConfigError as exc:
                if elem is None or exc.source != source:
                    raise
                raise ConfigError(source, _xml_path(elem, exc.path), exc.value,
                                  exc.allowed) from None
            # the end frame of a link_x beam is its tip section frame; what the URDF places
            # in the link frame is moved by Trans_x(-L)
            shift = (np.eye(3), np.array([-beam.length, 0.0, 0.0]))
            d["bodies"] = [(m, c + shift[1], I) for m, c, I in d["bodies"]]
            if i == len(out) - 1:
                end_tf = _compose(shift, end_tf if end_tf is not None else eye)
            else:
                shift_next = shift
        to_end = eye if end_tf is None else _inverse(end_tf)
        if d["flex"] is None:
            beam, root, end = None, RigidBody(), RigidBody()
        if d["flex"] is not None:
            parts = [(end.mass, to_end[0] @ np.asarray(end.offset, float) + to_end[1],
                      to_end[0] @ np.asarray(end.inertia, float) @ to_end[0].T)] \
                if not end.is_empty else []
            # end_body of the side file is given in the tip section frame
            parts += [(m, to_end[0] @ c + to_end[1], to_end[0] @ I @ to_end[0].T)
                      for m, c, I in d["bodies"]]
            end = lump_bodies(parts) if parts else RigidBody()
        else:
            if d["bodies"]:
                root = lump_bodies(d["bodies"])
        tf = None if end_tf is None else (tuple(map(tuple, end_tf[0])), tuple(end_tf[1]))
        result.append(SpatialLink(
            name=d["name"], joint=d["joint"], flexible=beam, root_body=root, end_body=end,
            origin=(tuple(map(tuple, origin[0])), tuple(origin[1])),
            end_transform=tf))
    return result


def spatial_arm_from_urdf(text: str, source: str = "<robot_description>", *,
                          flexible_links: dict | None = None, name: str | None = None,
                          gravity=(0.0, 0.0, -9.81), side_source: str | None = None,
                          description: str = "") -> SpatialArm:
    """A SpatialArm from URDF text (``robot_description``); ``flexible_links`` maps link
    names to their flexible data (the side YAML's ``flexible_links``)."""
    u = _Urdf(source)
    try:
        robot = ET.fromstring(text)
    except ET.ParseError as exc:
        raise u.error("xml", str(exc), "well-formed URDF XML") from None
    if robot.tag != "robot":
        raise u.error("/", f"<{robot.tag}>", "a <robot> root element")
    links, joints, children, root = _serial_tree(u, robot)
    flex, from_element = _flexible_links(u, links, flexible_links, side_source or source)
    out, end_last = _moving_links(u, links, children, root, joints, flex, from_element,
                                  side_source or source)
    result = _spatial_links(u, out, end_last, from_element, side_source or source)
    return SpatialArm(name=name or robot.get("name", "urdf_arm"), links=tuple(result),
                      gravity=tuple(float(g) for g in gravity), description=description,
                      source=source, convention="urdf")


def spatial_arm_from_side_file(data: dict, source: str) -> SpatialArm:
    """A spatial preset with a ``urdf`` key: the URDF path (relative to the YAML) and the
    flexible links (see the module docstring)."""
    f = Fields(data, source, "")
    name = f.string("name")
    description = f.string("description", "")
    rel = f.string("urdf")
    gravity = tuple(f.vector("gravity", 3, [0.0, 0.0, -9.81], unit="m/s^2"))
    flex = f.raw("flexible_links", {}) or {}
    if not isinstance(flex, dict) or not all(isinstance(v, dict) for v in flex.values()):
        raise f.error("flexible_links", flex, "a mapping: link name -> flexible data")
    path = Path(rel)
    if not path.is_absolute():
        path = Path(source).resolve().parent / path
    if not path.is_file():
        raise f.error("urdf", rel, f"an existing URDF file (looked for {path})")
    arm = spatial_arm_from_urdf(path.read_text(), str(path), flexible_links=flex, name=name,
                                gravity=gravity, side_source=source, description=description)
    stops = parse_joint_stops(f, arm.links, source)
    # the DH file's effects, payload and sensors (its fields and checks); a URDF joint has
    # no gear option: an elastic gear is a joint_elasticity effect on it
    links = [dataclasses.replace(lk, joint=dataclasses.replace(lk.joint, gear=""))
             for lk in arm.links]
    effects, links = joint_effects(f, links, source)
    payload = rigid_body(f.mapping("payload")) if f.has("payload") else RigidBody()
    from .sensors import parse_sensors
    sensors = parse_sensors(f.items("sensors", []), source, arm.joint_names,
                            [lk.name for lk in links]) if f.has("sensors") else ()
    f.done(["name", "description", "urdf", "gravity", "flexible_links", "convention",
            "joint_stops", "effects", "payload", "sensors"])
    return dataclasses.replace(arm, links=tuple(links), effects=effects, payload=payload,
                               sensors=sensors, joint_stops=stops)


def load_urdf_arm(urdf_path, flexible_links: dict | None = None, **kw) -> SpatialArm:
    """Read a URDF file (and the flexible links' data) into a SpatialArm."""
    path = Path(urdf_path)
    return spatial_arm_from_urdf(path.read_text(), str(path), flexible_links=flexible_links,
                                 **kw)
