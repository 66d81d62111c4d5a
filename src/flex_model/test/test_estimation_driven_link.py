"""The driven-link Kalman filter (flex_model.estimation.driven_link): exact discretization
against the closed form of white jerk, the gain against the discrete Riccati equation, and
the tip of a link driven by a known hub motion recovered from its quantized encoder."""
import numpy as np
from scipy.linalg import solve_discrete_are
from scipy.signal import StateSpace, lsim

from flex_model.estimation.driven_link import (LinkMode, continuous_model, discretize,
                                               estimate_driven_link)

MODE = LinkMode(1.85, 0.02, 0.3)


def test_discretization_is_white_jerk_closed_form():
    T, q = 1e-3, 7.0
    F, Qd = discretize(*continuous_model(MODE, q, 0.0), T)
    assert np.allclose(F[:3, :3], [[1, T, T * T / 2], [0, 1, T], [0, 0, 1]], atol=1e-15)
    exact = q * q * np.array([[T ** 5 / 20, T ** 4 / 8, T ** 3 / 6],
                              [T ** 4 / 8, T ** 3 / 3, T ** 2 / 2],
                              [T ** 3 / 6, T ** 2 / 2, T]])
    assert np.allclose(Qd[:3, :3], exact, rtol=1e-9, atol=0)


def test_filter_variance_tends_to_the_riccati_solution():
    T, q, r = 1e-3, 50.0, 1e-3
    mode = LinkMode(1.85, 0.3, 0.3)       # damped enough for d's variance to settle
    F, Qd = discretize(*continuous_model(mode, q, 0.01), T)
    H = np.array([[1.0, 0, 0, 0, 0]])
    P = solve_discrete_are(F.T, H.T, Qd, np.array([[r * r]]))   # predicted covariance
    Pc = P - np.outer(P[:, 0], P[0]) / (P[0, 0] + r * r)
    res = estimate_driven_link(np.zeros(20000), T, mode, q, 0.01, r)
    assert np.isclose(res.theta_std[-1], np.sqrt(Pc[0, 0]), rtol=1e-9)
    assert np.isclose(res.deflection_std[-1], np.sqrt(Pc[3, 3]), rtol=1e-9)


def test_tip_of_a_driven_link_from_its_quantized_encoder():
    """A smooth 0.5 rad hub move (0.4 s, 5th-order) drives the mode; the encoder (4096 counts
    per turn) alone gives the tip within 5 % of its peak RMS."""
    T = 1e-3
    t = np.arange(0.0, 3.0, T)
    s = np.clip((t - 0.5) / 0.4, 0, 1)
    theta = 0.5 * (10 * s ** 3 - 15 * s ** 4 + 6 * s ** 5)
    acc = np.gradient(np.gradient(theta, T), T)
    w = 2 * np.pi * MODE.frequency_hz
    sys = StateSpace([[0, 1], [-w * w, -2 * MODE.damping_ratio * w]], [[0], [-MODE.gain]],
                     [[1, 0]], [[0]])
    d = lsim(sys, acc, t)[1]
    quantum = 2 * np.pi / 4096
    res = estimate_driven_link(np.round(theta / quantum) * quantum, T, MODE, 300.0, 0.0,
                               0.0, quantum)
    err = np.sqrt(np.mean((res.deflection - d) ** 2)) / np.abs(d).max()
    assert err < 0.05, err
    assert np.abs(d).max() > 0.01
