"""Joint effects on spatial arms and seed 003's joint types (issue 25): geared rotors,
elastic gears with a motor coordinate, friction, locked motors. Closed forms, energy
conservation and equivalences; the compiled kernels against the Python reference are in
test_spatial_compiled.py (the ``effects`` arm)."""
import copy
from pathlib import Path

import numpy as np
import pytest

from flex_model.config import ConfigError, read_yaml
from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
from flex_model.spatial.analysis import natural_modes
from flex_model.spatial.integrate import simulate_fixed_compiled, simulate_variable

#: a 4-joint arm with every joint type of seed 003 (Sect. 2): AR with a geared rotor and
#: friction, AE_xi (elastic gear, flexible link, rotor on the motor coordinate, friction),
#: LE_xi (locked motor behind an elastic gear: spring to ground), LR (held joint)
EFFECTS_ARM = read_yaml(Path(__file__).with_name("data_spatial_effects_arm.yaml"))


def _conservative(data):
    """The arm without dampers and friction."""
    d = copy.deepcopy(data)
    d["effects"] = [dict(e, damping=0.0) if e["type"] == "joint_elasticity" else e
                    for e in d["effects"] if e["type"] != "joint_friction"]
    return d


def test_joint_types_coordinates_and_inputs():
    """Seed 003's names, one motor coordinate per active elastic gear (after the link
    coordinates), the torque input on the actuator coordinate, the held LR joint."""
    arm = spatial_arm_from_dict(EFFECTS_ARM)
    assert [arm.joint_type_003(i) for i in range(4)] == ["AR", "AE_xi", "LE_xi", "LR"]
    m = SpatialArmModel(arm)
    assert m.nq == m.nq_arm + 1
    assert list(m.actuator_index) == [0, m.nq_arm, -1, -1]
    assert list(m.held) == [m.off[3]]
    # elastic gear j2: K has the spring block, the locked j3 a spring to ground + preload
    k2, k3 = m.off[1], m.off[2]
    assert m.K[k2, m.nq_arm] == -800.0 and m.K[m.nq_arm, m.nq_arm] == 800.0
    assert m.K[k3, k3] == 300.0 and m.Q_const[k3] == pytest.approx(30.0)


def test_two_inertia_frequency_of_an_elastic_gear():
    """A rigid link on an elastic gear (motor free, link free: type AE_xi with a rigid
    link): the two-mass frequency omega^2 = k (1/(J_m + n^2 J_r) + 1/J_l), J_l the link's
    inertia about the joint axis (body inertia + m a^2); the rigid mode at 0."""
    k, jm, n, jr, m, a, izz = 1500.0, 0.02, 60.0, 1e-5, 2.0, 0.4, 0.03
    data = {"name": "two_inertia", "gravity": [0, 0, -9.81], "links": [
        {"joint": {"name": "j1", "a": a, "gear": "elastic"},
         "end_body": {"mass": m, "inertia": [0.01, 0.02, izz]}}],
        "effects": [{"type": "joint_elasticity", "joint": "j1", "stiffness": k,
                     "motor_inertia": jm},
                    {"type": "gear", "joint": "j1", "ratio": n, "rotor_inertia": jr}]}
    model = SpatialArmModel(spatial_arm_from_dict(data))
    f = natural_modes(model, joints="hinged").omega
    jl = izz + m * a * a
    assert f[0] == pytest.approx(0.0, abs=1e-6)
    assert f[1] == pytest.approx(np.sqrt(k * (1 / (jm + n * n * jr) + 1 / jl)), rel=1e-12)
    # clamped link side: the motor on its spring, omega^2 = k / (J_m + n^2 J_r)
    f = natural_modes(model, joints="clamped").omega
    assert f[0] == pytest.approx(np.sqrt(k / (jm + n * n * jr)), rel=1e-12)


