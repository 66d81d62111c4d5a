"""Effects (flex_model.effects): each alone, against closed forms and conservation."""
import numpy as np
import pytest
from scipy.integrate import cumulative_simpson

from flex_model.arm import arm_from_dict, load_arm
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_model.effects import (EFFECT_TYPES, ActuatorDelay, Backlash, BaseTilt, Cogging,
                                ContactSurface, DCMotor, Gear, JointElasticity, JointFriction,
                                StructuralDamping, TorqueSaturation)
from flex_model.modes import natural_modes
from flex_model.simulate import JointPD, Pulse, simulate
from flex_model.statics import TipLoad, static_equilibrium


def effect(cls, target="", **values):
    return cls(target=target, values=tuple(values.get(p.name, p.off) for p in cls.PARAMETERS))


def test_gear_reflects_rotor_inertia_with_ratio_squared():
    """Rotor energy 1/2 J_r (n theta_2' + Omega_stator)^2, stator on link 1's tip:
    in joint coordinates B gains J_r c c^T with c = n at theta_2, 1 at theta_1, gamma_1n."""
    arm = load_arm("thesis_example1", 4)
    base = FlexArmModel(arm)
    T = base.joint_coordinate_matrix()
    th1, th2 = base.off
    g1 = base.tip_rotation_index(0)
    q = np.random.default_rng(0).normal(size=base.nq) * 0.2
    for n in (10.0, 50.0):
        geared = FlexArmModel(arm.with_effects(effect(Gear, "joint2", ratio=n,
                                                      rotor_inertia=0.002)))
        dB = T.T @ (geared.mass_matrix(q) - base.mass_matrix(q)) @ T
        c = np.zeros(base.nq)
        c[[th1, g1, th2]] = 1.0, 1.0, n
        np.testing.assert_allclose(dB, 0.002 * np.outer(c, c), atol=1e-12)
        assert dB[th2, th2] == pytest.approx(0.002 * n**2, rel=1e-12)
    g1 = FlexArmModel(arm.with_effects(effect(Gear, "joint1", ratio=50, rotor_inertia=0.002)))
    assert (g1.mass_matrix(q) - base.mass_matrix(q))[0, 0] == pytest.approx(5.0, rel=1e-12)


def test_the_rotor_of_an_elastic_joint_turns_with_the_motor_coordinate():
    """Gear + joint elasticity on joint 2: n^2 J_r adds to the motor coordinate's inertia
    (next to motor_inertia), the stator's cross terms stay on link 1."""
    arm = load_arm("thesis_example1", 4)
    spring = effect(JointElasticity, "joint2", stiffness=500.0, motor_inertia=1e-3)
    base = FlexArmModel(arm.with_effects(spring))
    geared = FlexArmModel(arm.with_effects(spring, effect(Gear, "joint2", ratio=50.0,
                                                          rotor_inertia=2e-4)))
    q = np.zeros(base.nq)
    dB = geared.mass_matrix(q) - base.mass_matrix(q)
    m = base.nq_arm
    assert base.mass_matrix(q)[m, m] == pytest.approx(1e-3, rel=1e-12)
    assert dB[m, m] == pytest.approx(2e-4 * 50.0**2, rel=1e-12)
    assert dB[base.off[1], base.off[1]] == pytest.approx(0.0, abs=1e-15)
    assert dB[0, m] == pytest.approx(2e-4 * 50.0, rel=1e-12)


def test_rayleigh_damping_gives_the_modal_damping_ratios():
    a, b = 0.03, 2e-3
    arm = load_arm("thesis_single_link", 10)
    undamped = natural_modes(FlexArmModel(arm)).omega[:5]
    damped = natural_modes(FlexArmModel(arm.with_effects(effect(
        StructuralDamping, "link1", rayleigh_mass=a, rayleigh_stiffness=b))))
    zeta = a / (2 * undamped) + b * undamped / 2
    keep = zeta < 1
    np.testing.assert_allclose(damped.damping_ratio[:5][keep], zeta[keep], rtol=1e-8)


