"""Seed 000's PD-like cascade, Eq. (45), on spatial arms (issue 25: the PD laws in 3D):
the Table 3 step of VALIDATION.md section G with the arm about a vertical axis, the rotor
as a ``gear`` effect, against the planar step response (flex_control.step_response)."""
import dataclasses

import numpy as np
import pytest

from flex_control.step_response import (KPP, KPV, rise_and_overshoot, step_response,
                                        with_link_damping)
from flex_model.arm import load_arm
from flex_model.config import ConfigError
from flex_model.effects.gear import Gear
from flex_model.spatial import SpatialArmModel, from_planar
from flex_model.inputs import JointPD
from flex_model.scenario import Scenario, scenario_from_dict
from flex_model.spatial.scenario import eq45_joint_gains


def test_table3_step_in_3d_equals_the_planar_step_response():
    """Seed 000 Table 3 (L 1 m, EI 2 N m^2, payload 0.2 kg, xi_1 0.1), gear ratio 50 and
    rotor 0.002 kg m^2 as a ``gear`` effect (the planar run puts n^2 I_r into J-), Eq. (45)
    with K_pp 70, K_pv 50, step 10 -> 30 deg: the spatial scenario's joint angle equals the
    planar one over 2 s (1e-9 rad; measured 3.8e-15) and so do the rise time and
    overshoot; the joint gains are n^2 K_pv K_pp = 8.75e6 N m/rad, n^2 K_pv = 1.25e5
    N m s/rad."""
    ref = step_response("seed000_table3")
    planar = with_link_damping(load_arm("seed000_table3"), ref.damping_ratio)
    arm = from_planar(planar)
    arm = dataclasses.replace(arm, effects=arm.effects + (
        Gear(target="joint1", values=(50.0, 0.002)),))
    kp, kd = eq45_joint_gains(arm, [KPP], [KPV])
    assert kp[0] == pytest.approx(8.75e6) and kd[0] == pytest.approx(1.25e5)
    th0, th1 = np.radians(10.0), np.radians(30.0)
    dt = float(ref.t[1] - ref.t[0])
    # the first 2 s (rise, overshoot and the first swings); with this stiff loop (n^2 K_pv
    # K_pp on a 5 kg m^2 rotor) the accelerations reach their round-off floor once the
    # joint settles: the loop's stagnation test accepts it (before: no convergence at
    # 0.506 s with the default tolerance 1e-10)
    sc = Scenario(name="table3_3d", arm=arm, duration=2.0, step=1e-4,
                  sample_period=dt, rho_inf=0.9, joint_values=np.array([th0]),
                  joint_rates=np.zeros(1),
                  pd=JointPD(kp, kd, np.array([th1])))
    res = sc.run(model=SpatialArmModel(arm), advise=False)
    n = min(len(res.t), len(ref.t))
    assert np.max(np.abs(res.joint_angles[:n, 0] - ref.joint_angle[:n])) < 1e-9
    rise, over = rise_and_overshoot(res.t, res.joint_angles[:, 0], th0, th1)
    assert rise == pytest.approx(ref.joint_rise_time, rel=1e-6)
    assert over == pytest.approx(ref.joint_overshoot_pct, abs=1e-6)
    d = res.link_deflections()["link1"]["y"]
    assert np.max(np.abs(d[:n] - ref.tip_deflection[:n])) < 1e-9
    assert np.max(np.abs(d)) > 0.05                 # the link does swing (m)


def test_pd45_in_a_scenario_file_is_the_joint_pd():
    base = {"name": "s", "arm": {"name": "a", "convention": "standard_dh", "links": [
        {"joint": {"name": "joint1", "a": 0.5}, "end_body": {"mass": 1.0}}],
        "effects": [{"type": "gear", "joint": "joint1", "ratio": 10.0,
                     "rotor_inertia": 1e-4}]}, "duration": 0.1}
    sc = scenario_from_dict(dict(base, control={"pd45": {"kpp": [20.0], "kpv": [0.5],
                                                         "setpoints": [0.2]}}), "s.yaml")
    assert sc.pd.kp[0] == pytest.approx(100 * 0.5 * 20) and sc.pd.kd[0] == pytest.approx(50)
    with pytest.raises(ConfigError) as err:
        scenario_from_dict(dict(base, control={"pd45": {"kpp": [1.0], "kpv": [1.0]},
                                               "pd": {"kp": [1.0], "kd": [1.0]}}), "s.yaml")
    assert "s.yaml" in str(err.value) and "pd45" in str(err.value)
    with pytest.raises(ConfigError) as err:
        scenario_from_dict(dict(base, control={"pd45": {"kpp": [-1.0], "kpv": [1.0]}}),
                           "s.yaml")
    assert "control.pd45.kpp" in str(err.value)
