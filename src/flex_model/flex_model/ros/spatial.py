"""ROS message layout of a spatial arm (issue 25), written once for the spatial model node
(flex_model.ros.spatial_node) and the spatial bag writer (flex_twin.spatial_bags).

No physics here: the frames come from the model's chain (spatial/dynamics.py, seed 000
Eqs. 17-21), the deflections are the tip variables of the beams. The message classes are
passed in where two sources exist (rclpy's, or the rosbags Jazzy typestore's for
tf2_msgs, which the pip ROS wheels lack).

- ``/joint_states``: joint names, values (rad or m), rates, joint torques/forces.
- ``/flex/deflections``: per flexible link ``<link>/tip_deflection_y``,
  ``<link>/tip_deflection_z`` (m: the beam's v and w at the tip) and ``<link>/tip_twist``
  (rad), rates as velocities.
- ``/tf``: per link ``<link>`` (after the joint motion; parent the previous
  ``<link>_end`` or ``base_link``), ``<link>_tip`` (flexible: the deflected tip section
  frame of Eq. 19) and ``<link>_end`` (frame i).
- ``/flex/shape``: per flexible link the deformed centre line (LINE_STRIP) and its chord,
  in ``base_link``, z up.
- ``/robot_description``: the URDF of the rigid skeleton (:func:`skeleton_urdf`).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from ..urdf import quaternion_from_matrix, rpy_from_matrix

#: sampled bases of the centre lines per (beam, points); the beam is kept (its id stays
#: unique while cached)
_BASES: dict = {}


def frame_poses(model, q, link_frames=None) -> list:
    """Per link (name, parent, child, 4 x 4 pose in base_link) of the /tf frames;
    ``link_frames`` receives the (root, tip) frames of the chain (dynamics._chain)."""
    lf = [] if link_frames is None else link_frames
    ends = model._chain(np.asarray(q, float), False, lf)[0]
    out, parent = [], "base_link"
    for lk, (root, tip), end in zip(model.arm.links, lf, ends):
        out.append((parent, lk.name, root.matrix()))
        last = lk.name
        if tip is not None:
            out.append((lk.name, lk.name + "_tip", tip.matrix()))
            last = lk.name + "_tip"
        out.append((last, lk.name + "_end", end.matrix()))
        parent = lk.name + "_end"
    return out


def relative(poses) -> list:
    """(parent, child, 4 x 4 parent -> child) from poses in base_link."""
    by = {"base_link": np.eye(4)}
    out = []
    for parent, child, T in poses:
        by[child] = T
        out.append((parent, child, np.linalg.solve(by[parent], T)))
    return out


def centre_lines(model, q, points: int = 21, link_frames=None) -> list:
    """Per flexible link the deformed centre line (points, 3), base frame (m), from the
    chain's root frames ``link_frames`` (computed when not given)."""
    if link_frames is None:
        link_frames = []
        model._chain(np.asarray(q, float), False, link_frames)
    out = []
    for i, (b, (root, _)) in enumerate(zip(model.beams, link_frames)):
        if b is None:
            continue
        key = (id(b), points)
        if key not in _BASES:     # the sampled bases are constant: once per beam
            s = np.linspace(0.0, b.length, points)
            _BASES[key] = (b, s, b.bv.shape_matrix(s), b.bw.shape_matrix(s))
        _, s, Wv, Ww = _BASES[key]
        fv, fw, _ = b.split(np.asarray(q, float)[model.flex_slice(i)])
        r = np.column_stack([s, Wv @ fv, Ww @ fw])
        out.append(root.o + r @ (root.R @ b.P).T)
    return out


def frame_name(name: str, prefix: str = "", base: str = "base_link") -> str:
    """The published name of a frame of :func:`frame_poses`: ``base_link`` renamed
    ``base`` (the node's frame_id), then ``prefix`` (its frame_prefix) before it."""
    return prefix + (base if name == "base_link" else name)


