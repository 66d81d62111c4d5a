"""The arm as a ROS robot description (URDF) and its frames, in plain Python (no ROS).

REP 103 (z up): the arm moves in the plane of its frame ``arm_plane`` (x, y of the model,
joint axes along its z). With gravity the plane is vertical: ``arm_plane`` is turned so that
-gravity is the base frame's +z (gravity (0, -g), the usual case: plane x -> base x, plane
y -> base z, joint axes along base -y; the arm moves in the base's x-z plane). Without
gravity the plane is the base's x-y plane (horizontal arm, joint axes along +z).

Frames (``prefix`` before every frame, i.e. link, name; joint names stay as in the arm
file, as robot_state_publisher's frame_prefix leaves them, so that the URDF's joints are
those of /joint_states; a namespace per arm keeps two arms apart): ``base_link`` (the
root, REP 105's robot base) -> ``arm_plane`` (fixed) -> per link i: ``<link>`` (root
frame: origin at joint i, x along the link's root tangent; continuous joint ``<joint>``
about z at the joint angle theta_i: the model has no end stops) ->
``<link>_tip`` (the deflected tip: origin at the tip point, x along the tip tangent; a fixed
joint in the URDF at the undeformed tip (L_i, 0, 0)) -> the next link's joint. The joint
angle of link i+1 is measured from link i's tip tangent (thesis Eq. 12,
``theta = alpha_i - alpha_{i-1} - gamma_{i-1}``), so chaining the transforms of
:func:`arm_transforms` gives every tip exactly where :meth:`FlexArmModel.link_origins` and
:meth:`FlexArmModel.tip_pose` put it.

Inertial data (thesis Eqs. 7, 26): the URDF link ``<link>`` carries the beam and the root
body (M-, J-: mass M- + int m dz, centre of mass at int z m dz / mass, Izz about it from
J- + int z^2 m dz), ``<link>_tip`` the tip body (M+, J+; the last also the payload). Their
masses add up to :attr:`FlexArmModel.total_mass`. Iyy = Izz (a beam bending about either
axis), Ixx that of a solid box of the section's outer size.

Geared motors (``gear`` effect: ratio n, rotor inertia J_r; seed 000 Eq. 35): a
``<transmission>`` (SimpleTransmission, actuator ``<joint>_motor`` with
``mechanicalReduction`` n) and, on a rigid joint, the rotor as a link ``<link>_rotor``
(massless, Izz = J_r) on a continuous joint ``<joint>_rotor_joint`` that mimics the joint
with multiplier n, on the joint's parent frame (the stator): its kinetic energy
1/2 J_r (n theta_i' + Omega_stator)^2 is the gear's term J_r c c^T of B(q) exactly
(n^2 J_r reflected to the joint: 0.5 kg m^2 on thesis_example1_motors). An elastic joint's
rotor turns with its motor coordinate, which a URDF cannot express: there only the
transmission.
"""
from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np

from .dynamics import FlexArmModel


