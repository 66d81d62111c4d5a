"""Effects, payload and sensors in a URDF side file (issue 25: the effects library on the
joints of a URDF arm): the DH file's fields, applied to the UR5-like arm."""
import numpy as np
import pytest

from flex_model.config import ConfigError, read_yaml
from flex_model.spatial.description import SPATIAL_PRESET_DIR
from flex_model.spatial.loader import spatial_arm_from_dict
from flex_model.spatial.dynamics import SpatialArmModel
from flex_model.spatial.integrate import simulate_fixed, simulate_fixed_compiled


def _side(**extra):
    data = read_yaml(SPATIAL_PRESET_DIR / "ur5_like_flexible_forearm.yaml")
    data["urdf"] = str(SPATIAL_PRESET_DIR / "ur5_like_arm.urdf")
    data.update(extra)
    return data


def test_effects_payload_and_sensors_act_on_the_urdf_arm():
    """A rotor behind the shoulder pan (ratio 100), Coulomb friction on the gravity-loaded
    elbow, an elastic wrist gear (one motor coordinate more), a 1 kg payload and an
    encoder: the model has them (the pan joint's inertia grows by n^2 J_r = 1 kg m^2, M by
    the payload), and the compiled loop equals the Python reference over 20 steps with all
    of them on. (The elbow starting to slide takes > 20 Newton iterations in a step: the
    line search from the 20th on lets it converge; with a Stribeck peak, static 1.5 N m,
    the 1 ms loop still fails at 7 ms.)"""
    plain = SpatialArmModel(spatial_arm_from_dict(_side(), "side.yaml"))
    arm = spatial_arm_from_dict(_side(
        effects=[{"type": "gear", "joint": "shoulder_pan_joint", "ratio": 100.0,
                  "rotor_inertia": 1e-4},
                 {"type": "joint_friction", "joint": "elbow_joint", "viscous": 2.0,
                  "coulomb": 1.0, "static": 1.0, "regularization": 1e-3},
                 {"type": "joint_elasticity", "joint": "wrist_1_joint",
                  "stiffness": 2000.0, "damping": 2.0, "motor_inertia": 0.01}],
        payload={"mass": 1.0, "offset": [0.0, 0.0, 0.05]},
        sensors=[{"kind": "joint_encoder", "joint": "elbow_joint", "resolution": 1e-4}]),
        "side.yaml")
    model = SpatialArmModel(arm)
    assert model.nq == plain.nq + 1
    assert arm.joint_type_003(3) == "AE_xi" and len(model.friction) == 1
    assert len(arm.sensors) == 1 and arm.payload.mass == 1.0
    q = np.zeros(model.nq)
    M, M0 = model.mass_matrix(q), plain.mass_matrix(np.zeros(plain.nq))
    assert M[0, 0] - M0[0, 0] > 1.0          # the rotor's n^2 J_r and the payload
    rng = np.random.default_rng(4)
    q0 = np.zeros(model.nq)
    q0[model.off] = rng.uniform(-0.5, 0.5, model.n_links)
    q0[-1] = q0[model.off[3]]                 # the motor where its link is
    tau = rng.uniform(-5, 5, (20, model.n_links))
    ref = simulate_fixed(model, q0, np.zeros(model.nq), 1e-3, 20, joint_commands=tau)
    comp = simulate_fixed_compiled(model, q0, np.zeros(model.nq), 1e-3, 20,
                                   joint_torques=tau)
    assert np.max(np.abs(comp.q - ref.q)) < 1e-12
    assert np.max(np.abs(comp.q[:, -1] - comp.q[:, model.off[3]])) > 1e-7   # the gear winds


def test_a_bad_effect_in_a_side_file_names_the_file_and_field():
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(_side(effects=[{"type": "stick_slip_friction",
                                              "joint": "elbow_joint"}]), "side.yaml")
    assert "side.yaml" in str(err.value) and "effects[0].type" in str(err.value)
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(_side(effects=[{"type": "gear", "joint": "no_such_joint",
                                              "ratio": 2.0}]), "side.yaml")
    assert "side.yaml" in str(err.value) and "no_such_joint" in str(err.value)


def test_a_failed_newton_step_is_retried_in_substeps():
    """With a Stribeck peak (static 1.5 N m over Coulomb 1 N m) on the gravity-loaded
    elbow (and a 1 kg payload) the 1 ms loop fails at 7 ms; simulate_fixed_compiled
    integrates that step again as 4 substeps from a restart and goes on (substeps=0: the
    error). The steps before the failure are the plain run's, bit for bit; the retried
    step is the h/4 run's."""
    model = SpatialArmModel(spatial_arm_from_dict(_side(effects=[
        {"type": "joint_friction", "joint": "elbow_joint", "viscous": 2.0, "coulomb": 1.0,
         "static": 1.5, "regularization": 1e-3}], payload={"mass": 1.0,
                                                           "offset": [0.0, 0.0, 0.05]}),
        "side.yaml"))
    rng = np.random.default_rng(4)
    q0 = np.zeros(model.nq)
    q0[model.off] = rng.uniform(-0.5, 0.5, model.n_links)
    tau = rng.uniform(-5, 5, (20, model.n_links))
    z = np.zeros(model.nq)
    with pytest.raises(RuntimeError, match="t = 0.007 s"):
        simulate_fixed_compiled(model, q0, z, 1e-3, 20, joint_torques=tau, substeps=0)
    run = simulate_fixed_compiled(model, q0, z, 1e-3, 20, joint_torques=tau)
    assert run.q.shape == (21, model.nq) and np.all(np.isfinite(run.q))
    before = simulate_fixed_compiled(model, q0, z, 1e-3, 6, joint_torques=tau[:6])
    np.testing.assert_array_equal(run.q[:7], before.q)
    # the count has the steps before the failure, the failed attempt, the 4 substeps and
    # the 13 steps after
    assert run.newton_iterations > before.newton_iterations + 4 + 13
    retried = simulate_fixed_compiled(model, run.q[6], run.v[6], 2.5e-4, 4,
                                      joint_torques=np.repeat(tau[6:7], 4, axis=0))
    np.testing.assert_array_equal(run.q[7], retried.q[-1])
