"""flex-twin modes / static on spatial arms (issue 25): the same commands as planar arms,
dispatched by the arm file; numbers against closed forms of seed 000's strip in 3D."""
import json

import numpy as np
import pytest

from flex_twin.cli import main
from flex_twin.spatial_cli import is_spatial

G = 9.81
L, RHO_A, EI_STIFF, M_TIP = 0.28, 0.1289, 248.0, 0.025607   # seed000_real_arm_3d


def _json(capsys, argv):
    assert main(argv) == 0
    return json.loads(capsys.readouterr().out)


def test_spatial_presets_and_files_are_told_from_planar_ones(tmp_path):
    assert is_spatial("seed000_real_arm_3d") and is_spatial("ur5_like_flexible_forearm")
    assert not is_spatial("seed000_real_arm") and not is_spatial("thesis_example1")
    planar = tmp_path / "arm.yaml"
    planar.write_text("name: x\nlinks: []\n")
    assert not is_spatial(planar) and not is_spatial(tmp_path / "missing.yaml")


def test_modes_of_seed000_in_3d(capsys):
    """Horizontal bending first (8.46 Hz, the planar seed 000 value, VALIDATION.md G); the
    first vertical (stiff-plane) mode of the clamped strip with its tip mass: Rayleigh
    quotient of the static deflection shape, within 1 %."""
    out = _json(capsys, ["modes", "seed000_real_arm_3d", "--count", "6", "--json"])
    f = out["frequencies_hz"]
    assert f[0] == pytest.approx(8.46, abs=0.01) and out["dominant"][0] == "v"
    k = 3 * EI_STIFF / L ** 3
    m_eff = M_TIP + 33 / 140 * RHO_A * L
    f_w = [fk for fk, d in zip(f, out["dominant"]) if d == "w"][0]
    assert f_w == pytest.approx(np.sqrt(k / m_eff) / (2 * np.pi), rel=0.01)


def test_static_droop_of_seed000_in_3d(capsys):
    """Tip droop under gravity in the stiff plane: q L^4 / (8 EI) + m g L^3 / (3 EI)."""
    out = _json(capsys, ["static", "seed000_real_arm_3d", "--nonlinear", "--json"])
    w = out["links"]["link1"]["w"]
    expected = RHO_A * G * L ** 4 / (8 * EI_STIFF) + M_TIP * G * L ** 3 / (3 * EI_STIFF)
    assert -w == pytest.approx(expected, rel=2e-3)
    assert out["tip_position_m"][2] == pytest.approx(w, rel=1e-3)


@pytest.mark.parametrize("argv, flag", [
    (["modes", "seed000_real_arm_3d", "--joints", "pd"], "--joints pd"),
    (["modes", "seed000_real_arm_3d", "--vars-per-link", "4"], "--vars-per-link"),
    (["static", "seed000_real_arm_3d", "--tip-force", "1"], "--tip-force"),
    (["modes", "seed000_real_arm_3d", "--joint-angles-deg", "1", "2"], "--joint-angles-deg"),
])
def test_planar_only_options_get_one_line(capsys, argv, flag):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and flag in err[0] and "seed000_real_arm_3d" in err[0]


def test_presets_lists_the_spatial_arms(capsys):
    out = _json(capsys, ["presets", "--json"])
    assert {"seed000_real_arm_3d", "ur5_like_flexible_forearm"} <= set(out["spatial_arms"])
    assert not set(out["spatial_arms"]) & set(out["arms"])
