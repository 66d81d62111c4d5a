"""Structural damping of spatial flexible links (issue 25; effects.structural_damping:
thesis Eqs. 35-36 internal friction k_a int w' w'^T dz per bending plane, Rayleigh
a M_ff + b K_ff on both planes and the twist): closed-form modal damping, the logarithmic
decrement of the first mode of each plane, the energy balance dE/dt = -v^T D v, the
planar model's damping reproduced by an embedded arm, bad files refused."""
import dataclasses

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_model.effects import StructuralDamping
from flex_model.spatial import SpatialArmModel, from_planar, spatial_arm_from_dict
from flex_model.spatial.analysis import natural_modes
from flex_model.spatial.integrate import joint_input_matrix, simulate_variable

B_STIFF, A_MASS = 2e-3, 0.5      # s, 1/s


def _strip(effect: dict | None, variables: int = 4, torsion_variables: int = 2) -> dict:
    """A strip clamped at a held joint (locked motor, rigid gear): EI_z 0.5 and EI_y 8
    N m^2, a twist with a tip disc, end body on the beam axis (the planes decouple)."""
    data = {"name": "strip", "gravity": [0.0, 0.0, 0.0], "links": [
        {"joint": {"name": "j1", "a": 0.6, "motor": "locked"},
         "flexible": {"variables": variables, "torsion_variables": torsion_variables,
                      "section": {"EI_y": 8.0, "EI_z": 0.5, "GJ": 2.0, "rhoA": 0.3,
                                  "rhoJ": 2e-4}},
         "end_body": {"mass": 0.1, "inertia": [1e-4, 2e-4, 3e-4]}}]}
    if effect is not None:
        data["effects"] = [dict(effect, type="structural_damping", link="link1")]
    return data


def _state_matrix(model):
    free = model.free_indices
    M = model.mass_matrix(np.zeros(model.nq))[np.ix_(free, free)]
    K = model.K[np.ix_(free, free)]
    D = model.D[np.ix_(free, free)]
    n = len(free)
    return np.block([[np.zeros((n, n)), np.eye(n)],
                     [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])


def test_rayleigh_damping_gives_the_closed_form_modal_ratios():
    """D = a M_ff + b K_ff on a single flexible link with its joint clamped: every mode
    of both planes and the twist has zeta = a / (2 w) + b w / 2 at its undamped w
    (the eigenvalues -zeta w +- i w sqrt(1 - zeta^2) of the state matrix)."""
    model = SpatialArmModel(spatial_arm_from_dict(
        _strip({"rayleigh_mass": A_MASS, "rayleigh_stiffness": B_STIFF})))
    undamped = natural_modes(SpatialArmModel(spatial_arm_from_dict(_strip(None))),
                             joints="clamped").omega
    lam = np.linalg.eigvals(_state_matrix(model))
    lam = lam[lam.imag > 0]                          # the underdamped modes
    lam = lam[np.argsort(np.abs(lam))]
    w = np.abs(lam)
    zeta = -lam.real / w
    assert len(w) >= 6
    np.testing.assert_allclose(w, undamped[:len(w)], rtol=1e-9)
    np.testing.assert_allclose(zeta, A_MASS / (2 * w) + B_STIFF * w / 2, rtol=1e-9)
    # internal friction only: k_a S1 in the bending planes, nothing on the twist
    ka = SpatialArmModel(spatial_arm_from_dict(_strip({"internal_friction": 0.02})))
    phi = ka.plane_indices("phi")
    assert np.all(ka.D[phi] == 0.0) and np.max(np.abs(ka.D)) > 0
    b = ka.beams[0]
    v, w_ = ka.plane_indices("v")[1:], ka.plane_indices("w")
    np.testing.assert_allclose(ka.D[np.ix_(v, v)], 0.02 * b.bv.S1, rtol=0, atol=1e-15)
    np.testing.assert_allclose(ka.D[np.ix_(w_, w_)], 0.02 * b.bw.S1, rtol=0, atol=1e-15)


@pytest.mark.parametrize("plane", ["v", "w", "phi"])
def test_logarithmic_decrement_of_the_first_mode_per_plane(plane):
    """Free decay of the first mode of each plane (a small start along the undamped
    mode shape, DOP853): the tip deflection (twist) over one damped period decays by the
    logarithmic decrement delta = 2 pi zeta / sqrt(1 - zeta^2), zeta = b w / 2 for
    D = b K; the signal is the closed form exp(-zeta w t) (cos w_d t + zeta / sqrt(1 -
    zeta^2) sin w_d t) of a proportionally damped mode."""
    plain = SpatialArmModel(spatial_arm_from_dict(_strip(None, variables=2)))
    model = SpatialArmModel(spatial_arm_from_dict(
        _strip({"rayleigh_stiffness": B_STIFF}, variables=2)))
    md = natural_modes(plain, joints="clamped", coordinates=plain.plane_indices(plane)
                       if plane != "v" else plain.plane_indices("v")[1:])
    w = md.omega[0]
    shape = md.shapes_q[:, 0]
    tip = {"v": model.beams[0].tip_v, "w": model.beams[0].tip_w,
           "phi": model.beams[0].tip_phi}[plane] + model.flex_slice(0).start
    q0 = 1e-6 * shape / shape[tip]                 # 1 um (urad) at the tip
    zeta = B_STIFF * w / 2
    wd = w * np.sqrt(1 - zeta ** 2)
    period = 2 * np.pi / wd
    t = np.linspace(0.0, 3 * period, 61)
    run = simulate_variable(model, q0, np.zeros(model.nq), t, rtol=1e-11, atol=1e-20)
    x = run.q[:, tip] / 1e-6
    closed = np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta ** 2)
                                      * np.sin(wd * t))
    np.testing.assert_allclose(x, closed, rtol=0, atol=1e-9)      # reached 3e-11
    delta = np.log(x[0] / x[20])                   # one damped period later
    assert delta == pytest.approx(2 * np.pi * zeta / np.sqrt(1 - zeta ** 2), rel=1e-8)
    assert zeta > 0.005                            # a decrement that is measurable


