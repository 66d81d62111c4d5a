"""Spatial arms against closed forms, seed 000's real arm in 3D and the planar model."""
import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes as planar_modes
from flex_model.spatial import SpatialArmModel, from_planar, load_spatial_arm
from flex_model.spatial import spatial_arm_from_dict
from flex_model.spatial.analysis import natural_modes, static_equilibrium
from flex_model.spatial.integrate import joint_input_matrix
from flex_model.statics import static_equilibrium as planar_static


def cantilever_tip_mass_omega(EI, m, L, M, k):
    """k-th root of 1 + cos l cosh l + mu l (cos l sinh l - sin l cosh l) = 0 (Euler-
    Bernoulli cantilever with a tip point mass M, mu = M / (m L)); omega (rad/s)."""
    mu = M / (m * L)

    def f(lam):
        return (1 + np.cos(lam) * np.cosh(lam)
                + mu * lam * (np.cos(lam) * np.sinh(lam) - np.sin(lam) * np.cosh(lam)))
    grid = np.linspace(0.05, 20, 4000)
    vals = f(grid)
    roots = [brentq(f, a, b) for a, b, fa, fb in zip(grid[:-1], grid[1:], vals[:-1], vals[1:])
             if fa * fb < 0]
    return roots[k] ** 2 * np.sqrt(EI / (m * L ** 4))


def shaft_disc_omega(GJ, rhoJ, L, Jd, k):
    """k-th root of (beta L) tan(beta L) = rhoJ L / Jd, omega = beta sqrt(GJ / rhoJ):
    torsion of a clamped shaft with a tip disc (rad/s)."""
    r = rhoJ * L / Jd
    lo = k * np.pi + 1e-12
    x = brentq(lambda x: x * np.tan(x) - r, lo, lo + 0.5 * np.pi - 2e-12)
    return x / L * np.sqrt(GJ / rhoJ)


def single_link(section, variables=8, end_body=None):
    lk = {"joint": {"a": section.pop("L")}, "flexible": {"section": section,
                                                         "variables": variables}}
    if end_body:
        lk["end_body"] = end_body
    return SpatialArmModel(spatial_arm_from_dict({"name": "one", "gravity": [0, 0, 0],
                                                  "links": [lk]}))


def test_torsion_of_clamped_shaft_with_tip_disc():
    GJ, rhoJ, L, Jd = 80.0, 2e-3, 0.6, 4e-4
    model = single_link({"L": L, "EI_y": 500.0, "EI_z": 500.0, "GJ": GJ, "rhoA": 1.0,
                         "rhoJ": rhoJ}, variables=8,
                        end_body={"mass": 0.0, "inertia": [Jd, 0.0, 0.0]})
    md = natural_modes(model)
    phi_modes = [k for k in range(len(md.omega))
                 if np.linalg.norm(md.shapes_q[model.plane_indices("phi"), k])
                 > 0.99 * np.linalg.norm(md.shapes_q[:, k])]
    w = md.omega[phi_modes]
    for k, tol in ((0, 1e-7), (1, 1e-4)):
        exact = shaft_disc_omega(GJ, rhoJ, L, Jd, k)
        assert w[k] >= exact * (1 - 1e-12)        # Ritz: an upper bound
        assert w[k] == pytest.approx(exact, rel=tol)


def test_strip_bends_in_two_planes_with_tip_mass():
    """A strip with EI_z = 0.5, EI_y = 8 N m^2 and a tip mass: the first two modes are the
    first bending mode of each plane, each the closed form of its EI."""
    EIy, EIz, m, L, M = 8.0, 0.5, 0.2, 0.5, 0.05
    model = single_link({"L": L, "EI_y": EIy, "EI_z": EIz, "GJ": 5.0, "rhoA": m,
                         "rhoJ": 1e-6}, variables=8, end_body={"mass": M})
    md = natural_modes(model)
    for k, EI, plane in ((0, EIz, "v"), (1, EIy, "w")):
        # 4 wavelet intervals: 3.5e-6 above the closed form (Ritz upper bound)
        exact = cantilever_tip_mass_omega(EI, m, L, M, 0)
        assert exact < md.omega[k] < exact * (1 + 1e-5)
        shape = md.shapes_q[:, k]
        assert np.linalg.norm(shape[model.plane_indices(plane)]) == \
            pytest.approx(np.linalg.norm(shape), rel=1e-12)
    second_v = natural_modes(model, coordinates=model.plane_indices("v")).omega[1]
    exact = cantilever_tip_mass_omega(EIz, m, L, M, 1)
    assert exact < second_v < exact * (1 + 1e-3)        # 4 intervals: 6.4e-4


