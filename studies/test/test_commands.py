"""The studies' command lines (issue 43): every study runs as ``python -m studies.<name>``
with its own parser and the package's exit codes, and studies/README.md lists it."""
import importlib
import subprocess
import sys
from pathlib import Path

import pytest

STUDIES = Path(__file__).resolve().parents[1]
#: the studies with a command line (session_friction runs inside stick_slip_study)
COMMANDS = ("stick_slip_study", "unit_calibration", "stuck_holds", "link_response",
            "run_floor", "servo_split", "stiction_evidence", "transfer", "two_mass_study",
            "ucmerced_long", "cantilever", "frequency_gap")


def test_every_study_with_a_main_is_listed():
    found = {p.stem for p in STUDIES.glob("*.py")
             if "\ndef main(" in p.read_text(encoding="utf-8")}
    assert found == set(COMMANDS)
    readme = (STUDIES / "README.md").read_text(encoding="utf-8")
    assert all(f"python -m studies.{name}" in readme for name in COMMANDS)


@pytest.mark.parametrize("name", COMMANDS)
def test_help_names_the_command(name, capsys):
    module = importlib.import_module(f"studies.{name}")
    with pytest.raises(SystemExit) as done:
        module.main(["--help"])
    assert done.value.code == 0
    assert capsys.readouterr().out.startswith(f"usage: python -m studies.{name} ")


def test_bad_input_exits_2_with_one_line(capsys):
    """``--gauge-delay`` without ``--fit`` (no refit to add the lag to): exit 2, one line."""
    from studies import unit_calibration
    assert unit_calibration.main(["--gauge-delay", "--data", "/nonexistent"]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "give --fit too" in err[0]


def test_python_dash_m_runs_from_the_repository_root():
    done = subprocess.run([sys.executable, "-m", "studies.transfer", "--help"],
                          cwd=STUDIES.parent, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "DIAGNOSIS/transfer" in done.stdout