def test_energy_balance_with_structural_damping_and_pd():
    """The mechanical energy lost equals the work of the dampers: int v^T D v + Kd theta'^2.

    The arm is released from its static deflection under a tip force (mostly low modes:
    no sub-millisecond transient for the sampled power to miss)."""
    arm = load_arm("thesis_example1", 4).with_effects(
        effect(StructuralDamping, "link1", internal_friction=0.01, rayleigh_stiffness=1e-4),
        effect(StructuralDamping, "link2", rayleigh_mass=0.5))
    model = FlexArmModel(arm)
    kp, kd = np.array([400.0, 200.0]), np.array([20.0, 10.0])
    th0 = np.zeros(2)
    q0 = static_equilibrium(model, th0, joints="pd", kp=kp,
                            load=TipLoad(force=(0.0, 20.0))).q
    res = simulate(model, q0, t_final=1.0, sample_period=2e-4, pd=JointPD(kp, kd, th0),
                   rtol=1e-11)
    E = np.array([sum(model.energy(q, v).values()) for q, v in zip(res.q, res.v)])
    E += np.array([0.5 * kp @ (th - th0) ** 2 for th in res.joint_angles])
    power = np.einsum("ij,jk,ik->i", res.v, model.D, res.v) + res.joint_rates**2 @ kd
    lost = np.concatenate([[0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(res.t))])
    assert lost[-1] > 0.5 * (E[0] - E.min())
    assert np.max(np.abs(E[0] - E - lost)) / lost[-1] < 1e-6


def test_base_tilt_rotates_gravity_in_the_static_sag():
    """A stiff PD-held link on a base tilted by a: k_p theta = -N g cos(a + theta)."""
    from scipy.optimize import brentq
    tilt, kp = 0.05, 100.0
    arm = arm_from_dict({"name": "stiff", "links": [{"length": 1.0, "section": {
        "shape": "explicit", "EI": 1e12, "m": 2.0}}]})
    model = FlexArmModel(arm.with_effects(effect(BaseTilt, angle=tilt)))
    r = static_equilibrium(model, joints="pd", kp=kp)
    N = 2.0 * 0.5  # first mass moment of the link about the joint (kg m)
    theta = brentq(lambda th: kp * th + N * 9.81 * np.cos(tilt + th), -1.0, 0.0)
    assert r.joint_angles[0] == pytest.approx(theta, rel=1e-9)
    np.testing.assert_allclose(model.gravity, [-9.81 * np.sin(tilt), -9.81 * np.cos(tilt)])


def test_torque_saturation_limits_the_momentum_gain():
    arm = load_arm("thesis_single_link", 2).without_gravity()
    model = FlexArmModel(arm.with_effects(effect(TorqueSaturation, "joint1", limit=2.0)))
    res = simulate(model, np.zeros(model.nq), t_final=0.05, sample_period=1e-3,
                   pd=JointPD([1e6], [0.0], [1.0]), rtol=1e-10)
    momentum = (model.mass_matrix(res.q[-1]) @ res.v[-1])[0]
    assert momentum == pytest.approx(2.0 * 0.05, rel=1e-6)
    np.testing.assert_allclose(res.tau[:, 0], 2.0)


def test_static_contact_force_is_stiffness_times_penetration():
    """A clamped link sagging onto a floor 10 mm below its tip: Euler-Bernoulli
    superposition gives the penetration (q L^4/8EI - gap) / (1 + k L^3/3EI)."""
    arm = load_arm("thesis_example1", 2)
    arm = arm_from_dict({"name": "one", "links": [{
        "length": 2.0, "material": {"E": 6.4e10, "rho": 2700.0},
        "section": {"shape": "square_hollow", "side": 0.02, "wall": 0.001}}]})
    k, gap = 50.0, 0.01
    model = FlexArmModel(arm.with_effects(effect(ContactSurface, x=0.0, y=-gap,
                                                 stiffness=k, damping=5.0)))
    ei = arm.links[0].segments[0].properties(0.0)[0]
    w = model.bases[0].mass / 2.0 * 9.81
    L = 2.0
    pen = (w * L**4 / (8 * ei) - gap) / (1 + k * L**3 / (3 * ei))
    r = static_equilibrium(model, joints="clamped")
    force = model.contact_force(r.q)
    assert r.tip_position[1] == pytest.approx(-gap - pen, rel=1e-9)
    assert force[1] == pytest.approx(k * pen, rel=1e-9)
    assert abs(force[0]) < 1e-15


@pytest.mark.parametrize("kind", sorted(EFFECT_TYPES))
def test_every_effect_declares_its_parameters_and_is_inert_when_off(kind):
    cls = EFFECT_TYPES[kind]
    info = cls.describe()
    assert info["parameters"] and info["equivalent"] and info["description"]
    for p in cls.PARAMETERS:
        assert p.unit and p.bounds[0] <= p.off <= p.bounds[1] and p.tolerance >= 0
    arm = load_arm("thesis_example1", 4)
    target = {"joint": "joint2", "link": "link2", "arm": ""}[cls.TARGET]
    off = cls(target=target, values=tuple(p.off for p in cls.PARAMETERS))
    assert off.is_off
    a, b = FlexArmModel(arm), FlexArmModel(arm.with_effects(off))
    q = np.random.default_rng(1).normal(size=a.nq) * 0.1
    np.testing.assert_array_equal(a.mass_matrix(q), b.mass_matrix(q))
    np.testing.assert_array_equal(a.D, b.D)
    np.testing.assert_array_equal(a.gravity, b.gravity)
    np.testing.assert_array_equal(a.torque_limit, b.torque_limit)
    np.testing.assert_array_equal(a.contact_force(q), b.contact_force(q))


