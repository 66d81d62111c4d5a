"""Gear backlash on spatial joints (issue 25; effects.joint_elasticity.Backlash, the planar
dead zone integrators.dead_zone of the gear spring): the free play of a motor inside the
gap, momentum and energy conservation, the compiled loop against the Python reference,
bad files refused."""
import copy
from pathlib import Path

import numpy as np
import pytest

from flex_model.config import ConfigError, read_yaml
from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
from flex_model.spatial.integrate import (simulate_fixed, simulate_fixed_compiled,
                                          simulate_variable)

K, JM, IZZ, MASS, A = 1500.0, 0.02, 0.03, 2.0, 0.4
GAP, SMOOTH = 0.01, 1e-5
JL = IZZ + MASS * A * A


def _two_inertia(damping=0.0, half_width=GAP):
    """A rigid link on an elastic gear with backlash about a vertical axis (gravity does
    no work): the motor inertia J_m and the link's J_l = I_zz + m a^2."""
    return {"name": "play", "gravity": [0, 0, -9.81], "links": [
        {"joint": {"name": "j1", "a": A, "gear": "elastic"},
         "end_body": {"mass": MASS, "inertia": [0.01, 0.02, IZZ]}}],
        "effects": [{"type": "joint_elasticity", "joint": "j1", "stiffness": K,
                     "damping": damping, "motor_inertia": JM},
                    {"type": "backlash", "joint": "j1", "half_width": half_width,
                     "smoothing": SMOOTH}]}


def test_free_play_then_impact_conserves_momentum_and_energy():
    """The motor spins at w0 with the link at rest in the middle of the gap: the link
    stays still (the smoothed corners' residual force: < 1e-8 rad; 1.8e-9 reached) while
    the motor crosses the half gap in GAP / w0; then the teeth engage. Throughout:
    J_m w_m + J_l w_l = J_m w0 (no external torque) and the energy 1/2 J w^2 + k int dz
    (DOP853) are conserved; after the engagement the link moves. The same run without
    backlash moves the link at once."""
    model = SpatialArmModel(spatial_arm_from_dict(_two_inertia()))
    w0 = 0.5
    tc = GAP / w0
    t = np.linspace(0.0, 3 * tc, 301)
    v0 = np.array([0.0, w0])
    run = simulate_variable(model, np.zeros(2), v0, t, rtol=1e-12, atol=1e-14)
    inside = t < 0.95 * tc
    assert np.max(np.abs(run.q[inside, 0])) < 1e-8
    np.testing.assert_allclose(run.q[inside, 1], w0 * t[inside], rtol=0, atol=1e-7)
    p = JM * run.v[:, 1] + JL * run.v[:, 0]
    np.testing.assert_allclose(p, JM * w0, rtol=1e-9)
    e = np.array([model.total_energy(q, v) for q, v in zip(run.q, run.v)])
    np.testing.assert_allclose(e, 0.5 * JM * w0 ** 2, rtol=1e-9)
    assert run.v[-1, 0] > 0.1 * w0                     # engaged: the link was pushed
    plain = _two_inertia(half_width=0.0)
    stiff = SpatialArmModel(spatial_arm_from_dict(plain))
    assert not stiff.backlash
    r2 = simulate_variable(stiff, np.zeros(2), v0, t[:30], rtol=1e-12, atol=1e-14)
    assert np.max(np.abs(r2.q[:, 0])) > 1e-5


EFFECTS_ARM = read_yaml(Path(__file__).with_name("data_spatial_effects_arm.yaml"))


def _backlash_arm():
    """The seed 003 joint-type arm with backlash on the active elastic gear j2 and on
    the locked one j3."""
    data = copy.deepcopy(EFFECTS_ARM)
    data["effects"] += [{"type": "backlash", "joint": "j2", "half_width": 0.1,
                         "smoothing": 1e-4},
                        {"type": "backlash", "joint": "j3", "half_width": 0.1,
                         "smoothing": 1e-4}]
    return data


