"""The twin demo over ROS (planner -> model with Eq. 95 in its loop, one process), first
5.2 s of the thesis Ch. V task: the tip passes waypoint P2 at 5 s within 3 mm (measured
0.56 mm; the whole 15 s task: 0.56, 0.20, 0.12 mm; over topics 0.9, 0.8, 0.1 mm), and the
recorded bag holds the suite's topics in one time base, the simulation's (issue 23, defect
5): its duration is the simulated duration and ``play`` takes duration / rate of wall time.
With the controller in the model's loop the model publishes at its publish rate (50 Hz),
not after every control period, and no node publishes /effort_controller/commands (the
applied torques are the efforts of /joint_states)."""
import argparse
import json

import pytest

from flex_twin.bag_cli import add_bag_parsers
from flex_twin.bags import bag_info
from flex_twin.ros_twin_demo import run

from flex_model.command import run_command


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """The demo's first 5.2 s, run once: (summary, output directory)."""
    out = tmp_path_factory.mktemp("twin_demo")
    return run(out, duration=5.2), out


def test_twin_demo_passes_the_first_waypoints(demo):
    summary, tmp_path = demo
    errors = {w["t_s"]: w["tip_error_mm"] for w in summary["waypoints"]}
    assert errors[0.0] < 0.1 and errors[5.0] < 3.0
    assert 30.0 < summary["max_abs_tip_deflection_mm"][0] < 80.0
    info = bag_info(tmp_path / "bag")
    counts = {t["name"]: t["count"] for t in info["topics"]}
    assert counts["/joint_states"] == 5.2 * 50 + 1  # 50 Hz from t = 0
    assert counts["/effort_controller/commands"] == 0
    assert counts["/flex/shape"] >= 5.2 * 50 * 0.98
    assert json.loads((tmp_path / "summary.json").read_text())["waypoints"][1]["t_s"] == 5.0
    # one time base (sim time from 0): the bag spans the simulated 5.2 s within one period
    period = 1.0 / 500
    assert info["warnings"] == []
    assert info["duration_s"] == pytest.approx(5.2, abs=period + 1e-9)
    assert 0.0 <= info["start_time_s"] <= period and info["end_time_s"] <= 5.2 + period
    assert counts["/flex_planner/waypoints"] == 1  # latched, published before the recorder
    assert counts["/clock"] == 5.2 * 50 + 1
    assert summary["controller"] == "in the model's loop (eq95)"
    # where a first run's time goes (docs/development.md): the phases add up to wall_s,
    # and a child process compiled the in-loop kernels (or waited for the one compiling them)
    phases = summary["phases"]
    rows = {r["phase"]: r for r in phases["this_process"]}
    assert list(rows) == ["imports, rclpy.init", "wait for the shared kernels", "plan",
                          "wait for compile_ahead",
                          "model node", "loop and recording", "summary and plot"]
    timed = [r["wall_s"] for r in phases["this_process"][1:-1]]
    assert sum(timed) == pytest.approx(summary["wall_s"], abs=1e-3)
    assert phases["children_cpu_s"] > 0.0


def test_twin_demo_bag_plays_in_duration_over_rate(demo, capsys):
    """``play --clock --rate 4`` of the demo bag takes 5.2 s / 4 of wall time (it took 57
    years when log times mixed sim time and wall-clock time)."""
    _, tmp_path = demo
    parser = argparse.ArgumentParser()
    add_bag_parsers(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["play", str(tmp_path / "bag"), "--rate", "4", "--clock",
                              "--delay", "0", "--topics", "/joint_states", "/flex/tip_pose",
                              "/effort_controller/commands", "/clock"])
    assert run_command(args) == 0
    out = capsys.readouterr().out
    published = int(out.split("published ")[1].split()[0])
    wall = float(out.split(" in ")[1].split()[0])
    # /joint_states and /flex/tip_pose at 50 Hz (/clock is the player's)
    assert published == 2 * (5.2 * 50 + 1)
    assert 5.2 / 4 * 0.95 <= wall <= 5.2 / 4 * 1.5
