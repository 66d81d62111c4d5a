"""Timoshenko links (thesis Eq. 4, Remarks 3 and 6) against exact beam theory."""
import warnings

import numpy as np
import pytest
from scipy.optimize import brentq

from flex_model.arm import arm_from_dict
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from flex_model.statics import TipLoad, static_equilibrium

E, RHO, G = 2.1e11, 7800.0, 8.1e10


def cantilever(length, side, timoshenko, nv):
    data = {"name": "beam", "gravity": [0.0, 0.0], "links": [{
        "length": length, "material": {"E": E, "rho": RHO, "G": G},
        "section": {"shape": "rectangular", "width": side, "height": side},
        "variables": nv}]}
    if timoshenko:
        data["effects"] = [{"type": "timoshenko", "link": "link1"}]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return FlexArmModel(arm_from_dict(data))


def exact_timoshenko_frequencies(length, side, count):
    """Roots of the clamped-free Timoshenko frequency determinant (real form)."""
    A, I = side * side, side**4 / 12
    ei, ga, ra, ri = E * I, G * A / 1.2, RHO * A, RHO * I

    def det(w):
        w2 = w * w
        # ga ei mu^2 + (ga ri + ra ei) w^2 mu + ra w^2 (ri w^2 - ga) = 0
        mu = np.roots([ga * ei, (ga * ri + ra * ei) * w2, ra * w2 * (ri * w2 - ga)])
        a, b = np.sqrt(max(mu.real)), np.sqrt(-min(mu.real))
        r = ra * w2 / ga
        pa, pb, qb = a + r / a, b - r / b, -b + r / b
        L = length
        M = np.array([
            [1.0, 0.0, 1.0, 0.0],                                          # w(0)
            [0.0, pa, 0.0, pb],                                            # psi(0)
            [pa * a * np.cosh(a * L), pa * a * np.sinh(a * L),            # psi'(L)
             qb * b * np.cos(b * L), -pb * b * np.sin(b * L)],
            [(a - pa) * np.sinh(a * L), (a - pa) * np.cosh(a * L),        # w' - psi at L
             -(b + qb) * np.sin(b * L), (b - pb) * np.cos(b * L)]])
        return np.linalg.det(M) / np.cosh(a * L)

    grid = np.linspace(10.0, 2 * np.pi * 6000, 20000)
    vals = np.array([det(w) for w in grid])
    roots = [brentq(det, grid[k], grid[k + 1]) for k in range(len(grid) - 1)
             if np.sign(vals[k]) != np.sign(vals[k + 1])]
    return np.array(roots[:count]) / (2 * np.pi)


def test_static_tip_deflection_includes_shear_exactly_with_one_interval():
    L, h, F = 0.5, 0.1, 1000.0
    model = cantilever(L, h, True, 2)
    r = static_equilibrium(model, load=TipLoad(force=(0.0, F)), linear=True)
    I, A = h**4 / 12, h * h
    assert r.tip_displacement == pytest.approx(F * L**3 / (3 * E * I) + F * L * 1.2 / (G * A),
                                               rel=1e-10)
    assert r.tip_rotation == pytest.approx(F * L**2 / (2 * E * I), rel=1e-10)


def test_short_thick_cantilever_frequencies_approach_exact_timoshenko():
    """L/h = 5 (beta = 96): 3 % below Euler-Bernoulli; the model converges to theory."""
    exact = exact_timoshenko_frequencies(0.5, 0.1, 3)
    f40 = natural_modes(cantilever(0.5, 0.1, True, 40)).frequencies_hz[:3]
    f80 = natural_modes(cantilever(0.5, 0.1, True, 80)).frequencies_hz[:3]
    rel = np.abs(f80 - exact) / exact
    assert np.all(rel < [2e-5, 2e-4, 1e-3]), rel
    assert np.all(f80 - exact < f40 - exact) and np.all(f80 >= exact)  # from above
    eb = natural_modes(cantilever(0.5, 0.1, False, 40)).frequencies_hz[:3]
    assert exact[0] / eb[0] == pytest.approx(0.97, abs=0.005)


def test_slender_link_timoshenko_coincides_with_euler_bernoulli():
    """beta = 9.6e3 > 100 (thesis Remark 6): the first mode agrees within 0.05 %, the
    second within 0.5 %."""
    t = natural_modes(cantilever(2.0, 0.04, True, 10)).frequencies_hz[:2]
    e = natural_modes(cantilever(2.0, 0.04, False, 10)).frequencies_hz[:2]
    rel = np.abs(t - e) / e
    assert np.all(rel < [5e-4, 5e-3]), rel


def test_thick_euler_bernoulli_link_warns():
    data = {"name": "beam", "links": [{"length": 0.5, "material": {"E": E, "rho": RHO,
                                                                   "G": G},
                                       "section": {"shape": "rectangular", "width": 0.1,
                                                   "height": 0.1}}]}
    with pytest.warns(UserWarning, match=r"beta = .*96.4 < 100"):
        FlexArmModel(arm_from_dict(data))