def base_dict():
    return {"name": "t", "links": [{"length": 1.0, "section": {"shape": "explicit", "EI": 1.0,
                                                              "m": 1.0}}]}


@pytest.mark.parametrize("raw, path, allowed", [
    ({"type": "magic"}, "effects[0].type", "one of actuator_delay, backlash, base_tilt, cogging"),
    ({"type": "gear", "joint": "joint9", "ratio": 5}, "effects[0].joint", "one of joint1"),
    ({"type": "gear", "joint": "joint1", "ratio": -5}, "effects[0].ratio", ">= 0.001"),
    ({"type": "gear", "joint": "joint1", "torque": 5}, "effects[0].torque", "no such field"),
    ({"type": "structural_damping", "link": "link1", "rayleigh_mass": "x"},
     "effects[0].rayleigh_mass", "a finite number"),
])
def test_effect_config_errors(raw, path, allowed):
    data = base_dict()
    data["effects"] = [raw]
    with pytest.raises(ConfigError, match=path.replace("[", r"\[").replace("]", r"\]")) as exc:
        arm_from_dict(data, "arm.yaml")
    assert allowed in str(exc.value)


def test_duplicate_effect_is_rejected():
    data = base_dict()
    data["effects"] = [{"type": "base_tilt", "angle": 0.1}, {"type": "base_tilt", "angle": 0.2}]
    with pytest.raises(ConfigError, match=r"effects\[1\].type.*at most one base_tilt"):
        arm_from_dict(data, "arm.yaml")


def stiff_link(length=1.0, m=2.0, ei=1e9):
    """A single link so stiff that it is rigid for these tests, no gravity (time runs use
    the implicit fixed-step scheme: the explicit one would resolve its 1e5 rad/s mode)."""
    return arm_from_dict({"name": "stiff", "gravity": [0.0, 0.0], "links": [{
        "length": length, "section": {"shape": "explicit", "EI": ei, "m": m}}]})


def test_elastic_joint_has_the_two_inertia_frequency():
    """Motor J_m - spring k - rigid link J_l: omega^2 = k (J_m + J_l) / (J_m J_l)."""
    k, jm = 500.0, 0.2
    model = FlexArmModel(stiff_link().with_effects(effect(JointElasticity, "joint1",
                                                          stiffness=k, motor_inertia=jm)))
    jl = 2.0 * 1.0**3 / 3.0
    f = natural_modes(model, joints="hinged").omega
    # the rigid-body mode: zero up to the eigensolver's roundoff, sqrt(eps) omega_max
    # (the 1e9 N m^2 link puts omega_max at 1.6e6 rad/s; BLAS builds differ there)
    assert f[0] < 1e-7 * f[-1]
    assert f[1] == pytest.approx(np.sqrt(k * (jm + jl) / (jm * jl)), rel=1e-6)  # EI finite
    assert model.nq == 4 and model.coordinate_names()[-1] == "joint1/motor"


def test_friction_holds_below_break_away_and_slides_above():
    fr = effect(JointFriction, "joint1", coulomb=1.0, static=1.5, stribeck_velocity=0.01)
    model = FlexArmModel(stiff_link().with_effects(fr))
    jl = 2.0 / 3.0
    hold = simulate(model, np.zeros(model.nq), t_final=1.0, sample_period=0.01,
                    pulses=[Pulse(0.0, 2.0, (1.2,))], method="fixed")
    # held: after a start-up transient (4.5e-5 rad with rho_inf 0.9) the joint creeps at
    # exactly the regularization's rate eps atanh(tau / F_s)
    assert np.abs(hold.joint_angles[:, 0]).max() < 1e-4
    creep = (hold.joint_angles[-1, 0] - hold.joint_angles[50, 0]) / 0.5
    assert creep == pytest.approx(1e-6 * np.arctanh(1.2 / 1.5), rel=1e-6)
    slide = simulate(model, np.zeros(model.nq), t_final=1.0, sample_period=0.01,
                     pulses=[Pulse(0.0, 2.0, (3.0,))], method="fixed")
    # once past the Stribeck range the joint accelerates at (tau - F_c) / J
    acc = np.diff(slide.joint_rates[50:, 0]) / 0.01
    np.testing.assert_allclose(acc, (3.0 - 1.0) / jl, rtol=1e-6)


