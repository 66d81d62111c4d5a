"""engine._prune, the backward pruning of named effects: an effect is dropped when the
others without it leave the held-out excess under the gate or it explains less than
MIN_SHARE of the excess that remains without it; the rest are kept. The replays are
replaced by a table of held-out costs per set of effects (the rule alone, no twin)."""
from types import SimpleNamespace

import numpy as np

from flex_twin.diagnosis import engine


def _prune_with(table, names, cur_ho, gate=0.45, monkeypatch=None, unresolved=()):
    """Run _prune on effects ``names`` with held-out costs ``table[frozenset]``; the gain
    of the twin over one without the effects ``unresolved`` is not resolved."""
    def evaluate(spec):
        ctx, _, effects = spec
        labels = frozenset(h.label for h, _ in effects)
        return np.array([table[labels] if ctx == "ho" else table[labels] + 1.0])

    monkeypatch.setattr(engine, "evaluate", evaluate)
    monkeypatch.setattr(engine, "cost", lambda r: float(r[0]))
    monkeypatch.setattr(engine, "linearize", lambda *a: lin)
    monkeypatch.setattr(engine, "_refit_named", lambda *a: None)
    monkeypatch.setattr(engine, "_restate", lambda *a: None)
    monkeypatch.setattr(engine, "twin_arm", lambda *a: None)
    without = {table[frozenset(names) - {u}] for u in unresolved}
    monkeypatch.setattr(engine, "_gain_resolved",
                        lambda ctx_ho, r_with, r_without: float(r_without[0]) not in without)
    lin = SimpleNamespace(J=np.zeros((1, 1)), n_scales=1)
    effects = [(SimpleNamespace(label=n), np.zeros(1)) for n in names]
    current = engine.FitResult(np.ones(1), effects, np.zeros(1), cur_ho + 1.0)
    accepted = [SimpleNamespace(label=n) for n in names]
    out = engine._prune(None, "fit", "ho", current, cur_ho, lin, accepted, gate,
                        engine.MIN_SHARE, None, 0.0)
    return [c.label for c in out[3]], out[1]


def test_an_effect_that_explains_little_of_what_remains_without_it_is_dropped(monkeypatch):
    f = frozenset
    table = {f("ABC"): 3.0, f("BC"): 50.0, f("AC"): 40.0, f("AB"): 3.5,   # C: 0.2
             f("B"): 60.0, f("A"): 45.0}
    kept, ho = _prune_with(table, "ABC", 3.0, monkeypatch=monkeypatch)
    assert kept == ["A", "B"] and ho == 3.5
    # C explains 0.4 of the 5.0 - 1 left without it (>= MIN_SHARE 0.35): kept
    table[f("AB")] = 1.0 + (3.0 - 1.0) / (1.0 - 0.4)
    kept, ho = _prune_with(table, "ABC", 3.0, monkeypatch=monkeypatch)
    assert kept == ["A", "B", "C"] and ho == 3.0


def test_an_effect_whose_absence_stays_under_the_gate_is_dropped(monkeypatch):
    f = frozenset
    # without B the held-out excess is 0.4, under the gate 0.45 (B "explains" 0.75 of it)
    table = {f("AB"): 1.1, f("A"): 1.4, f("B"): 30.0}
    kept, ho = _prune_with(table, "AB", 1.1, monkeypatch=monkeypatch)
    assert kept == ["A"] and ho == 1.4
    # one named effect is never pruned
    kept, _ = _prune_with({f("A"): 1.4}, "A", 1.4, monkeypatch=monkeypatch)
    assert kept == ["A"]


def test_an_effect_whose_gain_the_held_out_data_do_not_resolve_is_dropped(monkeypatch):
    """The suite's B-samp500-stiffness-m1-s1: a structural damping of link 2 named after
    link 1's stiffness (the truth). The share rule keeps C (0.6 of what remains without
    it); when the held-out residuals do not resolve the twin with C from the one without
    it (engine._gain_resolved, the test of the near-ties), C is dropped."""
    f = frozenset
    table = {f("AC"): 2.0, f("A"): 3.5, f("C"): 40.0}
    kept, _ = _prune_with(table, "AC", 2.0, monkeypatch=monkeypatch)
    assert kept == ["A", "C"]
    kept, ho = _prune_with(table, "AC", 2.0, monkeypatch=monkeypatch, unresolved="C")
    assert kept == ["A"] and ho == 3.5


def test_a_gain_is_resolved_by_the_block_test():
    """engine._gain_resolved on white residuals, 10 s at 500 Hz in two channels."""
    from types import SimpleNamespace as NS
    rng = np.random.default_rng(5)
    ctx_ho = NS(rec=NS(residual_channels=["q1", "q2"], dt=2e-3))
    r_without = rng.standard_normal(10000) * np.sqrt(1.5)
    assert engine._gain_resolved(ctx_ho, rng.standard_normal(10000), r_without)
    assert not engine._gain_resolved(ctx_ho, r_without * 0 + rng.standard_normal(10000)
                                     * np.sqrt(1.5), r_without)
