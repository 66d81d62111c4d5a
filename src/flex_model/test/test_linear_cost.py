"""Second-order kinematics at a cost linear in the variables: the inverse dynamics with the
shortening accumulated interval by interval (kernels._inverse_dynamics_2) and the
banded-plus-low-rank iteration matrix of the fixed step (flex_model.iteration_matrix)."""
import copy

import numpy as np

from flex_model import kernels
from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.inputs import JointPD, input_data
from flex_model.integrators import joint_tangent
from flex_model.iteration_matrix import factor_solve, structured_factor
from flex_model.simulate import Pulse, simulate


def _model(nv):
    return FlexArmModel(load_arm("thesis_three_link", nv).with_kinematics("second_order"))


def _state(model, rng, scale=0.01):
    q = model.q_from_joint_angles(np.radians([-20.0, 20.0, -20.0]))
    q[model.flex_indices] = scale * rng.normal(size=len(model.flex_indices))
    return q, rng.normal(size=model.nq)


def test_inverse_dynamics_is_mass_matrix_times_acceleration_plus_bias():
    """B(q) a + c(q, v) of the accumulated kernel against the mass matrix assembled point
    by point with the full S(z) (an independent sum): equal to rounding (1e-12 relative)
    for Hermite wavelets of 2 to 16 variables per link, and its power v . f equals the
    rate of the kinetic energy 1/2 v^T B v plus gravity's (central differences)."""
    rng = np.random.default_rng(3)
    for nv in (2, 4, 16):
        m = _model(nv)
        q, v = _state(m, rng)
        a = rng.normal(size=m.nq)
        f = m.inverse_dynamics(q, v, a)
        ref = m.mass_matrix(q) @ a + m.bias(q, v)
        assert np.max(np.abs(f - ref)) <= 1e-12 * np.max(np.abs(ref)), nv
    # energy balance: d/dt (T + U_g) = v . (B a + c) along q' = v, v' = a
    m = _model(8)
    q, v = _state(m, rng)
    a = rng.normal(size=m.nq)
    h = 1e-6

    def energy(t):
        qq, vv = q + t * v + 0.5 * t * t * a, v + t * a
        e = m.energy(qq, vv)
        return e["kinetic"] + e["gravity"]
    rate = (energy(h) - energy(-h)) / (2 * h)
    power = v @ m.inverse_dynamics(q, v, a)
    assert abs(rate - power) <= 1e-6 * abs(power), (rate, power)


def _structured(model):
    """The model with the structured iteration matrix on (by default it is from
    dynamics.STRUCTURED_MIN_VARS variables per link)."""
    m = copy.copy(model)
    m.P = model.P[:kernels.P_BAND] + model._band_structure(model.P[kernels.P_BP], 1,
                                                           force=True)
    assert m.P[kernels.P_BAND][1] == 1
    return m


def test_structured_factor_solves_the_iteration_matrix():
    """The Woodbury solve with the banded factor against the dense solve of
    B + gamma' (D + C_j) + beta' (K + K_j): without deflection (no axial block) equal to
    1e-10 (relative): every other term is in the structure exactly; with deflection
    variables of 1e-3 (the axial block, projected on 4 polynomials per link) within 1e-5;
    the contraction of simplified Newton on it, the spectral radius of
    I - M_approx^-1 M, below 1e-3."""
    rng = np.random.default_rng(4)
    m = _structured(_model(8))
    E = input_data(m, JointPD(np.full(3, 5e3), np.full(3, 250.0), np.zeros(3)), (),
                   np.zeros(3))
    gp, bp = 6e-4, 3e-7
    for scale, tol in ((0.0, 1e-10), (1e-3, 1e-5)):
        q, v = _state(m, rng, scale)
        F = structured_factor(q, v, gp, bp, m.P, E)
        Kj, Cj = joint_tangent(v, E)
        M = m.mass_matrix(q) + gp * (m.D + Cj) + bp * (m.K + Kj)
        b = rng.normal(size=m.nq)
        x = factor_solve(F, b)
        ref = np.linalg.solve(M, b)
        assert np.max(np.abs(x - ref)) <= tol * np.max(np.abs(ref)), scale
    X = np.column_stack([factor_solve(F, M[:, j]) for j in range(m.nq)])
    assert np.max(np.abs(np.linalg.eigvals(np.eye(m.nq) - X))) < 1e-3


def test_structured_simplified_newton_matches_full_newton():
    """Section E at 8 variables per link with the structured iteration matrix, the 1 kN m
    pulse, 0.25 s at 1 ms: simplified Newton's tips within 1e-9 m of full Newton's (the
    tolerance is 1e-10 m per step), with at most 5 % more iterations than simplified
    Newton on the dense exact matrix."""
    m = _model(8)
    th0 = np.radians([-20.0, 20.0, -20.0])

    def run(model, newton):
        return simulate(model, model.q_from_joint_angles(th0), t_final=0.25,
                        sample_period=0.005, method="fixed", dt=1e-3, newton=newton,
                        pd=JointPD(np.full(3, 5e3), np.full(3, 250.0), th0),
                        pulses=[Pulse(0.1, 0.2, (1000.0, 0.0, 0.0))])
    full, ref, simp = run(m, "full"), run(m, "simplified"), run(_structured(m), "simplified")
    for r in (ref, simp):
        diff = np.max(np.abs(np.array(r.link_tips()) - np.array(full.link_tips())))
        assert diff < 1e-9, diff
    assert simp.stats["newton_iterations"] <= 1.05 * ref.stats["newton_iterations"]


def test_band_matvec_equals_dense_product_with_low_rank_rest():
    """kernels.band_matvec: the band of M plus V diag(lam) V^T x equals M x when the part
    of M outside the band is V diag(lam) V^T (here a rank-2 coupling of distant entries,
    as a geared joint's rotor inertia couples alpha_{i-1} and alpha_i)."""
    rng = np.random.default_rng(5)
    n, bw = 30, 3
    M = np.zeros((n, n))
    for i in range(n):
        for j in range(max(0, i - bw), min(n, i + bw + 1)):
            M[i, j] = M[j, i] = rng.normal()
    g = np.zeros(n)
    g[[2, 20]] = (1.0, -1.0)
    far = np.abs(np.subtract.outer(np.arange(n), np.arange(n))) > bw
    M += np.where(far, 2.5 * np.outer(g, g), 0.0)
    R = np.where(far, M, 0.0)
    w, V = np.linalg.eigh(R)
    keep = np.abs(w) > 1e-12
    x = rng.normal(size=n)
    y = kernels.band_matvec(M, x, bw, np.ascontiguousarray(V[:, keep]), w[keep])
    np.testing.assert_allclose(y, M @ x, rtol=0, atol=1e-12)
