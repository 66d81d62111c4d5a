"""``flex-twin control step|design|check`` through flex_control.cli (JSON, plots, exits)."""
import argparse
import json
import subprocess
import sys

import numpy as np
import pytest

from flex_control.cli import add_control_parser, main
from flex_control.nominal import save_trajectory


def run(capsys, *argv):
    code = main(["control", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_parser_hooks_into_a_subparsers_object():
    parser = argparse.ArgumentParser(prog="flex-twin")
    add_control_parser(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["control", "check", "thesis_example1", "--h", "25", "--a", "5",
                              "--trajectory", "p.npz", "--json"])
    assert args.command == "control" and args.control_command == "check"
    assert args.h == [25.0] and callable(args.func)


def test_step_json_and_plot(capsys, tmp_path):
    code, out, _ = run(capsys, "step", "--arm", "seed000_real_arm", "--json", "--out",
                       str(tmp_path))
    assert code == 0
    res = json.loads(out)["results"][0]
    assert res["joint_rise_time_s"] == pytest.approx(np.log(9) / 70, rel=0.005)
    assert res["tip_frequency_hz"] == pytest.approx(8.46, rel=0.002)
    assert res["paper"]["frequency_hz_measured"] == 8.24
    assert (tmp_path / "step_seed000_real_arm.png").stat().st_size > 10_000


@pytest.fixture(scope="module")
def plan_file(section_f_quasi_static, tmp_path_factory):
    return save_trajectory(tmp_path_factory.mktemp("plan") / "plan.npz",
                           section_f_quasi_static)


def test_design_then_check_with_the_schedule(capsys, tmp_path, plan_file):
    code, out, _ = run(capsys, "design", "thesis_example1", "--trajectory", str(plan_file),
                       "--points", "3", "--json", "--out", str(tmp_path))
    assert code == 0
    d = json.loads(out)
    assert d["stabilizing"] and d["n_points"] == 3 and d["zeta_min"] > 0.01
    assert (tmp_path / "schedule.yaml").exists() and (tmp_path / "design.png").exists()
    code, out, _ = run(capsys, "check", "thesis_example1", "--trajectory", str(plan_file),
                       "--schedule", str(tmp_path / "schedule.yaml"), "--points", "3",
                       "--json", "--out", str(tmp_path / "chk"))
    c = json.loads(out)
    assert code == 0 and c["converged"] and c["frozen_time_stable"]
    assert len(c["frozen_time"]) == 3 and c["free_responses"]["count"] == 12
    assert (tmp_path / "chk" / "ltv.png").exists() and (tmp_path / "chk" / "frozen.png").exists()


def test_check_exit_code_follows_the_verdict(capsys, tmp_path, plan_file):
    common = ["check", "thesis_example1", "--trajectory", str(plan_file), "--points", "2",
              "--no-plot"]
    code, out, _ = run(capsys, *common, "--h", "25", "--a", "5", "--nonlinear", "--json")
    d = json.loads(out)
    assert code == 0 and d["converged"] and d["nonlinear"]["converged"]
    assert d["nonlinear"]["indices"] == [0, 4]      # alpha_1 and link 2's tip deflection
    assert d["nonlinear"]["max_tip_error_m"] < 2e-3
    code, out, _ = run(capsys, *common, "--h", "0.01", "--a", "5", "--json")
    assert code == 1 and json.loads(out)["converged"] is False


def test_quasi_static_waypoints_in_degrees(capsys, tmp_path):
    code, out, _ = run(capsys, "check", "seed000_table3", "--vars-per-link", "2",
                       "--waypoints-deg", "0", "20", "--times", "0", "2", "--sample-period",
                       "0.1", "--h", "0.5", "--a", "3", "--hold", "10", "--points", "2",
                       "--json", "--no-plot")
    d = json.loads(out)
    assert code == 0 and d["converged"] and d["horizon_s"] == [0.0, 12.0]
    # no gravity in the plane: the frozen loop is stable for any positive gain scale
    assert d["frozen_time"][0]["gain_margin_low"] == d["frozen_time"][0]["gain_margin_high"] \
        == 1e3


@pytest.mark.parametrize("argv,match", [
    (["check", "thesis_example1", "--waypoints-deg", "1", "2", "3", "--times", "0", "1",
      "--h", "1", "--a", "1"], "--waypoints-deg: got 3 values; expected 2 per time"),
    (["check", "thesis_example1", "--h", "1", "--a", "1"], "--trajectory or --waypoints-deg"),
    (["check", "thesis_example1", "--waypoints-deg", "0", "0", "1", "1", "--times", "0", "1",
      "--h", "-1", "--a", "1"], r"--h: got \[-1.0\]; expected 1 or 2 values > 0"),
    (["step", "--arm", "no_such_arm"], "no_such_arm"),
])
def test_bad_input_exits_2_with_one_line(capsys, argv, match):
    code, _, err = run(capsys, *argv)
    assert code == 2 and err.count("\n") == 1
    assert pytest.importorskip("re").search(match, err)


def test_module_entry_point(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "flex_control.cli", "control", "step",
                           "--arm", "seed000_table3", "--duration", "1.0", "--json",
                           "--no-plot"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout)["results"][0]["arm"] == "seed000_table3"
