"""The ``second_order`` kinematics of spatial arms (issue 25): the axial shortening of the
bent beams in both planes. (That a planar second_order arm embedded in 3D has the planar
model's equations of motion: test_spatial_closed_forms.test_planar_dynamics_embedded_in_3d.)
Out-of-plane bending shortens the beam exactly as in-plane bending does; the velocity
terms are those of the kinetic energy (Christoffel form); energy is conserved; and a
rotating beam stiffens (centrifugal)."""
import dataclasses

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.spatial import SpatialArmModel, from_planar, spatial_arm_from_dict
from flex_model.spatial.integrate import simulate_variable


def _second_order(name):
    return dataclasses.replace(load_arm(name), kinematics="second_order")


def _strip(kin, EI_y=2.0, EI_z=2.0, twist=4):
    return SpatialArmModel(spatial_arm_from_dict({
        "name": "strip", "gravity": [0.0, 0.0, -9.81], "kinematics": kin,
        "links": [{"name": "link1", "joint": {"name": "joint1", "a": 0.6}, "flexible": {
            "section": {"EI_y": EI_y, "EI_z": EI_z, "GJ": 1.5, "rhoA": 0.3, "rhoJ": 1e-5},
            "variables": 4, "torsion_variables": twist}, "end_body": {"mass": 0.2}}]},
        "strip.yaml"))


def test_out_of_plane_bending_shortens_the_beam_as_in_plane_bending():
    """The same deflection shape in w as in v moves the tip back by the same
    u(L) = 1/2 f^T S(L) f, which for the cantilever shape y = d (3 s^2 L - s^3) / (2 L^3)
    is 3 d^2 / (5 L) (the shape is in the cubic Hermite space: exact)."""
    m = _strip("second_order")
    b = m.beams[0]
    L, d = 0.6, 0.03
    s = m.flex_slice(0)
    # the cubic's values and slopes at the wavelet nodes: least squares on the shape matrix
    zs = np.linspace(0.0, L, 41)
    y = d * (3 * zs ** 2 * L - zs ** 3) / (2 * L ** 3)
    fv = np.linalg.lstsq(b.bv.shape_matrix(zs), y, rcond=None)[0]
    for plane in (slice(0, b.nv), slice(b.nv, 2 * b.nv)):
        q = np.zeros(m.nq)
        q[s][plane] = fv
        tip = m.tip_position(q)
        assert tip[0] == pytest.approx(L - 3 * d * d / (5 * L), rel=1e-12)
    small = _strip("small_deflection")
    assert small.tip_position(q)[0] == pytest.approx(L, rel=1e-15)


def test_velocity_terms_are_the_christoffel_form():
    """c(q, v) - g(q) = (dM/dq v) v - 1/2 d/dq (v^T M v) by central differences of M."""
    m = _strip("second_order", EI_y=8.0)
    rng = np.random.default_rng(5)
    q = rng.normal(scale=0.05, size=m.nq)
    v = rng.normal(scale=1.0, size=m.nq)
    h = 1e-6
    dM = np.array([(m.mass_matrix(q + h * e) - m.mass_matrix(q - h * e)) / (2 * h)
                   for e in np.eye(m.nq)])            # dM[k] = dM/dq_k
    chris = np.einsum("kij,j,k->i", dM, v, v) - 0.5 * np.einsum("ijk,j,k->i", dM, v, v)
    c = m.bias(q, v) - m.gravity_force(q)
    np.testing.assert_allclose(c, chris, rtol=0, atol=1e-7 * np.max(np.abs(chris)))


def test_energy_is_conserved_in_a_free_run():
    """No damping: a strip released from a bent, spinning state, DOP853, 0.1 s (no twist
    variables: the stiff twist modes would make DOP853 crawl)."""
    m = _strip("second_order", EI_y=8.0, twist=0)
    rng = np.random.default_rng(2)
    q0 = np.zeros(m.nq)
    q0[m.flex_slice(0)] = rng.normal(scale=0.01, size=m.beams[0].n)
    v0 = np.zeros(m.nq)
    v0[0] = 3.0
    run = simulate_variable(m, q0, v0, np.linspace(0.0, 0.1, 11), rtol=1e-11, atol=1e-13)
    E = np.array([m.total_energy(q, v) for q, v in zip(run.q, run.v)])
    kin = max(m.energy(q, v)["kinetic"] for q, v in zip(run.q, run.v))
    assert np.max(np.abs(E - E[0])) < 1e-9 * kin


