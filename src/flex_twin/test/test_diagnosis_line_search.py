"""A candidate fit whose evaluation budget ends mid-descent is continued along its last
step (:func:`flex_twin.diagnosis.fitting.line_search`, issue 21).

The toy residual is the mechanism of Exudyn case A-cont-payload-m1-s1: a tip mass sets the
frequency of a lightly damped oscillation, so the cost along the mass is a narrow valley
with flat, saturated sides, where Gauss-Newton steps grow by ~1.2 x one after the other
(the trust-region search used its 8 evaluations going from 0.066 to 0.166 kg, the truth
0.3 kg). The replay is replaced by the closed form; the fit is the engine's own
(:func:`.fitting.fit_candidate`, variable projection with a baseline column)."""
import numpy as np
import pytest

from flex_twin.diagnosis import fitting
from flex_twin.diagnosis.evaluation import SerialExecutor, cost
from flex_twin.diagnosis.fitting import FitResult, Linearization, fit_candidate, line_search
from flex_twin.diagnosis.hypotheses import _h

T = np.linspace(0.0, 2.0, 1001)
TRUE_X = 3.0
SIGMA = 0.02


def _signal(x, offset=0.0):
    """The tip's oscillation after a step: 4 Hz without the mass, 1 / sqrt(1 + x / 2)
    slower with it (x in 0.1 kg), decaying at 1.5 / s, plus an offset (the baseline)."""
    f = 4.0 / np.sqrt(1.0 + 0.5 * x)
    return np.exp(-1.5 * T) * np.sin(2.0 * np.pi * f * T) + offset


DATA = _signal(TRUE_X, 0.01) + SIGMA * np.random.default_rng(3).standard_normal(len(T))


def _toy_evaluate(task):
    _, scales, effects = task
    x = float(effects[-1][1][0]) if effects else 0.0
    return (DATA - _signal(x, 0.01 * (scales[0] - 1.0) / 0.1 + 0.01)) / SIGMA


def _fit(monkeypatch, start):
    monkeypatch.setattr(fitting, "evaluate", _toy_evaluate)
    hyp = _h("payload", "", ("mass",), (0.1,), (0.0,), (100.0,), [(0.0,)], (1.0,))
    s0 = np.ones(1)
    r0 = _toy_evaluate((None, s0, []))
    Jb = ((_toy_evaluate((None, s0 + 0.01, [])) - r0) / 0.01)[:, None]
    lin = Linearization(Jb, np.array([-0.1]), np.array([0.1]), 1)
    return fit_candidate(SerialExecutor(), None, hyp, FitResult(s0, [], r0, cost(r0)), lin,
                         start=np.array([start]), broyden=True)


def test_fit_ending_mid_descent_continues_along_its_last_step(monkeypatch):
    fit = _fit(monkeypatch, 0.66)
    assert fit.x[0] == pytest.approx(TRUE_X, rel=0.01)
    assert fit.J < 1.2          # the noise level: J = 1 at the truth
    # without the line search the same fit stops on the valley's side
    monkeypatch.setattr(fitting, "LINE_GAIN", np.inf)
    short = _fit(monkeypatch, 0.66)
    assert abs(short.x[0] - TRUE_X) > 0.3
    assert short.J > 10.0


def test_line_search_brackets_and_reduces():
    """A quadratic along the line: the doubled steps bracket the minimum, the golden
    sections bring it within the last bracket's width."""
    calls = []

    def f(x):
        calls.append(float(x[0]))
        return float((x[0] - 4.3) ** 2)
    x = line_search(f, np.array([0.0]), np.array([0.5]), np.array([-10.0]),
                    np.array([10.0]))
    # t = 1, 2, 4, 8 (x 1, 1.5, 2.5, 4.5), 16 (x 8.5) rises: bracket [2.5, 8.5]
    assert calls[:6] == [0.5, 1.0, 1.5, 2.5, 4.5, 8.5]
    assert abs(x[0] - 4.3) < 0.5
    assert len(calls) == 6 + fitting.LINE_REDUCTIONS
    # the box's edge stops the expansion
    x = line_search(f, np.array([0.0]), np.array([0.5]), np.array([-10.0]),
                    np.array([2.0]))
    assert x[0] == pytest.approx(2.0)
