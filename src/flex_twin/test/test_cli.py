"""The ``flex-twin`` command line, run in-process: JSON outputs, exit codes, the run CSV."""
import contextlib
import io
import json
import os

import numpy as np
import pytest

from flex_model.arm import preset_names
from flex_twin.cli import main

HEADER = ("t,q1,q2,q3,v1,v2,v3,tau1,tau2,tau3,tip_x,tip_y,link1_tip_deflection,"
          "link2_tip_deflection,link3_tip_deflection,link1_tip_rotation,link2_tip_rotation,"
          "link3_tip_rotation")
SUMMARY_KEYS = {"scenario", "arm", "vars_per_link", "duration_s", "method", "wall_s", "cpu_s",
                "cpu_s_per_simulated_s", "steps", "csv", "final_joint_angles_deg",
                "final_tip_m", "max_abs_tip_deflection_mm"}


def run_json(capsys, *argv):
    assert main(list(argv)) == 0
    out, err = capsys.readouterr()
    assert err == ""
    return json.loads(out)


def test_modes_single_link(capsys):
    out = run_json(capsys, "modes", "thesis_single_link", "--joints", "clamped", "--count",
                   "10", "--json")
    assert {"frequencies_hz", "omega_rad_s", "inertia_condition_number"} <= set(out)
    assert len(out["omega_rad_s"]) == len(out["frequencies_hz"]) == 10
    assert [round(w, 4) for w in out["omega_rad_s"][:3]] == [0.1406, 0.8818, 2.4768]
    assert np.allclose(2 * np.pi * np.array(out["frequencies_hz"]), out["omega_rad_s"])
    assert out["inertia_condition_number"] == pytest.approx(785, abs=1)


@pytest.mark.parametrize("argv, deg, mm", [
    (["--joints", "clamped", "--tip-torque", "10", "--no-gravity"], 7.81, 273),
    (["--tip-force", "5", "--no-gravity"], 7.81, 363),
    ([], -4.19, -220),
], ids=["tip_torque", "tip_force", "own_weight"])
def test_static_example1(capsys, argv, deg, mm):
    out = run_json(capsys, "static", "thesis_example1", *argv, "--json")
    assert out["analysis"] == "linear"
    assert round(out["tip_rotation_deg"], 2) == deg
    assert round(out["tip_displacement_mm"]) == mm
    assert len(out["links"]) == 2
    assert all(set(lk) == {"tip_deflection_m", "tip_rotation_rad"} for lk in out["links"])
    # the tip rotation is the sum of the link tip rotations (joints clamped at 0)
    total = sum(lk["tip_rotation_rad"] for lk in out["links"])
    assert np.degrees(total) == pytest.approx(out["tip_rotation_deg"], rel=1e-9)
    assert out["tip_position_m"][0] == 4.0  # linear response: no foreshortening


def test_static_nonlinear(capsys):
    out = run_json(capsys, "static", "thesis_example1", "--nonlinear", "--json")
    assert out["analysis"] == "nonlinear"
    assert round(out["tip_rotation_deg"], 2) == -4.19
    # the exact equilibrium shortens the sagging arm's reach (linear: exactly 4 m)
    assert 3.99 < out["tip_position_m"][0] < 3.999


