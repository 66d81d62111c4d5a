"""DC motors on spatial joints (issue 25; effects.motor.DCMotor, seed 003 Eq. 48 with the
armature inductance neglected, as the planar model): the joint command is a voltage,
tau = n K_t clip((V - K_e n w) / R, i_max). The no-load speed and mechanical time
constant under a voltage step, the current-limited ramp, the compiled loop against the
Python reference with motors, structural damping and every seed 003 joint type, and bad
files refused."""
import copy
from pathlib import Path

import numpy as np
import pytest

from flex_model.config import ConfigError, read_yaml
from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
from flex_model.spatial.integrate import (simulate_fixed, simulate_fixed_compiled,
                                          simulate_variable)
from flex_model.scenario import scenario_from_dict

R, KT, KE, N, JR = 2.0, 0.05, 0.06, 40.0, 2e-5       # ohm, N m/A, V s/rad, -, kg m^2
MASS, A, IZZ = 1.5, 0.4, 0.02


def _one_joint(imax=None):
    """A rigid link on a vertical axis (gravity does no work) behind a gear (the rotor,
    the armature inertia, on the fixed base) and a DC motor."""
    motor = {"type": "dc_motor", "joint": "j1", "resistance": R, "torque_constant": KT,
             "back_emf_constant": KE}
    if imax is not None:
        motor["current_limit"] = imax
    return {"name": "motor", "gravity": [0.0, 0.0, -9.81], "links": [
        {"joint": {"name": "j1", "a": A},
         "end_body": {"mass": MASS, "inertia": [0.0, 0.0, IZZ]}}],
        "effects": [{"type": "gear", "joint": "j1", "ratio": N, "rotor_inertia": JR},
                    motor]}


J = IZZ + MASS * A * A + N * N * JR


def test_voltage_step_reaches_the_no_load_speed_with_the_mechanical_time_constant():
    """J w' = n K_t (V - K_e n w) / R: w(t) = V / (n K_e) (1 - exp(-t / T)) with
    T = J R / (n^2 K_t K_e) (DOP853 through model.actuator_force)."""
    model = SpatialArmModel(spatial_arm_from_dict(_one_joint()))
    volt = 12.0
    T = J * R / (N * N * KT * KE)
    t = np.array([0.0, 0.5, 1.0, 2.0, 5.0]) * T
    run = simulate_variable(model, np.zeros(1), np.zeros(1), t,
                            joint_commands=lambda _t: np.array([volt]), rtol=1e-12,
                            atol=1e-14)
    w_inf = volt / (N * KE)
    np.testing.assert_allclose(run.v[:, 0], w_inf * (1 - np.exp(-t / T)), rtol=1e-8,
                               atol=1e-12)
    # the back-EMF is a viscous damping n^2 K_t K_e / R: the slope of actuator_force
    Q, slope = model.actuator_force([volt], np.array([1.0]))
    assert Q[0] == pytest.approx(N * KT * (volt - KE * N) / R, rel=1e-15)
    assert slope[0] == pytest.approx(-N * N * KT * KE / R, rel=1e-15)


def test_current_limit_gives_a_constant_torque_ramp_then_the_exponential():
    """With i_max below V / R: w = n K_t i_max t / J until the back-EMF brings the current
    under the limit at w_1 = (V - R i_max) / (K_e n), then the exponential towards the
    no-load speed from there."""
    imax, volt = 2.0, 12.0
    model = SpatialArmModel(spatial_arm_from_dict(_one_joint(imax)))
    T = J * R / (N * N * KT * KE)
    w1 = (volt - R * imax) / (KE * N)
    t1 = w1 * J / (N * KT * imax)
    w_inf = volt / (N * KE)
    t = np.array([0.0, 0.3 * t1, 0.9 * t1, t1 + 0.5 * T, t1 + 3 * T])
    closed = np.where(t <= t1, N * KT * imax * t / J,
                      w_inf - (w_inf - w1) * np.exp(-(t - t1) / T))
    run = simulate_variable(model, np.zeros(1), np.zeros(1), t,
                            joint_commands=lambda _t: np.array([volt]), rtol=1e-12,
                            atol=1e-14)
    np.testing.assert_allclose(run.v[:, 0], closed, rtol=1e-7, atol=1e-12)
    # the fixed-step compiled loop (trapezoidal), 1 ms against T = 0.12 s: 2.5e-6 reached
    h = 1e-3
    n = int(round((t1 + 3 * T) / h))
    fixed = simulate_fixed_compiled(model, np.zeros(1), np.zeros(1), h, n,
                                    joint_torques=volt, rho_inf=1.0)
    tf = h * np.arange(n + 1)
    ref = np.where(tf <= t1, N * KT * imax * tf / J,
                   w_inf - (w_inf - w1) * np.exp(-(tf - t1) / T))
    assert np.max(np.abs(fixed.v[:, 0] - ref)) < 1e-5 * w_inf