@dataclass(frozen=True)
class Transform:
    """A parent -> child transform: translation (m) and rotation quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple
    rotation: tuple


@dataclass(frozen=True)
class Frames:
    """Frame names of an arm (``prefix`` applied) and its joint names (without)."""

    base: str
    plane: str
    links: tuple
    tips: tuple
    joints: tuple

    @classmethod
    def of(cls, model: FlexArmModel, prefix: str = "", base: str = "base_link") -> "Frames":
        arm = model.arm
        return cls(base=prefix + base, plane=prefix + "arm_plane",
                   links=tuple(prefix + lk.name for lk in arm.links),
                   tips=tuple(prefix + lk.name + "_tip" for lk in arm.links),
                   joints=tuple(arm.joint_names))


def plane_rotation(gravity) -> np.ndarray:
    """R (3 x 3): base-frame coordinates of the arm plane's axes (columns), REP 103 z up:
    -gravity (a 2-vector in the plane) along +z; no gravity: the identity (horizontal)."""
    g = np.asarray(gravity, float)[:2]
    norm = float(np.hypot(*g))
    if norm == 0.0:
        return np.eye(3)
    ux, uy = -g / norm                     # "up" in plane coordinates
    e = np.array([[uy, ux, 0.0], [-ux, uy, 0.0], [0.0, 0.0, 1.0]])  # columns e, u, z_p
    w = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # their images
    return w @ e.T


def plane_rpy(gravity) -> tuple:
    """Fixed-axis roll, pitch, yaw (URDF ``rpy``) of :func:`plane_rotation`."""
    return rpy_from_matrix(plane_rotation(gravity))


def rpy_from_matrix(r) -> tuple:
    """URDF rpy (R = Rz(yaw) Ry(pitch) Rx(roll)) of a rotation matrix."""
    r = np.asarray(r, float)
    pitch = math.asin(max(-1.0, min(1.0, -r[2, 0])))
    if abs(r[2, 0]) < 1.0 - 1e-12:
        roll = math.atan2(r[2, 1], r[2, 2])
        yaw = math.atan2(r[1, 0], r[0, 0])
    else:  # gimbal lock: yaw 0
        roll, yaw = math.atan2(-r[1, 2], r[1, 1]), 0.0
    return roll, pitch, yaw


def quaternion_from_matrix(r) -> tuple:
    """(x, y, z, w) of a rotation matrix (w >= 0)."""
    r = np.asarray(r, float)
    tr = float(np.trace(r))
    if tr > 0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = ((r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s, (r[1, 0] - r[0, 1]) / s,
             0.25 * s)
    else:
        k = int(np.argmax(np.diag(r)))
        i, j = (k + 1) % 3, (k + 2) % 3
        s = 2.0 * math.sqrt(1.0 + r[k, k] - r[i, i] - r[j, j])
        v = [0.0, 0.0, 0.0]
        v[k] = 0.25 * s
        v[i] = (r[i, k] + r[k, i]) / s
        v[j] = (r[j, k] + r[k, j]) / s
        q = (*v, (r[j, i] - r[i, j]) / s)
    if q[3] < 0:
        q = tuple(-c for c in q)
    return tuple(float(c) for c in q)


def matrix_from_quaternion(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def yaw_quaternion(angle: float) -> tuple:
    """(x, y, z, w) of a rotation by ``angle`` (rad) about z."""
    return 0.0, 0.0, math.sin(angle / 2.0), math.cos(angle / 2.0)


@dataclass(frozen=True)
class Rotor:
    """A geared motor's rotor on a rigid joint (module docstring): joint index, ratio n,
    rotor inertia J_r (kg m^2)."""

    joint: int
    ratio: float
    inertia: float


def gears(model: FlexArmModel) -> list:
    """Per joint the ``gear`` effect (ratio, rotor inertia, rigid joint) or None."""
    out = []
    for i, name in enumerate(model.arm.joint_names):
        e = model.arm.effect("gear", name)
        elastic = model.arm.effect("joint_elasticity", name)
        out.append(None if e is None else (float(e["ratio"]), float(e["rotor_inertia"]),
                                           elastic is None or elastic.is_off))
    return out


def rotors(model: FlexArmModel) -> list[Rotor]:
    """The rotors a URDF can carry: geared rigid joints with a rotor inertia."""
    return [Rotor(i, g[0], g[1]) for i, g in enumerate(gears(model))
            if g is not None and g[2] and g[1] > 0.0]


def static_transforms(model: FlexArmModel, frames: Frames) -> list[Transform]:
    """The fixed base -> arm_plane transform (/tf_static)."""
    return [Transform(frames.base, frames.plane, (0.0, 0.0, 0.0),
                      quaternion_from_matrix(plane_rotation(model.gravity)))]


def arm_transforms(model: FlexArmModel, q, frames: Frames) -> list[Transform]:
    """The moving transforms at state q (/tf): per link i, its joint (previous tip or
    arm_plane -> link root: rotation theta_i about z) and its deflected tip (root -> tip:
    the tip point in the root frame, rotation gamma_i); then the motors' rotors
    (:func:`rotors`: the joint's parent -> ``<link>_rotor``, rotation n theta_i)."""
    moving = ArmTransforms(model, frames)
    return [Transform(parent, child, tuple(row[:3].tolist()), tuple(row[3:].tolist()))
            for (parent, child), row in zip(moving.pairs, moving.values(q))]


class ArmTransforms:
    """The transforms of :func:`arm_transforms` as numbers (the model node's /tf): their
    (parent, child) frames once, per state an (N, 7) array of translation x, y, z and
    rotation x, y, z, w (the same arithmetic; no Transform objects per publication)."""

    def __init__(self, model: FlexArmModel, frames: Frames):
        self.model = model
        self.rotors = [(r.joint, r.ratio) for r in rotors(model)]
        n = model.n_links
        self.pairs = []
        for i in range(n):
            parent = frames.plane if i == 0 else frames.tips[i - 1]
            self.pairs += [(parent, frames.links[i]), (frames.links[i], frames.tips[i])]
        for joint, _ in self.rotors:
            parent = frames.plane if joint == 0 else frames.tips[joint - 1]
            self.pairs.append((parent, frames.links[joint] + "_rotor"))
        self._alpha = [model.alpha_index(i) for i in range(n)]
        self._tip_rotation = model.tip_rotation_matrix()
        self._rows = np.zeros((len(self.pairs), 7))

    def values(self, q, origins=None) -> np.ndarray:
        """(N, 7) at state q (``origins``: model.link_origins(q) if known); a view of one
        array, overwritten by the next call."""
        m, out = self.model, self._rows
        q = np.asarray(q, float)
        org = m.link_origins(q) if origins is None else origins
        theta = m.joint_angles(q).tolist()
        gamma = (self._tip_rotation @ q).tolist()
        for i, alpha in enumerate(self._alpha):
            out[2 * i, 5:] = math.sin(theta[i] / 2.0), math.cos(theta[i] / 2.0)
            a = float(q[alpha])
            dx, dy = org[i + 1] - org[i]
            c, s = math.cos(a), math.sin(a)
            out[2 * i + 1, :2] = c * dx + s * dy, -s * dx + c * dy
            out[2 * i + 1, 5:] = math.sin(gamma[i] / 2.0), math.cos(gamma[i] / 2.0)
        for k, (joint, ratio) in enumerate(self.rotors, start=2 * len(self._alpha)):
            angle = ratio * theta[joint]
            out[k, 5:] = math.sin(angle / 2.0), math.cos(angle / 2.0)
        return out


def plane_to_base(rotation, points) -> np.ndarray:
    """Plane points (N, 2) (model x, y) in base-frame coordinates (N, 3), REP 103;
    ``rotation`` is :func:`plane_rotation` of the arm's gravity."""
    p = np.asarray(points, float)
    return np.column_stack([p, np.zeros(len(p))]) @ rotation.T


def base_to_plane(rotation, points) -> np.ndarray:
    """Base-frame points (N, 3) in plane coordinates (N, 2): the inverse of
    :func:`plane_to_base` (the model node's flex/tip_pose and flex/shape -> the plane)."""
    return (np.atleast_2d(np.asarray(points, float)) @ rotation)[:, :2]


def compose(transforms, child: str, root: str) -> tuple[np.ndarray, np.ndarray]:
    """(R, p) of frame ``child`` in ``root`` by chaining ``transforms`` (a tree)."""
    by_child = {t.child: t for t in transforms}
    r, p = np.eye(3), np.zeros(3)
    frame = child
    while frame != root:
        t = by_child[frame]
        rt = matrix_from_quaternion(t.rotation)
        r, p = rt @ r, rt @ p + np.asarray(t.translation, float)
        frame = t.parent
    return r, p


def _section_size(link) -> tuple[str, float, float]:
    """('box' | 'cylinder', width, height) of a link's root section (m) for the visual."""
    seg = link.segments[0]
    dims = {k: v[0] for k, v in seg.dims.items()}
    if seg.shape == "square_hollow":
        return "box", dims["side"], dims["side"]
    if seg.shape in ("rectangular", "rectangular_hollow"):
        return "box", dims["width"], dims["height"]
    if seg.shape in ("circular", "circular_hollow"):
        return "cylinder", dims["diameter"], dims["diameter"]
    side = link.length / 100.0  # explicit EI and m: no geometry
    return "box", side, side


def link_inertials(model: FlexArmModel) -> list[dict]:
    """Per link: the inertial data of its root body with the beam and of its tip body
    (module docstring), ``{"link": (mass, x_c, Izz_c), "tip": (mass, Izz)}``."""
    mass_payload, inertia_payload = model.payload
    out = []
    for i, (lk, b) in enumerate(zip(model.arm.links, model.bases)):
        m = lk.M_minus + b.mass
        xc = b.first_moment / m if m > 0 else 0.0
        izz = lk.J_minus + b.second_moment - m * xc * xc
        last = i == model.n_links - 1
        out.append({"link": (m, xc, izz),
                    "tip": (lk.M_plus + (mass_payload if last else 0.0),
                            lk.J_plus + (inertia_payload if last else 0.0))})
    return out


def _fmt(*values) -> str:
    return " ".join(repr(float(v)) for v in values)


def _inertial(parent, mass, xc, ixx, iyy, izz) -> None:
    if mass > 0.0:
        _inertia(parent, mass, xc, ixx, iyy, izz)


def _inertia(parent, mass, xc, ixx, iyy, izz) -> None:
    el = ET.SubElement(parent, "inertial")
    ET.SubElement(el, "origin", xyz=_fmt(xc, 0, 0), rpy=_fmt(0, 0, 0))
    ET.SubElement(el, "mass", value=_fmt(mass))
    ET.SubElement(el, "inertia", ixx=_fmt(ixx), ixy="0.0", ixz="0.0", iyy=_fmt(iyy),
                  iyz="0.0", izz=_fmt(izz))


def robot_description(model: FlexArmModel, prefix: str = "", base: str = "base_link",
                      effort_limits=None, velocity_limit: float = 100.0) -> str:
    """The URDF (XML text) of the arm: frames, joints, inertials, transmissions and rotors
    as in the module docstring. Joints are continuous (the model has no stops); their
    ``effort`` is the arm's torque limit (a torque_saturation effect) or else
    ``effort_limits[i]`` (the model node passes its max_torque), ``velocity`` (rad/s) a
    nominal value the model does not enforce."""
    frames = Frames.of(model, prefix, base)
    robot = ET.Element("robot", name=model.arm.name)
    ET.SubElement(robot, "link", name=frames.base)
    ET.SubElement(robot, "link", name=frames.plane)
    _joint(robot, "arm_plane_joint", "fixed", frames.base, frames.plane,
           rpy=plane_rpy(model.gravity))
    inertials = link_inertials(model)
    for i, lk in enumerate(model.arm.links):
        _beam_link(robot, frames.links[i], lk, inertials[i]["link"])
        tip = ET.SubElement(robot, "link", name=frames.tips[i])
        m_tip, j_tip = inertials[i]["tip"]
        _inertial(tip, m_tip, 0.0, j_tip, j_tip, j_tip)
        parent = frames.plane if i == 0 else frames.tips[i - 1]
        joint = _joint(robot, frames.joints[i], "continuous", parent, frames.links[i])
        limit = float(model.torque_limit[i])
        if not math.isfinite(limit):
            limit = float(effort_limits[i]) if effort_limits is not None else 0.0
        ET.SubElement(joint, "limit", effort=_fmt(limit), velocity=_fmt(velocity_limit))
        _joint(robot, lk.name + "_tip_joint", "fixed", frames.links[i], frames.tips[i],
               xyz=(lk.length, 0.0, 0.0))
    for r in rotors(model):
        name = frames.joints[r.joint]
        rotor = ET.SubElement(robot, "link", name=frames.links[r.joint] + "_rotor")
        _inertia(rotor, 0.0, 0.0, r.inertia / 2, r.inertia / 2, r.inertia)
        parent = frames.plane if r.joint == 0 else frames.tips[r.joint - 1]
        j = _joint(robot, name + "_rotor_joint", "continuous", parent,
                   frames.links[r.joint] + "_rotor")
        ET.SubElement(j, "mimic", joint=name, multiplier=_fmt(r.ratio), offset="0.0")
    for i, g in enumerate(gears(model)):
        if g is not None:
            _transmission(robot, frames.joints[i], g[0])
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def _joint(robot, name, kind, parent, child, xyz=(0.0, 0.0, 0.0), rpy=(0.0, 0.0, 0.0)):
    """A URDF joint (axis z unless fixed)."""
    joint = ET.SubElement(robot, "joint", name=name, type=kind)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    ET.SubElement(joint, "origin", xyz=_fmt(*xyz), rpy=_fmt(*rpy))
    if kind != "fixed":
        ET.SubElement(joint, "axis", xyz=_fmt(0, 0, 1))
    return joint


def _beam_link(robot, name, lk, inertial) -> None:
    """A link's URDF link: the beam and root body's inertial, a box (or cylinder)."""
    shape, w, h = _section_size(lk)
    link = ET.SubElement(robot, "link", name=name)
    mass, xc, izz = inertial
    _inertial(link, mass, xc, mass * (w * w + h * h) / 12.0, izz, izz)
    for tag in ("visual", "collision"):
        el = ET.SubElement(link, tag)
        if shape == "box":
            ET.SubElement(el, "origin", xyz=_fmt(lk.length / 2, 0, 0), rpy=_fmt(0, 0, 0))
            ET.SubElement(ET.SubElement(el, "geometry"), "box", size=_fmt(lk.length, w, h))
        else:
            ET.SubElement(el, "origin", xyz=_fmt(lk.length / 2, 0, 0),
                          rpy=_fmt(0, math.pi / 2, 0))
            ET.SubElement(ET.SubElement(el, "geometry"), "cylinder",
                          radius=_fmt(w / 2), length=_fmt(lk.length))


def _transmission(robot, joint: str, ratio: float) -> None:
    """A SimpleTransmission: joint <- actuator ``<joint>_motor`` through ``ratio``."""
    tr = ET.SubElement(robot, "transmission", name=joint + "_transmission")
    ET.SubElement(tr, "type").text = "transmission_interface/SimpleTransmission"
    j = ET.SubElement(tr, "joint", name=joint)
    ET.SubElement(j, "hardwareInterface").text = "hardware_interface/EffortJointInterface"
    act = ET.SubElement(tr, "actuator", name=joint + "_motor")
    ET.SubElement(act, "mechanicalReduction").text = _fmt(ratio)
