"""engine._tie_break: a pick the screening fit puts within TIE of another acceptable
candidate of the same shape and size is decided by their fine fits' held-out costs; a
rival with more parameters, further than TIE, of the other shape (pair / single), not
acceptable or of the pick's equivalence class is not fitted. The fine fits are replaced
by a table of held-out costs and residuals (the rule alone, no twin): a rival replaces
the pick only when its held-out residuals are resolved better (test of equal predictive
accuracy, :func:`flex_twin.diagnosis.fitting.resolved_lower`), else it is reported as an
alternative the data do not tell from the pick."""
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from flex_twin.diagnosis import engine
from flex_twin.diagnosis.fitting import resolved_lower

SUITE = Path(__file__).resolve().parents[3] / "test" / "data" / "independent_suite"
N_CH, N_T, DT = 2, 5000, 2e-3     # 10 s held out, two channels: 10 blocks of 1 s


def _white(J, seed):
    return np.sqrt(J) * np.random.default_rng(seed).standard_normal(N_CH * N_T)


def _cand(label, share, n_params=2, ok=True):
    return engine.Candidate(label=label, kind=label, target="", names=(), values=[], ci=[],
                            x=[], screen=0.0, J_fit=2.0, J_holdout=2.0, share=share,
                            delta_bic=-10.0 if ok else 10.0, cond=1.0, identifiable=True,
                            n_params=n_params, share_fit=share)


def _tie_break(cands, fine_ho, pick_label, monkeypatch, residuals=None, nominal=None,
               channels=("q1", "q2"), fit_residuals=None):
    """(the kept label, the labels fine-fitted besides the pick); ``residuals``: label ->
    held-out residuals (default: independent white noise of the label's cost)."""
    fitted = []
    fit_r = fit_residuals or {}
    residuals = residuals or {c: _white(J, k) for k, (c, J) in enumerate(fine_ho.items())}

    def accept(executor, ctx, ctx_ho, fit):
        fitted.append(fit[0].label)
        return (SimpleNamespace(label=fit[0].label, r=fit_r.get(fit[0].label)),
                fine_ho[fit[0].label], None,
                (None, None))

    monkeypatch.setattr(engine, "_accept", accept)
    monkeypatch.setattr(engine, "_holdout_residuals",
                        lambda state, new: residuals[new[0].label])
    fits = {c.label: (SimpleNamespace(label=c.label, effects=[(SimpleNamespace(  # a single
        kind=c.label.split("@")[0], target=c.label.partition("@")[2]), None)]), c.J_holdout)
        for c in cands}
    pick = next(c for c in cands if c.label == pick_label)
    rec = SimpleNamespace(residual_channels=list(channels), dt=DT)
    state = SimpleNamespace(ctx=SimpleNamespace(nominal=nominal, rec=rec),
                            ctx_ho=SimpleNamespace(rec=rec), progress=False,
                            t_start=0.0)
    new = (SimpleNamespace(label=pick_label, r=fit_r.get(pick_label)), fine_ho[pick_label],
           None, (None, None))
    _, kept = engine._tie_break(None, state, new, pick, cands, fits, engine.MIN_SHARE,
                                False, None)
    _tie_break.kept = kept
    return kept.label, fitted


def test_a_near_tie_is_decided_by_the_fine_fits(monkeypatch):
    # the suite's A-cont-two-sensor_bias+stiffness-s1: shares 0.986 / 0.984, held out
    # after the fine fits 0.50 (bias at joint 1) and 0.17 (joint 2, the truth)
    cands = [_cand("bias@joint1", 0.986), _cand("bias@joint2", 0.984),
             _cand("far", 0.986 - engine.TIE - 0.01), _cand("bigger", 0.985, n_params=3),
             _cand("rejected", 0.985, ok=False)]
    fine = {"bias@joint1": 0.50, "bias@joint2": 0.17, "far": 0.01, "bigger": 0.49,
            "rejected": 0.01}
    kept, fitted = _tie_break(cands, fine, "bias@joint1", monkeypatch)
    assert kept == "bias@joint2" and sorted(fitted) == ["bias@joint2", "bigger"]
    # the pick stays when its fine fit is the better one
    fine["bias@joint2"] = 0.6
    assert _tie_break(cands, fine, "bias@joint1", monkeypatch)[0] == "bias@joint1"