def test_energy_decays_at_the_rate_v_D_v():
    """A two-link arm, both links flexible, with internal friction and Rayleigh damping,
    moving freely under gravity (DOP853): E(t) - E(0) = -int v^T D v dt (Simpson on a
    fine output grid), and D is symmetric positive semi-definite."""
    data = {"name": "two", "gravity": [0.0, -3.0, -9.81], "links": [
        {"joint": {"name": "j1", "a": 0.5, "alpha": 1.2},
         "flexible": {"variables": 2, "torsion_variables": 2,
                      "section": {"EI_y": 30.0, "EI_z": 20.0, "GJ": 12.0, "rhoA": 0.5,
                                  "rhoJ": 2e-3}},
         "end_body": {"mass": 0.3, "inertia": [1e-3, 2e-3, 1e-3]}},
        {"joint": {"name": "j2", "a": 0.4},
         "flexible": {"variables": 2, "torsion_variables": 0,
                      "section": {"EI_y": 10.0, "EI_z": 8.0, "GJ": 5.0, "rhoA": 0.3}},
         "end_body": {"mass": 0.2, "offset": [0.0, 0.02, 0.01]}}],
        "effects": [{"type": "structural_damping", "link": "link1", "internal_friction": 0.05,
                     "rayleigh_mass": 0.3, "rayleigh_stiffness": 1e-3},
                    {"type": "structural_damping", "link": "link2",
                     "rayleigh_stiffness": 2e-3}]}
    model = SpatialArmModel(spatial_arm_from_dict(data))
    D = model.D
    assert np.max(np.abs(D - D.T)) == 0.0
    assert np.min(np.linalg.eigvalsh(D)) > -1e-12 * np.max(np.abs(D))
    q0 = np.zeros(model.nq)
    q0[model.off] = [0.3, -0.5]
    v0 = np.zeros(model.nq)
    v0[model.off] = [2.0, -1.0]
    t = np.linspace(0.0, 0.15, 601)
    run = simulate_variable(model, q0, v0, t, rtol=1e-11, atol=1e-13, compiled=True)
    e = np.array([model.total_energy(q, v) for q, v in zip(run.q, run.v)])
    p = np.einsum("ni,ij,nj->n", run.v, D, run.v)
    dt = t[1] - t[0]
    lost = dt / 3 * (p[0] + p[-1] + 4 * p[1:-1:2].sum() + 2 * p[2:-1:2].sum())
    assert lost > 1e-3 * abs(e[0])                     # damping is doing something
    assert e[-1] - e[0] == pytest.approx(-lost, rel=1e-6)


