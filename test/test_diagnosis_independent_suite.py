"""The diagnosis on data it did not make (issue 21): a healthy run of the Exudyn suite
(test/data/independent_suite, bench/independent_suite/generate.py: geometrically exact ANCF
cable elements, a two-link aluminium arm without hub inertia under a continuous PD).

Before the continuous laws and the model-form floor this run could not be replayed with its
controller, and with the D term rewritten by hand the search named a spurious rotor inertia
at joint 2: the twin's own model-form error was above the gate."""
from pathlib import Path

import pytest
import yaml

from flex_twin.diagnosis.batch import RunSpec, diagnose_run
from flex_twin.diagnosis.evaluation import default_executor

SUITE = Path(__file__).resolve().parent / "data" / "independent_suite"
HEALTHY = "A-cont-healthy-s1"


def test_a_healthy_run_of_an_independent_simulator_is_no_material_discrepancy(tmp_path):
    case = SUITE / HEALTHY
    truth = yaml.safe_load((case / "truth.yaml").read_text())
    assert truth["expected"] == "none" and truth["hidden"] == []
    run = RunSpec.from_case_dir(case)
    pool = default_executor()
    try:
        s = diagnose_run(run, str(tmp_path), plots=False, executor=pool)
    finally:
        if hasattr(pool, "shutdown"):
            pool.shutdown()
    assert s["verdict"] == "no material discrepancy", s["stop"]
    assert s["named"] == []
    # the floor saw a finer model's run: the replay was refined and the part of the
    # residual that is model form is stated (0.051 measured), within the gate
    g = s["gate"]
    assert s["floor"] is not None
    assert 0 < g["model_form_holdout"] < g["excess_threshold"]
    assert g["baseline_excess_holdout"] < g["effective_threshold"]
    assert "model form" in (tmp_path / "report.md").read_text()


if not SUITE.is_dir():  # pragma: no cover - the suite is committed with the tests
    pytest.skip(f"{SUITE} missing", allow_module_level=True)