def skeleton_urdf(model, prefix: str = "", base: str = "base_link") -> str:
    """URDF of the rigid skeleton: the /tf frames at q = 0, joints with axis and limits;
    link (frame) names as :func:`frame_name`, joint names unchanged (joint_states')."""
    q0 = np.zeros(model.nq)
    poses = frame_poses(model, q0)
    lf = []
    model._chain(q0, False, lf)
    robot = ET.Element("robot", name=model.arm.name)
    ET.SubElement(robot, "link", name=frame_name("base_link", prefix, base))
    rel = relative(poses)
    roots = {lk.name: root for lk, (root, _) in zip(model.arm.links, lf)}
    for (parent, child, T) in rel:
        ET.SubElement(robot, "link", name=frame_name(child, prefix, base))
        lk = next((x for x in model.arm.links if x.name == child), None)
        if lk is None:
            j = ET.SubElement(robot, "joint", name=f"{parent}_to_{child}", type="fixed")
        else:
            jt = lk.joint
            i = model.arm.links.index(lk)
            F = roots[child]
            k = model.off[i]
            world_axis = F.Jo[:, k] if jt.type == "prismatic" else F.Jw[:, k]
            axis = F.R.T @ world_axis
            kind = jt.type
            if kind == "revolute" and not (np.isfinite(jt.lower) and np.isfinite(jt.upper)):
                kind = "continuous"
            j = ET.SubElement(robot, "joint", name=jt.name, type=kind)
            ET.SubElement(j, "axis", xyz=" ".join(f"{x:.17g}" for x in axis))
            if kind != "continuous":
                big = 1e9
                ET.SubElement(j, "limit", **{
                    "lower": f"{jt.lower if np.isfinite(jt.lower) else -big:.17g}",
                    "upper": f"{jt.upper if np.isfinite(jt.upper) else big:.17g}",
                    "effort": f"{jt.effort if np.isfinite(jt.effort) else big:.17g}",
                    "velocity": f"{jt.velocity if np.isfinite(jt.velocity) else big:.17g}"})
        ET.SubElement(j, "parent", link=frame_name(parent, prefix, base))
        ET.SubElement(j, "child", link=frame_name(child, prefix, base))
        ET.SubElement(j, "origin", xyz=" ".join(f"{x:.17g}" for x in T[:3, 3]),
                      rpy=" ".join(f"{x:.17g}" for x in rpy_from_matrix(T[:3, :3])))
    return ET.tostring(robot, encoding="unicode")


def stamp(t: float):
    """(sec, nanosec) of a simulation time t (s)."""
    sec, nsec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return sec, nsec


def deflection_names(model) -> list:
    """``<link>/tip_deflection_y``, ``_z``, ``<link>/tip_twist`` per flexible link."""
    return [f"{lk.name}/{x}" for lk, b in zip(model.arm.links, model.beams) if b is not None
            for x in ("tip_deflection_y", "tip_deflection_z", "tip_twist")]


def deflection_index(model) -> np.ndarray:
    """Per flexible link the coordinates of (v, w, phi) at the tip (-1: no twist
    variable, the twist is 0), flattened in :func:`deflection_names` order."""
    out = []
    for i, b in enumerate(model.beams):
        if b is None:
            continue
        s = model.flex_slice(i).start
        out += [s + b.tip_v, s + b.tip_w, -1 if b.tip_phi is None else s + b.tip_phi]
    return np.array(out, dtype=int)