@pytest.mark.parametrize("argv, fragment", [
    (["static", "no_such_arm"], "no_such_arm: <preset>: got 'no_such_arm'; expected"),
    (["modes", "thesis_example1", "--vars-per-link", "3"],
     "vars_per_link: got 3; expected an even integer >= 2"),
    (["static", "thesis_example1", "--joints", "pd"], "--kp: required with --joints pd"),
    (["modes", "thesis_example1", "--joints", "pd"], "--kp: required with --joints pd"),
    (["static", "thesis_example1", "--joint-angles-deg", "10", "20", "30"],
     "--joint-angles-deg: got 3 values; expected 2"),
], ids=["unknown_preset", "odd_vars", "static_pd_no_kp", "modes_pd_no_kp", "angle_count"])
def test_bad_input_exits_2_with_one_line(capsys, argv, fragment):
    assert main(argv + ["--json"]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    assert err.startswith("flex-twin: error: ") and err.endswith("\n")
    assert err.count("\n") == 1
    assert fragment in err


def test_presets_lists_arms_and_scenarios(capsys):
    out = run_json(capsys, "presets", "--json")
    assert sorted(out["arms"]) == preset_names()
    assert "thesis_three_link" in out["arms"] and "thesis_example1" in out["arms"]
    assert out["arms"]["thesis_three_link"].startswith("Three steel links")
    assert "thesis_three_link_pd" in out["scenarios"]


def test_ros_environment_defaults(monkeypatch, capsys):
    monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE", raising=False)
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    run_json(capsys, "presets", "--json")
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    # the user's processes keep ROS's default domain: separate terminals see each other
    assert "ROS_DOMAIN_ID" not in os.environ
    # a domain the user chose is kept
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    run_json(capsys, "presets", "--json")
    assert os.environ["ROS_DOMAIN_ID"] == "42"
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


@pytest.fixture(scope="module")
def simulated(tmp_path_factory):
    """One 0.2 s run of the section E scenario (shared: the simulation takes seconds)."""
    out_dir = tmp_path_factory.mktemp("run")
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = main(["simulate", "thesis_three_link_pd", "--duration", "0.2", "--out",
                     str(out_dir), "--no-plot", "--json"])
    assert code == 0, stderr.getvalue()
    csv = out_dir / "thesis_three_link_pd.csv"
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    return out_dir, json.loads(stdout.getvalue()), csv, data


def test_simulate_writes_csv_and_summary(simulated):
    out_dir, summary, csv, data = simulated
    assert csv.read_text().splitlines()[0] == HEADER
    assert data.shape == (41, 18)
    assert data[:, 0] == pytest.approx(np.arange(41) * 0.005, abs=1e-12)
    first = data[0]
    # start at the set point, at rest and undeformed: PD torque exactly zero
    assert first[1:4] == pytest.approx(np.radians([-20.0, 20.0, -20.0]), rel=1e-10)
    assert list(first[4:7]) == [0.0, 0.0, 0.0]
    assert list(first[7:10]) == [0.0, 0.0, 0.0]  # tau1, tau2, tau3
    absolute = np.radians([-20.0, 0.0, -20.0])
    tip = 2.5 * np.array([np.cos(absolute).sum(), np.sin(absolute).sum()])
    assert first[10:12] == pytest.approx(tip, abs=1e-8)
    # gravity then pulls the arm down: joint 1 sags, PD pushes back
    assert data[-1, 1] < first[1] and data[-1, 7] > 0
    assert SUMMARY_KEYS <= set(summary) and "png" not in summary
    assert summary["csv"] == str(csv)
    assert (summary["scenario"], summary["arm"]) == ("thesis_three_link_pd",
                                                     "thesis_three_link")
    assert summary["duration_s"] == 0.2 and summary["vars_per_link"] == [4, 4, 4]
    assert summary["final_joint_angles_deg"] == pytest.approx(np.degrees(data[-1, 1:4]),
                                                              rel=1e-9)
    assert summary["final_tip_m"] == pytest.approx(data[-1, 10:12], rel=1e-9)
    assert sorted(p.name for p in out_dir.iterdir()) == ["thesis_three_link_pd.csv"]


def test_simulate_csv_keeps_full_precision(simulated):
    first = simulated[3][0]
    assert first[1:4] == pytest.approx(np.radians([-20.0, 20.0, -20.0]), abs=1e-12, rel=0)


def test_modes_state_space_file_reproduces_frequencies(tmp_path, capsys):
    """The written A matrix has the clamped arm's natural frequencies as eigenvalues."""
    path = tmp_path / "ss.npz"
    assert main(["modes", "thesis_example1", "--joints", "clamped", "--json",
                 "--state-space", str(path)]) == 0
    out = json.loads(capsys.readouterr().out)
    data = np.load(path)
    lam = np.linalg.eigvals(data["A"])
    f = np.sort(np.abs(lam.imag[lam.imag > 0])) / (2 * np.pi)
    np.testing.assert_allclose(f, out["frequencies_hz"], rtol=1e-9)
    assert list(data["inputs"]) == ["tip/force_x", "tip/force_y", "tip/torque"]
    assert data["C"].shape[0] == len(data["outputs"]) == 2 + 3 + 2


def test_effects_library_listing(capsys):
    assert main(["effects", "--json"]) == 0
    lib = json.loads(capsys.readouterr().out)
    types = {e["type"]: e for e in lib["effects"]}
    assert {"gear", "joint_elasticity", "joint_friction", "backlash", "dc_motor",
            "structural_damping", "contact_surface", "timoshenko", "torque_saturation",
            "actuator_delay", "base_tilt", "cogging"} <= set(types)
    fr = {p["name"]: p for p in types["joint_friction"]["parameters"]}
    assert fr["coulomb"]["unit"] == "N m" and fr["coulomb"]["off"] == 0.0
    assert "Coulomb within Stribeck" in types["joint_friction"]["equivalent"]
    assert lib["nominal_tolerances"]["E"] == 0.05
