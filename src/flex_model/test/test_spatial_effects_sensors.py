"""Sensors of spatial arms (issue 25; spatial/sensors.py, the planar sensor model of
flex_model.sensors): joint and motor encoders with bias, quantisation, delay and noise,
the spring torque of an elastic gear against the link's equation of motion, the tip
position, bad sensor lists refused."""
import copy
from pathlib import Path

import numpy as np
import pytest

from flex_model.config import ConfigError, read_yaml
from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
from flex_model.spatial.integrate import joint_input_matrix, simulate_fixed_compiled
from flex_model.spatial.sensors import measure

EFFECTS_ARM = read_yaml(Path(__file__).with_name("data_spatial_effects_arm.yaml"))
RES = 2 * np.pi / 4096            # a 12-bit encoder


def _arm_with_sensors():
    data = copy.deepcopy(EFFECTS_ARM)
    data["sensors"] = [
        {"name": "enc1", "kind": "joint_encoder", "joint": "j1", "bias": 0.01,
         "resolution": RES, "delay": 0.002},
        {"name": "mot2", "kind": "motor_encoder", "joint": "j2", "resolution": RES},
        {"name": "mot3", "kind": "motor_encoder", "joint": "j3"},
        {"name": "spring2", "kind": "joint_torque", "joint": "j2"},
        {"name": "tau1", "kind": "joint_torque", "joint": "j1"},
        {"name": "tip", "kind": "tip_position", "noise": 1e-4}]
    return spatial_arm_from_dict(data)


def test_encoders_bias_quantisation_delay_and_noise():
    """Along a compiled run of the seed 003 joint-type arm: the delayed, biased, 12-bit
    joint encoder is round((q(t - 2 ms) + bias) / res) res exactly; the motor encoder of
    the elastic gear reads n theta_m (quantised), of the locked gear n locked_at; the
    tip position's noise has the stated deviation and is seeded; the rigid joint's
    torque sensor reads the run's torques."""
    arm = _arm_with_sensors()
    model = SpatialArmModel(arm)
    s = {x.name: x for x in arm.sensors}
    h, n = 1e-3, 200
    rng = np.random.default_rng(2)
    tau = rng.normal(scale=0.5, size=(n, model.n_links))
    q0 = np.zeros(model.nq)
    q0[model.held] = 0.3
    run = simulate_fixed_compiled(model, q0, np.zeros(model.nq), h, n, joint_torques=tau)
    taus = np.vstack([tau[:1], tau])      # the torque acting at each sample
    t, y = measure(s["enc1"], model, run.t, run.q, run.v)
    x = run.q[:, 0]
    expect = np.round((np.concatenate([[x[0], x[0]], x[:-2]]) + 0.01) / RES) * RES
    np.testing.assert_array_equal(y[:, 0], expect)
    assert np.max(np.abs(y[2:, 0] - x[:-2] - 0.01)) <= RES / 2 + 1e-15
    assert np.ptp(x) > 10 * RES                              # the encoder sees it move
    _, y = measure(s["mot2"], model, run.t, run.q, run.v)
    np.testing.assert_array_equal(y[:, 0], np.round(80.0 * run.q[:, model.nq_arm] / RES) * RES)
    _, y = measure(s["mot3"], model, run.t, run.q, run.v)
    assert np.all(y == 30.0 * 0.1)
    _, y = measure(s["tau1"], model, run.t, run.q, run.v, taus)
    np.testing.assert_array_equal(y[:, 0], taus[:, 0])
    _, y1 = measure(s["tip"], model, run.t, run.q, run.v, seed=3)
    _, y2 = measure(s["tip"], model, run.t, run.q, run.v, seed=3)
    np.testing.assert_array_equal(y1, y2)
    tip = np.array([model.tip_position(q) for q in run.q])
    assert np.std(y1 - tip) == pytest.approx(1e-4, rel=0.1)


def test_spring_torque_sensor_drives_the_link():
    """A rigid link on an elastic gear about a vertical axis (gravity does no work): the
    link side feels only the spring, so the joint_torque sensor equals J_l theta'' (J_l =
    I_zz + m a^2) along a run with a motor torque, at every state (1e-12 relative)."""
    data = {"name": "two_inertia", "gravity": [0, 0, -9.81], "links": [
        {"joint": {"name": "j1", "a": 0.4, "gear": "elastic"},
         "end_body": {"mass": 2.0, "inertia": [0.01, 0.02, 0.03]}}],
        "effects": [{"type": "joint_elasticity", "joint": "j1", "stiffness": 1500.0,
                     "damping": 0.8, "motor_inertia": 0.02}],
        "sensors": [{"kind": "joint_torque", "joint": "j1"}]}
    arm = spatial_arm_from_dict(data)
    model = SpatialArmModel(arm)
    run = simulate_fixed_compiled(model, np.zeros(2), np.zeros(2), 1e-3, 100,
                                  joint_torques=3.0)
    _, y = measure(arm.sensors[0], model, run.t, run.q, run.v)
    H = joint_input_matrix(model)
    acc = np.array([model.acceleration(q, v, H @ [3.0])[0] for q, v in zip(run.q, run.v)])
    jl = 0.03 + 2.0 * 0.4 ** 2
    np.testing.assert_allclose(y[:, 0], jl * acc, rtol=0, atol=1e-12 * np.max(np.abs(y)))
    assert np.max(np.abs(y)) > 1.0


@pytest.mark.parametrize("sensor, where", [
    ({"kind": "strain_gauge", "link": "link2"}, "sensors[0].kind"),
    ({"kind": "joint_encoder", "joint": "j9"}, "sensors[0].joint"),
    ({"kind": "joint_encoder", "joint": "j1", "resolution": -1.0}, "sensors[0].resolution"),
])
def test_bad_sensors_name_the_field(sensor, where):
    data = dict(copy.deepcopy(EFFECTS_ARM), sensors=[sensor])
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "arm.yaml")
    assert "arm.yaml" in str(err.value) and where in str(err.value)