def test_locked_motor_is_the_rigid_joint_with_its_spring_to_ground():
    """LE_xi (locked motor, elastic gear) = the same arm with a rigid, unactuated joint
    and the force -k (q - locked_at) - b q' on it; LR keeps its joint at rest."""
    arm = spatial_arm_from_dict(EFFECTS_ARM)
    data = copy.deepcopy(EFFECTS_ARM)
    data["links"][2]["joint"] = {"name": "j3", "a": 0.3}
    data["effects"] = [e for e in data["effects"]
                       if not (e["type"] == "joint_elasticity" and e["joint"] == "j3")]
    # the locked motor's rotor does not spin: rotor fixed to the stator (ratio 0 spin)
    plain = SpatialArmModel(spatial_arm_from_dict(data))
    plain.rotors[2] = (plain.rotors[2][0], plain.rotors[2][1], -1)
    locked = SpatialArmModel(arm)
    assert plain.nq == locked.nq
    plain.held = locked.held
    rng = np.random.default_rng(5)
    k3 = locked.off[2]
    for _ in range(3):
        q = rng.normal(scale=0.3, size=locked.nq)
        v = rng.normal(scale=1.0, size=locked.nq)
        Q = np.zeros(plain.nq)
        Q[k3] = -300.0 * (q[k3] - 0.1) - 0.2 * v[k3]
        a1 = locked.acceleration(q, v)
        a2 = plain.acceleration(q, v, Q)
        assert np.max(np.abs(a1 - a2)) < 1e-12 * np.max(np.abs(a2))
        assert a1[locked.off[3]] == 0.0


def test_energy_conserved_with_elastic_gears_rotors_and_locked_motors():
    """Free run (DOP853, compiled terms) of the 4-joint arm without dampers and friction,
    under gravity: kinetic (link, rotors with the stators' rotation and gyroscopic terms,
    motor) + elastic (links, gear springs, locked spring) + gravity energy conserved to
    1e-9 of the kinetic energy."""
    model = SpatialArmModel(spatial_arm_from_dict(_conservative(EFFECTS_ARM)))
    rng = np.random.default_rng(11)
    q0 = rng.normal(scale=0.2, size=model.nq)
    v0 = rng.normal(scale=2.0, size=model.nq)
    q0[model.held], v0[model.held] = 0.0, 0.0
    run = simulate_variable(model, q0, v0, np.linspace(0.0, 0.05, 6), compiled=True,
                            rtol=1e-12, atol=1e-14)
    e = np.array([model.total_energy(q, v) for q, v in zip(run.q, run.v)])
    ek = model.energy(q0, v0)["kinetic"]
    assert np.max(np.abs(e - e[0])) < 1e-9 * ek
    assert np.max(np.abs(run.q[:, model.held] - 0.0)) == 0.0
    assert np.ptp(run.q[:, model.nq_arm]) > 1e-3        # the motor coordinate moves


def test_friction_dissipates_and_holds():
    """Joint friction on the AR joint: the energy of a free run decays, and under a
    torque below the break-away F_s the joint creeps at about eps atanh(tau / F_s)."""
    data = {"name": "fr", "gravity": [0, 0, -9.81], "links": [
        {"joint": {"name": "j1", "a": 0.4}, "end_body": {"mass": 2.0}}],
        "effects": [{"type": "joint_friction", "joint": "j1", "viscous": 0.0, "coulomb": 1.0,
                     "static": 1.0, "regularization": 1e-3}]}
    model = SpatialArmModel(spatial_arm_from_dict(data))
    h, n = 1e-3, 400
    run = simulate_fixed_compiled(model, [0.0], [0.0], h, n, joint_torques=np.full((n, 1), 0.5),
                                  rho_inf=0.8)
    creep = 1e-3 * np.arctanh(0.5)
    assert run.v[-1, 0] == pytest.approx(creep, rel=1e-3)
    # Coulomb deceleration of a spinning link: tau_f / J = -1 / (2 * 0.16)
    run = simulate_fixed_compiled(model, [0.0], [1.0], h, 100, rho_inf=0.8)
    assert run.v[-1, 0] == pytest.approx(1.0 - 0.1 / 0.32, rel=1e-6)


@pytest.mark.parametrize("change, where", [
    (lambda d: d["links"][0]["joint"].update(gear="elastic"), "links[0].joint.gear"),
    (lambda d: d["links"][1]["joint"].update(gear="rigid"), "links[1].joint.gear"),
    (lambda d: d["links"][1]["joint"].update(motor="stuck"), "links[1].joint.motor"),
    (lambda d: d["links"][0]["joint"].update(motor="locked"), "links[0].joint.motor"),
    (lambda d: d["links"][0]["joint"].update(locked_at=0.2), "links[0].joint.locked_at"),
    (lambda d: d["effects"].append({"type": "cogging", "joint": "j2", "amplitude": 0.01}),
     "effects[7].type"),
    (lambda d: d["effects"][3].update(motor_inertia=0.0), "effects[3].motor_inertia"),
])
def test_bad_effects_name_the_field(change, where):
    data = copy.deepcopy(EFFECTS_ARM)
    change(data)
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "arm.yaml")
    assert where in str(err.value) and "arm.yaml" in str(err.value)


