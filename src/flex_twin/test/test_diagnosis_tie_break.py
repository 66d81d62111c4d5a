"""engine._tie_break: a pick the screening fit puts within TIE of another acceptable
candidate of the same shape and size is decided by their fine fits' held-out costs; a
rival with more parameters, further than TIE, of the other shape (pair / single), not
acceptable or of the pick's equivalence class is not fitted. The fine fits are replaced
by a table of held-out costs (the rule alone, no twin)."""
from types import SimpleNamespace

from flex_twin.diagnosis import engine


def _cand(label, share, n_params=2, ok=True):
    return engine.Candidate(label=label, kind=label, target="", names=(), values=[], ci=[],
                            x=[], screen=0.0, J_fit=2.0, J_holdout=2.0, share=share,
                            delta_bic=-10.0 if ok else 10.0, cond=1.0, identifiable=True,
                            n_params=n_params, share_fit=share)


def _tie_break(cands, fine_ho, pick_label, monkeypatch):
    """(the kept label, the labels fine-fitted besides the pick)."""
    fitted = []

    def accept(executor, ctx, ctx_ho, fit):
        fitted.append(fit[0].label)
        return (None, fine_ho[fit[0].label], None, (None, None))

    monkeypatch.setattr(engine, "_accept", accept)
    fits = {c.label: (SimpleNamespace(label=c.label, effects=[(SimpleNamespace(  # a single
        kind=c.label.split("@")[0], target=c.label.partition("@")[2]), None)]), c.J_holdout)
        for c in cands}
    pick = next(c for c in cands if c.label == pick_label)
    state = SimpleNamespace(ctx=None, ctx_ho=None, progress=False, t_start=0.0)
    new = (None, fine_ho[pick_label], None, (None, None))
    _, kept = engine._tie_break(None, state, new, pick, cands, fits, engine.MIN_SHARE,
                                False, None)
    return kept.label, fitted


def test_a_near_tie_is_decided_by_the_fine_fits(monkeypatch):
    # the suite's A-cont-two-sensor_bias+stiffness-s1: shares 0.986 / 0.984, held out
    # after the fine fits 0.50 (bias at joint 1) and 0.17 (joint 2, the truth)
    cands = [_cand("bias@joint1", 0.986), _cand("bias@joint2", 0.984),
             _cand("far", 0.986 - engine.TIE - 0.01), _cand("bigger", 0.985, n_params=3),
             _cand("rejected", 0.985, ok=False)]
    fine = {"bias@joint1": 0.50, "bias@joint2": 0.17, "far": 0.01, "bigger": 0.01,
            "rejected": 0.01}
    kept, fitted = _tie_break(cands, fine, "bias@joint1", monkeypatch)
    assert kept == "bias@joint2" and fitted == ["bias@joint2"]
    # the pick stays when its fine fit is the better one
    fine["bias@joint2"] = 0.6
    assert _tie_break(cands, fine, "bias@joint1", monkeypatch)[0] == "bias@joint1"


def test_without_a_near_tie_nothing_more_is_fitted(monkeypatch):
    cands = [_cand("a", 0.9), _cand("b", 0.9 - engine.TIE - 1e-6)]
    kept, fitted = _tie_break(cands, {"a": 1.0, "b": 0.1}, "a", monkeypatch)
    assert kept == "a" and fitted == []


def test_a_rival_of_the_same_class_is_not_fitted(monkeypatch):
    """A stick-slip tied with the joint's friction names the same mechanism."""
    cands = [_cand("joint_friction@joint1", 0.968, 3),
             _cand("stick_slip_friction@joint1", 0.968, 3)]
    fine = {"joint_friction@joint1": 1.0, "stick_slip_friction@joint1": 0.5}
    kept, fitted = _tie_break(cands, fine, "joint_friction@joint1", monkeypatch)
    assert kept == "joint_friction@joint1" and fitted == []
