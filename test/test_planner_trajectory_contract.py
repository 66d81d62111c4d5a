"""The planner -> controller contract: ``flex_planner.plan_tip_path`` returns a
``flex_model.trajectory.JointTrajectoryData`` as agreed (the plan reaches the controller as
data; neither package imports the other)."""
import inspect

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.trajectory import JointTrajectoryData
import flex_planner
from flex_planner import (SECTION_F_TIMES, SECTION_F_WAYPOINTS, UnreachableError,
                          invert_waypoints, plan_tip_path)


def test_agreed_signature():
    sig = inspect.signature(plan_tip_path)
    assert list(sig.parameters) == ["model", "waypoints", "times", "sample_period", "elbow",
                                    "orientations", "tip_load"]
    defaults = {k: p.default for k, p in sig.parameters.items()
                if p.default is not inspect.Parameter.empty}
    assert defaults == {"sample_period": 1e-3, "elbow": "up", "orientations": None,
                        "tip_load": None}
    assert all(sig.parameters[k].kind is inspect.Parameter.KEYWORD_ONLY for k in defaults)


def test_section_F_constants():
    np.testing.assert_array_equal(flex_planner.SECTION_F_WAYPOINTS,
                                  [[-1, -1], [-2, -1], [-2, -2], [-1, -2]])
    np.testing.assert_array_equal(flex_planner.SECTION_F_TIMES, [0, 5, 10, 15])
    with pytest.raises(ValueError):
        SECTION_F_WAYPOINTS[0, 0] = 3.0               # read-only


def test_trajectory_data_holds_the_plan():
    model = FlexArmModel(load_arm("thesis_example1"))
    traj = plan_tip_path(model, SECTION_F_WAYPOINTS, SECTION_F_TIMES, sample_period=0.01)
    assert isinstance(traj, JointTrajectoryData)
    assert traj.joint_names == ["joint1", "joint2"] and traj.duration == 15.0
    n = len(traj.t)
    assert traj.positions.shape == traj.efforts.shape == (n, 2)
    assert traj.q_nominal.shape == (n, model.nq) and traj.tip.shape == (n, 2)
    poses = invert_waypoints(model, SECTION_F_WAYPOINTS)
    for tk, pose in zip(SECTION_F_TIMES, poses):
        position, velocity, _, effort = traj.sample(tk)
        np.testing.assert_allclose(position, pose.joint_angles, atol=1e-12)
        assert np.all(np.isfinite(effort)) and np.max(np.abs(effort)) > 0.1   # N m
    np.testing.assert_allclose(traj.sample(0.0)[1], 0.0, atol=1e-12)
    np.testing.assert_allclose(traj.sample(15.0)[1], 0.0, atol=1e-12)


def test_unreachable_error_carries_index_and_reason():
    model = FlexArmModel(load_arm("thesis_example1"))
    with pytest.raises(UnreachableError) as info:
        plan_tip_path(model, [[-1.0, -1.0], [-2.0, -1.0], [9.0, 9.0]], [0.0, 1.0, 2.0])
    err = info.value
    assert isinstance(err, ValueError)
    assert err.index == 2 and "outside the reach of the sagging arm" in err.reason