EFFECTS_ARM = read_yaml(Path(__file__).with_name("data_spatial_effects_arm.yaml"))


def _motor_arm():
    """The seed 003 joint-type arm (test_spatial_effects.py) with DC motors on j1 (a
    geared rigid joint with friction) and j2 (behind the elastic gear: on the motor
    coordinate; a current limit), and structural damping on the flexible link 2."""
    data = copy.deepcopy(EFFECTS_ARM)
    data["effects"] += [
        {"type": "dc_motor", "joint": "j1", "resistance": 1.5, "torque_constant": 0.04,
         "back_emf_constant": 0.05, "voltage_limit": 6.0},
        {"type": "dc_motor", "joint": "j2", "resistance": 0.8, "torque_constant": 0.03,
         "back_emf_constant": 0.03, "current_limit": 1.0},
        {"type": "structural_damping", "link": "link2", "internal_friction": 0.01,
         "rayleigh_mass": 0.2, "rayleigh_stiffness": 1e-3}]
    return data


def test_compiled_loop_with_motors_and_damping_equals_the_python_loop():
    """20 generalized-alpha steps with voltages (one above V_max, currents above i_max on
    j2), friction, structural damping, elastic and locked gears and a held joint: the
    compiled loop equals simulate_fixed(joint_commands=...) to 1e-12; the limits are
    active; the motor voltage is not clipped to a torque limit."""
    model = SpatialArmModel(spatial_arm_from_dict(_motor_arm()))
    assert [m[:2] for m in model.motors] == [(0, 0), (1, model.nq_arm)]
    h, n = 1e-3, 20
    rng = np.random.default_rng(2)
    volts = rng.normal(scale=2.0, size=(n, model.n_links))
    volts[3, 0] = 10.0                                   # above V_max = 6 V
    q0 = rng.normal(scale=0.1, size=model.nq)
    v0 = rng.normal(scale=0.5, size=model.nq)
    q0[model.held], v0[model.held] = 0.3, 0.0
    ref = simulate_fixed(model, q0, v0, h, n, joint_commands=volts)
    run = simulate_fixed_compiled(model, q0, v0, h, n, joint_torques=volts)
    assert np.max(np.abs(run.q - ref.q)) < 1e-12
    assert np.max(np.abs(run.v - ref.v)) < 1e-9
    assert run.newton_iterations == ref.newton_iterations
    cur2 = [(u - 0.03 * 80 * v[model.nq_arm]) / 0.8 for u, v in zip(volts[:, 1], run.v[1:])]
    assert max(np.abs(cur2)) > 1.0                   # the current limit acts
    # the voltages as torques give another run
    torque = simulate_fixed_compiled(SpatialArmModel(spatial_arm_from_dict(EFFECTS_ARM)),
                                     q0[:model.nq], v0, h, n, joint_torques=volts)
    assert np.max(np.abs(torque.q[-1] - run.q[-1])) > 1e-6


@pytest.mark.parametrize("change, where", [
    (lambda d: d["links"][0]["joint"].update(motor="locked"), "links[0].joint.motor"),
    (lambda d: d["effects"][-2].update(resistance=0.0), "resistance"),
])
def test_bad_motor_files_name_the_field(change, where):
    data = _motor_arm()
    change(data)
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "arm.yaml")
    assert "arm.yaml" in str(err.value) and where in str(err.value)


def test_a_scenario_on_a_dc_motor_arm_is_refused():
    with pytest.raises(ConfigError) as err:
        scenario_from_dict({"arm": _one_joint(), "duration": 0.1}, "sc.yaml")
    assert "sc.yaml" in str(err.value) and "dc_motor" in str(err.value)
