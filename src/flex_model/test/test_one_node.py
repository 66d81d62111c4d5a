"""One model node class for every arm (issue 43): a spatial arm in the same ModelNode as a
planar one, the continuous in-loop PD on it against the plain-Python core run, and the
one-line refusals of parameters that mean nothing for the arm kind."""
import re

import numpy as np
import pytest
import rclpy
from rclpy.parameter import Parameter

from flex_model.ros.model_node import ModelNode, SpatialModelNode
from flex_model.ros.main import ParameterError
from flex_model.spatial import SpatialArmModel, load_spatial_arm
from flex_model.inputs import JointPD
from flex_model.scenario import Scenario
from flex_model.spatial.scenario import pd_matrices, pd_static_equilibrium

ARM = "seed003_like_arm"


@pytest.fixture
def ctx():
    c = rclpy.Context()
    rclpy.init(context=c)
    yield c
    rclpy.try_shutdown(context=c)


def make(ctx, factory=ModelNode, **params):
    return factory(context=ctx, parameter_overrides=[Parameter(k, value=v)
                                                     for k, v in params.items()])


def test_the_continuous_pd_on_a_spatial_arm_reaches_its_set_point(ctx):
    """ModelNode (not the spatial defaults) with a spatial arm and controller eq95: 1 s
    of 100 Hz periods (2.5 ms steps) from zero to the set-points [0.3, -0.2, 0.4] rad
    equals the plain-Python core run (Scenario with the same PD, one compiled
    run) to 1e-10 and settles on the PD's static equilibrium (within 1e-4 rad: the gravity
    sag kp^-1 tau_g, 0.011 rad at joint 2, not a set-point error of the loop)."""
    kp, kd, sp = [400.0, 2500.0, 800.0], [41.0, 107.0, 31.0], [0.3, -0.2, 0.4]
    node = make(ctx, arm=ARM, mode="lockstep", rate=100.0, step=2.5e-3, controller="eq95",
                kp=kp, kd=kd, setpoints=sp, lockstep_timeout=60.0)
    try:
        assert type(node) is ModelNode and type(node.arm_io).__name__ == "SpatialArm"
        assert not node.braked      # the in-loop PD drives it from the start
        for _ in range(100):
            node.advance()
        assert node.t == pytest.approx(1.0, abs=1e-12) and node.diverged is None
        arm = load_spatial_arm(ARM)
        sc = Scenario(name="pd", arm=arm, duration=1.0, step=2.5e-3,
                      sample_period=1e-2, rho_inf=0.9, joint_values=np.zeros(3),
                      joint_rates=np.zeros(3),
                      pd=JointPD(np.array(kp), np.array(kd), np.array(sp)))
        run = sc.run(advise=False)
        np.testing.assert_allclose(node.q, run.q[-1], rtol=0, atol=1e-10)
        model = SpatialArmModel(arm)
        K_pd, _ = pd_matrices(sc, model)
        q_eq = pd_static_equilibrium(model, K_pd, np.array(kp) * sp)
        np.testing.assert_allclose(node.q[model.off], q_eq[model.off], rtol=0, atol=1e-4)
        sag = q_eq[model.off] - sp
        assert sag[1] == pytest.approx(-0.0110, abs=2e-4)     # not a zero test
        np.testing.assert_allclose(node.joint_values()[:3], node.q[model.off], rtol=0,
                                   atol=0)
    finally:
        node.destroy_node()


def test_one_class_and_one_line_refusals(ctx):
    """The spatial entry point is the same class; a parameter of the other arm kind, a
    plugin controller on a spatial arm and two values for one aliased parameter are one
    line each naming the parameter and what to use instead."""
    for params, text in (
            ({"arm": "thesis_example1", "kp": [1.0]}, "parameter kp: got [1] on the planar "
             "arm 'thesis_example1'; expected the default [0]: on a planar arm the in-loop "
             "PD is the plugin controller eq95"),
            ({"arm": ARM, "vars_per_link": 4}, "parameter vars_per_link: got 4 on the "
             "spatial arm 'seed003_like_arm'; expected the default 0: a spatial arm's "
             "discretization is its arm file's"),
            ({"arm": ARM, "controller": "state_feedback"}, "parameter controller: got "
             "'state_feedback' on the spatial arm seed003_like_arm; expected none, eq95 or "
             "eq45"),
            ({"arm": ARM, "step": 2e-3, "max_step": 5e-4}, "parameter step: got 0.002 and "
             "max_step 0.0005; expected one of them"),
            ({"arm": "thesis_example1", "payload": [1.0, 2.0, 3.0, 4.0]}, "parameter "
             "payload: got [1, 2, 3, 4]; expected [mass] or [mass, inertia]")):
        with pytest.raises(ParameterError, match=re.escape(text)):
            make(ctx, **params)
    node = make(ctx, SpatialModelNode, mode="lockstep", lockstep_timeout=60.0)
    try:
        assert type(node) is ModelNode and node.p["arm"] == ARM
        assert node.p["rate"] == 250.0 and node.per == 4      # the spatial defaults
    finally:
        node.destroy_node()


def test_a_failed_spatial_period_is_integrated_again_in_finer_steps(ctx, monkeypatch):
    """A period whose Newton fails in its 4 steps is done again from the same state in
    16 (4 x shorter, the first of REFINEMENTS): the node goes on, with the state of the
    finer run (1e-12), and logs the refinement; no divergence."""
    import flex_model.spatial.integrate as integrate
    real = integrate.simulate_fixed_compiled
    calls = []

    def coarse_fails(model, q, v, h, n, **kw):
        calls.append(n)
        if n == 4:
            raise RuntimeError("generalized-alpha: no convergence (test)")
        return real(model, q, v, h, n, **kw)
    node = make(ctx, SpatialModelNode, mode="lockstep", lockstep_timeout=60.0,
                initial_joint_values=[0.1, -0.2, 0.3])
    try:
        u = np.array([2.0, -1.0, 0.5])
        node.arm_io.set_command(u)
        monkeypatch.setattr(integrate, "simulate_fixed_compiled", coarse_fails)
        node.advance()
        assert calls == [4, 16] and node.diverged is None and node.steps == 1
        model = SpatialArmModel(load_spatial_arm(ARM))
        ref = real(model, node.q0, node.v0, 1.0 / 250 / 16, 16, joint_torques=u)
        np.testing.assert_allclose(node.q, ref.q[-1], rtol=0, atol=1e-12)
        assert any("integrated again in steps # x shorter" in k for k in node.drops.last)
    finally:
        node.destroy_node()


def test_the_kinematics_parameter_on_a_spatial_arm(ctx):
    """kinematics: exact on a spatial arm (issue 43: every kinematics option on every
    arm) reaches the arm the compiled loop steps; an unknown one is one line."""
    node = make(ctx, SpatialModelNode, kinematics="exact", mode="lockstep",
                lockstep_timeout=60.0)
    try:
        assert node.model.arm.kinematics == "exact" and node.arm0.kinematics == "exact"
    finally:
        node.destroy_node()
    with pytest.raises(ParameterError, match=re.escape(
            "parameter kinematics: got 'exactly'; expected one of small_deflection, "
            "second_order, exact")):
        make(ctx, SpatialModelNode, kinematics="exactly")
