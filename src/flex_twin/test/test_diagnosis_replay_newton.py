"""The replay's Newton iterations (diagnosis.replay, issue 44 item 5).

- The retry of a control period whose Newton iterations stall (SUBSTEPS) restarts from the
  last accepted state and that state's consistent acceleration, never from the
  acceleration the failed attempt ended with (the sampled loop handed the failed
  attempt's acceleration to the retry). The compiled loops are run as Python
  (``py_func``) with a stand-in integrator that fails the first attempt of the first
  period with a garbage acceleration and records what each call starts from.
- A continuous law on second-order kinematics is replayed by simplified Newton, one call
  per stretch of one held input: the same trajectory as full Newton to the tolerance, and
  a stretch it does not finish is replayed period by period by full Newton.
"""
import dataclasses

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.inputs import JointPD, input_data
from flex_model.integrators import consistent_acceleration
from flex_twin.diagnosis import replay
from flex_model.kernels import P_MODE

GARBAGE = 1e9


class FailingOnce:
    """solvers.loop.fixed_step's signature: the first call returns status 2 (Newton failed)
    with a garbage acceleration; every call is recorded and, after the first, steps
    nothing (the state held: enough for the loops' bookkeeping)."""

    def __init__(self):
        self.calls = []

    def __call__(self, md, n, t, x, a, abar, h, n_steps, every, s, F0):
        self.calls.append((t, x.copy(), a.copy(), abar.copy(), h))
        X = np.tile(x, (n_steps // int(every) + 1, 1))
        bad = np.full_like(a, GARBAGE)
        status = 2 if len(self.calls) == 1 else 0
        return X, status, t + n_steps * h, x.copy(), bad if status else a.copy(), \
            bad if status else abar.copy(), 1


@pytest.fixture(scope="module")
def arm():
    m = FlexArmModel(load_arm("thesis_example1"))
    x0 = replay.initial_state(m, np.array([-1.2, 0.3]))
    return m, x0


def test_sampled_loop_retry_starts_from_the_accepted_state(arm, monkeypatch):
    m, x0 = arm
    fake = FailingOnce()
    monkeypatch.setattr(replay, "fixed_step", fake)
    E = input_data(m, None, (), np.zeros(2))
    nc = 2
    C = np.zeros((nc, len(x0) // 2))
    ref = np.tile([-1.2, 0.3], (3, 1))
    _, _, status, _ = replay._closed_loop.py_func(
        x0, m.P, E, 1e-3, 2, 2, 0.9, C, np.eye(2), np.eye(2), ref, np.zeros((3, 2)),
        np.zeros(nc), np.zeros(2, np.int64), np.zeros(nc, np.int64), 1, False)
    assert status == 0
    t, x, a, abar, h = fake.calls[1]           # the retry of the first period
    a0 = consistent_acceleration(0.0, x0, m.P, E)
    assert h == pytest.approx(1e-3 / replay.SUBSTEPS)
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_allclose(a, a0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(abar, a0, rtol=1e-12, atol=1e-12)


def test_continuous_loop_retry_starts_from_the_accepted_state(arm, monkeypatch):
    m, x0 = arm
    fake = FailingOnce()
    monkeypatch.setattr(replay, "fixed_step", fake)
    monkeypatch.setattr(replay, "_continuous_periods", replay._continuous_periods.py_func)
    E = input_data(m, JointPD(np.full(2, 625.0), np.full(2, 176.8), np.zeros(2)), (),
                   np.zeros(2))
    U = np.zeros((2, 2))
    _, status, _ = replay._continuous_loop.py_func(x0, m.P, E, 1e-3, 2, 2, 0.9, U, 1,
                                                   False)
    assert status == 0
    t, x, a, abar, h = fake.calls[1]
    E.u[:] = U[0]
    a0 = consistent_acceleration(0.0, x0, m.P, E)
    assert h == pytest.approx(1e-3 / replay.SUBSTEPS)
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_allclose(a, a0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(abar, a0, rtol=1e-12, atol=1e-12)


@pytest.fixture(scope="module")
def second_order():
    """Thesis Example 1 (hub-less) on second-order kinematics under the issue's continuous
    PD, a set-point step at 0.3 s: what the replay of a hub-less run takes after its floor."""
    m = FlexArmModel(dataclasses.replace(load_arm("thesis_example1"),
                                         kinematics="second_order"))
    assert m.P[P_MODE] == 1
    E = input_data(m, JointPD(np.full(2, 625.0), np.full(2, 176.8), np.zeros(2)), (),
                   np.zeros(2))
    x0 = replay.initial_state(m, np.array([-1.2, 0.3]))
    n = 400   # 0.8 s of 2 ms periods
    U = np.zeros((n, 2))
    U[150:] = 625.0 * np.array([0.2, 0.2])
    return m, E, x0, U


def test_simplified_newton_replay_equals_full_newton_to_the_tolerance(second_order):
    m, E, x0, U = second_order
    runs = [replay._continuous_loop(x0, m.P, E, 1e-3, 2, len(U), 0.9, U, 2, s)
            for s in (False, True)]
    (X_full, st_full, _), (X_simp, st_simp, _) = runs
    assert st_full == st_simp == 0
    # the same trajectory to the Newton tolerance (1e-10 m or rad per step): measured
    # 1e-11 rad on the joints, a part in 1e8 of the motion
    assert np.max(np.abs(X_simp[:, :m.nq] - X_full[:, :m.nq])) < 1e-8
    assert np.max(np.abs(X_full[-1, :m.nq] - X_full[0, :m.nq])) > 0.1


def test_a_stretch_simplified_newton_does_not_finish_is_replayed_by_full_newton(
        second_order, monkeypatch):
    m, E, x0, U = second_order
    X_full, _, _ = replay._continuous_loop(x0, m.P, E, 1e-3, 2, len(U), 0.9, U, 2, False)

    def stalls(md, n, t, x, a, abar, h, n_steps, every, s, F0):
        assert F0 is not None   # simplified Newton: its full Newton is _continuous_periods'
        return np.full((n_steps + 1, x.shape[0]), np.nan), 2, t + h, x, a, abar, 0
    monkeypatch.setattr(replay, "fixed_step", stalls)
    X, status, _ = replay._continuous_loop.py_func(x0, m.P, E, 1e-3, 2, len(U), 0.9, U, 2,
                                                   True)
    assert status == 0
    np.testing.assert_array_equal(X, X_full)
