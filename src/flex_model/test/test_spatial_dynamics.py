"""Spatial arms: velocity terms, energy conservation, fixed-step integration, a prismatic
joint carrying a flexible link."""
import numpy as np
import pytest

from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
from flex_model.spatial.analysis import natural_modes
from flex_model.spatial.integrate import simulate_fixed, simulate_variable

HALF_PI = 0.5 * np.pi
FLEX = {"section": {"EI_y": 4.0, "EI_z": 1.5, "GJ": 1.0, "rhoA": 0.5, "rhoJ": 5e-3},
        "variables": 2}


def cylindrical_arm(second="prismatic", d2=0.2, flexible=FLEX):
    """Revolute base (vertical axis), a horizontal prismatic joint, and a flexible link
    behind a third revolute joint; bodies with full (off-diagonal) inertias."""
    return SpatialArmModel(spatial_arm_from_dict({
        "name": "cyl", "gravity": [0.0, 0.0, -9.81],
        "links": [
            {"joint": {"type": "revolute", "alpha": -HALF_PI, "d": 0.3},
             "end_body": {"mass": 1.0, "inertia": [0.01, 0.02, 0.01]}},
            {"joint": {"type": second, "alpha": HALF_PI, "d": d2},
             "end_body": {"mass": 0.5, "inertia": [0.002, 0.002, 0.001],
                          "offset": [0.0, 0.0, 0.05]}},
            {"joint": {"type": "revolute", "a": 0.8, "alpha": 0.3}, "flexible": flexible,
             "root_body": {"mass": 0.3, "inertia": [0.001, 0.001, 0.002]},
             "end_body": {"mass": 0.2, "offset": [0.02, 0.0, 0.01],
                          "inertia": [[2e-4, 1e-5, 0], [1e-5, 3e-4, 0], [0, 0, 1e-4]]}}]}))


@pytest.fixture(scope="module")
def free_run():
    model = cylindrical_arm()
    q0 = np.zeros(model.nq)
    q0[model.off] = [0.3, 0.1, 0.5]
    v0 = np.zeros(model.nq)
    v0[model.off] = [1.0, 0.2, -1.5]
    run = simulate_variable(model, q0, v0, np.linspace(0.0, 0.15, 4), rtol=1e-8,
                            atol=1e-10)
    return model, q0, v0, run


def test_velocity_terms_are_the_christoffel_form():
    """c(q, v) (complex-step Newton-Euler form) = dM/dt v - 1/2 d(v^T M v)/dq + dU_g/dq,
    the latter by central differences of M and U_g."""
    model = cylindrical_arm(flexible=dict(FLEX, variables=4))
    rng = np.random.default_rng(0)
    q, v = rng.normal(scale=0.1, size=model.nq), rng.normal(size=model.nq)
    h = 1e-6
    E = np.eye(model.nq)
    Mdot = (model.mass_matrix(q + h * v) - model.mass_matrix(q - h * v)) / (2 * h)
    dT = np.array([v @ (model.mass_matrix(q + h * e) - model.mass_matrix(q - h * e)) @ v
                   for e in E]) / (2 * h)
    dU = np.array([model.gravity_potential(q + h * e) - model.gravity_potential(q - h * e)
                   for e in E]) / (2 * h)
    expect = Mdot @ v - 0.5 * dT + dU
    c = model.bias(q, v)
    assert np.max(np.abs(c - expect)) < 1e-8 * np.max(np.abs(c))


def test_energy_conserved_without_damping(free_run):
    """Free motion (revolute base, moving prismatic joint, flexible link bending and
    twisting): total energy constant to 1e-9 of the kinetic energy (DOP853, rtol 1e-8)."""
    model, q0, v0, run = free_run
    e0 = model.energy(q0, v0)
    total = [model.total_energy(q, v) for q, v in zip(run.q, run.v)]
    assert np.max(np.abs(np.array(total) - sum(e0.values()))) < 1e-9 * e0["kinetic"]
    assert abs(run.q[-1, model.off[1]] - q0[model.off[1]]) > 1e-3    # the slider moved
    flex = model.flex_slice(2)
    assert np.max(np.abs(run.q[:, flex])) > 1e-3                       # the link deformed


def test_generalized_alpha_is_second_order(free_run):
    """Fixed step (trapezoidal, rho_inf = 1): error at 0.15 s against DOP853 falls 4x per
    halving of the step; energy drift small."""
    model, q0, v0, run = free_run
    errs = []
    for h in (3e-3, 1.5e-3):
        fixed = simulate_fixed(model, q0, v0, h, int(round(0.15 / h)), rho_inf=1.0)
        errs.append(np.max(np.abs(fixed.q[-1] - run.q[-1])))
        drift = abs(model.total_energy(fixed.q[-1], fixed.v[-1])
                    - model.total_energy(q0, v0))
        assert drift < 2e-5 * model.energy(q0, v0)["kinetic"]   # 1.1e-5 at 3 ms
    assert 3.0 < errs[0] / errs[1] < 5.0                          # 3.8
    assert errs[1] < 3e-4                                         # 2.0e-4 at 1.5 ms


def test_prismatic_joint_carrying_a_flexible_link():
    """Clamped slider at extension d: the same frequencies as the arm with a fixed DH
    offset d (exact), and the first frequency with a free base as the slider extends."""
    first = []
    for ext in (0.0, 0.2, 0.4):
        slid = cylindrical_arm("prismatic", d2=0.2)
        fixed = cylindrical_arm("revolute", d2=0.2 + ext)
        qs = np.zeros(slid.nq)
        qs[slid.off[1]] = ext
        f_s = natural_modes(slid, qs[slid.off], gravity_preload=True).frequencies_hz
        f_f = natural_modes(fixed, None, gravity_preload=True).frequencies_hz
        np.testing.assert_allclose(f_s, f_f, rtol=1e-11)
        hinged = natural_modes(slid, qs[slid.off], joints="hinged",
                               coordinates=np.setdiff1d(np.arange(slid.nq), slid.off[1:]))
        first.append(hinged.frequencies_hz[1])
        assert hinged.frequencies_hz[0] < 1e-6 * hinged.frequencies_hz[1]  # base rotation
    # more hub inertia as the slider extends: the free-base frequency falls towards the
    # clamped-base one
    clamped = natural_modes(cylindrical_arm(), None).frequencies_hz[0]
    assert first[0] > first[1] > first[2] > clamped
