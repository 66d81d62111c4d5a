"""The compiled spatial kernels (numba, analytic Newton-Euler velocity terms) against the
Python reference (complex-step velocity terms): M, c, inverse dynamics and the compiled
generalized-alpha loop, on arms covering DH (dh_x, aux_z), prismatic joints, torsion,
bending rotary inertia and a URDF arm (general axes, link_x beam, merged fixed links,
effort limits)."""
import copy
from pathlib import Path

import numpy as np
import pytest

from flex_model.config import read_yaml
from flex_model.spatial import SpatialArmModel, load_spatial_arm, spatial_arm_from_dict
from flex_model.spatial.compiled import CompiledSpatialModel, spatial_eval
from flex_model.spatial.integrate import (joint_input_matrix, simulate_fixed,
                                          simulate_fixed_compiled)
from flex_model.spatial.limits import clip_efforts

AUX = {"name": "aux", "gravity": [0.5, -2.0, -9.81], "links": [
    {"joint": {"type": "revolute", "alpha": -1.2, "d": 0.2, "a": 0.1},
     "end_body": {"mass": 0.7, "inertia": [[0.01, 0.002, 0.0], [0.002, 0.02, 0.001],
                                           [0.0, 0.001, 0.015]], "offset": [0.02, 0.03, -0.01]}},
    {"joint": {"type": "prismatic", "alpha": 0.7, "theta": 0.4, "d": 0.1}},
    {"joint": {"type": "revolute", "a": 0.05, "alpha": 0.3, "d": 0.02},
     "flexible": {"placement": "aux_z", "length": 0.6, "variables": 4, "torsion_variables": 2,
                  "section": {"EI_y": [6.0, 3.0], "EI_z": 2.0, "GJ": 1.5, "rhoA": [0.6, 0.4],
                              "rhoJ": 4e-3}},
     "root_body": {"mass": 0.3, "inertia": [1e-3, 2e-3, 3e-3], "offset": [0.0, 0.01, 0.0]},
     "end_body": {"mass": 0.2, "inertia": [2e-4, 3e-4, 1e-4], "offset": [0.01, 0.0, 0.02]}},
    {"joint": {"type": "revolute", "a": 0.4, "alpha": 0.5},
     "flexible": {"variables": 2, "torsion_variables": 0,
                  "section": {"EI_y": 3.0, "EI_z": 1.0, "GJ": 1.0, "rhoA": 0.3}},
     "end_body": {"mass": 0.1}}]}


def _rotary_aux() -> dict:
    """AUX with bending rotary inertia on both beams (one twisting, one not)."""
    arm = copy.deepcopy(AUX)
    for lk in arm["links"][2:]:
        lk["flexible"]["rotary_inertia"] = True
    arm["links"][3]["flexible"]["section"]["rhoJ"] = 2e-3
    return arm


def _models():
    effects = read_yaml(Path(__file__).with_name("data_spatial_effects_arm.yaml"))
    return {"seed000": SpatialArmModel(load_spatial_arm("seed000_real_arm_3d")),
            "aux_prismatic": SpatialArmModel(spatial_arm_from_dict(AUX)),
            "aux_rotary": SpatialArmModel(spatial_arm_from_dict(_rotary_aux())),
            "urdf_6_joint": SpatialArmModel(load_spatial_arm("ur5_like_flexible_forearm")),
            "effects": SpatialArmModel(spatial_arm_from_dict(effects))}


@pytest.fixture(scope="module")
def models():
    return _models()


@pytest.mark.parametrize("name", ["seed000", "aux_prismatic", "aux_rotary", "urdf_6_joint",
                                  "effects"])