def _hermite_beam_frequencies(segments, tip_mass, tip_inertia, per_segment=20, count=2):
    """Independent: clamped Euler-Bernoulli beam of uniform segments [(length, EI, rhoA)]
    with a tip mass and rotary inertia, cubic Hermite finite elements (consistent mass)."""
    els = [(ln / per_segment, ei, ra) for ln, ei, ra in segments for _ in range(per_segment)]
    n = 2 * (len(els) + 1)
    K, M = np.zeros((n, n)), np.zeros((n, n))
    for e, (h, ei, ra) in enumerate(els):
        h2 = h * h
        k = ei / h ** 3 * np.array([[12, 6 * h, -12, 6 * h], [6 * h, 4 * h2, -6 * h, 2 * h2],
                                    [-12, -6 * h, 12, -6 * h], [6 * h, 2 * h2, -6 * h, 4 * h2]])
        m = ra * h / 420 * np.array([[156, 22 * h, 54, -13 * h],
                                     [22 * h, 4 * h2, 13 * h, -3 * h2],
                                     [54, 13 * h, 156, -22 * h],
                                     [-13 * h, -3 * h2, -22 * h, 4 * h2]])
        s = slice(2 * e, 2 * e + 4)
        K[s, s] += k
        M[s, s] += m
    M[-2, -2] += tip_mass
    M[-1, -1] += tip_inertia
    import scipy.linalg as sla
    w2 = sla.eigh(K[2:, 2:], M[2:, 2:], eigvals_only=True)
    return np.sqrt(w2[:count]) / (2 * np.pi)


def test_seed003_like_arm_frequencies_against_finite_elements():
    """Preset ``seed003_like_arm`` (joints AE_xi, AR, AR with a flexible forearm): with the
    joints clamped, the motor of the elastic gear swings at sqrt(C_xi / (J_m + n^2 J_r))
    and the forearm (two segments from seed 003's C_s1,1, C_s1,2, tip body) bends in the
    vertical (v, EI_z, tip I_zz) and horizontal (w, EI_y, tip I_yy) planes as a clamped
    beam: first frequency against an independent Hermite finite-element model (40
    elements, converged to 1e-8) within 1e-3 with the preset's two modes per plane
    (reached 3.6e-4: 24.546 / 24.573 Hz against 24.537 / 24.564 Hz), 1e-5 with 12
    variables (3.6e-6)."""
    from flex_model.spatial import load_spatial_arm
    arm = load_spatial_arm("seed003_like_arm")
    assert [arm.joint_type_003(i) for i in range(3)] == ["AE_xi", "AR", "AE_theta"]
    segs = [(0.35, 8799.2, 1.5), (0.35, 267.69, 1.5)]
    fe_v = _hermite_beam_frequencies(segs, 0.5, 0.0006)
    fe_w = _hermite_beam_frequencies(segs, 0.5, 0.0005)
    f_motor = np.sqrt(1.0e4 / (0.05 + 100 ** 2 * 3e-5)) / (2 * np.pi)
    for nv, tol1 in ((2, 1e-3), (12, 1e-5)):
        a = arm
        if nv != 2:
            import dataclasses
            lk = arm.links[2]
            a = dataclasses.replace(arm, links=arm.links[:2] + (dataclasses.replace(
                lk, flexible=dataclasses.replace(lk.flexible, variables=nv)),))
        model = SpatialArmModel(a)
        modes = natural_modes(model)
        f = modes.frequencies_hz
        assert np.min(np.abs(f - f_motor)) < 1e-9 * f_motor
        for plane, fe in (("v", fe_v), ("w", fe_w)):
            sub = natural_modes(model, coordinates=model.plane_indices(plane)).frequencies_hz
            assert abs(sub[0] - fe[0]) < tol1 * fe[0], (nv, plane, sub[:2], fe)
