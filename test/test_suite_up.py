"""flex-twin up: model and controller nodes from the suite's parameter file, one process,
lockstep; the loop settles at the static equilibrium of the arm held by the PD of Eq. (95)
(Kp = h a^2 per joint, seen at the joints through the sampled loop)."""
from pathlib import Path

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_model.ros_suite import node_parameters, run_in_one_process
from flex_model.statics import static_equilibrium

PARAMS = Path(__file__).resolve().parents[1] / "ros2_ws" / "params" / "suite.yaml"


def test_model_and_controller_hold_the_static_pd_equilibrium():
    params = node_parameters(PARAMS)
    params.pop("flex_planner")
    nodes = run_in_one_process(params, duration=2.0)
    model = nodes["flex_model"]
    theta = model.model.joint_angles(model.stepper.q)
    arm = FlexArmModel(load_arm(params["flex_model"]["arm"]))
    h, a = np.array(params["flex_controller"]["h"]), np.array(params["flex_controller"]["a"])
    set_deg = params["flex_model"]["initial_joint_angles_deg"]
    eq = static_equilibrium(arm, np.radians(set_deg), joints="pd", kp=h * a * a)
    assert model.stepper.t == pytest.approx(2.0, abs=2e-3)
    np.testing.assert_allclose(np.degrees(theta), np.degrees(eq.joint_angles), atol=0.02)
    assert np.degrees(np.abs(eq.joint_angles - np.radians(set_deg))).max() > 0.1  # it sags


def test_parameter_file_errors_name_the_node(tmp_path):
    bad = tmp_path / "p.yaml"
    bad.write_text("flex_modle:\n  ros__parameters: {arm: x}\n")
    with pytest.raises(ConfigError, match=r"p.yaml: flex_modle: got 'flex_modle'; expected "
                                          r"one of flex_model, flex_controller, flex_planner"):
        node_parameters(bad)
