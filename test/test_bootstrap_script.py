"""scripts/bootstrap.sh's command line (issue 43, fast feedback): ``--interfaces-in-background``
(the interface build goes on beside what follows) and ``--demo`` (``make demo``: the same,
and the twin demo's kernels start compiling once the wheels are in); anything else is
refused with one line before the script takes its lock or touches .venv."""
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_an_unknown_option_is_refused_with_one_line():
    res = subprocess.run(["bash", str(ROOT / "scripts" / "bootstrap.sh"), "--interfaces-later"],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2
    assert res.stderr.splitlines() == [
        "[bootstrap] error: unknown option --interfaces-later "
        "(only --interfaces-in-background or --demo)"]


def test_make_demo_builds_the_interfaces_beside_the_demo_and_waits_for_them():
    """The demo target starts the bootstrap in the demo mode (the interfaces in the
    background) after choosing numba's cache (the bootstrap starts compiling into it) and
    ends with a plain bootstrap.sh (which waits for the build's lock and fails if the build
    failed)."""
    recipe = (ROOT / "Makefile").read_text().split("\ndemo:")[1].split("\n\n")[0]
    assert "scripts/bootstrap.sh --demo" in recipe
    assert recipe.index("NUMBA_CACHE_DIR=") < recipe.index("bootstrap.sh --demo")
    assert recipe.rstrip().endswith("bash $(ROOT)/scripts/bootstrap.sh && exit $$status")
