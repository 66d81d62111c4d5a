"""Wavelet basis: thesis Ch. II numbers (VALIDATION.md section A) and Theorem 1."""
import numpy as np
import pytest
import scipy.linalg as sla
from scipy.integrate import trapezoid  # np.trapezoid needs numpy 2 (ROS images: 1.26)

from flex_model.basis import link_basis
from flex_model.sections import Segment, SectionProfile

# VALIDATION.md section A (rad/s)
OMEGA_10 = [0.1406, 0.8818, 2.4768, 4.8928, 8.1208, 13.4909, 19.7305, 28.6136, 40.6478, 59.7951]
OMEGA_20 = [0.1406, 0.8814, 2.4685, 4.8407, 8.0145, 12.0067, 16.8460, 22.5689, 29.1814, 36.2766]


def uniform_link(length=5.0, ei=1.0, m=1.0):
    return SectionProfile([Segment(length, "explicit", {"EI": (ei, ei), "m": (m, m)})])


@pytest.mark.parametrize("n_vars, expected", [(10, OMEGA_10), (20, OMEGA_20)])
def test_section_A_frequencies(n_vars, expected):
    b = link_basis(uniform_link(), n_vars // 2)
    omega = np.sqrt(sla.eigh(b.K, b.Bw, eigvals_only=True))[:10]
    np.testing.assert_allclose(omega, expected, atol=0.51e-4)


def test_section_A_condition_number():
    b = link_basis(uniform_link(), 5)
    assert np.linalg.cond(b.Bw) == pytest.approx(7.85e2, rel=1e-3)


def test_constant_section_gives_hermite_consistent_matrices():
    """For constant EI the wavelets are cubic Hermite polynomials (thesis §II.3)."""
    L, ei, m = 2.0, 3.0, 0.7
    b = link_basis(uniform_link(L, ei, m), 1)
    k_ref = ei / L**3 * np.array([[12, -6 * L], [-6 * L, 4 * L * L]])
    m_ref = m * L / 420 * np.array([[156, -22 * L], [-22 * L, 4 * L * L]])
    np.testing.assert_allclose(b.K, k_ref, rtol=1e-12)
    np.testing.assert_allclose(b.Bw, m_ref, rtol=1e-12)
    assert b.h == pytest.approx([m * L / 2, -m * L * L / 12], rel=1e-12)


@pytest.mark.parametrize("n_intervals", [1, 2, 5])
def test_theorem1_tapered_tip_load_exact(n_intervals):
    """Static tip deflection under a tip force is exact for any partition (Theorem 1)."""
    seg = Segment(2.5, "square_hollow", {"side": (0.05, 0.03), "wall": (0.002, 0.002)},
                  E=2.1e11, rho=7800.0)
    b = link_basis(SectionProfile([seg]), n_intervals)
    f = np.zeros(b.n_vars)
    f[-2] = 1.0
    tip = np.linalg.solve(b.K, f)[-2]
    # closed form: delta = int_0^L (L - z)^2 / EI(z) dz, by dense quadrature
    z = np.linspace(0, 2.5, 200001)
    ei = seg.properties(z / 2.5)[0]
    exact = trapezoid((2.5 - z) ** 2 / ei, z)
    assert tip == pytest.approx(exact, rel=1e-8)


def test_piecewise_section_mass_and_shape_continuity():
    segs = [Segment(1.25, "square_hollow", {"side": (0.04, 0.04), "wall": (0.002, 0.002)},
                    E=2.1e11, rho=7800.0),
            Segment(1.25, "square_hollow", {"side": (0.03, 0.03), "wall": (0.002, 0.002)},
                    E=2.1e11, rho=7800.0)]
    b = link_basis(SectionProfile(segs), 3)
    area = (0.04**2 - 0.036**2) + (0.03**2 - 0.026**2)
    assert b.mass == pytest.approx(7800 * 1.25 * area, rel=1e-12)
    # the shape functions are continuous with continuous slope at interval ends
    eps = 1e-9
    for zc in b.nodes[1:-1]:
        np.testing.assert_allclose(b.shape_matrix([zc - eps]), b.shape_matrix([zc + eps]),
                                   atol=1e-7)
        np.testing.assert_allclose(b.slope_matrix([zc - eps]), b.slope_matrix([zc + eps]),
                                   atol=1e-7)
    # unit end values: W(z_k) picks delta_k, W'(z_k) picks gamma_k
    w = b.shape_matrix(b.nodes[1:])
    dw = b.slope_matrix(b.nodes[1:])
    np.testing.assert_allclose(w[:, 0::2], np.eye(3), atol=1e-12)
    np.testing.assert_allclose(dw[:, 1::2], np.eye(3), atol=1e-12)
