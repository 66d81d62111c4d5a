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


def test_model_form_with_the_named_effects_counts_at_most_the_own_error(monkeypatch):
    """model_form_with on stated replays: the data's residual lies wholly along the twins'
    difference (along 1) and that difference is 3.65e3 noise units with the effects named;
    the gate counts the own error at the nominal parameters instead."""
    import dataclasses

    import numpy as np

    from flex_model.arm import load_arm
    from flex_twin.diagnosis import floor as floor_mod

    @dataclasses.dataclass
    class Ctx:
        nominal: object
        dt: float

    ref = Setting((4, 4), "second_order", 2.5e-4)
    fl = Floor(S, ref, S, {"fit": 21.0, "holdout": 18.0}, {"fit": 21.0, "holdout": 18.0},
               {}, {}, {}, {"fit": 0.0, "holdout": 0.0}, {}, False)
    u = np.full(100, np.sqrt(3.65e3))

    def evaluate(spec):   # the replay at S leaves u, the refined twin nothing
        ctx, _, _ = spec
        return u.copy() if ctx.dt == S.dt else np.zeros_like(u)

    monkeypatch.setattr(floor_mod, "evaluate", evaluate)
    arm = load_arm("thesis_example1")
    out = floor_mod.model_form_with(SimpleExecutor(), Ctx(arm, S.dt), Ctx(arm, S.dt), fl,
                                    np.ones(4), [])
    assert out["along"]["holdout"] == 1.0
    assert out["model_form_unbounded"]["holdout"] == 3.65e3
    assert out["model_form"] == {"fit": 21.0, "holdout": 18.0}


class SimpleExecutor:
    map = staticmethod(lambda f, xs: [f(x) for x in xs])