def test_a_richer_rival_replaces_the_parsimonious_pick_only_when_resolved(monkeypatch):
    """Parsimony decides a near-tie only while the data do not: a rival with more
    parameters within TIE is fine-fitted too and replaces the pick when its held-out
    residuals are resolved better (the suite's C-cont-joint_elasticity-rotor-joint1-s2:
    link 1's stiffness, one parameter, share 0.939, was named over the elastic joint with
    its rotor, three parameters, 0.983). Without that rule the richer rival is never
    fitted; not resolved better, the pick stays and the rival is its alternative."""
    cands = [_cand("stiffness@link1", 0.939, 1), _cand("joint_elasticity@joint1", 0.983, 3)]
    fine = {"stiffness@link1": 1.9, "joint_elasticity@joint1": 0.4}
    kept, fitted = _tie_break(cands, fine, "stiffness@link1", monkeypatch)
    assert kept == "joint_elasticity@joint1" and fitted == ["joint_elasticity@joint1"]
    base = _white(1.0, 7)
    res = {"stiffness@link1": base + 0.02 * _white(1.0, 8), "joint_elasticity@joint1": base}
    kept, _ = _tie_break(cands, {"stiffness@link1": 1.0, "joint_elasticity@joint1": 0.998},
                         "stiffness@link1", monkeypatch, res)
    assert kept == "stiffness@link1"
    assert _tie_break.kept.alternatives == ("joint_elasticity@joint1",)


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


def test_the_width_of_the_friction_law_is_not_counted_against_the_stick_slip_law():
    """The two laws of a joint's friction within TIE (A-cont-joint_friction-m1-s1:
    the regularized law with its width, 4 parameters, shared 1.193, the stick-slip law,
    3, 1.162): the width is the law's shape, not a further level, so the larger share is
    named; a richer law of another class still loses the near-tie on parameters."""
    fric = engine.Candidate(
        label="joint_friction@joint1", kind="joint_friction", target="joint1",
        names=("viscous", "coulomb", "static", "regularization"), values=[], ci=[], x=[],
        screen=0.0, J_fit=2.0, J_holdout=2.0, share=1.193, delta_bic=-10.0, cond=1.0,
        identifiable=True, n_params=4, share_fit=1.193)
    slip = engine.Candidate(
        label="stick_slip_friction@joint1", kind="stick_slip_friction", target="joint1",
        names=("viscous", "coulomb", "static"), values=[], ci=[], x=[], screen=0.0,
        J_fit=2.0, J_holdout=2.0, share=1.162, delta_bic=-10.0, cond=1.0,
        identifiable=True, n_params=3, share_fit=1.162)
    assert engine._pick([fric, slip], engine.MIN_SHARE).label == "joint_friction@joint1"
    other = _cand("joint_elasticity@joint1", 1.17, 3)
    assert engine._pick([fric, slip, other], engine.MIN_SHARE).label == other.label
    slip2 = _cand("stick_slip_friction@joint2", 1.162, 3)   # another joint: parameters
    assert engine._pick([fric, slip2], engine.MIN_SHARE).label == slip2.label


def test_a_rival_not_resolved_better_does_not_replace_the_pick(monkeypatch):
    """The suite's B-cont-sensor_bias-m0-s1 (bias 5 mrad at joint 2): the bias at joint 2
    (5.0 mrad) and at joint 1 (2.6 mrad: the tip moves alike) held out 0.2766 and
    0.2771, which the noise decides; the lower one named joint 1. Not resolved: the pick
    stays and the rival is reported beside it."""
    cands = [_cand("sensor_bias@joint2", 1.994, 1), _cand("sensor_bias@joint1", 1.994, 1)]
    fine = {"sensor_bias@joint2": 0.2771, "sensor_bias@joint1": 0.2766}
    base = _white(0.2766, 1)   # the two twins' residuals differ by 2 % of the noise
    res = {"sensor_bias@joint2": base + 0.02 * _white(1.0, 2) * np.sqrt(0.2766),
           "sensor_bias@joint1": base}
    kept, fitted = _tie_break(cands, fine, "sensor_bias@joint2", monkeypatch, res)
    assert kept == "sensor_bias@joint2" and fitted == ["sensor_bias@joint1"]
    assert _tie_break.kept.alternatives == ("sensor_bias@joint1",)
    # resolved: the rival replaces the pick, nothing is left unresolved
    kept, _ = _tie_break(cands, {"sensor_bias@joint2": 0.50, "sensor_bias@joint1": 0.17},
                         "sensor_bias@joint2", monkeypatch)
    assert kept == "sensor_bias@joint1" and _tie_break.kept.alternatives == ()


def test_equal_predictive_accuracy_is_not_resolved():
    """resolved_lower: residuals of equal power are not told apart, a 10 % lower cost
    over 10 s of two white channels is (the block t-test at 95 %)."""
    a, b = _white(1.0, 3), _white(1.0, 4)
    assert not resolved_lower(a, b, N_CH, 500) and not resolved_lower(b, a, N_CH, 500)
    assert resolved_lower(_white(0.9, 5), _white(1.0, 6), N_CH, 500)
    assert not resolved_lower(_white(0.9, 5), _white(1.0, 6), N_CH, 5000)   # 2 blocks