def test_compiled_loop_with_backlash_equals_the_python_loop():
    """20 generalized-alpha steps of the seed 003 joint-type arm with two gaps (an active
    and a locked elastic gear, half width 0.1 rad, both crossed) under joint torques:
    compiled loop = simulate_fixed to 1e-12 with the same Newton count; the gaps change
    the run. (Narrow gaps crossed at speed make the simplified Newton of this violent
    random start fail in both: the arm without gaps is already at ~11 iterations/step.)"""
    model = SpatialArmModel(spatial_arm_from_dict(_backlash_arm()))
    assert [b[:2] for b in model.backlash] == [(model.off[1], model.nq_arm),
                                               (model.off[2], -1)]
    h, n = 1e-3, 20
    rng = np.random.default_rng(2)
    tau = rng.normal(scale=2.0, size=(n, model.n_links))
    q0 = rng.normal(scale=0.1, size=model.nq)
    v0 = rng.normal(scale=0.5, size=model.nq)
    q0[model.held], v0[model.held] = 0.3, 0.0
    ref = simulate_fixed(model, q0, v0, h, n, joint_commands=tau)
    run = simulate_fixed_compiled(model, q0, v0, h, n, joint_torques=tau)
    assert np.max(np.abs(run.q - ref.q)) < 1e-12           # reached 6.5e-15
    assert np.max(np.abs(run.v - ref.v)) < 1e-9
    assert run.newton_iterations == ref.newton_iterations
    # both gears cross their gap (+-0.1 rad) during the run: engaged, free, engaged
    x2 = run.q[:, model.nq_arm] - run.q[:, model.off[1]]
    x3 = 0.1 - run.q[:, model.off[2]]
    for x in (x2, x3):
        assert np.any(np.abs(x) < 0.1) and np.any(np.abs(x) > 0.1)
    plain = simulate_fixed_compiled(SpatialArmModel(spatial_arm_from_dict(EFFECTS_ARM)),
                                    q0, v0, h, n, joint_torques=tau)
    assert np.max(np.abs(plain.q[-1] - run.q[-1])) > 1e-5


def test_energy_conserved_with_backlash_in_a_moving_arm():
    """The arm of the previous test without dampers and friction (rotors, flexible link,
    gravity, two gaps crossed): the total energy with the dead-zone potential k int dz
    (integrators.dead_zone_energy) is conserved by DOP853 to 2e-9 of the kinetic energy
    (4.9e-10 reached)."""
    data = _backlash_arm()
    data["effects"] = [dict(e, damping=0.0) if e["type"] == "joint_elasticity" else e
                       for e in data["effects"] if e["type"] != "joint_friction"]
    model = SpatialArmModel(spatial_arm_from_dict(data))
    rng = np.random.default_rng(6)
    q0 = rng.normal(scale=0.05, size=model.nq)
    v0 = rng.normal(scale=0.5, size=model.nq)
    q0[model.held], v0[model.held] = 0.3, 0.0
    t = np.linspace(0.0, 0.05, 11)
    run = simulate_variable(model, q0, v0, t, rtol=1e-12, atol=1e-14, compiled=True)
    e = np.array([model.total_energy(q, v) for q, v in zip(run.q, run.v)])
    kin = max(model.energy(q, v)["kinetic"] for q, v in zip(run.q, run.v))
    assert np.max(np.abs(e - e[0])) < 2e-9 * kin
    x2 = run.q[:, model.nq_arm] - run.q[:, model.off[1]]
    assert np.any(np.abs(x2) < 0.1) and np.any(np.abs(x2) > 0.1)


@pytest.mark.parametrize("change, where", [
    (lambda d: d["effects"].__setitem__(3, {"type": "gear", "joint": "j4"}), "effects[7].type"),
    (lambda d: d["effects"][-1].update(half_width=1.0), "effects[8].half_width"),
])
def test_bad_backlash_names_the_field(change, where):
    data = _backlash_arm()
    change(data)
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "arm.yaml")
    assert "arm.yaml" in str(err.value) and where in str(err.value)


def test_scenario_static_start_takes_up_the_play():
    """A spatial scenario starting at the static state under gravity with the holding
    torque (gravity along -y loads the joint): the motor coordinate sits a half gap
    beyond the linear spring's deflection, k dz(x) = m g a, and the arm stays at rest
    (0.05 s, the compiled loop); the linear spring's start would not."""
    from flex_model.integrators import dead_zone
    from flex_model.scenario import scenario_from_dict
    arm = _two_inertia()
    arm["gravity"] = [0.0, -9.81, 0.0]
    sc = scenario_from_dict({"arm": arm, "duration": 0.05, "step": 1e-3,
                             "initial": {"state": "static"},
                             "control": {"gravity_hold": True}}, "sc.yaml")
    model = sc.model()
    from flex_model.spatial.scenario import initial_state
    q0, v0, hold = initial_state(sc, model)
    assert hold[0] == pytest.approx(MASS * 9.81 * A, rel=1e-12)
    x = q0[1] - q0[0]
    assert x > GAP                                         # the play taken up
    assert K * dead_zone(x, GAP, SMOOTH)[0] == pytest.approx(hold[0], rel=1e-12)
    sim = sc.run(model=model, advise=False)
    assert np.max(np.abs(sim.q - q0)) < 1e-9
    linear = q0.copy()
    linear[1] = q0[0] + hold[0] / K
    run = simulate_fixed_compiled(model, linear, v0, 1e-3, 50, joint_torques=hold)
    assert np.max(np.abs(run.q[:, 0])) > 1e-4
