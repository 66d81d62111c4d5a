"""``flex-twin plan`` (flex_planner.cli): CSV and PNG of the section F plan, waypoint files,
errors with exit code 2; and the core imports without ROS."""
import argparse
import json
import subprocess
import sys

import numpy as np
import pytest

from flex_planner import SECTION_F_TIMES, SECTION_F_WAYPOINTS
from flex_planner.cli import add_plan_parser, main


def run(argv):
    parser = argparse.ArgumentParser(prog="flex-twin")
    add_plan_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.func(args)


def test_section_F_task_writes_csv_png_and_summary(tmp_path, capsys):
    assert run(["plan", "thesis_example1", "--task", "thesis_ch5", "--sample-period", "0.01",
                "--out", str(tmp_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["samples"] == 1501 and summary["elbow"] == "up"
    for k, w in enumerate(summary["waypoints"]):
        assert w["target_m"] == SECTION_F_WAYPOINTS[k].tolist()
        assert w["static_tip_error_m"] < 1e-6           # independent forward static solve
        assert w["nominal_tip_error_mm"] < 5.0
    header = (tmp_path / "plan.csv").read_text().splitlines()[0].split(",")
    assert header[:3] == ["t", "joint1_position", "joint2_position"]
    assert "joint2_effort" in header and "link1_tip_deflection" in header
    data = np.loadtxt(tmp_path / "plan.csv", delimiter=",", skiprows=1)
    assert data.shape == (1501, len(header))
    np.testing.assert_allclose(data[-1, header.index("tip_x")], -1.0, atol=5e-3)
    assert (tmp_path / "plan.png").stat().st_size > 10_000


def test_waypoint_file_with_elbow_and_tip_load(tmp_path, capsys):
    path = tmp_path / "task.yaml"
    path.write_text("elbow: down\ntip_load: {force: [0.0, -1.0]}\nwaypoints:\n"
                    + "".join(f"  - {{t: {t}, x: {x}, y: {y}}}\n"
                              for t, (x, y) in zip(SECTION_F_TIMES, SECTION_F_WAYPOINTS)))
    assert run(["plan", "thesis_example1", str(path), "--sample-period", "0.05",
                "--no-plot", "--out", str(tmp_path), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["elbow"] == "down" and "png" not in summary
    assert summary["waypoints"][0]["joint_angles_deg"][1] < 0     # elbow down: bend < 0 here
    assert all(w["static_tip_error_m"] < 1e-6 for w in summary["waypoints"])


@pytest.mark.parametrize("text, message", [
    ("waypoints:\n  - {t: 0, x: -1, y: -1}\n  - {t: 1, x: 5, y: 0}\n",
     "waypoint 1 at (5, 0) m is unreachable: outside the reach"),
    ("waypoints:\n  - {t: 0, x: -1, y: -1}\n  - {t: 1, x: -2}\n", "waypoints[1].y: got <missing>"),
    ("waypoints:\n  - {t: 1, x: -1, y: -1}\n  - {t: 0, x: -2, y: -1}\n",
     "times[1]: got 0.0 s after 1.0 s"),
    ("waypoint: []\n", "waypoints: got <missing>"),
])
def test_bad_waypoint_files_exit_2_naming_the_problem(tmp_path, capsys, text, message):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    assert main(["plan", "thesis_example1", str(path), "--out", str(tmp_path),
                 "--no-plot"]) == 2
    assert message in capsys.readouterr().err


def test_file_or_task_but_not_both(tmp_path, capsys):
    assert main(["plan", "thesis_example1", "--out", str(tmp_path)]) == 2
    assert "give a waypoint YAML file or --task" in capsys.readouterr().err


def test_core_modules_import_without_ros():
    core = ["flex_planner", "flex_planner.cli", "flex_planner.closed_form",
            "flex_planner.config", "flex_planner.inverse_statics", "flex_planner.nominal_input",
            "flex_planner.planning", "flex_planner.plots", "flex_planner.residual_vibration",
            "flex_planner.rigid_kinematics", "flex_planner.trajectories"]
    code = ("import sys\n"
            "class Block:\n"
            "    def find_spec(self, name, path=None, target=None):\n"
            "        if name.split('.')[0] in ('rclpy', 'rosidl_runtime_py', 'nav_msgs',\n"
            "                'trajectory_msgs', 'geometry_msgs', 'builtin_interfaces'):\n"
            "            raise ImportError('ROS hidden: ' + name)\n"
            "sys.meta_path.insert(0, Block())\n"
            + "".join(f"import {m}\n" for m in core))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
