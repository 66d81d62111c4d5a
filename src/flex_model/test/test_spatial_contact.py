"""Seed 003's environment force on spatial arms (issue 25): the ``contact_surface`` effect
as a plane in 3D (effects.contact, spatial.dynamics). A planar arm with a floor embedded
in 3D against the planar ``simulate``, closed forms of a link pushed against a wall
(dynamic run to rest, statics), the compiled loop against the Python reference, energy
with the contact potential, and the validation of the arm file."""
from __future__ import annotations

import numpy as np
import pytest

from flex_model.arm import PRESET_DIR, arm_from_dict
from flex_model.config import ConfigError, read_yaml
from flex_model.dynamics import FlexArmModel
from flex_model.inputs import JointPD, Pulse
from flex_model.scenario import Scenario, scenario_from_dict
from flex_model.spatial.analysis import static_equilibrium
from flex_model.spatial.compiled import pack, tip_point
from flex_model.spatial.description import SPATIAL_PRESET_DIR, from_planar
from flex_model.spatial.loader import spatial_arm_from_dict
from flex_model.spatial.dynamics import SpatialArmModel
from flex_model.spatial.integrate import (simulate_fixed, simulate_fixed_compiled,
                                          simulate_variable)

L = 0.5


def _link(k: float, c: float, *, flexible: bool = False, d0: float = 0.0,
          end_mass: float = 1.0) -> dict:
    """One revolute link about z (a = L), no gravity, a wall through (L, -d0, 0) with the
    normal -y (free side y < -d0): the tip at q = 0 penetrates by d0."""
    link = {"name": "link1", "joint": {"name": "joint1", "a": L},
            "end_body": {"mass": end_mass}}
    if flexible:
        link["flexible"] = {"section": {"EI_y": 2.0, "EI_z": 2.0, "GJ": 1.5, "rhoA": 0.2,
                                        "rhoJ": 1e-5}, "variables": 4}
    return {"name": "wall_link", "gravity": [0.0, 0.0, 0.0], "links": [link],
            "effects": [{"type": "contact_surface", "x": L, "y": -d0, "z": 0.0,
                         "normal": [0.0, -2.0, 0.0], "stiffness": k, "damping": c}]}


def test_embedded_planar_arm_on_a_floor_follows_the_planar_simulate():
    """thesis_example1 (vertical plane, gravity) with a floor at y = -0.85 m under the tip,
    a joint PD, a torque pulse and a set-point step pressing the tip down, fixed step
    1 ms: the embedded arm (from_planar carries the contact_surface) equals the planar
    run (measured 2.1e-10 rad, 6.5e-10 m, 1.6e-6 N of a 10 N contact force)."""
    data = read_yaml(PRESET_DIR / "thesis_example1.yaml")
    data["effects"] = [{"type": "contact_surface", "x": 0.0, "y": -0.85,
                        "normal_angle": float(np.pi / 2), "stiffness": 2.0e3,
                        "damping": 20.0}]
    arm = arm_from_dict(data, "example1_floor")
    sp0, step = np.array([-0.3, 0.2]), np.radians(3.0)
    kp, kd = [200.0, 200.0], [20.0, 20.0]
    planar = scenario_from_dict({
        "arm": data, "duration": 1.0, "sample_period": 0.01,
        "initial": {"joint_angles_deg": np.degrees(sp0).tolist()},
        "control": {"pd": {"kp": kp, "kd": kd, "setpoints_deg": np.degrees(sp0).tolist()},
                    "setpoint_schedule": [{"time": 0.3, "setpoints_deg":
                                           np.degrees(sp0 - step).tolist()}]},
        "pulses": [{"joint": "joint1", "torque": -5.0, "start": 0.1, "end": 0.2}],
        "integrator": {"method": "fixed", "step": 1e-3, "rho_inf": 0.9}}).run(
            advise=False)  # both sides at one step: the step's own error is not compared
    spatial = from_planar(arm)
    model = SpatialArmModel(spatial)
    p0, n, k, c = model.contact
    assert np.allclose(p0, [0.0, -0.85, 0.0]) and np.allclose(n, [0.0, 1.0, 0.0], atol=1e-16)
    sc = Scenario(name="embedded_floor", arm=spatial, duration=1.0, step=1e-3,
                  sample_period=0.01, rho_inf=0.9, joint_values=sp0,
                  joint_rates=np.zeros(2), pd=JointPD(np.array(kp), np.array(kd), sp0),
                  setpoint_schedule=((0.3, sp0 - step, 0.0),),
                  pulses=(Pulse(0.1, 0.2, (-5.0, 0.0)),))
    res = sc.run(model=model, advise=False)
    assert np.max(np.abs(res.joint_angles - planar.joint_angles)) < 1e-9
    assert np.max(np.abs(res.joint_rates - planar.joint_rates)) < 1e-7
    tip = res.tip_positions
    assert np.max(np.abs(tip[:, :2] - planar.tip_positions)) < 2e-9
    assert np.max(np.abs(tip[:, 2])) == 0.0
    Fp = planar.contact_forces
    Fs = res.contact_forces
    names, table = res.table()
    assert names[-3:] == ["contact_fx", "contact_fy", "contact_fz"]
    assert np.array_equal(table[:, -3:], Fs)
    assert np.max(Fp[:, 1]) > 5.0 and np.sum(Fp[:, 1] > 0) > 50     # the tip rests on it
    assert np.max(np.abs(Fs[:, :2] - Fp)) < 1e-6 * np.max(np.abs(Fp))
    assert np.max(np.abs(Fs[:, 2])) == 0.0


