"""The pair round also fits the single the fits put first with its best partner of the
linearized pair screening (:func:`flex_twin.diagnosis.engine._partner_pair`, issue 21:
Exudyn case A-cont-two-sensor_bias+stiffness-s2, whose right pair, link 1's stiffness and
joint 2's bias, was third in the pair screening and never fitted)."""
import numpy as np

from flex_twin.diagnosis.engine import Candidate, _partner_pair
from flex_twin.diagnosis.hypotheses import HypothesisPair, _h


def _hyp(kind, target):
    return _h(kind, target, ("p",), (1.0,), (-10.0,), (10.0,), [(0.0,)], (1.0,))


STIFF, BIAS2, BIAS1, ELAST2 = (_hyp("stiffness", "link1"), _hyp("sensor_bias", "joint2"),
                               _hyp("sensor_bias", "joint1"),
                               _hyp("joint_elasticity", "joint2"))


def _cand(h, share):
    return Candidate(label=h.label, kind=h.kind, target=h.target, names=("p",),
                     values=[0.0], ci=[0.0], x=[0.0], screen=0.0, J_fit=1.0, J_holdout=1.0,
                     share=share, delta_bic=-1.0, cond=1.0, identifiable=True, n_params=1,
                     share_fit=share)


# the screening of the Exudyn case (cost reductions predicted on the fit recording)
PAIR_SCORES = {HypothesisPair(ELAST2, BIAS2): (22.108, np.zeros(2)),
               HypothesisPair(BIAS1, ELAST2): (21.939, np.zeros(2)),
               HypothesisPair(BIAS2, STIFF): (20.862, np.array([-15.0, -0.5])),
               HypothesisPair(BIAS1, STIFF): (20.819, np.zeros(2)),
               HypothesisPair(ELAST2, STIFF): (14.546, np.zeros(2))}


def test_the_best_fitted_single_gets_its_best_screened_partner():
    cands = [_cand(ELAST2, 0.630), _cand(STIFF, 0.739), _cand(BIAS1, np.nan)]
    screened = [HypothesisPair(ELAST2, BIAS2), HypothesisPair(BIAS1, ELAST2)]
    pr, score, start = _partner_pair(cands, PAIR_SCORES, screened)
    assert {pr.first.label, pr.second.label} == {"stiffness@link1", "sensor_bias@joint2"}
    assert score == 20.862
    assert start.tolist() == [-15.0, -0.5]
    # already among the pairs (in the other order): nothing added
    assert _partner_pair(cands, PAIR_SCORES, screened + [HypothesisPair(STIFF, BIAS2)]) \
        is None
    # the elasticity first: its best partner is the first screened pair, already fitted
    cands[0] = _cand(ELAST2, 0.9)
    assert _partner_pair(cands, PAIR_SCORES, screened) is None