def _two_channels(J_q, J_w, seed):
    """Residuals of a q1 and a w1 channel with the given costs."""
    rng = np.random.default_rng(seed)
    return np.concatenate([np.sqrt(J_q) * rng.standard_normal(N_T),
                           np.sqrt(J_w) * rng.standard_normal(N_T)])


def test_a_links_gauge_tells_its_stiffness_from_its_root_joints_elasticity(monkeypatch):
    """The suite's B-cont-two-sensor_bias+stiffness-s1 (geared arm B, link 1 stiffer):
    joint 1's elasticity, held-out share 0.665, was named over link 1's stiffness, 0.605
    (not a near-tie; J_ho 27.6 / 32.4). Link 1's gauge w1 (its bending) is the channel
    that tells them apart: the stiffness is fine-fitted as the elasticity's rival and
    named when its gauge residual is resolved lower, though its cost on all channels is
    higher. Without a nominal planar arm (no gauge rule) the elasticity stays."""
    from flex_model.arm import load_arm
    arm = load_arm(SUITE / "B-samp500-healthy-s1" / "arm.yaml")
    cands = [_cand("joint_elasticity@joint1", 0.665, 2), _cand("stiffness@link1", 0.605, 1)]
    fine = {"joint_elasticity@joint1": 27.6, "stiffness@link1": 32.4}
    res = {"joint_elasticity@joint1": _two_channels(50.0, 5.2, 11),
           "stiffness@link1": _two_channels(63.0, 1.8, 12)}
    kw = dict(residuals=res, channels=("q1", "w1"))
    kept, fitted = _tie_break(cands, fine, "joint_elasticity@joint1", monkeypatch,
                              nominal=arm, **kw)
    assert kept == "stiffness@link1" and fitted == ["stiffness@link1"]
    kept, fitted = _tie_break(cands, fine, "joint_elasticity@joint1", monkeypatch, **kw)
    assert kept == "joint_elasticity@joint1" and fitted == []
    # the gauge resolves nothing: parsimony and the held-out cost decide as before
    res["stiffness@link1"] = _two_channels(63.0, 5.2, 13)
    kept, _ = _tie_break(cands, fine, "joint_elasticity@joint1", monkeypatch, nominal=arm,
                         **kw)
    assert kept == "joint_elasticity@joint1"


def test_which_gauge_tells_two_candidates_apart():
    from flex_model.arm import load_arm
    arm = load_arm(SUITE / "B-samp500-healthy-s1" / "arm.yaml")
    bias = ("sensor_bias", "joint2")
    assert engine._gauge_between(arm, [("stiffness", "link1"), bias],
                                 [bias, ("joint_elasticity", "joint1")]) == "w1"
    assert engine._gauge_between(arm, [("backlash", "joint2")],
                                 [("stiffness", "link2")]) == "w2"
    # not the joint that carries the link, not one difference, not a compliance
    assert engine._gauge_between(arm, [("stiffness", "link2")],
                                 [("joint_elasticity", "joint1")]) is None
    assert engine._gauge_between(arm, [("stiffness", "link1"), bias],
                                 [("joint_elasticity", "joint1"), ("payload", "")]) is None
    assert engine._gauge_between(arm, [("stiffness", "link1")],
                                 [("joint_friction", "joint1")]) is None


def test_rivals_of_one_size_are_decided_on_both_recordings(monkeypatch):
    """The suite's A-cont-two-sensor_bias+stiffness-s1: the bias at joint 1 or 2 with link
    1's stiffness (pairs of three parameters), J_ho 0.68 / 0.54 after the fine fits, not
    resolved on the held-out blocks alone; the truth (joint 2) was named before the block
    test. With as many parameters neither fits more noise of the fit recording, whose
    blocks count too: resolved there, the rival replaces the pick."""
    cands = [_cand("bias@joint1", 0.986, 3), _cand("bias@joint2", 0.984, 3)]
    fine = {"bias@joint1": 0.68, "bias@joint2": 0.54}
    base = _white(0.6, 21)
    res = {"bias@joint1": base + 0.02 * _white(1.0, 22), "bias@joint2": base}
    fit = {"bias@joint1": _white(1.0, 23), "bias@joint2": _white(0.5, 24)}
    kept, _ = _tie_break(cands, fine, "bias@joint1", monkeypatch, res)
    assert kept == "bias@joint1"    # the held-out blocks alone
    kept, _ = _tie_break(cands, fine, "bias@joint1", monkeypatch, res, fit_residuals=fit)
    assert kept == "bias@joint2" and _tie_break.kept.alternatives == ()
    # a richer rival is decided on the held-out blocks alone (it fits more noise)
    cands[1] = _cand("bias@joint2", 0.984, 4)
    kept, _ = _tie_break(cands, fine, "bias@joint1", monkeypatch, res, fit_residuals=fit)
    assert kept == "bias@joint1"
