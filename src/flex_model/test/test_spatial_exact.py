"""``kinematics: exact`` of spatial links (spatial/exact.py; issues 43, 47): in the plane it
is the planar exact model (flex_model.exact_kinematics, written apart), under a large tip
load in either bending plane it is the elastica, its velocity terms are those of its
kinetic energy, and the compiled kernels equal the Python reference."""
import dataclasses

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.spatial import SpatialArmModel, from_planar, spatial_arm_from_dict
from flex_model.spatial.analysis import static_equilibrium
from flex_model.spatial.compiled import _coupling, pack, spatial_terms, tip_point
from flex_model.spatial.integrate import joint_input_matrix

L = 1.0


def _cantilever(kinematics, EI_y=5.0, EI_z=2.0, nv=8):
    return SpatialArmModel(spatial_arm_from_dict({
        "name": "c", "gravity": [0, 0, 0], "kinematics": kinematics,
        "links": [{"name": "link1", "joint": {"name": "joint1", "a": L}, "flexible": {
            "section": {"EI_y": EI_y, "EI_z": EI_z, "GJ": 1.5, "rhoA": 0.3, "rhoJ": 1e-5},
            "variables": nv, "torsion_variables": nv}}]}, "c.yaml"))


def _elastica(P, EI):
    """Tip (angle, x, y) of EI theta'' = P cos(theta), theta(0) = 0, theta'(L) = 0 (a
    cantilever under a dead tip load P), by shooting (scipy, rtol 1e-12)."""
    def shoot(k0):
        return solve_ivp(lambda s, y: [y[1], P / EI * np.cos(y[0]), np.cos(y[0]),
                                       np.sin(y[0])], (0, L), [0, k0, 0, 0], rtol=1e-12,
                         atol=1e-14).y[:, -1]
    ref = shoot(brentq(lambda k: shoot(k)[1], -1.01 * P * L / EI, -1e-6))
    return ref[0], ref[2], ref[3]


@pytest.mark.parametrize("name", ["thesis_example1", "thesis_three_link"])
def test_in_plane_it_is_the_planar_exact_model(name, embedded_state_check):
    """At random planar states with large deflections (slopes ~0.2 rad), rates, joint
    torques and gravity, the spatial exact model's accelerations equal the planar exact
    model's (theta'' = G a_alpha) to 1e-9 of their scale (measured 4e-14), the motion
    stays in the plane, and the energies agree to 1e-12."""
    arm = dataclasses.replace(load_arm(name), kinematics="exact")
    planar = FlexArmModel(arm)
    spatial = SpatialArmModel(from_planar(arm))
    vidx = spatial.plane_indices("v")
    flex_s = np.setdiff1d(vidx, spatial.off)
    H = joint_input_matrix(spatial)
    rng = np.random.default_rng(1)
    for _ in range(2):
        theta, rates = rng.uniform(-1, 1, arm.n_links), rng.uniform(-2, 2, arm.n_links)
        flex, dflex = rng.normal(scale=0.2, size=len(flex_s)), rng.normal(size=len(flex_s))
        tau = rng.normal(scale=20.0, size=arm.n_links)
        qp, vp, ap, qs, vs, as_, scale = embedded_state_check(
            planar, spatial, flex_s, H, theta, rates, flex, dflex, tau, atol=1e-9)
        assert np.max(np.abs(np.delete(as_, vidx))) < 1e-12 * scale
        e_p, e_s = planar.energy(qp, vp), spatial.energy(qs, vs)
        for k in ("kinetic", "elastic", "gravity"):
            assert e_s[k] == pytest.approx(e_p[k], rel=1e-12, abs=1e-12)


def test_large_tip_load_in_either_plane_is_the_elastica():
    """A cantilever (EI_z 2, EI_y 5 N m^2) under a dead tip load P L^2 / EI = 2 (tip angle
    45 deg) in -y (bending v, EI_z) and in -z (bending w, EI_y): the exact static tip
    within 5e-6 m of the elastica (measured 2.9e-6 with 8 variables; 1.8e-7 with 16) and
    the tip slope within 1e-4 rad; second_order is 0.2 m off; and an oblique load at 30
    deg on an isotropic section bends the link in the load's plane onto the elastica."""
    for EI, axis in ((2.0, 1), (5.0, 2)):
        P = 2.0 * EI / L ** 2
        angle, x, y = _elastica(P, EI)
        F = np.zeros(3)
        F[axis] = -P
        st = static_equilibrium(_cantilever("exact"), [0.0], tip_force=F)
        assert np.hypot(st.tip_position[0] - x, st.tip_position[axis] - y) < 5e-6
        assert abs(st.tip_position[3 - axis]) < 1e-12
        d = st.deflections["link1"]
        assert d["dv" if axis == 1 else "dw"] == pytest.approx(angle, abs=1e-4)
        so = static_equilibrium(_cantilever("second_order"), [0.0], tip_force=F)
        assert np.hypot(so.tip_position[0] - x, so.tip_position[axis] - y) > 0.1
    P = 6.0
    angle, x, y = _elastica(P, 3.0)
    a = np.radians(30.0)
    st = static_equilibrium(_cantilever("exact", 3.0, 3.0), [0.0],
                            tip_force=[0.0, -P * np.cos(a), -P * np.sin(a)])
    tip = st.tip_position
    assert np.hypot(tip[0] - x, np.hypot(tip[1], tip[2]) + y) < 2e-5
    assert np.arctan2(-tip[2], -tip[1]) == pytest.approx(a, abs=1e-5)