def test_a_spinning_beam_stiffens():
    """The first in-plane frequency of a beam spinning at Omega about its joint rises
    (centrifugal stiffening, Southwell: w^2 ~ w0^2 + k Omega^2 with k ~ 1.19 for the
    first cantilever mode without tip mass); small deflections have no such term (the
    linearization about the spinning state softens instead). Checked: second_order
    rises, small_deflection does not."""
    from scipy.linalg import eig
    out = {}
    for kin in ("second_order", "small_deflection"):
        m = _strip(kin, EI_y=8.0)
        m.arm = dataclasses.replace(m.arm, gravity=(0.0, 0.0, 0.0))
        m.gravity = np.zeros(3)
        idx = m.plane_indices("v")[1:]       # in-plane deformation, joint spinning
        W = 8.0
        v = np.zeros(m.nq)
        v[0] = W
        q = np.zeros(m.nq)
        h = 1e-7
        # linearized in-plane dynamics of the deformation at constant spin (numerical)
        M = m.mass_matrix(q)[np.ix_(idx, idx)]

        def force(dq):
            qq = q.copy()
            qq[idx] += dq
            return -(m.K @ qq + m.bias(qq, v))[idx]
        Kt = -np.array([(force(h * e) - force(-h * e)) / (2 * h) for e in np.eye(len(idx))]).T
        w2 = np.sort(np.real(eig(Kt, M, right=False)))
        out[kin] = np.sqrt(w2[0])
    assert out["second_order"] > out["small_deflection"] * 1.01


def _l_arm(kin):
    flex = lambda ei_y, ei_z, gj, rho: {"section": {      # noqa: E731
        "EI_y": ei_y, "EI_z": ei_z, "GJ": gj, "rhoA": rho, "rhoJ": 1e-4}, "variables": 4,
        "torsion_variables": 2}
    return SpatialArmModel(spatial_arm_from_dict({
        "name": "L", "gravity": [0.0, 0.0, -9.81], "kinematics": kin, "links": [
            {"name": "link1", "joint": {"name": "joint1", "a": 0.8},
             "flexible": flex(600.0, 400.0, 300.0, 0.6), "end_body": {"mass": 0.5}},
            {"name": "link2", "joint": {"name": "joint2", "a": 0.6, "theta": 1.5707963},
             "flexible": flex(250.0, 200.0, 150.0, 0.4),
             "end_body": {"mass": 0.3, "offset": [0.01, 0.02, 0.0],
                          "inertia": [2e-4, 3e-4, 4e-4]}}]}, "L.yaml"))


@pytest.mark.parametrize("which", ["L", "example1", "three_link"])
def test_compiled_kernels_equal_the_python_reference(which):
    """spatial_eval (M, c, inverse dynamics) and tip_point with second_order kinematics
    = the Python reference (complex-step velocity terms) at random states (1e-10)."""
    from flex_model.spatial.compiled import CompiledSpatialModel, pack, spatial_eval, tip_point
    name = "thesis_example1" if which == "example1" else "thesis_three_link"
    model = _l_arm("second_order") if which == "L" else SpatialArmModel(from_planar(
        _second_order(name)))
    small = _l_arm("small_deflection") if which == "L" else SpatialArmModel(from_planar(
        load_arm(name)))
    cm = CompiledSpatialModel(model)
    data = pack(model)
    rng = np.random.default_rng(11)
    flex = np.setdiff1d(np.arange(model.nq), model.off)
    for _ in range(3):
        q = rng.uniform(-1, 1, model.nq)
        q[flex] *= 0.05
        v = rng.uniform(-2, 2, model.nq)
        a = rng.uniform(-3, 3, model.nq)
        M, c = model.terms(q, v)
        Mc, cc = cm.terms(q, v)
        np.testing.assert_allclose(Mc, M, rtol=0, atol=1e-10 * np.max(np.abs(M)))
        np.testing.assert_allclose(cc, c, rtol=0, atol=1e-10 * np.max(np.abs(c)))
        _, f = spatial_eval(data, q, v, a, False)
        np.testing.assert_allclose(f, M @ a + c, rtol=0, atol=1e-10 * np.max(np.abs(M @ a)))
        o, Jo = tip_point(data, q)
        F = model.tip_frame(q)
        np.testing.assert_allclose(o, np.real(F.o), rtol=0, atol=1e-13)
        np.testing.assert_allclose(Jo, np.real(F.Jo), rtol=0, atol=1e-12)
    assert np.max(np.abs(CompiledSpatialModel(small).terms(q, v)[1] - cc)) > 1e-6


def test_unknown_kinematics_names_the_field():
    from flex_model.config import ConfigError
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict({"name": "x", "kinematics": "elastica", "links": [
            {"joint": {"a": 0.5}}]}, "bad.yaml")
    msg = str(err.value)
    assert "bad.yaml" in msg and "kinematics" in msg and "second_order" in msg
    assert "exact" in msg