def test_compiled_terms_equal_the_python_reference(models, name):
    """M, c (velocity terms + gravity) and M a + c (inverse dynamics) at random states:
    the analytic recursion equals the complex-step reference to 1e-10 (relative)."""
    model = models[name]
    cm = CompiledSpatialModel(model)
    rng = np.random.default_rng(7)
    for _ in range(3):
        q = rng.normal(scale=0.3, size=model.nq)
        v = rng.normal(scale=2.0, size=model.nq)
        a = rng.normal(scale=5.0, size=model.nq)
        Mr, cr = model.terms(q, v)
        Mc, cc = cm.terms(q, v)
        assert np.max(np.abs(Mc - Mr)) < 1e-10 * np.max(np.abs(Mr))
        assert np.max(np.abs(cc - cr)) < 1e-10 * np.max(np.abs(cr))
        f = spatial_eval(cm.data, q, v, a, False)[1]
        ref = Mr @ a + cr
        assert np.max(np.abs(f - ref)) < 1e-10 * np.max(np.abs(ref))
    g = cm.gravity_force(q)
    gr = model.gravity_force(q)
    assert np.max(np.abs(g - gr)) < 1e-10 * np.max(np.abs(gr))


def test_compiled_loop_equals_python_loop_and_clips_efforts(models):
    """20 generalized-alpha steps of the URDF arm with torques above the effort limits
    and a damping matrix: the compiled loop equals simulate_fixed fed the clipped
    torques (1e-12 m or rad), and the clip is active (a run without it differs)."""
    model = models["urdf_6_joint"]
    h, n = 1e-3, 20
    rng = np.random.default_rng(1)
    tau = rng.normal(scale=100.0, size=(n, model.n_links))      # wrist limits are 28 N m
    clipped = clip_efforts(model.arm, tau)
    assert np.any(clipped != tau)
    H = joint_input_matrix(model)
    D = 1e-4 * model.K + np.diag(np.full(model.nq, 0.05))
    q0 = np.zeros(model.nq)
    q0[model.off] = [0.2, -0.4, 0.8, -0.3, 0.5, 0.1]
    v0 = np.zeros(model.nq)
    v0[model.off] = [0.5, -0.2, 0.3, 0.0, 1.0, -1.0]
    # row n acts at t_{n+1}; at t = 0 (initial acceleration) the compiled loop uses row 0
    ref = simulate_fixed(model, q0, v0, h, n, damping=D,
                         force=lambda t, q, v: H @ clipped[max(int(round(t / h)) - 1, 0)])
    run = simulate_fixed_compiled(model, q0, v0, h, n, joint_torques=tau, damping=D)
    assert np.max(np.abs(run.q - ref.q)) < 1e-12
    assert np.max(np.abs(run.v - ref.v)) < 1e-9
    free = simulate_fixed_compiled(model, q0, v0, h, n, joint_torques=tau, damping=D,
                                   clip_to_effort=False)
    assert np.max(np.abs(free.q[-1] - run.q[-1])) > 1e-4


def test_compiled_loop_with_joint_effects_equals_python_loop(models):
    """20 steps of the arm with every seed 003 joint type (geared rotors, an elastic gear
    with its motor coordinate, friction on two actuators, a locked elastic gear with
    preload, a held joint) under joint torques: compiled loop = simulate_fixed to 1e-12;
    the held joint does not move."""
    model = models["effects"]
    h, n = 1e-3, 20
    rng = np.random.default_rng(2)
    tau = rng.normal(scale=2.0, size=(n, model.n_links))
    H = joint_input_matrix(model)
    q0 = rng.normal(scale=0.1, size=model.nq)
    v0 = rng.normal(scale=0.5, size=model.nq)
    q0[model.held], v0[model.held] = 0.3, 0.0
    ref = simulate_fixed(model, q0, v0, h, n,
                         force=lambda t, q, v: H @ tau[max(int(round(t / h)) - 1, 0)])
    run = simulate_fixed_compiled(model, q0, v0, h, n, joint_torques=tau)
    assert np.max(np.abs(run.q - ref.q)) < 1e-12
    assert np.max(np.abs(run.v - ref.v)) < 1e-9
    assert np.all(run.q[:, model.held] == 0.3)
