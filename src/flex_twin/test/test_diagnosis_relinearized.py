"""engine._relinearized: a later round that screens nothing in screens again from the
linearization at the named twin (its scales, effects and residuals), not the one of the
fine fit's baseline step (taken with the effect at its screening value). Independent
suite, B-cont-two-sensor_bias+stiffness-s2: with the stale one the joint-2 bias screened
under 0.1 (need 3.9) and round 2 fitted nothing; at the twin, 14.7 (docs/diagnosis.md).
The replays are replaced by a linear residual model (the rule alone, no twin)."""
from types import SimpleNamespace

import numpy as np

from flex_twin.diagnosis import engine


def test_relinearized_at_the_current_twin(monkeypatch):
    A = np.array([[1.0, 0.0], [0.0, 2.0], [1.0, 1.0]])   # residual r(s) = A (s - s*)
    s_star = np.array([0.9, 1.1])
    seen = {}

    def jacobian(executor, ctx, scales, effects, r0):
        seen["jacobian_at"] = (np.array(scales), list(effects), np.array(r0))
        return A * (1.0 + np.linalg.norm(scales - s_star))   # differs off the point

    def linearize(executor, ctx, scales, effects, Jb):
        seen["linearized_at"] = (np.array(scales), list(effects))
        return SimpleNamespace(J=Jb)

    monkeypatch.setattr(engine, "baseline_jacobian", jacobian)
    monkeypatch.setattr(engine, "linearize", linearize)
    effects = [("stiffness@link1", np.array([-0.887]))]
    current = SimpleNamespace(scales=s_star.copy(), effects=effects,
                              r=A @ (s_star - s_star))
    lin = engine._relinearized(None, None, current)
    np.testing.assert_array_equal(seen["jacobian_at"][0], s_star)
    assert seen["jacobian_at"][1] == effects
    np.testing.assert_array_equal(seen["jacobian_at"][2], current.r)
    np.testing.assert_array_equal(seen["linearized_at"][0], s_star)
    np.testing.assert_allclose(lin.J, A)   # the Jacobian at the twin, not elsewhere


def test_a_later_round_screens_again_only_when_nothing_screened_in(monkeypatch):
    calls = []

    def ranked(executor, ctx, hyps, current, lin, top, need):
        calls.append(lin)
        return {}, {}, {}, (["h"] if lin == "fresh" else [])

    monkeypatch.setattr(engine, "_ranked", ranked)
    monkeypatch.setattr(engine, "_relinearized", lambda executor, ctx, current: "fresh")
    # the first round (need None) keeps its linearization even when nothing screens in
    assert engine._screened_round(None, None, [], None, "stale", 4, None)[0] == "stale"
    assert calls == ["stale"]
    calls.clear()
    lin, out = engine._screened_round(None, None, [], None, "stale", 4, 3.8)
    assert (lin, out[3], calls) == ("fresh", ["h"], ["stale", "fresh"])
    calls.clear()   # a later round that screens something in: no second screening
    monkeypatch.setattr(engine, "_relinearized", lambda *a: "unused")
    assert engine._screened_round(None, None, [], None, "fresh", 4, 3.8)[0] == "fresh"
    assert calls == ["fresh"]