def test_seed000_arm_in_3d():
    """Seed 000's real arm, vertical joint axis: 8.46 Hz in the horizontal plane (the planar
    model's value), the droop under gravity q L^4 / 8 EI + P L^3 / 3 EI in the 248 N m^2
    direction and the first vertical frequency of that direction."""
    model = SpatialArmModel(load_spatial_arm("seed000_real_arm_3d"))
    L, rhoA, M, EIh, EIv, g = 0.28, 0.1289, 0.025607, 0.70656, 248.0, 9.81
    md = natural_modes(model)
    f_planar = planar_modes(FlexArmModel(load_arm("seed000_real_arm"))).frequencies_hz[0]
    assert md.frequencies_hz[0] == pytest.approx(f_planar, rel=1e-10)
    assert round(md.frequencies_hz[0], 2) == 8.46
    exact = cantilever_tip_mass_omega(EIh, rhoA, L, M, 0) / (2 * np.pi)
    assert exact < md.frequencies_hz[0] < exact * (1 + 5e-6)   # 4 intervals: 2.1e-6
    # horizontal: the first mode moves along the beam's y axis, normal to the joint axis z_0
    tip_motion = model.tip_jacobian(md.q0)[:3] @ md.shapes_q[:, 0]
    assert abs(tip_motion[2]) < 1e-12 * np.linalg.norm(tip_motion)
    st = static_equilibrium(model)
    droop = rhoA * g * L ** 4 / (8 * EIv) + M * g * L ** 3 / (3 * EIv)
    assert -st.deflections["link1"]["w"] == pytest.approx(droop, rel=1e-9)
    assert st.tip_position[2] == pytest.approx(-droop, rel=1e-9)
    assert abs(st.deflections["link1"]["v"]) < 1e-15
    vertical = [f for k, f in enumerate(md.frequencies_hz)
                if np.linalg.norm(md.shapes_q[model.plane_indices("w"), k]) > 0.99 *
                np.linalg.norm(md.shapes_q[:, k])]
    exact = cantilever_tip_mass_omega(EIv, rhoA, L, M, 0) / (2 * np.pi)   # 158.49 Hz
    assert exact < vertical[0] < exact * (1 + 5e-6)
    # the gravity preload (the 11 um droop) couples the horizontal bending and the twist
    # through the droop's curvature (the second-order curvature energy, issue 47):
    # 2.5e-5 on these modes, no longer zero
    preloaded = natural_modes(model, gravity_preload=True).frequencies_hz
    assert preloaded[:4] == pytest.approx(md.frequencies_hz[:4], rel=1e-4)
    assert not preloaded[:4] == pytest.approx(md.frequencies_hz[:4], rel=1e-6)


PLANAR = ["thesis_example1", "thesis_three_link", "thesis_example2", "thesis_example4",
          "seed000_real_arm"]


@pytest.mark.parametrize("name", PLANAR)
def test_planar_arm_embedded_in_3d(name):
    """A planar arm file converted to a spatial arm: its in-plane natural frequencies
    (clamped and hinged joints) equal the planar model's to 1e-10 relative."""
    arm = load_arm(name)
    planar = FlexArmModel(arm)
    spatial = SpatialArmModel(from_planar(arm))
    for joints in ("clamped", "hinged"):
        f1 = planar_modes(planar, [0.3] * arm.n_links, joints=joints).frequencies_hz
        f2 = natural_modes(spatial, [0.3] + [0.3] * (arm.n_links - 1), joints=joints,
                           coordinates=spatial.plane_indices("v")).frequencies_hz
        elastic = f1 > 1e-3 * f1.max()
        assert len(f1) == len(f2)
        np.testing.assert_allclose(f2[elastic], f1[elastic], rtol=1e-10)


def test_planar_gravity_equilibrium_embedded():
    """Nonlinear static equilibrium under gravity (two links held at 20 and -40 deg): tip
    position of the spatial embedding equals the planar model's."""
    arm = load_arm("thesis_example1")
    theta = np.radians([20.0, -40.0])
    st_p = planar_static(FlexArmModel(arm), theta, joints="clamped")
    st_s = static_equilibrium(SpatialArmModel(from_planar(arm)), theta)
    np.testing.assert_allclose(st_s.tip_position[:2], st_p.tip_position, rtol=0, atol=1e-12)
    assert abs(st_s.tip_position[2]) < 1e-15