def test_embedded_planar_arm_has_the_planar_damping(embedded_state_check):
    """thesis_example1 with a structural_damping effect on every link (internal
    friction, Rayleigh mass and stiffness; the planar M_ff: beam, M+, J+) embedded by
    from_planar: accelerations at random planar states with deformation rates equal
    the planar model's to 1e-10."""
    arm = load_arm("thesis_example1")
    effects = tuple(StructuralDamping(target=lk.name, values=(0.02 * (i + 1), 0.4, 3e-3))
                    for i, lk in enumerate(arm.links))
    arm = dataclasses.replace(arm, effects=arm.effects + effects)
    planar = FlexArmModel(arm)
    spatial = SpatialArmModel(from_planar(arm))
    assert np.max(np.abs(planar.D)) > 0
    vidx = spatial.plane_indices("v")
    flex_s = np.setdiff1d(vidx, spatial.off)
    np.testing.assert_allclose(spatial.D[np.ix_(flex_s, flex_s)],
                               planar.D[np.ix_(planar.flex_indices, planar.flex_indices)],
                               rtol=0, atol=1e-12 * np.max(np.abs(planar.D)))
    H = joint_input_matrix(spatial)
    rng = np.random.default_rng(3)
    for _ in range(2):
        theta, rates = rng.uniform(-1, 1, arm.n_links), rng.uniform(-2, 2, arm.n_links)
        flex = rng.normal(scale=0.01, size=len(flex_s))
        dflex = rng.normal(scale=0.5, size=len(flex_s))
        tau = rng.normal(scale=20.0, size=arm.n_links)
        embedded_state_check(planar, spatial, flex_s, H, theta, rates, flex, dflex, tau,
                             atol=1e-10)


def test_embedded_calibrated_quanser_arm_has_the_planar_damping_block():
    """quanser_cuboulder_calibrated (Rayleigh mass damping fitted to the real arm, a
    payload, a DC motor, friction) embedded: the in-plane deformation block of D equals
    the planar one (both leave the payload out of M_ff), and M at rest too."""
    arm = load_arm("quanser_cuboulder_calibrated")
    assert arm.payload_mass > 0
    planar = FlexArmModel(arm)
    spatial = SpatialArmModel(from_planar(arm))
    flex_s = np.setdiff1d(spatial.plane_indices("v"), spatial.off)
    fp = planar.flex_indices
    scale = np.max(np.abs(planar.D))
    assert scale > 0
    np.testing.assert_allclose(spatial.D[np.ix_(flex_s, flex_s)], planar.D[np.ix_(fp, fp)],
                               rtol=0, atol=1e-12 * scale)
    Ms = spatial.mass_matrix(np.zeros(spatial.nq))[np.ix_(flex_s, flex_s)]
    Mp = planar.mass_matrix(np.zeros(planar.nq))[np.ix_(fp, fp)]
    np.testing.assert_allclose(Ms, Mp, rtol=0, atol=1e-12 * np.max(np.abs(Mp)))


def test_structural_damping_on_a_rigid_link_is_refused():
    data = _strip({"rayleigh_stiffness": 1e-3})
    del data["links"][0]["flexible"]
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "arm.yaml")
    assert "arm.yaml" in str(err.value) and "effects[0].link" in str(err.value)
    data = _strip({"rayleigh_stiffness": 2.0})          # above the bound 1 s
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "arm.yaml")
    assert "rayleigh_stiffness" in str(err.value)
