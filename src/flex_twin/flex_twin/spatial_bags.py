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

from types import SimpleNamespace

from flex_model.ros.spatial import (SpatialOutputs, centre_lines, frame_poses, joint_state,
                                    relative, shape_markers, skeleton_urdf, stamp,
                                    transforms)

from .bags.message_types import jazzy_typestore
from .bags.writer import BagWriter

TF_TYPE = "tf2_msgs/msg/TFMessage"
#: the message layout is flex_model.ros.spatial's (shared with the spatial model node)
__all__ = ["TF_TYPE", "centre_lines", "frame_poses", "relative", "skeleton_urdf",
           "write_spatial_bag"]


def write_spatial_bag(res, path, points: int = 21) -> dict:
    """Write the run ``res`` (flex_model.result.SimulationResult of a spatial arm) to a new bag
    at ``path``; returns the message counts per topic."""
    from rclpy.qos import DurabilityPolicy, QoSProfile
    from sensor_msgs.msg import JointState
    from std_msgs.msg import String

    model = res.model
    store = jazzy_typestore()
    TFMessage = store.types[TF_TYPE]
    types = SimpleNamespace(**{k: store.types[f"{p}/msg/{k}"] for p, k in (
        ("geometry_msgs", "TransformStamped"), ("geometry_msgs", "Transform"),
        ("geometry_msgs", "Vector3"), ("geometry_msgs", "Quaternion"),
        ("std_msgs", "Header"), ("builtin_interfaces", "Time"))})
    outputs = SpatialOutputs(model)
    m = len(outputs.names)
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    with BagWriter(path) as w:
        w.add_topic("/robot_description", "std_msgs/msg/String", qos=latched)
        w.add_topic("/joint_states", "sensor_msgs/msg/JointState")
        w.add_topic("/flex/deflections", "sensor_msgs/msg/JointState")
        w.add_topic("/flex/shape", "visualization_msgs/msg/MarkerArray")
        w.add_topic("/tf", TF_TYPE, qos=QoSProfile(depth=100), installed=False)
        w.write("/robot_description", String(data=skeleton_urdf(model)), 0)
        for k, t in enumerate(res.t):
            t = float(t)
            t_ns = int(round(t * 1e9))
            w.write("/joint_states", joint_state(JointState, model.arm.joint_names,
                                                 res.joint_angles[k], res.joint_rates[k],
                                                 res.tau[k], t), t_ns)
            d = outputs.deflections(res.q[k], res.v[k])
            w.write("/flex/deflections", joint_state(JointState, outputs.names, d[:m], d[m:],
                                                     (), t, effort=False), t_ns)
            q = res.q[k]
            lf = []
            tfs = transforms(types, model, q, t, lf)
            w.write("/tf", bytes(store.serialize_cdr(TFMessage(transforms=tfs), TF_TYPE)),
                    t_ns)
            w.write("/flex/shape", shape_markers(model, q, t, points, lf), t_ns)
        return dict(w.counts)


_stamp = stamp   # the former private name
