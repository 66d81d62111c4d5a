"""tf2_msgs and control_msgs built into the venv (issue 46, scripts/gen_interfaces.py).

The type hashes (RIHS01) of the generated packages are ROS 2 Jazzy's, so a real RViz,
robot_state_publisher or MoveIt matches them. The expected values come from elsewhere:
tf2_msgs/msg/TFMessage from rosbags' ros2_jazzy type store (its own RIHS01 code, computed
here) and the rosidl_generator_c output of a public Jazzy-era colcon build
(tf2_msgs/msg/detail/tf_message__struct.h); control_msgs from a public colcon build of
control_msgs (saahu27/aprs, aprs_ws/build/control_msgs/rosidl_generator_c/control_msgs/
action/detail/follow_joint_trajectory__description.c) and, for the messages, rosbags'
hash of the shipped definitions. Live: /tf_static + /tf of a model node in another process
rebuild the frame chain, which ends at the pose on /flex/tip_pose; the graph reports Jazzy's
hash for /tf, and rosbags decodes the raw /tf bytes to the same numbers (the wire format).
"""
import json
import os
import re
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from tf2_msgs.msg import TFMessage  # built into .venv by scripts/bootstrap.sh


JAZZY = {
    "tf2_msgs/msg/TFMessage":
        "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
    "control_msgs/action/FollowJointTrajectory":
        "RIHS01_738ebcb7a2d7cfa42f9f1001cc99ce3a4383d1cfe508015d9be8485e4b1c66f6",
    "control_msgs/action/FollowJointTrajectory_Goal":
        "RIHS01_8a9060704b269608f5a340934cc26e66869dd14bdac29e2e7fd9ec8b9882d205",
    "control_msgs/action/FollowJointTrajectory_Result":
        "RIHS01_8002e99ed2c14c6faa522f2a93c26d744c5982f254f9e98ff9c6f19789bdb220",
    "control_msgs/action/FollowJointTrajectory_Feedback":
        "RIHS01_3fd0aaecf71725121ae1ff7f01098a5e0da581e672be18a6b2c286cb43d96b49",
    "control_msgs/action/FollowJointTrajectory_SendGoal":
        "RIHS01_b13789dddc325a7a962825c45e28c77d37237ec129dd0c34dc5994562938c57f",
    "control_msgs/action/FollowJointTrajectory_FeedbackMessage":
        "RIHS01_80398fcb9674a79081a9906e2ccf0c804dd7cb15e22e362e606ee87186beab71",
    "control_msgs/msg/JointTolerance":
        "RIHS01_c254f9cece0f3b733017b6990fd46d1326e25242d6b8844398c97d9a88e7d648",
    "control_msgs/msg/JointComponentTolerance":
        "RIHS01_739ea7566931944d33830fa10f1bf5e7a7fbdc3172bce7a7eaac642bd6e3ffa4",
}
SOURCES = Path(__file__).resolve().parents[1] / "scripts" / "interfaces"


def generated_hashes() -> dict:
    """Every type hash in the generated .json type descriptions in the venv's share."""
    share = Path(sys.prefix) / "share"
    out = {}
    for pkg in ("tf2_msgs", "control_msgs"):
        for path in (share / pkg).glob("*/*.json"):
            for entry in json.loads(path.read_text())["type_hashes"]:
                out[entry["type_name"]] = entry["hash_string"]
    return out


def test_generated_hashes_are_jazzys():
    got = generated_hashes()
    for name, want in JAZZY.items():
        assert got[name] == want, name


def test_rosbags_hashes_the_shipped_definitions_alike():
    """rosbags (its own RIHS01 code): its Jazzy store's TFMessage, and control_msgs'
    messages and the action's goal/result/feedback parsed from scripts/interfaces."""
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg
    store = get_typestore(Stores.ROS2_JAZZY)
    assert store.hash_rihs01("tf2_msgs/msg/TFMessage") == JAZZY["tf2_msgs/msg/TFMessage"]
    types = {}
    for msg in ("JointTolerance", "JointComponentTolerance"):
        text = (SOURCES / "control_msgs" / "msg" / f"{msg}.msg").read_text()
        types.update(get_types_from_msg(text, f"control_msgs/msg/{msg}"))
    action = (SOURCES / "control_msgs" / "action" / "FollowJointTrajectory.action")
    # rosbags resolves a bare type name within control_msgs/action; rosidl, as written
    # here, within control_msgs/msg
    text = re.sub(r"^(Joint\w*Tolerance)", r"control_msgs/msg/\1", action.read_text(),
                  flags=re.M)
    parts = text.split("\n---\n")
    for part, suffix in zip(parts, ("Goal", "Result", "Feedback")):
        types.update(get_types_from_msg(part, f"control_msgs/action/FollowJointTrajectory_"
                                              f"{suffix}"))
    store.register(types)
    for name in types:
        assert store.hash_rihs01(name) == JAZZY[name], name


def test_generated_packages_import_with_their_constants():
    from control_msgs.action import FollowJointTrajectory
    from control_msgs.msg import JointComponentTolerance
    from tf2_msgs.action import LookupTransform
    from tf2_msgs.msg import TF2Error
    from tf2_msgs.srv import FrameGraph
    r = FollowJointTrajectory.Result
    assert (r.SUCCESSFUL, r.INVALID_GOAL, r.INVALID_JOINTS, r.OLD_HEADER_TIMESTAMP,
            r.PATH_TOLERANCE_VIOLATED, r.GOAL_TOLERANCE_VIOLATED) == (0, -1, -2, -3, -4, -5)
    assert JointComponentTolerance.ROTATION == 5 and TF2Error.TRANSFORM_ERROR == 6
    assert FrameGraph.Response().frame_yaml == "" and LookupTransform.Goal().advanced is False