def test_energy_balance_with_friction_and_an_elastic_joint():
    """Released with a motor speed: the energy lost equals the work of friction and of the
    joint damper."""
    arm = stiff_link(ei=200.0).with_effects(
        effect(JointElasticity, "joint1", stiffness=300.0, damping=0.5, motor_inertia=0.1),
        effect(JointFriction, "joint1", viscous=0.05, coulomb=0.3, static=0.3,
               regularization=0.05))
    model = FlexArmModel(arm)
    v0 = np.zeros(model.nq)
    v0[-1] = 3.0  # motor turning, link at rest
    res = simulate(model, np.zeros(model.nq), v0, t_final=1.0, sample_period=1e-4,
                   rtol=1e-11)
    E = np.array([sum(model.energy(q, v).values()) for q, v in zip(res.q, res.v)])
    w = res.v[:, -1]
    dx = res.v[:, -1] - res.joint_rates[:, 0]
    power = -w * np.array([float(JointFriction(target="joint1", values=(
        0.05, 0.3, 0.3, 0.01, 0.05)).torque(x)) for x in w]) + 0.5 * dx**2
    lost = cumulative_simpson(power, x=res.t, initial=0.0)
    assert lost[-1] > 0.5 * E[0]
    assert np.max(np.abs(E[0] - E - lost)) / lost[-1] < 1e-6


def test_backlash_potential_is_the_integral_of_the_dead_zone():
    """integrators.dead_zone_energy: its derivative is dead_zone (central differences,
    across the gap, on both sides, at two smoothings), 0 at 0; s = 0 is the sharp gap's
    (|x| - b)^2 / 2 outside it."""
    from flex_model.integrators import dead_zone, dead_zone_energy
    for b, s in ((2e-3, 1e-4), (0.05, 1e-5)):
        assert dead_zone_energy(0.0, b, s) == 0.0
        for x in np.linspace(-4 * b, 4 * b, 17):
            h = 1e-7 * b
            slope = (dead_zone_energy(x + h, b, s) - dead_zone_energy(x - h, b, s)) / (2 * h)
            assert abs(slope - dead_zone(x, b, s)[0]) < 1e-6 * b
    assert dead_zone_energy(0.3, 0.1, 0.0) == pytest.approx(0.5 * 0.2 ** 2, rel=1e-12)
    assert dead_zone_energy(-0.3, 0.1, 0.0) == pytest.approx(0.5 * 0.2 ** 2, rel=1e-12)


def test_backlash_adds_the_play_to_the_spring_deflection():
    """Motor held (stiff PD on the motor), torque C on the link: rotation b + C / k."""
    k, b, C = 200.0, 0.01, 1.0
    arm = stiff_link().with_effects(
        effect(JointElasticity, "joint1", stiffness=k, motor_inertia=0.1),
        effect(Backlash, "joint1", half_width=b, smoothing=1e-7))
    model = FlexArmModel(arm)
    r = static_equilibrium(model, joints="pd", kp=1e9, load=TipLoad(torque=C))
    assert r.joint_angles[0] == pytest.approx(b + C / k, rel=1e-6)
    r0 = static_equilibrium(model, joints="pd", kp=1e9, load=TipLoad(torque=0.3 * k * b))
    assert r0.joint_angles[0] == pytest.approx(b + 0.3 * b, rel=1e-5)  # k dz = load


def test_dc_motor_no_load_speed_and_stall_torque():
    """J w' = n K_t (V - K_e n w) / R: w -> V / (K_e n); with a current limit the joint's
    angular momentum grows at n K_t i_max."""
    R, kt, ke, n, volt = 2.0, 0.05, 0.05, 20.0, 6.0
    jl = 2.0 / 3.0
    arm = stiff_link().with_effects(
        effect(Gear, "joint1", ratio=n),
        effect(DCMotor, "joint1", resistance=R, torque_constant=kt, back_emf_constant=ke))
    model = FlexArmModel(arm)
    tau_m = jl * R / (n * n * kt * ke)
    res = simulate(model, np.zeros(model.nq), t_final=12 * tau_m, sample_period=tau_m / 10,
                   policy=lambda t, x: [volt], method="fixed", dt=tau_m / 1000)
    assert res.joint_rates[-1, 0] == pytest.approx(volt / (ke * n) * (1 - np.exp(-12)),
                                                   rel=1e-6)
    limited = FlexArmModel(arm.with_effects(effect(
        DCMotor, "joint1", resistance=R, torque_constant=kt, back_emf_constant=ke,
        current_limit=1.0)))
    res = simulate(limited, np.zeros(model.nq), t_final=0.01, sample_period=1e-3,
                   policy=lambda t, x: [100.0], method="fixed", dt=1e-4)
    momentum = (limited.mass_matrix(res.q[-1]) @ res.v[-1])[0]
    assert momentum == pytest.approx(n * kt * 1.0 * 0.01, rel=1e-8)
    np.testing.assert_allclose(res.tau[:, 0], n * kt * 1.0)


