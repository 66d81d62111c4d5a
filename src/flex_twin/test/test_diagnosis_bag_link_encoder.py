"""A bag carries an elastic joint's link-side encoder (ql<i>, vl<i>) on a second
sensor_msgs/JointState topic and the CSV's ``# start_window`` in metadata.yaml's
custom_data (issue 22): the same Recording as the equivalent CSV, and the CSV path's
refusals (pairs, lengths, NaN) as one line with exit code 2."""
import numpy as np
import pytest
import yaml

pytest.importorskip("rclpy")

from builtin_interfaces.msg import Duration  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint  # noqa: E402

from flex_model.ros import conversions as conv  # noqa: E402
from flex_twin.bags import BagWriter  # noqa: E402
from flex_twin.cli import main  # noqa: E402
from flex_twin.diagnosis.batch import RunSpec, expand_runs  # noqa: E402
from flex_twin.diagnosis.recording import RecordingError, load_csv  # noqa: E402
from flex_twin.diagnosis.ros_recording import LINK_TOPIC, load_bag  # noqa: E402
from flex_twin.diagnosis.sources import load_recording  # noqa: E402

DT, N = 0.002, 120
NAMES = ["joint1", "joint2"]
PD = {"controller": {"law": "pd", "kp": [200.0, 80.0], "kd": [20.0, 8.0], "period": 0.002,
                     "feedforward": "gravity"}}


def _channels():
    """A two-joint run whose joint 2 alone has a link-side encoder (twisted against q2)."""
    t = np.arange(N) * DT
    ch = {"q1": 0.3 * np.sin(2.0 * t), "v1": 0.6 * np.cos(2.0 * t),
          "q2": -0.2 * np.sin(5.0 * t), "v2": -1.0 * np.cos(5.0 * t),
          "tau1": 1.5 + np.cos(3.0 * t), "tau2": -0.25 * t,
          "qset1": 0.1 * t, "qset2": 0.05 - 0.2 * t * t}
    ch["ql2"] = ch["q2"] + 1e-3 * np.sin(40.0 * t)       # the coupling's twist
    ch["vl2"] = ch["v2"] + 4e-2 * np.cos(40.0 * t)
    return t, ch


def _write_bag(path, t, ch, topic=LINK_TOPIC, link=None):
    """Our writer: /joint_states, the reference as one trajectory with a point per sample,
    and the link-side encoders as JointState ``link`` = (names, positions, velocities) per
    sample (default: joint2's ql2, vl2)."""
    t_ns = [int(round(x * 1e9)) for x in t]
    with BagWriter(path) as bag:
        traj = JointTrajectory(joint_names=NAMES)
        traj.points = [JointTrajectoryPoint(
            positions=[float(ch["qset1"][k]), float(ch["qset2"][k])],
            time_from_start=Duration(sec=t_ns[k] // 10 ** 9, nanosec=t_ns[k] % 10 ** 9))
            for k in range(len(t))]
        bag.write("/flex_planner/trajectory", traj, 0)
        for k, tk in enumerate(t):
            bag.write("/joint_states", conv.joint_state(
                tk, NAMES, [ch["q1"][k], ch["q2"][k]], [ch["v1"][k], ch["v2"][k]],
                [ch["tau1"][k], ch["tau2"][k]]), t_ns[k])
            names, q, v = link(k) if link else (["joint2"], [ch["ql2"][k]], [ch["vl2"][k]])
            msg = JointState(name=names, position=[float(x) for x in q],
                             velocity=[float(x) for x in v])
            conv.set_time(msg.header.stamp, tk)
            bag.write(topic, msg, t_ns[k])
    return path


def _write_csv(path, t, ch, head=""):
    names = list(ch)
    np.savetxt(path, np.column_stack([t] + [ch[n] for n in names]), delimiter=",",
               header=head + ",".join(["t"] + names), comments="", fmt="%.17g")
    return path


def _custom_data(bag, **values):
    """Set the bag's metadata.yaml custom_data (as ``ros2 bag record --custom-data``)."""
    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    meta["rosbag2_bagfile_information"]["custom_data"] = values
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta))
    return bag


def test_a_bag_with_the_link_side_topic_is_the_csvs_recording(tmp_path):
    t, ch = _channels()
    path = _custom_data(_write_bag(tmp_path / "bag", t, ch), start_window="0.0008")
    bag = load_recording(path, 2)
    csv = load_csv(_write_csv(tmp_path / "run.csv", t, ch, "# start_window: 0.0008\n"), 2)
    assert bag.meta == csv.meta == {"start_window": 0.0008}
    assert sorted(bag.channels) == sorted(csv.channels)
    assert bag.link_encoders() == csv.link_encoders() == [1]
    assert np.max(np.abs(bag.t - csv.t)) < 1e-12
    for name in csv.channels:
        assert np.max(np.abs(bag.channels[name] - csv.channels[name])) < 1e-12, name
    # twisted as written: the link side is not the motor side
    assert np.std(bag.channels["ql2"] - bag.channels["q2"]) > 5e-4
    # another topic name: the default one is then an ordinary topic, not read
    other = load_bag(_write_bag(tmp_path / "bag2", t, ch, topic="/arm/link_side"), 2,
                     link_topic="/arm/link_side")
    assert other.link_encoders() == [1]
    assert np.max(np.abs(other.channels["vl2"] - csv.channels["vl2"])) < 1e-12
    assert load_bag(tmp_path / "bag2", 2).link_encoders() == []
    # the topic travels with the run (RunSpec.link_topic; --link-topic, a manifest's
    # link_topic), not as a setting of the process that reads the bag
    assert load_recording(tmp_path / "bag2", 2, "/arm/link_side").link_encoders() == [1]
    assert load_recording(tmp_path / "bag2", 2).link_encoders() == []