def _matrix(q):
    """Rotation matrix of a unit quaternion (x, y, z, w)."""
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _chain(transforms, parent, child):
    """(R, p) of ``child`` in ``parent`` from a {child: TransformStamped} tree."""
    r, p = np.eye(3), np.zeros(3)
    frame = child
    while frame != parent:
        tf = transforms[frame].transform
        rt, pt = _matrix((tf.rotation.x, tf.rotation.y, tf.rotation.z, tf.rotation.w)), \
            np.array([tf.translation.x, tf.translation.y, tf.translation.z])
        r, p = rt @ r, rt @ p + pt
        frame = transforms[frame].header.frame_id
    return r, p


def test_tf_from_another_process_ends_at_the_tip_pose(repo_root):
    """A model node (realtime, the arm falling from 40, -30 deg under gravity) in its own
    process; here /tf_static (latched) + /tf rebuild base_link -> link2_tip: at the stamps
    of /flex/tip_pose (in the base frame, z up) its position and orientation, in the arm's
    plane."""
    prefix = f"t{uuid.uuid4().hex[:6]}/"
    ns = f"/tf{uuid.uuid4().hex[:6]}"
    env = dict(os.environ, FLEX_TWIN_NUMBA_WARMUP="0")
    proc = subprocess.Popen(
        [sys.executable, "-m", "flex_model.ros.model_node", "--ros-args", "-r", f"__ns:={ns}",
         "-p", f"frame_prefix:={prefix}", "-p", "initial_joint_angles_deg:=[40.0, -30.0]",
         "-p", "publish_rate:=100.0",
         "-p", "hold_until_command:=false"],  # (it falls: the chain must follow it)
        env=env, cwd=repo_root,
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    probe = None
    try:
        probe = rclpy.create_node(f"tfprobe_{uuid.uuid4().hex[:6]}", context=ctx)
        static, tfs, tips = {}, {}, {}
        latched = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)

        def stamp(h):
            return h.stamp.sec * 10**9 + h.stamp.nanosec

        def on_tf(msg, into):
            for t in msg.transforms:
                if t.child_frame_id.startswith(prefix):
                    into.setdefault(stamp(t.header), {})[t.child_frame_id] = t
        probe.create_subscription(TFMessage, "/tf_static", lambda m: on_tf(m, static),
                                  latched)
        probe.create_subscription(TFMessage, "/tf", lambda m: on_tf(m, tfs), 100)
        raw = []  # the same messages as bytes, decoded by rosbags (Jazzy's wire format)
        probe.create_subscription(TFMessage, "/tf", raw.append, 100, raw=True)
        probe.create_subscription(PoseStamped, f"{ns}/flex/tip_pose",
                                  lambda m: tips.__setitem__(stamp(m.header), m), 100)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(probe)
        end = time.monotonic() + 180.0  # a fresh numba cache compiles the kernels first
        common = []
        while len(common) < 20 or not static:
            assert proc.poll() is None, proc.stderr.read()
            assert time.monotonic() < end, "timed out waiting for /tf and /flex/tip_pose"
            ex.spin_once(timeout_sec=0.05)
            common = sorted(set(tfs) & set(tips))
        info = [i for i in probe.get_publishers_info_by_topic("/tf") if i.node_namespace == ns]
        assert [str(i.topic_type_hash) for i in info] == [JAZZY["tf2_msgs/msg/TFMessage"]]
        base, plane, tip = f"{prefix}base_link", f"{prefix}arm_plane", f"{prefix}link2_tip"
        tree = dict(next(iter(static.values())))
        assert tree[plane].header.frame_id == base
        tips_x = []
        for s in common[-10:]:
            tree.update(tfs[s])
            pose = tips[s].pose   # in the base frame, as the markers (issue 46 item 10e)
            assert tips[s].header.frame_id == base
            o = pose.orientation
            r, p = _chain(tree, base, tip)
            np.testing.assert_allclose(p, [pose.position.x, pose.position.y, pose.position.z],
                                       rtol=0, atol=1e-9)
            np.testing.assert_allclose(r, _matrix((o.x, o.y, o.z, o.w)), rtol=0, atol=1e-9)
            assert abs(_chain(tree, plane, tip)[1][2]) < 1e-12   # in the arm's plane
            tips_x.append(pose.position.x)
        assert np.ptp(tips_x) > 1e-4  # the arm moved: the chain followed it
        from rosbags.typesys import Stores, get_typestore
        store, decoded = get_typestore(Stores.ROS2_JAZZY), 0
        for data in raw:
            msg = store.deserialize_cdr(data, "tf2_msgs/msg/TFMessage")
            for t in msg.transforms:
                s = t.header.stamp.sec * 10**9 + t.header.stamp.nanosec
                if t.child_frame_id == tip and tip in tfs.get(s, {}):
                    got = tfs[s][tip].transform
                    assert (t.transform.translation.x, t.transform.rotation.w) == \
                        (got.translation.x, got.rotation.w)
                    decoded += 1
        assert decoded >= 10
    finally:
        if probe is not None:
            probe.destroy_node()
        rclpy.try_shutdown(context=ctx)
        proc.terminate()
        proc.wait(timeout=20)