class SpatialOutputs:
    """What the model node publishes of a spatial arm's (q, v), simulated or estimated:
    flex/deflections (:func:`deflection_names`: per flexible link tip v, w, twist, 0
    without a twist variable, then their rates) and the end frame
    (SpatialArmModel.tip_frame, seed 000 Eq. 19) as position and quaternion, for an
    estimate with the covariance J P_qq J^T of its position and rotation (J: the frame's
    6 x nq Jacobian, linear then angular)."""

    def __init__(self, model):
        self.model, self.nq = model, model.nq
        self.names = deflection_names(model)
        index = deflection_index(model)
        self.present, self.index = index >= 0, index[index >= 0]
        self.values = np.zeros(2 * len(index))

    def deflections(self, q, v) -> np.ndarray:
        m, out = len(self.present), self.values
        out[:m][self.present], out[m:][self.present] = q[self.index], v[self.index]
        return out

    def tip_values(self, q, state_cov=None, out=None, model=None) -> np.ndarray:
        """Position, orientation (x, y, z, w) and with ``state_cov`` the covariance
        row-major, into ``out`` (7 or 43 values); ``model``: the arm with its payload."""
        frame = (model or self.model).tip_frame(np.asarray(q, float))
        out = np.empty(7 if state_cov is None else 43) if out is None else out
        out[:3] = np.real(frame.o)
        out[3:7] = quaternion_from_matrix(np.real(frame.R))
        if state_cov is not None:
            j = np.real(np.vstack([frame.Jo, frame.Jw]))
            out[7:] = (j @ state_cov[:self.nq, :self.nq] @ j.T).ravel()
        return out


def joint_state(JointState, names, values, rates, efforts, t: float, effort=True):
    """A sensor_msgs/JointState at simulation time t."""
    js = JointState(name=list(names), position=[float(x) for x in values],
                    velocity=[float(x) for x in rates])
    if effort:
        js.effort = [float(x) for x in efforts]
    js.header.stamp.sec, js.header.stamp.nanosec = stamp(t)
    return js


def transforms(types, model, q, t: float, link_frames=None, prefix: str = "",
               base: str = "base_link") -> list:
    """The /tf transforms (geometry_msgs/TransformStamped, from ``types``: an object with
    TransformStamped, Transform, Vector3, Quaternion, Header, Time) at state q, time t;
    ``link_frames`` receives the chain's (root, tip) frames (for :func:`shape_markers`);
    frame names as :func:`frame_name`."""
    sec, nsec = stamp(t)
    out = []
    for parent, child, T in relative(frame_poses(model, q, link_frames)):
        x, y, z, qw = quaternion_from_matrix(T[:3, :3])
        out.append(types.TransformStamped(
            header=types.Header(stamp=types.Time(sec=sec, nanosec=nsec),
                                frame_id=frame_name(parent, prefix, base)),
            child_frame_id=frame_name(child, prefix, base),
            transform=types.Transform(translation=types.Vector3(x=float(T[0, 3]),
                                                                y=float(T[1, 3]),
                                                                z=float(T[2, 3])),
                                      rotation=types.Quaternion(x=float(x), y=float(y),
                                                                z=float(z), w=float(qw)))))
    return out


def shape_markers(model, q, t: float, points: int = 21, link_frames=None, prefix: str = "",
                  base: str = "base_link"):
    """visualization_msgs/MarkerArray: per flexible link its deformed centre line
    (LINE_STRIP, ``points`` samples, width 0.01 m) and chord (0.003 m), in base_link
    (named as :func:`frame_name`)."""
    from std_msgs.msg import ColorRGBA
    from geometry_msgs.msg import Point
    from visualization_msgs.msg import Marker, MarkerArray

    sec, nsec = stamp(t)
    ma = MarkerArray()
    names = [lk.name for lk, b in zip(model.arm.links, model.beams) if b is not None]
    for i, (name, line) in enumerate(zip(names, centre_lines(model, q, points,
                                                             link_frames))):
        for j, (pts, width) in enumerate(((line, 0.01), (line[[0, -1]], 0.003))):
            m = Marker(ns=f"flex/{name}", id=2 * i + j, type=Marker.LINE_STRIP,
                       action=Marker.ADD,
                       color=ColorRGBA(r=0.1, g=0.4, b=0.9, a=1.0) if j == 0 else
                       ColorRGBA(r=0.6, g=0.6, b=0.6, a=0.8))
            m.header.frame_id = frame_name("base_link", prefix, base)
            m.header.stamp.sec, m.header.stamp.nanosec = sec, nsec
            m.scale.x = width
            m.pose.orientation.w = 1.0
            m.points = [Point(x=float(a), y=float(b_), z=float(c)) for a, b_, c in pts]
            ma.markers.append(m)
    return ma
