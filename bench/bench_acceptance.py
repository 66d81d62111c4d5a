"""The acceptance tier: the tests marked ``acceptance`` (diagnoses of minutes each: the
fixed-seed diagnosis subset of test/test_diagnosis_hidden_effects.py, the Quanser run of
issue 22), which ``make test`` skips, run here with every assertion; prints pytest's
verdicts and each diagnosis's verdict and time.

    python bench/bench_acceptance.py            # the default tier (about 6 min on 2 cores)
    python bench/bench_acceptance.py --full     # and the costliest five diagnoses
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def print_diagnoses(timings: Path) -> None:
    """The fixed-seed diagnoses' verdicts and times (the fixture writes them)."""
    if not timings.is_file():
        return
    runs = json.loads(timings.read_text())
    print(f"\n{'case':44s} {'verdict':34s} {'wall s':>7s} {'CPU s':>7s}")
    for case, r in runs.items():
        print(f"{case:44s} {str(r.get('verdict')):34s} {r.get('diagnose_s') or 0:7.1f} "
              f"{r.get('diagnose_cpu_s') or 0:7.1f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--full", action="store_true", help="the costliest diagnoses too")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        timings = Path(tmp) / "timings.json"
        env = {**os.environ, "FLEX_TWIN_ACCEPTANCE": "full" if args.full else "on",
               "FLEX_TWIN_DIAGNOSIS_TIMINGS": str(timings)}
        # no paths: pytest.ini's testpaths, every test directory
        code = subprocess.call([sys.executable, "-m", "pytest", "-m", "acceptance", "-q",
                                "-p", "no:cacheprovider", "--durations=0"],
                               cwd=ROOT, env=env)
        print_diagnoses(timings)
    return code


if __name__ == "__main__":
    sys.exit(main())