def _l_arm(twist):
    flex = lambda ei_y, ei_z, gj, rho: {"section": {      # noqa: E731
        "EI_y": ei_y, "EI_z": ei_z, "GJ": gj, "rhoA": rho, "rhoJ": 1e-4}, "variables": 4,
        "torsion_variables": twist, "rotary_inertia": True}
    return SpatialArmModel(spatial_arm_from_dict({
        "name": "L", "gravity": [0.0, 0.0, -9.81], "kinematics": "exact", "links": [
            {"name": "link1", "joint": {"name": "joint1", "a": 0.8, "alpha": 1.2},
             "flexible": flex(600.0, 400.0, 300.0, 0.6), "end_body": {"mass": 0.5}},
            {"name": "link2", "joint": {"name": "joint2", "a": 0.6, "theta": 1.5707963},
             "flexible": flex(250.0, 200.0, 150.0, 0.4), "end_body": {
                 "mass": 0.3, "inertia": [1e-3, 2e-3, 3e-3]}}]}, "L.yaml"))


@pytest.mark.parametrize("twist", [4, 0])
def test_velocity_terms_christoffel_and_compiled_equals_python(twist):
    """At a large random state: c(q, v) - g(q) is the Christoffel form of M(q) (central
    differences, 1e-7), and the compiled Newton-Euler kernels (M, c, the tip and its
    Jacobian, the curvature load and tangent) equal the Python complex-step reference
    to 1e-12."""
    m = _l_arm(twist)
    rng = np.random.default_rng(3)
    q, v = rng.normal(scale=0.3, size=m.nq), rng.normal(size=m.nq)
    h = 1e-6
    dM = np.array([(m.mass_matrix(q + h * e) - m.mass_matrix(q - h * e)) / (2 * h)
                   for e in np.eye(m.nq)])
    chris = np.einsum("kij,j,k->i", dM, v, v) - 0.5 * np.einsum("ijk,j,k->i", dM, v, v)
    c = m.bias(q, v) - m.gravity_force(q)
    np.testing.assert_allclose(c, chris, rtol=0, atol=1e-7 * np.max(np.abs(chris)))
    P = pack(m)
    M, cc = spatial_terms(P, q, v)
    Mr, cr = m.terms(q, v)
    np.testing.assert_allclose(M, Mr, rtol=0, atol=1e-12 * np.max(np.abs(Mr)))
    np.testing.assert_allclose(cc, cr, rtol=0, atol=1e-12 * np.max(np.abs(cr)))
    o, Jo = tip_point(P, q)
    F = m.tip_frame(q)
    np.testing.assert_allclose(o, np.real(F.o), rtol=0, atol=1e-14)
    np.testing.assert_allclose(Jo, np.real(F.Jo), rtol=0, atol=1e-14)
    g, Hc = np.zeros(m.nq), np.zeros((m.nq, m.nq))
    _coupling(P, q, g, Hc, True)
    np.testing.assert_allclose(-g, m.curvature_load(q), rtol=0, atol=1e-12 * np.max(abs(g)))
    np.testing.assert_allclose(Hc, m.curvature_tangent(q), rtol=0,
                               atol=1e-12 * np.max(abs(Hc)))


def test_in_plane_run_is_the_planar_exact_run():
    """thesis_example1 released from a deflected state under gravity, 0.05 s at 0.1 ms,
    rho_inf 0.9: the spatial compiled loop (its own generalized-alpha and Newton) follows
    the planar exact fixed step (full Newton) to 1e-8 rad in the joint angles and 1e-8 in
    the deformation variables (measured 4.1e-9, 1.5e-9 of 0.12), and stays in the plane."""
    from flex_model.simulate import simulate
    from flex_model.spatial.integrate import simulate_fixed_compiled
    arm = dataclasses.replace(load_arm("thesis_example1"), kinematics="exact")
    planar, spatial = FlexArmModel(arm), SpatialArmModel(from_planar(arm))
    vidx = spatial.plane_indices("v")
    flex_s = np.setdiff1d(vidx, spatial.off)
    theta = np.array([0.3, -0.5])
    flex = np.random.default_rng(2).normal(scale=0.05, size=len(flex_s))
    qs = np.zeros(spatial.nq)
    qs[spatial.off], qs[flex_s] = theta, flex
    h, T = 1e-4, 0.05
    rp = simulate(planar, planar.q_from_joint_angles(theta, flex), t_final=T,
                  sample_period=0.005, method="fixed", dt=h, rho_inf=0.9, newton="full")
    rs = simulate_fixed_compiled(spatial, qs, np.zeros(spatial.nq), h, int(round(T / h)),
                                 rho_inf=0.9, tol=1e-12).q[::50]
    assert len(rs) == len(rp.q) == 11
    theta_p = rp.q @ planar.G.T
    assert np.max(np.abs(theta_p - rs[:, spatial.off])) < 1e-8
    assert np.max(np.abs(rp.q[:, planar.flex_indices] - rs[:, flex_s])) < 1e-8
    assert np.max(np.abs(np.delete(rs, vidx, axis=1))) == 0.0