def test_the_link_topic_travels_with_the_run_spec(tmp_path):
    """--link-topic and a manifest's per-run link_topic become RunSpec.link_topic (a run
    sent to a cluster's worker carries it); a run without one keeps the default (None)."""
    import pickle
    (tmp_path / "a.csv").write_text("t\n")
    (tmp_path / "runs.yaml").write_text(yaml.safe_dump({"runs": [
        {"data": "a.csv", "name": "own", "link_topic": "/arm07/link"},
        {"data": "a.csv", "name": "default"}]}))
    own, default = expand_runs([str(tmp_path / "runs.yaml")], "arm", "c.yaml", "/cli/link")
    assert (own.link_topic, default.link_topic) == ("/arm07/link", "/cli/link")
    assert expand_runs([str(tmp_path / "a.csv")], "arm", "c.yaml")[0].link_topic is None
    assert pickle.loads(pickle.dumps(own)).link_topic == "/arm07/link"
    with pytest.raises(ValueError, match="link_topic: got 'link side'"):
        RunSpec("r", "a.csv", "arm", "c.yaml", link_topic="link side")
    (tmp_path / "bad.yaml").write_text(yaml.safe_dump({"runs": [
        {"data": "a.csv", "link_topic": "no/slash"}]}))
    with pytest.raises(ValueError, match="link_topic"):
        expand_runs([str(tmp_path / "bad.yaml")], "arm", "c.yaml")


def _refusal(tmp_path, capsys, name, link, match, extra=()):
    t, ch = _channels()
    bag = _write_bag(tmp_path / name, t, ch, link=link)
    ctl = tmp_path / "c.yaml"
    ctl.write_text(yaml.safe_dump(PD))
    code = main(["diagnose", str(bag), "--arm", "thesis_example1_motors", "--controller",
                 str(ctl), "--out", str(tmp_path / "out"), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1, err
    assert match in err[0] and "Traceback" not in err[0]


def test_bag_link_side_refusals_are_one_line(tmp_path, capsys):
    t, ch = _channels()
    _refusal(tmp_path, capsys, "no_rate", lambda k: (["joint2"], [ch["ql2"][k]], []),
             "has 1 positions and 0 velocities for 1 joints")
    _refusal(tmp_path, capsys, "nan", lambda k: (
        ["joint2"], [np.nan if k == 7 else ch["ql2"][k]], [ch["vl2"][k]]),
        "channel ql2: non-finite value at message 7 (t = 0.014 s)")
    _refusal(tmp_path, capsys, "stranger", lambda k: (["elbow"], [0.0], [0.0]),
             "joint 'elbow' is not among the arm's /joint_states joints")
    _refusal(tmp_path, capsys, "bad_topic", None, "--link-topic: got 'link side'",
             extra=("--link-topic", "link side"))
    with pytest.raises(RecordingError, match="custom_data: start_window: '-1' is not a "
                       "number of seconds >= 0"):
        load_bag(_custom_data(_write_bag(tmp_path / "window", t, ch), start_window="-1"), 2)


def test_a_base_frame_tip_pose_needs_the_arms_gravity(tmp_path):
    """The model node publishes /flex/tip_pose in the base frame (z up); the recording wants
    it in the arm's plane, which depends on the arm's gravity: given, the plane's (x, y)
    come back to 1e-12; not given, the bag is refused with a reason (a default vertical
    plane would be silently wrong for a horizontal or tilted arm)."""
    from geometry_msgs.msg import PoseStamped
    from flex_model.urdf import plane_rotation, plane_to_base
    t, ch = _channels()
    path = _write_bag(tmp_path / "bag", t, ch)
    plane_xy = np.column_stack([1.0 + 0.1 * np.sin(t), 0.2 * np.cos(t)])
    gravity = (3.0, -9.0)   # a tilted arm
    base = plane_to_base(plane_rotation(gravity), plane_xy)
    with BagWriter(tmp_path / "tip") as bag:
        bag.write("/flex_planner/trajectory", _read_one(path, "/flex_planner/trajectory"), 0)
        for k, tk in enumerate(t):
            t_ns = int(round(tk * 1e9))
            bag.write("/joint_states", conv.joint_state(
                tk, NAMES, [ch["q1"][k], ch["q2"][k]], [ch["v1"][k], ch["v2"][k]],
                [ch["tau1"][k], ch["tau2"][k]]), t_ns)
            pose = PoseStamped()
            pose.header.frame_id = "base_link"
            conv.set_time(pose.header.stamp, tk)
            pose.pose.position.x, pose.pose.position.y, pose.pose.position.z = \
                (float(v) for v in base[k])
            bag.write("/flex/tip_pose", pose, t_ns)
    rec = load_bag(tmp_path / "tip", 2, gravity=gravity)
    np.testing.assert_allclose(rec.channels["tip_x"], plane_xy[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec.channels["tip_y"], plane_xy[:, 1], rtol=0, atol=1e-12)
    with pytest.raises(RecordingError, match="needs the arm's gravity"):
        load_recording(tmp_path / "tip", 2)


def _read_one(path, topic):
    """The first message of ``topic`` in a bag."""
    from flex_twin.bags import read_bag
    return next(msg for _, _, _, msg in read_bag(path, [topic]))
