"""A payload on a spatial arm (spatial/payload.py): the kinetic energy it adds is that of
a rigid body at the last link's end frame, M_new - M = m Jp^T Jp + Jw^T R I R^T Jw with
the end frame's Jacobians (rigid-body kinetic energy, no fitting), its gravity m g; the
shallow model copy the node uses equals a model built anew."""
from dataclasses import replace

import numpy as np
import pytest

from flex_model.spatial import SpatialArmModel, load_spatial_arm
from flex_model.spatial.description import RigidBody
from flex_model.spatial.integrate import simulate_fixed_compiled
from flex_model.spatial.payload import (model_with_payload, payload_inertia, with_payload)


@pytest.mark.parametrize("name", ["seed003_like_arm", "ur5_like_flexible_forearm"])
def test_the_payload_adds_a_rigid_body_at_the_end_frame(name):
    arm = load_spatial_arm(name)
    model = SpatialArmModel(arm)
    m, inertia = payload_inertia([0.8, 0.004, 0.006, 0.009, 0.001, -0.0005, 0.0007])
    loaded = SpatialArmModel(with_payload(arm, m, inertia))
    rng = np.random.default_rng(7)
    q = rng.normal(0.0, 0.5, model.nq)
    q[np.setdiff1d(np.arange(model.nq), model.off)] *= 0.01   # small deflections
    J = model.tip_jacobian(q)
    R = np.real(model.tip_frame(q).R)
    dM = m * J[:3].T @ J[:3] + J[3:].T @ (R @ inertia @ R.T) @ J[3:]
    np.testing.assert_allclose(loaded.mass_matrix(q) - model.mass_matrix(q), dM, rtol=0,
                               atol=1e-12 * np.max(np.abs(dM)))
    dG = loaded.gravity_force(q) - model.gravity_force(q)
    np.testing.assert_allclose(dG, -m * J[:3].T @ model.gravity, rtol=0, atol=1e-11)
    assert np.max(np.abs(dM)) > 0.01
    # the node's shallow copy (from the model with another payload) = a new model
    other = SpatialArmModel(with_payload(arm, 2.0))
    fast = model_with_payload(other, arm, m, inertia)
    np.testing.assert_array_equal(fast.mass_matrix(q), loaded.mass_matrix(q))
    v = rng.normal(0.0, 0.2, model.nq)
    # a start the 1 ms loop converges from (the UR5-like tube's stiff modes: larger
    # deflections fail in the first step, which once came out as NaN taken for converged)
    flex = np.setdiff1d(np.arange(model.nq), model.off)
    q[flex] *= 0.01
    v[flex] *= 1e-4
    a = simulate_fixed_compiled(fast, q, v, 1e-3, 20, joint_torques=np.ones(arm.n_links))
    b = simulate_fixed_compiled(loaded, q, v, 1e-3, 20, joint_torques=np.ones(arm.n_links))
    assert np.all(np.isfinite(a.q))
    np.testing.assert_array_equal(a.q, b.q)
    # the copy leaves the model it came from alone
    np.testing.assert_array_equal(other.mass_matrix(q),
                                  SpatialArmModel(with_payload(arm, 2.0)).mass_matrix(q))
    assert with_payload(arm, 0.0) is arm
    # an arm file's own payload (a tool) stays under the node's payload, in both ways
    tool = replace(arm, payload=RigidBody(mass=0.3, offset=(0.01, 0.0, 0.02),
                                          inertia=((1e-3, 0, 0), (0, 2e-3, 0), (0, 0, 1e-3))))
    fast = model_with_payload(SpatialArmModel(tool), tool, m, inertia)
    full = SpatialArmModel(with_payload(tool, m, inertia))
    np.testing.assert_allclose(fast.mass_matrix(q), full.mass_matrix(q), rtol=0,
                               atol=1e-13 * np.max(np.abs(full.mass_matrix(q))))
    assert np.max(np.abs(full.mass_matrix(q) - loaded.mass_matrix(q))) > 1e-3


@pytest.mark.parametrize("values,words", [
    ([1.0, 2.0, 3.0], "got 3 values; expected one of [mass], [mass, J_z]"),
    ([np.nan], "expected finite values"),
    ([-0.1], "payload mass: got -0.1 kg; expected >= 0"),
    ([1.0, 1.0, 1.0, 1.0, 5.0, 0.0, 0.0], "expected a positive semi-definite inertia"),
])
def test_bad_payload_vectors_say_why(values, words):
    with pytest.raises(ValueError) as err:
        payload_inertia(values)
    assert words in str(err.value)


def test_payload_layouts():
    m, I = payload_inertia([0.5, 0.02])          # the planar node's [mass, inertia]: J_z
    assert m == 0.5 and I[2, 2] == 0.02 and np.count_nonzero(I) == 1
    _, I = payload_inertia([0.5, 1.0, 2.0, 3.0, 0.1, 0.2, 0.3])
    np.testing.assert_array_equal(I, [[1.0, 0.1, 0.2], [0.1, 2.0, 0.3], [0.2, 0.3, 3.0]])