def test_l_shaped_arm_twist_bending_coupling_under_tip_force():
    """Two links in an L (link 2 at 90 deg in the horizontal plane), vertical tip force F:
    by beam theory the tip rises F L1^3 / 3 EI_y1 (link 1 bending) + F L2^2 L1 / GJ_1
    (link 1 twisted by the torque F L2, carrying link 2 round) + F L2^3 / 3 EI_y2."""
    L1, L2, EIy1, GJ1, EIy2, F = 0.7, 0.4, 30.0, 12.0, 9.0, 2.0

    def link(a, EIy, GJ, theta):
        return {"joint": {"a": a, "theta": theta}, "flexible": {
            "section": {"EI_y": EIy, "EI_z": 50.0, "GJ": GJ, "rhoA": 0.4, "rhoJ": 1e-4},
            "variables": 4, "torsion_variables": 2}}
    model = SpatialArmModel(spatial_arm_from_dict({
        "name": "L", "gravity": [0, 0, 0],
        "links": [link(L1, EIy1, GJ1, 0.0), link(L2, EIy2, 20.0, 0.5 * np.pi)]}))
    st = static_equilibrium(model, tip_force=[0.0, 0.0, F], linear=True)
    bend1, twist1, bend2 = (F * L1 ** 3 / (3 * EIy1), F * L2 ** 2 * L1 / GJ1,
                            F * L2 ** 3 / (3 * EIy2))
    assert st.tip_position[2] == pytest.approx(bend1 + twist1 + bend2, rel=1e-12)
    assert st.deflections["link1"]["phi"] == pytest.approx(F * L2 * L1 / GJ1, rel=1e-12)
    assert st.deflections["link1"]["w"] == pytest.approx(bend1, rel=1e-12)
    # the full (nonlinear) equilibrium differs from it at second order only
    full = static_equilibrium(model, tip_force=[0.0, 0.0, F])
    assert full.tip_position[2] == pytest.approx(st.tip_position[2], rel=0.05)
    assert full.tip_position[2] != pytest.approx(st.tip_position[2], rel=1e-6)


@pytest.mark.parametrize("name, kinematics", [
    ("thesis_example1", "small_deflection"), ("thesis_three_link", "small_deflection"),
    ("thesis_example4", "small_deflection"), ("thesis_example1_motors", "small_deflection"),
    ("thesis_example1", "second_order"), ("thesis_three_link", "second_order")])
def test_planar_dynamics_embedded_in_3d(name, kinematics, embedded_state_check):
    """The full nonlinear equations of motion: at random planar states (joint angles,
    rates, deformations and their rates) with joint torques and gravity, the spatial
    model's accelerations equal the planar model's (theta'' = G a_alpha) to 1e-10, and so
    do the energies. (A free run of example 1 over 0.5 s with DOP853 at rtol 1e-11 agrees
    in the joint angles to 7e-14 rad; too slow for a unit test.) ``thesis_example1_motors``
    has a gear on each joint: the spatial rotor on the stator (omega_s + n theta' e, seed
    000 Eq. 35 in 3D) is the planar J_r c c^T with the stator's rotation in c. With
    ``second_order`` kinematics (the axial shortening in 3D) the embedded arm has the
    planar second_order equations, which differ from the small-deflection ones (> 1e-6 of
    the accelerations at these deflections, twice the others)."""
    arm = dataclasses.replace(load_arm(name), kinematics=kinematics)
    planar = FlexArmModel(arm)
    spatial = SpatialArmModel(from_planar(arm))
    assert spatial.arm.kinematics == kinematics
    second = kinematics == "second_order"
    vidx = spatial.plane_indices("v")
    flex_s = np.setdiff1d(vidx, spatial.off)
    H = joint_input_matrix(spatial)
    rng = np.random.default_rng(3 if second else 1)
    for _ in range(3):
        theta, rates = rng.uniform(-1, 1, arm.n_links), rng.uniform(-2, 2, arm.n_links)
        flex = rng.normal(scale=0.02 if second else 0.01, size=len(flex_s))
        dflex = rng.normal(scale=0.2 if second else 0.1, size=len(flex_s))
        tau = rng.normal(scale=20.0, size=arm.n_links)
        qp, vp, ap, qs, vs, as_, scale = embedded_state_check(
            planar, spatial, flex_s, H, theta, rates, flex, dflex, tau, atol=1e-10)
        assert np.max(np.abs(np.delete(as_, vidx))) < 1e-12 * scale   # stays planar
        e_p, e_s = planar.energy(qp, vp), spatial.energy(qs, vs)
        assert e_s["kinetic"] == pytest.approx(e_p["kinetic"], rel=1e-12)
        assert e_s["elastic"] == pytest.approx(e_p["elastic"], rel=1e-12)
        assert e_s["gravity"] == pytest.approx(e_p["gravity"], rel=1e-12, abs=1e-12)
        if second:
            small = SpatialArmModel(from_planar(load_arm(name)))
            assert np.max(np.abs(small.acceleration(qs, vs, H @ tau) - as_)) > 1e-6 * scale
