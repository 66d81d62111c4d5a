"""Users' asks of issue 24: set-point schedules in scenario files, ``end: .inf``, a clear
message for an endless duration, ``--step`` / ``--rho-inf`` on ``flex-twin simulate`` with
the load/compile time apart, and the step advice (the highest mode a joint torque excites,
the step it needs; the explicit variable-step mode on a stiff arm)."""
import json

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from flex_model.scenario import scenario_from_dict
from flex_model.statics import static_equilibrium
from flex_model.step_advice import step_advice

KP, KD = [400.0, 300.0], [60.0, 40.0]


def _scenario(control, duration=0.4, pulses=(), integrator=None):
    return scenario_from_dict({
        "arm": "thesis_example1_motors", "vars_per_link": 2, "duration": duration,
        "sample_period": 0.01, "initial": {"joint_angles_deg": [0.0, 0.0]},
        "control": control, "pulses": list(pulses),
        "integrator": integrator or {"method": "fixed", "step": 1e-3}})


def test_a_setpoint_step_at_zero_is_the_pd_with_the_new_setpoint():
    """PD(s0) + kp (s1 - s0) = PD(s1): a schedule's step at t = 0 gives the run of the PD
    that holds s1 from the start, to rounding."""
    pd0 = {"kp": KP, "kd": KD, "setpoints_deg": [0.0, 0.0]}
    stepped = _scenario({"pd": pd0, "setpoint_schedule": [
        {"time": 0.0, "setpoints_deg": [20.0, -10.0]}]}).run()
    direct = _scenario({"pd": dict(pd0, setpoints_deg=[20.0, -10.0])}).run()
    np.testing.assert_allclose(stepped.q, direct.q, rtol=0, atol=1e-10)
    assert np.degrees(stepped.joint_angles[-1, 0]) > 5.0  # it moved towards 20 deg


def test_a_ramp_settles_at_the_pd_equilibrium_of_its_final_setpoints():
    sp1 = np.array([25.0, -15.0])
    sc = _scenario({"pd": {"kp": KP, "kd": KD, "setpoints_deg": [0.0, 0.0]},
                    "setpoint_schedule": [{"time": 0.1, "setpoints_deg": sp1.tolist(),
                                           "ramp": 0.5}]}, duration=6.0)
    # the ramp's torque, averaged over each hold: its integral is kp delta (t_end - t0 - r/2)
    _, policy = sc.setpoint_inputs()
    T = sc.sample_period
    total = sum(policy(k * T, None) for k in range(int(round(2.0 / T)))) * T
    kp, kd = np.array(KP), np.array(KD)
    delta = np.radians(sp1)
    np.testing.assert_allclose(total, kp * delta * (2.0 - 0.1 - 0.25) + kd * delta,
                               rtol=1e-12)
    res = sc.run()
    model = sc.model()
    eq = static_equilibrium(model, np.radians(sp1), joints="pd", kp=kp)
    assert np.degrees(np.abs(eq.joint_angles - np.radians(sp1))).max() > 0.5  # it sags
    np.testing.assert_allclose(res.joint_angles[-1], eq.joint_angles, atol=np.radians(0.05))


def test_schedule_and_endless_times_are_validated():
    pd = {"kp": KP, "kd": KD}
    with pytest.raises(ConfigError, match=r"setpoint_schedule\[1\].time: got 0.2; expected "
                                          r"a time >= 0.3 s"):
        _scenario({"pd": pd, "setpoint_schedule": [
            {"time": 0.1, "setpoints_deg": [1, 2], "ramp": 0.2},
            {"time": 0.2, "setpoints_deg": [1, 2]}]})
    with pytest.raises(ConfigError, match="control.pd as well"):
        _scenario({"setpoint_schedule": [{"time": 0.1, "setpoints_deg": [1, 2]}]})
    with pytest.raises(ConfigError, match=r"duration: got inf; expected a finite time > 0 s "
                                          r"\(a simulation ends; .*flex-twin up\)"):
        scenario_from_dict({"arm": "thesis_example1_motors", "duration": float("inf")})
    # end: .inf = to the end of the run: the same as a pulse past the end
    pulse = {"joint": "joint1", "torque": 5.0, "start": 0.1}
    forever = _scenario({"pd": pd}, pulses=[dict(pulse, end=".inf")]).run()
    past = _scenario({"pd": pd}, pulses=[dict(pulse, end=99.0)]).run()
    np.testing.assert_array_equal(forever.q, past.q)


def test_step_advice_names_the_excited_mode_and_the_step_it_needs():
    hubless = FlexArmModel(load_arm("thesis_example1", 8))
    kp = np.array([625.0, 625.0])
    adv = step_advice(hubless, np.zeros(2), method="fixed", step=1e-3, kp=kp)
    omega = natural_modes(hubless, np.zeros(2), joints="pd", kp=kp).omega
    assert np.min(np.abs(omega / (2 * np.pi) - adv.highest_excited_mode_hz)) < 1e-9
    assert adv.step_needed_s == pytest.approx(0.25 / adv.highest_excited_mode_hz)
    assert adv.highest_excited_mode_hz > 1000.0  # the root of a hub-less beam
    assert f"mode at {adv.highest_excited_mode_hz:.4g} Hz" in adv.warning
    assert f"step of {adv.step_needed_s:.2g} s or less" in adv.warning
    assert step_advice(hubless, np.zeros(2), method="fixed", step=adv.step_needed_s,
                       kp=kp).warning is None
    # the geared motors' rotors at the joints: the torque excites only the low modes
    motors = FlexArmModel(load_arm("thesis_example1_motors", 8))
    adv_m = step_advice(motors, np.zeros(2), method="fixed", step=1e-3, kp=kp)
    assert adv_m.warning is None and adv_m.highest_excited_mode_hz < 50.0
    # explicit variable step: bounded by the highest mode, whatever rtol
    stiff = FlexArmModel(load_arm("thesis_example1", 32))
    adv_v = step_advice(stiff, np.zeros(2), method="variable", kp=kp)
    assert adv_v.variable_steps_per_s == pytest.approx(
        2 * np.pi * adv_v.highest_mode_hz / 3.3)
    assert adv_v.variable_steps_per_s > 1e4 and "the fixed mode" in adv_v.warning


def test_simulate_cli_step_rho_inf_and_load_time_apart(tmp_path, capsys):
    from flex_twin.cli import main
    sc = tmp_path / "s.yaml"
    sc.write_text("arm: thesis_example1_motors\nvars_per_link: 2\nduration: 0.2\n"
                  "sample_period: 0.01\ncontrol:\n  pd: {kp: [400, 300], kd: [60, 40]}\n")
    assert main(["simulate", str(sc), "--step", "5e-4", "--rho-inf", "0.5", "--json",
                 "--no-plot", "--out", str(tmp_path)]) == 0
    s = json.loads(capsys.readouterr().out)
    assert (s["method"], s["step_s"], s["rho_inf"], s["steps"]) == ("fixed", 5e-4, 0.5, 400)
    assert s["load_compile_cpu_s"] >= 0 and s["cpu_s"] >= 0
    # 2 variables per link are 12.5 % off (8 variables at 1/16 ms): the advice says so
    assert "2 variables per link" in s["warning"] and \
        s["estimated_tip_error"]["variables"] > 0.1
    assert main(["simulate", str(sc), "--step", "0.02", "--no-plot",
                 "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0
    assert "--step: got 0.02; expected a step > 0 s and at most the sample period" in err