def test_rigid_link_pushed_into_a_wall_settles_on_the_closed_form():
    """A rigid link (end mass 1 kg at L = 0.5 m) driven by a constant joint torque tau
    = 2 N m against a wall normal to the tip's motion at distance L: at rest
    tau = J^T F = k L^2 sin q cos q (exact), the force k delta, delta = L sin q, and the
    small-angle closed form delta = tau / (k L) (its error 1 - cos q = 3e-7)."""
    k, c, tau = 1.0e4, 100.0, 2.0
    model = SpatialArmModel(spatial_arm_from_dict(_link(k, c), "wall.yaml"))
    run = simulate_fixed_compiled(model, [0.0], [0.0], 1e-3, 1500, joint_torques=[tau])
    q, v = run.q[-1], run.v[-1]
    assert abs(v[0]) < 1e-12
    q_exact = 0.5 * np.arcsin(2 * tau / (k * L * L))
    assert abs(q[0] - q_exact) < 1e-9 * q_exact
    F = model.contact_force(q, v)
    delta = L * np.sin(q[0])
    assert np.allclose(F, [0.0, -k * delta, 0.0], rtol=1e-12, atol=1e-12)
    J = model.tip_jacobian(q)[:3]
    assert abs(tau + J[:, 0] @ F) < 1e-9 * tau                # torque balance tau = -J^T F
    assert abs(delta - tau / (k * L)) < 1e-6 * delta
    assert model.energy(q, v)["contact"] == pytest.approx(0.5 * k * delta ** 2, rel=1e-12)


def test_flexible_link_static_against_a_wall_closed_form():
    """The joint held at q = 0 with the tip d0 = 1 cm inside the wall: the beam (uniform EI,
    tip stiffness k_b = 3 EI / L^3) and the contact spring in series, v_tip = -k d0 /
    (k + k_b), F = k (d0 + v_tip) = k_b |v_tip| (the static solver with the contact)."""
    k, d0 = 100.0, 0.01
    model = SpatialArmModel(spatial_arm_from_dict(_link(k, 5.0, flexible=True, d0=d0),
                                                  "wall.yaml"))
    st = static_equilibrium(model, [0.0])
    kb = 3 * 2.0 / L ** 3
    v_tip = -k * d0 / (k + kb)
    assert st.deflections["link1"]["v"] == pytest.approx(v_tip, rel=1e-9)
    assert abs(st.deflections["link1"]["w"]) < 1e-15
    F = model.contact_force(st.q)
    assert F[1] == pytest.approx(-k * (d0 + v_tip), rel=1e-9)
    assert F[1] == pytest.approx(kb * v_tip, rel=1e-6)
    assert st.tip_position[1] == pytest.approx(v_tip, rel=1e-9)


def _seed003_with_contact(k=5.0e3, c=20.0, depth=0.02):
    data = read_yaml(SPATIAL_PRESET_DIR / "seed003_like_arm.yaml")
    plain = SpatialArmModel(spatial_arm_from_dict(data, "seed003"))
    q0 = np.zeros(plain.nq)
    q0[plain.off] = [0.3, -0.4, 0.6]
    q0[plain.motor_index[0]] = 0.3
    n = np.array([1.0, -1.0, 2.0]) / np.sqrt(6.0)
    p0 = plain.tip_position(q0) + depth * n
    data = dict(data, effects=list(data["effects"]) + [
        {"type": "contact_surface", "x": float(p0[0]), "y": float(p0[1]), "z": float(p0[2]),
         "normal": (3 * n).tolist(), "stiffness": k, "damping": c}])
    return SpatialArmModel(spatial_arm_from_dict(data, "seed003_contact")), q0