def test_cogging_torque_is_periodic_in_the_motor_angle():
    amp, periods, n = 0.2, 6.0, 10.0
    model = FlexArmModel(stiff_link().with_effects(
        effect(Gear, "joint1", ratio=n),
        effect(Cogging, "joint1", amplitude=amp, periods=periods, phase=0.3)))
    for th in (0.0, 0.01, 0.05, 1.0):
        q = model.q_from_joint_angles([th])
        assert model.joint_forces(q)[0] == pytest.approx(amp * np.sin(periods * n * th + 0.3),
                                                         rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("method", ["variable", "fixed"])
def test_payload_pick_conserves_momentum_and_place_keeps_velocity(method):
    model = FlexArmModel(stiff_link(ei=1e4))
    v0 = model.v_from_joint_rates([2.0])
    res = simulate(model, np.zeros(model.nq), v0, t_final=0.2, sample_period=1e-3,
                   payload_changes=[(0.05, 0.5, 0.01), (0.15, 0.0, 0.0)], method=method,
                   rtol=1e-10, dt=1e-4)
    assert model.payload == (0.0, 0.0)  # the caller's model is untouched
    jl = 2.0 / 3.0
    held = model.__class__(model.arm)
    held.set_payload(0.5, 0.01)

    def momentum(m, k):  # angular momentum about the joint: the momentum of alpha_1
        return (m.mass_matrix(res.q[k]) @ res.v[k])[0]

    # no gravity, no torque: conserved, and through the pick (payload picked at rest);
    # generalized-alpha conserves it to its (second-order) accuracy
    rel = 1e-9 if method == "variable" else 1e-6
    assert momentum(model, 40) == pytest.approx(2.0 * jl, rel=rel)
    assert momentum(held, 100) == pytest.approx(2.0 * jl, rel=rel)
    assert momentum(held, 150) == pytest.approx(2.0 * jl, rel=rel)
    # the place: the payload leaves with its own momentum, the arm keeps its velocity
    assert momentum(model, 190) == pytest.approx(momentum(model, 150), rel=rel)


def test_actuator_delay_applies_commands_late():
    model = FlexArmModel(stiff_link().with_effects(effect(ActuatorDelay, "joint1",
                                                          delay=0.02)))
    res = simulate(model, np.zeros(model.nq), t_final=0.05, sample_period=1e-3,
                   policy=lambda t, x: [1.0], control_period=1e-3, method="fixed", dt=1e-4)
    np.testing.assert_allclose(res.tau[:20, 0], 0.0)   # a sample holds the torque that
    np.testing.assert_allclose(res.tau[21:, 0], 1.0)   # acted up to it (left limit)


def test_contact_force_and_motor_angles_are_outputs(tmp_path):
    arm = stiff_link(ei=1e4).with_effects(
        effect(JointElasticity, "joint1", stiffness=100.0, motor_inertia=0.1),
        effect(ContactSurface, x=0.0, y=-0.5, normal_angle=np.pi / 2, stiffness=1e4,
               damping=10.0))
    model = FlexArmModel(arm.__class__(**{**arm.__dict__, "gravity": (0.0, -9.81)}))
    res = simulate(model, model.q_from_joint_angles([-0.4]), t_final=0.5, sample_period=0.01,
                   method="fixed", dt=1e-3)
    names, data = res.table()
    assert names[-3:] == ["qm1", "contact_fx", "contact_fy"]
    assert np.all(res.contact_forces[:, 1] >= 0) and res.contact_forces[:, 1].max() > 0
    np.testing.assert_allclose(data[:, -3], res.motor_angles[:, 0])


def test_arm_tolerances_override_the_defaults():
    data = {"name": "t", "links": [{"length": 1.0, "section": {"shape": "explicit",
                                                               "EI": 1.0, "m": 1.0}}],
            "tolerances": {"E": 0.1}}
    arm = arm_from_dict(data)
    assert arm.tolerance("E") == 0.1 and arm.tolerance("rho") == 0.02
    data["tolerances"] = {"Young": 0.1}
    with pytest.raises(ConfigError, match=r"tolerances.Young: got 0.1; expected no such"):
        arm_from_dict(data)
