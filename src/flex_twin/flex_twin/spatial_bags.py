"""A spatial run as a rosbag2 (MCAP) bag (issue 25): ``flex-twin simulate <spatial
scenario> --bag``, written with our :class:`flex_twin.bags.BagWriter`.

Topics (standard messages only; stamps = simulated time):

- ``/joint_states`` (sensor_msgs/JointState): joint names, values (rad or m), rates,
  joint torques/forces.
- ``/flex/deflections`` (sensor_msgs/JointState): per flexible link ``<link>/tip_deflection_y``
  and ``<link>/tip_deflection_z`` (m: the beam's v and w at the tip) and
  ``<link>/tip_twist`` (rad), with their rates as velocities (the planar node's
  ``<link>/tip_deflection``, ``tip_rotation`` carried to two bending planes and torsion).
- ``/tf`` (tf2_msgs/TFMessage): per link ``<link>`` (the frame after the joint motion,
  where the beam starts; parent: the previous link's ``<link>_end`` or ``base_link``),
  ``<link>_tip`` (flexible links: the deflected tip section frame of seed 000 Eq. 19, x along
  the tip tangent; parent ``<link>``) and ``<link>_end`` (the link's end frame i, where
  the next joint sits). tf2_msgs is not in the pip ROS wheels: its CDR comes from the
  rosbags Jazzy typestore (same definition and RIHS01 hash).
- ``/flex/shape`` (visualization_msgs/MarkerArray): per flexible link the deformed centre
  line (LINE_STRIP, ``points`` samples) and its chord, in ``base_link``, z up.
- ``/robot_description`` (std_msgs/String, once, transient local): the URDF of the rigid
  skeleton (the frames above at zero deflection, the joints with their axes and limits).
"""
from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from flex_model.urdf import quaternion_from_matrix, rpy_from_matrix

from .bags.message_types import jazzy_typestore
from .bags.writer import BagWriter

TF_TYPE = "tf2_msgs/msg/TFMessage"
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


def skeleton_urdf(model) -> str:
    """URDF of the rigid skeleton: the /tf frames at q = 0, joints with axis and limits."""
    q0 = np.zeros(model.nq)
    poses = frame_poses(model, q0)
    lf = []
    model._chain(q0, False, lf)
    robot = ET.Element("robot", name=model.arm.name)
    ET.SubElement(robot, "link", name="base_link")
    rel = relative(poses)
    roots = {lk.name: root for lk, (root, _) in zip(model.arm.links, lf)}
    for (parent, child, T) in rel:
        ET.SubElement(robot, "link", name=child)
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
        ET.SubElement(j, "parent", link=parent)
        ET.SubElement(j, "child", link=child)
        ET.SubElement(j, "origin", xyz=" ".join(f"{x:.17g}" for x in T[:3, 3]),
                      rpy=" ".join(f"{x:.17g}" for x in rpy_from_matrix(T[:3, :3])))
    return ET.tostring(robot, encoding="unicode")


def _stamp(t: float):
    sec, nsec = divmod(int(round(t * 1e9)), 1_000_000_000)
    return sec, nsec


def write_spatial_bag(res, path, points: int = 21) -> dict:
    """Write the run ``res`` (flex_model.spatial.scenario.SpatialSimulation) to a new bag
    at ``path``; returns the message counts per topic."""
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import JointState
    from std_msgs.msg import ColorRGBA, String
    from geometry_msgs.msg import Point
    from visualization_msgs.msg import Marker, MarkerArray

    model = res.model
    store = jazzy_typestore()
    TFMessage = store.types[TF_TYPE]
    TransformStamped = store.types["geometry_msgs/msg/TransformStamped"]
    Transform = store.types["geometry_msgs/msg/Transform"]
    Vector3 = store.types["geometry_msgs/msg/Vector3"]
    Quaternion = store.types["geometry_msgs/msg/Quaternion"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    defl = res.tip_deflections()
    dnames = [f"{k}/{q}" for k in defl for q in ("tip_deflection_y", "tip_deflection_z",
                                                   "tip_twist")]
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    with BagWriter(path) as w:
        w.add_topic("/robot_description", "std_msgs/msg/String", qos=latched)
        w.add_topic("/joint_states", "sensor_msgs/msg/JointState")
        w.add_topic("/flex/deflections", "sensor_msgs/msg/JointState")
        w.add_topic("/flex/shape", "visualization_msgs/msg/MarkerArray")
        w.add_topic("/tf", TF_TYPE, qos=QoSProfile(depth=100), installed=False)
        w.write("/robot_description", String(data=skeleton_urdf(model)), 0)
        for k, t in enumerate(res.t):
            t_ns = int(round(float(t) * 1e9))
            sec, nsec = _stamp(float(t))
            js = JointState(name=list(model.arm.joint_names),
                            position=res.joint_values[k].tolist(),
                            velocity=res.joint_rates[k].tolist(), effort=res.tau[k].tolist())
            js.header.stamp.sec, js.header.stamp.nanosec = sec, nsec
            w.write("/joint_states", js, t_ns)
            pos, vel = [], []
            for d in defl.values():
                pos += [float(d["y"][k]), float(d["z"][k]), float(d["twist"][k])]
                vel += [float(d["y_rate"][k]), float(d["z_rate"][k]),
                        float(d["twist_rate"][k])]
            ds = JointState(name=dnames, position=pos, velocity=vel)
            ds.header.stamp.sec, ds.header.stamp.nanosec = sec, nsec
            w.write("/flex/deflections", ds, t_ns)
            q = res.q[k]
            tfs = []
            lf = []
            for parent, child, T in relative(frame_poses(model, q, lf)):
                x, y, z, qw = quaternion_from_matrix(T[:3, :3])
                tfs.append(TransformStamped(
                    header=Header(stamp=Time(sec=sec, nanosec=nsec), frame_id=parent),
                    child_frame_id=child,
                    transform=Transform(translation=Vector3(x=float(T[0, 3]),
                                                            y=float(T[1, 3]),
                                                            z=float(T[2, 3])),
                                        rotation=Quaternion(x=float(x), y=float(y),
                                                            z=float(z), w=float(qw)))))
            w.write("/tf", bytes(store.serialize_cdr(TFMessage(transforms=tfs), TF_TYPE)),
                    t_ns)
            ma = MarkerArray()
            names = [lk.name for lk, b in zip(model.arm.links, model.beams) if b is not None]
            for i, (name, line) in enumerate(zip(names, centre_lines(model, q, points, lf))):
                for j, (pts, width) in enumerate(((line, 0.01), (line[[0, -1]], 0.003))):
                    m = Marker(ns=f"flex/{name}", id=2 * i + j, type=Marker.LINE_STRIP,
                               action=Marker.ADD,
                               color=ColorRGBA(r=0.1, g=0.4, b=0.9, a=1.0) if j == 0 else
                               ColorRGBA(r=0.6, g=0.6, b=0.6, a=0.8))
                    m.header.frame_id = "base_link"
                    m.header.stamp.sec, m.header.stamp.nanosec = sec, nsec
                    m.scale.x = width
                    m.pose.orientation.w = 1.0
                    m.points = [Point(x=float(a), y=float(b_), z=float(c)) for a, b_, c in pts]
                    ma.markers.append(m)
            w.write("/flex/shape", ma, t_ns)
        return dict(w.counts)
