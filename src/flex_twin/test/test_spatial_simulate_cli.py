"""``flex-twin simulate`` on a spatial scenario (issue 25): summary, CSV, and the bag read
back against the CSV (/joint_states, /flex/deflections, /tf, /flex/shape,
/robot_description)."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from flex_twin.cli import main

SCENARIO = """
name: short_003
arm: seed003_like_arm
duration: 0.2
step: 1.0e-3
sample_period: 0.01
initial: {joint_values: [0.0, 0.3, -0.6], state: static}
control:
  gravity_hold: true
  pd: {kp: [2000.0, 3000.0, 1000.0], kd: [200.0, 300.0, 50.0], setpoints: [0.0, 0.3, -0.6]}
  setpoint_schedule: [{time: 0.05, setpoints: [0.1, 0.3, -0.6]}]
pulses:
  - {joint: joint3, torque: 20.0, start: 0.1, end: 0.12}
"""


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("spatial_sim")
    path = tmp / "short_003.yaml"
    path.write_text(SCENARIO)
    out = tmp / "out"
    import contextlib
    import io
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = main(["simulate", str(path), "--out", str(out), "--bag", "--no-plot", "--json"])
    assert rc == 0
    summary = json.loads(buf.getvalue())
    data = np.genfromtxt(summary["csv"], delimiter=",", names=True)
    return summary, data, out / "bag"


def _tf_messages(bag):
    from flex_twin.bags.message_types import jazzy_typestore
    from flex_twin.bags.reader import iter_raw
    store = jazzy_typestore()
    return [(t_ns, store.deserialize_cdr(raw, typ))
            for _, typ, t_ns, raw, _ in iter_raw(bag, ["/tf"])]


def _matrix(tr):
    from flex_model.urdf import matrix_from_quaternion
    T = np.eye(4)
    r, p = tr.rotation, tr.translation
    T[:3, :3] = matrix_from_quaternion((r.x, r.y, r.z, r.w))
    T[:3, 3] = p.x, p.y, p.z
    return T


def test_summary_and_csv(run):
    summary, data, _ = run
    assert summary["spatial"] and summary["arm"] == "seed003_like_arm"
    assert summary["steps"] == 200 and len(data) == 21
    # the PD's step moved joint 1 (motor behind the elastic gear) towards 0.1 rad
    assert 0.01 < data["q1"][-1] < 0.1
    assert summary["final_joint_values"] == pytest.approx([data[f"q{i}"][-1]
                                                           for i in (1, 2, 3)], abs=1e-15)
    assert summary["final_tip_m"] == pytest.approx([data["tip_x"][-1], data["tip_y"][-1],
                                                    data["tip_z"][-1]], abs=1e-15)
    assert summary["max_abs_tip_deflection"]["forearm"]["z_mm"] > 0.1


def test_bag_equals_the_csv(run):
    from flex_twin.bags.reader import read_bag
    _, data, bag = run
    t = data["t"]
    js, defl, shapes, desc = [], [], [], []
    for topic, _, t_ns, msg in read_bag(bag, ["/joint_states", "/flex/deflections",
                                              "/flex/shape", "/robot_description"]):
        {"/joint_states": js, "/flex/deflections": defl, "/flex/shape": shapes,
         "/robot_description": desc}[topic].append((t_ns, msg))
    assert len(js) == len(defl) == len(shapes) == len(t) and len(desc) == 1
    assert np.array_equal([n for n, _ in js], np.round(t * 1e9).astype(int))
    q = np.array([m.position for _, m in js])
    v = np.array([m.velocity for _, m in js])
    tau = np.array([m.effort for _, m in js])
    for i in range(3):
        assert np.max(np.abs(q[:, i] - data[f"q{i + 1}"])) <= 1e-12
        assert np.max(np.abs(v[:, i] - data[f"v{i + 1}"])) <= 1e-12
        assert np.max(np.abs(tau[:, i] - data[f"tau{i + 1}"])) <= 1e-12
    assert list(js[0][1].name) == ["joint1", "joint2", "joint3"]
    names = list(defl[0][1].name)
    assert names == ["forearm/tip_deflection_y", "forearm/tip_deflection_z",
                     "forearm/tip_twist"]
    d = np.array([m.position for _, m in defl])
    for k, col in enumerate(("y", "z", "twist")):
        assert np.max(np.abs(d[:, k] - data[f"forearm_tip_{'deflection_' if k < 2 else ''}"
                                            f"{col}"])) <= 1e-12
    # /tf: the chain base_link -> ... -> forearm_end is the CSV's tip; forearm_tip is the
    # last point of the forearm's centre line in /flex/shape
    tfs = _tf_messages(bag)
    assert len(tfs) == len(t)
    for k, (t_ns, msg) in enumerate(tfs):
        by = {tr.child_frame_id: (tr.header.frame_id, _matrix(tr.transform))
              for tr in msg.transforms}

        def pose(frame):
            T = np.eye(4)
            while frame != "base_link":
                parent, M = by[frame]
                T = M @ T
                frame = parent
            return T
        tip = pose("forearm_end")[:3, 3]
        assert np.max(np.abs(tip - [data["tip_x"][k], data["tip_y"][k], data["tip_z"][k]])) \
            <= 1e-12
        line = shapes[k][1].markers[0]
        assert line.type == 4 and line.ns == "flex/forearm"      # LINE_STRIP
        last = line.points[-1]
        assert np.max(np.abs(pose("forearm_tip")[:3, 3] - [last.x, last.y, last.z])) <= 1e-12
    urdf = ET.fromstring(desc[0][1].data)
    joints = {j.get("name"): j.get("type") for j in urdf.iter("joint")}
    assert [joints[n] for n in ("joint1", "joint2", "joint3")] == ["continuous"] * 3
    assert {ln.get("name") for ln in urdf.iter("link")} >= {
        "base_link", "column", "column_end", "forearm", "forearm_tip", "forearm_end"}


def test_planar_only_options_refused(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(SCENARIO)
    assert main(["simulate", str(path), "--method", "variable", "--out",
                 str(tmp_path / "o")]) == 2
    assert "--method: not available for a spatial scenario" in capsys.readouterr().err
    assert main(["simulate", "thesis_three_link_pd", "--bag", "--out",
                 str(tmp_path / "p")]) == 2
    assert "--bag: only for spatial scenarios" in capsys.readouterr().err


def test_a_newton_failure_is_one_line_and_exit_1(tmp_path, capsys):
    """A 1000 N m kick on seed 000's 0.28 m strip at 5 ms: the step's Newton fails even in
    substeps; the user gets one line naming the time and what to change (issue 47), not a
    traceback (a plain RuntimeError before)."""
    path = tmp_path / "kick.yaml"
    path.write_text("name: hard_kick\narm: seed000_real_arm_3d\nduration: 0.1\n"
                    "step: 5.0e-3\nsample_period: 0.005\ninitial: {joint_values: [0.0]}\n"
                    "pulses:\n  - {joint: joint1, torque: 1000.0, start: 0.0, end: 0.05}\n")
    assert main(["simulate", str(path), "--out", str(tmp_path / "o")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("flex-twin: failed: hard_kick: Newton did not "
                                               "converge in the step after t = 0 s")
    assert "reduce the step or the input" in err[0]


def test_kinematics_exact_on_a_spatial_scenario(tmp_path, capsys):
    """``--kinematics exact`` runs a spatial scenario (spatial/exact.py) and says so in the
    summary; at this arm's small deflections (< 1 mm) its tip path equals second_order's
    to 1e-6 m (they differ from the fourth order of the deflection)."""
    path = tmp_path / "short_003.yaml"
    path.write_text(SCENARIO.replace("duration: 0.2", "duration: 0.06"))
    tips = {}
    for kin in ("exact", "second_order"):
        assert main(["simulate", str(path), "--kinematics", kin, "--no-advice", "--no-plot",
                     "--json", "--out", str(tmp_path / kin)]) == 0
        summary = json.loads(capsys.readouterr().out)
        assert summary["kinematics"] == kin
        tips[kin] = np.array(summary["final_tip_m"])
    assert np.max(np.abs(tips["exact"] - tips["second_order"])) < 1e-6
