"""Issue 44, item 1, on data the twin did not make: Exudyn case C-cont-stiffness20-link2-s1
(test/data/independent_suite: the hub-less two-link arm with Kelvin-Voigt damping in its
nominal description, continuous PD, link 2's E 20 % low). The recalibration within
tolerance reaches the gate with link 2's EI at its bound (held out J 0.75 against the
nominal's 3.73): before the rule the verdict was "no material discrepancy". With it the
recalibration is set aside and the stiffness of link 2 is named with its value (51.05 GPa
measured, truth 51.2 GPa). Minutes of diagnosis: acceptance tier."""
from pathlib import Path

import pytest
import yaml

from flex_twin.diagnosis.batch import RunSpec, diagnose_run
from flex_twin.diagnosis.evaluation import default_executor

CASE = Path(__file__).resolve().parent / "data" / "independent_suite" / \
    "C-cont-stiffness20-link2-s1"


@pytest.mark.acceptance
def test_a_link_stiffness_absorbed_at_its_tolerance_bound_is_named(tmp_path):
    truth = yaml.safe_load((CASE / "truth.yaml").read_text())
    E_true = truth["hidden"][0]["parameters"]["E"]
    run = RunSpec.from_case_dir(CASE)
    pool = default_executor()
    try:
        s = diagnose_run(run, str(tmp_path), plots=False, executor=pool)
    finally:
        if hasattr(pool, "shutdown"):
            pool.shutdown()
    assert [a["scale"] for a in s["at_bound"]] == ["link2.EI"]
    assert s["verdict"] == "named", s["stop"]
    assert [n["label"] for n in s["named"]] == ["stiffness@link2"]
    assert s["named"][0]["parameters"]["E"] == pytest.approx(E_true, rel=0.05)
    assert s["reduction_by"]["named_effects"] > 0.9
    assert s["stop"] == "held-out excess within the gate"
    assert "outside its tolerance" in (tmp_path / "report.md").read_text()


if not CASE.is_dir():  # pragma: no cover - the case is committed with the tests
    pytest.skip(f"{CASE} missing", allow_module_level=True)
