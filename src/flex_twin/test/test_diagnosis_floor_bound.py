"""Issue 44, item 2: the model-form floor measures only the twin's own error, never a
physical effect. Re-measured with the named effects (floor.model_form_with), the model form
counted by the gate is bounded by the twin's own error at the nominal parameters (the first
measurement's d at the chosen setting): the rule alone, on a stated Floor (no replay)."""
import math

from flex_twin.diagnosis.floor import Floor, Setting, bounded_model_form

S = Setting((2, 2), "small_deflection", 1e-3)


def _floor(own):
    zero = {"fit": 0.0, "holdout": 0.0}
    return Floor(S, S, S, dict(own), dict(own), zero, zero, zero, zero, {}, False)


def test_the_remeasured_model_form_is_bounded_by_the_twins_own_error():
    fl = _floor({"fit": 21.0, "holdout": 18.0})
    # a joint friction left out while the payload is named: the twins' difference along
    # the data's residual grows to thousands of noise units; the gate counts the own error
    assert bounded_model_form(fl, {"fit": 3.9e3, "holdout": 3.65e3}) == \
        {"fit": 21.0, "holdout": 18.0}
    # under the bound the re-measured model form stands (the Exudyn payload case
    # B-samp500-payload-m1-s1: 1.0 / 0.92 with an own error of ~5-7)
    assert bounded_model_form(fl, {"fit": 1.0, "holdout": 0.92}) == \
        {"fit": 1.0, "holdout": 0.92}


def test_no_own_error_measured_no_model_form():
    fl = _floor({"fit": math.nan, "holdout": math.nan})
    assert bounded_model_form(fl, {"fit": 5.0, "holdout": 5.0}) == {"fit": 0.0, "holdout": 0.0}
