"""Effects (flex_model.effects): each alone, against closed forms and conservation."""
import numpy as np
import pytest

from flex_model.arm import arm_from_dict, load_arm
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_model.effects import (EFFECT_TYPES, BaseTilt, ContactSurface, Gear,
                                StructuralDamping, TorqueSaturation)
from flex_model.modes import natural_modes
from flex_model.simulate import JointPD, simulate
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
    ({"type": "magic"}, "effects[0].type", "one of base_tilt, contact_surface"),
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
