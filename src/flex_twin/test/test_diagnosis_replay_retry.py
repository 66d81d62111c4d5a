"""The replay's retry of a control period whose Newton iterations stall (diagnosis.replay,
SUBSTEPS): it restarts from the last accepted state and that state's consistent
acceleration, never from the acceleration the failed attempt ended with (issue 44 item 5:
the sampled loop handed the failed attempt's acceleration to the retry).

The compiled loops are run as Python (``py_func``) with a stand-in integrator that fails
the first attempt of the first period with a garbage acceleration and records what each
call starts from."""
import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.inputs import JointPD, input_data
from flex_model.integrators import consistent_acceleration
from flex_twin.diagnosis import replay

GARBAGE = 1e9


class FailingOnce:
    """generalized_alpha's signature: the first call returns status 2 (Newton failed)
    with a garbage acceleration; every call is recorded and, after the first, steps
    nothing (the state held: enough for the loops' bookkeeping)."""

    def __init__(self):
        self.calls = []

    def __call__(self, t, x, a, abar, h, n_steps, every, rho_inf, tol, limit, P, E):
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
    monkeypatch.setattr(replay, "generalized_alpha", fake)
    E = input_data(m, None, (), np.zeros(2))
    nc = 2
    C = np.zeros((nc, len(x0) // 2))
    ref = np.tile([-1.2, 0.3], (3, 1))
    _, _, status, _ = replay._closed_loop.py_func(
        x0, m.P, E, 1e-3, 2, 2, 0.9, C, np.eye(2), np.eye(2), ref, np.zeros((3, 2)),
        np.zeros(nc), np.zeros(2, np.int64), np.zeros(nc, np.int64), 1)
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
    monkeypatch.setattr(replay, "generalized_alpha", fake)
    E = input_data(m, JointPD(np.full(2, 625.0), np.full(2, 176.8), np.zeros(2)), (),
                   np.zeros(2))
    U = np.zeros((2, 2))
    _, status, _ = replay._continuous_loop.py_func(x0, m.P, E, 1e-3, 2, 2, 0.9, U, 1)
    assert status == 0
    t, x, a, abar, h = fake.calls[1]
    E[8][:] = U[0]
    a0 = consistent_acceleration(0.0, x0, m.P, E)
    assert h == pytest.approx(1e-3 / replay.SUBSTEPS)
    np.testing.assert_array_equal(x, x0)
    np.testing.assert_allclose(a, a0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(abar, a0, rtol=1e-12, atol=1e-12)
