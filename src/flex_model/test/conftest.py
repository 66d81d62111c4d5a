"""Fixtures shared by flex_model's tests."""
import numpy as np
import pytest


@pytest.fixture
def embedded_state_check():
    """A check of a planar arm against its ``from_planar`` embedding at one planar state:
    ``check(planar, spatial, flex_s, H, theta, rates, flex, dflex, tau, atol)`` asserts the
    spatial joint and in-plane accelerations equal the planar ones (theta'' = G a) to
    ``atol`` x their scale and returns (qp, vp, ap, qs, vs, as_, scale) for further checks."""
    def check(planar, spatial, flex_s, H, theta, rates, flex, dflex, tau, atol):
        qp = planar.q_from_joint_angles(theta, flex)
        z = np.zeros(planar.nq)
        z[planar.off], z[planar.flex_indices] = rates, dflex
        vp = planar.joint_coordinate_matrix() @ z
        ap = planar.acceleration(qp, vp, planar.input_matrix() @ tau)
        qs, vs = np.zeros(spatial.nq), np.zeros(spatial.nq)
        qs[spatial.off], qs[flex_s] = theta, flex
        vs[spatial.off], vs[flex_s] = rates, dflex
        as_ = spatial.acceleration(qs, vs, H @ tau)
        scale = np.max(np.abs(ap))
        np.testing.assert_allclose(as_[spatial.off], planar.G @ ap, rtol=0, atol=atol * scale)
        np.testing.assert_allclose(as_[flex_s], ap[planar.flex_indices], rtol=0,
                                   atol=atol * scale)
        return qp, vp, ap, qs, vs, as_, scale
    return check


@pytest.fixture
def lagrange_bias():
    """The bias forces of an arm by Lagrange's equations from its mass matrix and gravity
    energy, by central differences of step ``h``: ``lagrange(m, q, v)`` = dM/dt v -
    1/2 d(v' M v)/dq + dU/dq (the independent check of ``m.bias(q, v)``)."""
    def lagrange(m, q, v, h=1e-6):
        E = np.eye(m.nq)
        Bd = (m.mass_matrix(q + h * v) - m.mass_matrix(q - h * v)) / (2 * h)
        dT = [(v @ m.mass_matrix(q + h * e) @ v - v @ m.mass_matrix(q - h * e) @ v) / (2 * h)
              for e in E]
        U = [m.energy(q + h * e, v)["gravity"] - m.energy(q - h * e, v)["gravity"]
             for e in E]
        return Bd @ v - 0.5 * np.array(dT) + np.array(U) / (2 * h)
    return lagrange