def test_compiled_loop_equals_python_with_the_contact_active():
    """seed003_like_arm with a tilted plane (normal (1, -1, 2)/sqrt 6) 2 cm into the tip,
    joint rates and torques: the compiled loop equals integrate.simulate_fixed over 20
    steps (1e-12), the contact acting at every step; the compiled tip point equals
    SpatialArmModel.tip_frame."""
    model, q0 = _seed003_with_contact()
    v0 = np.zeros(model.nq)
    v0[model.off] = [0.2, 0.3, -0.4]
    v0[model.motor_index[0]] = 0.2
    n_steps, h = 20, 1e-3
    tau = np.array([[1.0, 30.0, 8.0]] * n_steps)
    fast = simulate_fixed_compiled(model, q0, v0, h, n_steps, joint_torques=tau)
    ref = simulate_fixed(model, q0, v0, h, n_steps, joint_commands=tau)
    assert np.max(np.abs(fast.q - ref.q)) < 1e-12
    assert np.max(np.abs(fast.v - ref.v)) < 1e-12 * max(1.0, np.max(np.abs(ref.v)))
    F = np.array([model.contact_force(q, v) for q, v in zip(ref.q, ref.v)])
    assert np.min(np.linalg.norm(F, axis=1)) > 10.0             # measured 33 to 101 N
    assert np.allclose(np.cross(F, model.contact[1]), 0.0, atol=1e-12)   # along n
    data = pack(model)
    for q in (q0, ref.q[-1], q0 + 0.1 * np.sin(np.arange(model.nq))):
        o, Jo = tip_point(data, q)
        assert np.max(np.abs(o - model.tip_position(q))) < 1e-14
        assert np.max(np.abs(Jo - model.tip_jacobian(q)[:3])) < 1e-13


def test_arm_without_contact_is_unchanged_by_the_contact_code():
    """A plane far away (never touched) leaves the run equal to the arm without it."""
    model, q0 = _seed003_with_contact(depth=-1.0)
    plain = SpatialArmModel(spatial_arm_from_dict(read_yaml(
        SPATIAL_PRESET_DIR / "seed003_like_arm.yaml"), "seed003"))
    v0 = np.zeros(model.nq)
    v0[model.off] = 0.3
    a = simulate_fixed_compiled(model, q0, v0, 1e-3, 20, joint_torques=[1.0, 30.0, 8.0])
    b = simulate_fixed_compiled(plain, q0, v0, 1e-3, 20, joint_torques=[1.0, 30.0, 8.0])
    assert np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v)


def test_energy_with_the_contact_potential_is_conserved_over_a_bounce():
    """No damping anywhere (c = 0): a flexible link swinging into the wall and bouncing
    back (the contact potential holds up to 93 % of the energy); kinetic + elastic +
    k delta^2 / 2 is conserved by DOP853 (measured 2.7e-11 of the energy)."""
    model = SpatialArmModel(spatial_arm_from_dict(
        _link(2.0e3, 0.0, flexible=True, d0=-0.02, end_mass=0.2), "wall.yaml"))
    q0, v0 = np.zeros(model.nq), np.zeros(model.nq)
    v0[0] = 1.0                                   # tip at 0.5 m/s towards the wall
    t = np.linspace(0.0, 0.2, 201)
    run = simulate_variable(model, q0, v0, t, compiled=True)
    E = np.array([model.total_energy(q, v) for q, v in zip(run.q, run.v)])
    C = np.array([model.energy(q, v)["contact"] for q, v in zip(run.q, run.v)])
    assert np.max(C) > 0.5 * E[0] and C[-1] == 0.0     # in contact (0.041 to 0.074 s), out
    vy = model.tip_jacobian(run.q[-1])[1] @ run.v[-1]
    assert vy < -0.3                                   # bounced back (0.5 m/s in)
    assert np.max(np.abs(E - E[0])) < 1e-6 * E[0]


@pytest.mark.parametrize("effect, field", [
    ({"normal": [0.0, 0.0, 0.0]}, "effects[0].normal"),
    ({"normal": [0.0, 1.0]}, "effects[0].normal"),
    ({"normal": [0.0, 1.0, 0.0], "normal_angle": 1.0}, "effects[0].normal"),
    ({"stiffness": -5.0}, "effects[0].stiffness"),
    ({"stiffness": 0.0}, "effects[0].stiffness"),
    ({"damping": -1.0}, "effects[0].damping"),
])
def test_bad_contact_fields_name_file_and_field(effect, field):
    data = _link(1e3, 1.0)
    eff = data["effects"][0]
    eff.pop("normal")
    eff.update(effect)
    with pytest.raises(ConfigError) as exc:
        spatial_arm_from_dict(data, "bad_contact.yaml")
    assert exc.value.source == "bad_contact.yaml"
    assert exc.value.path == field


def test_planar_arm_refuses_a_normal_out_of_its_plane():
    data = read_yaml(PRESET_DIR / "thesis_example1.yaml")
    data["effects"] = [{"type": "contact_surface", "y": -1.0, "normal": [0.0, 1.0, 1.0],
                        "stiffness": 1e3}]
    with pytest.raises(ConfigError) as exc:
        FlexArmModel(arm_from_dict(data, "planar_floor.yaml"))
    assert exc.value.source == "planar_floor.yaml" and "normal" in exc.value.path
    data["effects"][0]["normal"] = [0.0, 3.0, 0.0]   # in the plane: the same as pi / 2
    a = FlexArmModel(arm_from_dict(data, "planar_floor.yaml")).contact
    del data["effects"][0]["normal"]
    data["effects"][0]["normal_angle"] = float(np.pi / 2)
    b = FlexArmModel(arm_from_dict(data, "planar_floor.yaml")).contact
    assert np.allclose(a, b, rtol=0, atol=1e-16)
