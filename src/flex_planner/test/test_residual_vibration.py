"""Residual vibration (seed 002 Eqs. 21-22) on the arm of VALIDATION.md section H.

Trends of the paper: the radius of the residual vibration grows with the payload (with
local maxima: the paper fits a tangent line over them, Figs. 6, 10), and joint
flexibility increases the deviation and the radius.
"""
import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_planner.residual_vibration import (SECTION_H_JOINT_STIFFNESS, payload_sweep,
                                             residual_vibration, section_h_motion)

PAYLOADS = (0.0, 0.5, 1.0, 1.5, 2.0)   # kg, the paper's range


@pytest.fixture(scope="module")
def arm():
    model = FlexArmModel(load_arm("seed002_two_link"))
    assert [lk.n_vars for lk in model.arm.links] == [4, 4]      # two elements per link
    return model


@pytest.fixture(scope="module")
def rigid_joints(arm):
    return {path: payload_sweep(arm, PAYLOADS, path) for path in (1, 2)}


@pytest.fixture(scope="module")
def flexible_joints(arm):
    return {path: payload_sweep(arm, (0.0, 1.0, 2.0), path,
                                joint_stiffness=SECTION_H_JOINT_STIFFNESS) for path in (1, 2)}


@pytest.mark.parametrize("path", [1, 2])
def test_radius_grows_with_payload(rigid_joints, flexible_joints, path):
    for runs, masses in ((rigid_joints[path], PAYLOADS), (flexible_joints[path], (0, 1, 2))):
        radius = np.array([r.radius for r in runs])
        assert radius[-1] > 1.4 * radius[0]                  # 2 kg against none
        half = len(radius) // 2
        assert radius[half:].max() > radius[:half + 1].max()   # the upper envelope rises
        assert np.polyfit(masses, radius, 1)[0] > 0
    # the centre of the vibration sags below the goal under gravity (seed 002 Fig. 5)
    centre = [r.centre_offset for r in rigid_joints[path]]
    assert centre[-1] > centre[0] > 1e-3


@pytest.mark.parametrize("path", [1, 2])
def test_joint_flexibility_increases_deviation_and_radius(rigid_joints, flexible_joints,
                                                          path):
    rigid = [rigid_joints[path][i] for i in (0, 2, 4)]          # 0, 1, 2 kg
    flexible = flexible_joints[path]
    for name in ("radius", "path_deviation"):
        mean_rigid = np.mean([getattr(r, name) for r in rigid])
        mean_flexible = np.mean([getattr(r, name) for r in flexible])
        assert mean_flexible > 1.05 * mean_rigid, name
    if path == 1:   # along the joint-space path at every payload
        for r, f in zip(rigid, flexible):
            assert f.path_deviation > 1.1 * r.path_deviation


def test_the_goal_and_timing_of_the_paths(arm):
    motion, t_f = section_h_motion(arm, 2)
    assert round(t_f, 3) == 1.452                                    # seed 002 Eq. 30
    run = residual_vibration(arm, motion, t_f)
    np.testing.assert_allclose(run.desired[-1], [0.75, 1.5], atol=1e-12)
    assert run.t[-1] == pytest.approx(t_f + 1.0)                     # 1 s observed
    motion, t_f = section_h_motion(arm, 1)
    run = residual_vibration(arm, motion, t_f)
    np.testing.assert_allclose(run.desired[-1], [0.0, -np.sqrt(2.0)], atol=1e-12)
    # Eq. 22 after t_f: the distance to the goal point
    after = run.t > t_f
    np.testing.assert_allclose(run.deviation[after],
                               np.linalg.norm(run.tip[after] - run.desired[-1], axis=1))


def test_stiff_joint_springs_approach_rigid_joints(arm):
    """Two independent computations: the prescribed-motion solver (rigid joints) and
    flex_model's simulator with a stiff joint spring driven by the planned motor angle."""
    motion, t_f = section_h_motion(arm, 1, 5e-4)
    rigid = residual_vibration(arm, motion, t_f, sample_period=5e-4)
    stiff = residual_vibration(arm, motion, t_f, joint_stiffness=1e5, sample_period=5e-4)
    soft = residual_vibration(arm, motion, t_f, joint_stiffness=1e4, sample_period=5e-4)
    gap_stiff = np.max(np.linalg.norm(stiff.tip - rigid.tip[:len(stiff.t)], axis=1))
    gap_soft = np.max(np.linalg.norm(soft.tip - rigid.tip[:len(soft.t)], axis=1))
    assert gap_stiff < 0.4 * gap_soft
    assert abs(stiff.radius - rigid.radius) < 0.2 * rigid.radius
