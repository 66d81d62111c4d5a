"""One set-point convention in both scenario formats (issue 43): every joint-value key is SI
(rad, m) and may be given in degrees as ``<key>_deg`` when every joint is revolute; giving both
is refused with one line naming the file and field."""
import math

import numpy as np
import pytest

from flex_model.config import ConfigError
from flex_model.scenario import scenario_from_dict

PLANAR = {"name": "p", "arm": "seed002_two_link", "gravity": False, "duration": 0.01,
          "sample_period": 0.01}
SPATIAL = {"name": "s", "arm": "seed000_real_arm_3d", "duration": 0.01, "step": 1e-3,
           "sample_period": 0.005}
PRISMATIC = {"name": "prism", "gravity": [0.0, 0.0, -9.81], "links": [
    {"joint": {"type": "revolute", "alpha": -math.pi / 2, "d": 0.3},
     "end_body": {"mass": 1.0, "inertia": [0.01, 0.02, 0.01]}},
    {"joint": {"type": "prismatic", "alpha": math.pi / 2, "d": 0.2},
     "end_body": {"mass": 0.5, "inertia": [0.002, 0.002, 0.001]}}]}


def planar(initial, pd, step):
    return scenario_from_dict(dict(PLANAR, initial=initial, control={
        "pd": dict({"kp": [400.0, 150.0], "kd": [120.0, 45.0]}, **pd),
        "setpoint_schedule": [dict({"time": 0.005}, **step)]}))


def spatial(arm, initial, pd, step, n=1):
    return scenario_from_dict(dict(SPATIAL, arm=arm, initial=initial, control={
        "pd": dict({"kp": [0.2] * n, "kd": [0.03] * n}, **pd),
        "setpoint_schedule": [dict({"time": 0.005}, **step)]}))


def test_planar_setpoints_in_rad_equal_those_in_degrees():
    deg = planar({"joint_angles_deg": [5.0, -5.0]}, {"setpoints_deg": [10.0, -10.0]},
                 {"setpoints_deg": [20.0, 0.0]})
    rad = planar({"joint_angles": [math.radians(5.0), math.radians(-5.0)]},
                 {"setpoints": [math.radians(10.0), math.radians(-10.0)]},
                 {"setpoints": [math.radians(20.0), 0.0]})
    np.testing.assert_allclose(rad.joint_values, deg.joint_values, rtol=0, atol=1e-15)
    np.testing.assert_allclose(rad.pd.setpoints, deg.pd.setpoints, rtol=0, atol=1e-15)
    np.testing.assert_allclose(rad.setpoint_schedule[0][1], deg.setpoint_schedule[0][1],
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(deg.pd.setpoints, np.radians([10.0, -10.0]), atol=1e-15)


def test_spatial_setpoints_in_degrees_equal_those_in_rad():
    rad = spatial("seed000_real_arm_3d", {"joint_values": [0.1]}, {"setpoints": [0.2]},
                  {"setpoints": [0.3]})
    deg = spatial("seed000_real_arm_3d", {"joint_values_deg": [math.degrees(0.1)]},
                  {"setpoints_deg": [math.degrees(0.2)]},
                  {"setpoints_deg": [math.degrees(0.3)]})
    np.testing.assert_allclose(deg.pd.setpoints, rad.pd.setpoints, rtol=0, atol=1e-15)
    np.testing.assert_allclose(deg.setpoint_schedule[0][1], [0.3], rtol=0, atol=1e-15)


def test_both_units_at_once_are_refused_with_the_field():
    with pytest.raises(ConfigError, match=r"control\.pd\.setpoints_deg.*not both"):
        planar({}, {"setpoints_deg": [10.0, 0.0], "setpoints": [0.1, 0.0]},
               {"setpoints": [0.0, 0.0]})
    with pytest.raises(ConfigError, match=r"setpoint_schedule\[0\]\.setpoints_deg"):
        spatial("seed000_real_arm_3d", {}, {"setpoints": [0.0]},
                {"setpoints": [0.1], "setpoints_deg": [5.0]})


def test_degrees_are_refused_on_an_arm_with_a_prismatic_joint():
    with pytest.raises(ConfigError, match="prismatic joint has no degrees"):
        spatial(PRISMATIC, {}, {"setpoints_deg": [10.0, 5.0]}, {"setpoints": [0.0, 0.1]},
                n=2)


def test_one_schedule_rule_in_both_formats():
    """Strictly increasing times, none inside the previous ramp (scenario.setpoint_schedule)."""
    for steps in ([{"time": 0.005, "setpoints": [0.1, 0.0]},
                   {"time": 0.005, "setpoints": [0.2, 0.0]}],
                  [{"time": 0.002, "setpoints": [0.1, 0.0], "ramp": 0.004},
                   {"time": 0.005, "setpoints": [0.2, 0.0]}]):
        with pytest.raises(ConfigError, match=r"setpoint_schedule\[1\]\.time"):
            scenario_from_dict(dict(PLANAR, control={"pd": {"kp": [1.0, 1.0], "kd": [1.0, 1.0]},
                                                     "setpoint_schedule": steps}))
        with pytest.raises(ConfigError, match=r"setpoint_schedule\[1\]\.time"):
            scenario_from_dict(dict(SPATIAL, control={
                "pd": {"kp": [0.2], "kd": [0.03]},
                "setpoint_schedule": [dict(s, setpoints=s["setpoints"][:1]) for s in steps]}))
    sc = scenario_from_dict(dict(PLANAR, control={"pd": {"kp": [1.0, 1.0], "kd": [1.0, 1.0]},
                                                  "setpoint_schedule": [
        {"time": 0.002, "setpoints": [0.1, 0.0], "ramp": 0.003},
        {"time": 0.005, "setpoints": [0.2, 0.0]}]}))
    assert [e[0] for e in sc.setpoint_schedule] == [0.002, 0.005]
