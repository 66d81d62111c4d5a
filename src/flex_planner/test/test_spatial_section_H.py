"""VALIDATION.md section H in 3D (issue 25): seed 002's two-link arm with flexible joints
(springs 1e4 N m/rad driven by the planned motor angles, flex_planner.residual_vibration)
embedded by from_planar, run by the spatial compiled loop with the planar run's scheme
(the spring as an in-loop joint stiffness, k_t q_ac(t) at mid-interval held over each
0.25 ms step, a restart at each): the same tip path, so the same path deviation and
residual-vibration radius, and the paper's trend (the radius grows with the payload).
Measured: tips 7.6e-11 / 9.2e-11 m apart (0 / 2 kg), radius 20.34 / 34.49 mm, path
deviation 48.5 / 53.8 mm, both codes. (From the static start the accelerations of the
deformation variables sit at a round-off floor above the Newton tolerance 1e-10: the
loop's stagnation test, integrate.STAGNATION, accepts them; before it the first step
failed.) The rigid-joint case (prescribed joint motion, the planner's
NominalInputSolver) has no spatial counterpart."""
import dataclasses

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.spatial import SpatialArmModel, from_planar
from flex_model.spatial.description import RigidBody
from flex_model.spatial.integrate import simulate_fixed_compiled
from flex_model.spatial.scenario import pd_static_equilibrium
from flex_planner.residual_vibration import (SECTION_H_JOINT_STIFFNESS, SPRING_INPUT_PERIOD,
                                             _result, payload_sweep, section_h_motion)

MASSES = (0.0, 2.0)     # kg: no payload and the paper's largest


def spatial_run(planar, motion, t_f, mass):
    """The flexible-joint run of residual_vibration on the arm embedded in 3D."""
    arm = from_planar(planar.arm)
    arm = dataclasses.replace(arm, payload=RigidBody(mass=mass))
    model = SpatialArmModel(arm)
    n = model.n_links
    kt = np.full(n, SECTION_H_JOINT_STIFFNESS)
    Kp = np.zeros((model.nq, model.nq))
    Kp[model.off, model.off] = kt
    q = pd_static_equilibrium(model, Kp, kt * motion.p[0], start=motion.p[0])
    v = np.zeros(model.nq)
    h = SPRING_INPUT_PERIOD
    steps = int(round((motion.t[-1] - motion.t[0]) / h))
    per = int(round(1e-3 / h))
    model.K = model.K + Kp
    tips = [model.tip_position(q)[:2]]
    for k in range(steps):
        tm = motion.t[0] + (k + 0.5) * h
        u = kt * np.array([np.interp(tm, motion.t, motion.p[:, i]) for i in range(n)])
        run = simulate_fixed_compiled(model, q, v, h, 1, joint_torques=u)
        q, v = run.q[-1], run.v[-1]
        if (k + 1) % per == 0:
            tips.append(model.tip_position(q)[:2])
    t = motion.t[0] + 1e-3 * np.arange(len(tips))
    return _result(planar, motion, t_f, t, np.array(tips), np.zeros((len(tips), n)))


@pytest.mark.parametrize("path", [1])
def test_flexible_joint_runs_in_3d_equal_the_planar_and_grow_with_payload(path):
    planar = FlexArmModel(load_arm("seed002_two_link"))
    motion, t_f = section_h_motion(planar, path)
    radii = []
    refs = payload_sweep(planar, MASSES, path, joint_stiffness=SECTION_H_JOINT_STIFFNESS)
    for mass, ref in zip(MASSES, refs):
        res = spatial_run(planar, motion, t_f, mass)
        n = min(len(res.t), len(ref.t))
        assert np.max(np.abs(res.tip[:n] - ref.tip[:n])) < 1e-9
        assert res.radius == pytest.approx(ref.radius, rel=1e-6)
        assert res.path_deviation == pytest.approx(ref.path_deviation, rel=1e-6)
        radii.append(res.radius)
    assert radii[1] > 1.4 * radii[0]          # the paper's trend: 2 kg against none


@pytest.mark.parametrize("path", [1, 2])
def test_rigid_joint_runs_in_3d_equal_the_planar_nominal_input(path):
    """The rigid-joint case: the joint motion prescribed, the links' deformation integrated
    (flex_planner.spatial_nominal, the planar NominalInputSolver's scheme) on the arm
    embedded in 3D: the same tip path and joint torques as the planar solver, so the same
    radius and path deviation; the radius grows with the payload (0 -> 2 kg). Measured:
    tips 7e-16 m, torques 2.3e-9 N m apart; radius 18.93 -> 36.36 mm (path 1), 69.66 ->
    113.18 mm (path 2) in both."""
    from flex_planner.spatial_nominal import spatial_nominal_input
    planar = FlexArmModel(load_arm("seed002_two_link"))
    motion, t_f = section_h_motion(planar, path)
    radii = []
    for mass, ref in zip(MASSES, payload_sweep(planar, MASSES, path)):
        arm = dataclasses.replace(from_planar(planar.arm), payload=RigidBody(mass=mass))
        nom = spatial_nominal_input(SpatialArmModel(arm), motion)
        res = _result(planar, motion, t_f, nom.t, nom.tip[:, :2], nom.tau)
        assert np.max(np.abs(nom.tip[:, 2])) == 0.0
        assert np.max(np.abs(res.tip - ref.tip)) < 1e-9
        assert np.max(np.abs(nom.tau - ref.joint_torques)) < 1e-6 * np.max(np.abs(
            ref.joint_torques))
        assert res.radius == pytest.approx(ref.radius, rel=1e-6)
        radii.append(res.radius)
    assert radii[1] > 1.4 * radii[0]
