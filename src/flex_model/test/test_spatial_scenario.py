"""Spatial scenarios (issue 25): the PD law inside the integrator against the static spring
balance, energy without damping, a planar arm embedded in 3D against the planar
``simulate``, and the validation of the scenario file."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.config import ConfigError
from flex_model.inputs import JointPD, Pulse
from flex_model.scenario import Scenario, load_scenario, scenario_from_dict, scenario_names
from flex_model.spatial.analysis import static_equilibrium
from flex_model.spatial.description import from_planar
from flex_model.spatial.loader import spatial_arm_from_dict
from flex_model.spatial.scenario import pd_matrices, pd_static_equilibrium


def test_presets_load_and_are_spatial():
    """One loader: the spatial presets give spatial scenarios, the planar ones planar."""
    assert set(scenario_names(spatial=True)) >= {"seed000_3d_pd_step", "seed003_like_pd_step"}
    for name in scenario_names(spatial=True):
        sc = load_scenario(name)
        assert sc.spatial
        assert sc.duration > 0 and sc.step <= sc.sample_period
    assert not load_scenario("thesis_three_link_pd").spatial


def test_pd_end_state_is_the_static_spring_balance():
    """seed003_like_arm without gravity compensation: the PD (thesis Eq. 95, on the motor
    behind joint 1's elastic gear, on the joints 2, 3) carries the weight. After a
    set-point step the run settles on the PD equilibrium, and that equilibrium is the
    ``static`` analysis at its joint values with kp (s - theta_a) = holding torque."""
    sc = dataclasses.replace(load_scenario("seed003_like_pd_step"), duration=4.0,
                             pulses=(), gravity_hold=False, rho_inf=0.5)
    model = sc.model()
    res = sc.run(model=model, advise=False)
    sp = sc.setpoint_schedule[-1][1]
    K_pd, _ = pd_matrices(sc, model)
    q_eq = pd_static_equilibrium(model, K_pd, sc.pd.kp * sp, start=sp)
    assert np.max(np.abs(res.q[-1] - q_eq)) < 1e-9
    assert np.max(np.abs(res.v[-1])) < 1e-8
    # the weight moves joints 2 and 3 off their set-points: a balance that could fail
    sag = sp - q_eq[model.off]
    assert abs(sag[1]) > 1e-3 and abs(sag[2]) > 1e-3
    # the spring balance against the static analysis (joints held at the PD's values)
    st = static_equilibrium(model, q_eq[model.off])
    holding = (model.K @ st.q + model.gravity_force(st.q))[model.off]
    pd_torque = sc.pd.kp * (sp - q_eq[model.actuator_index])
    assert np.allclose(pd_torque, holding, rtol=1e-9, atol=1e-9 * np.max(np.abs(holding)))
    flex = np.setdiff1d(np.arange(model.nq_arm), model.off)
    assert np.max(np.abs(st.q[flex] - q_eq[flex])) < 1e-10
    # the static start stays at rest before the step (the PD inside the integrator is
    # the static one)
    before = res.t < 0.1
    assert np.max(np.abs(res.q[before] - res.q[0])) < 1e-12


def test_energy_without_damping_second_order():
    """No PD, no inputs, dampers off, rho_inf = 1 (trapezoidal): the energy error is the
    integrator's O(h^2) (measured: 9.5e-7 of the largest kinetic energy at 1 ms, 2.4e-7
    at 0.5 ms on the planar example 1 in 3D, moving in gravity)."""
    arm = from_planar(load_arm("thesis_example1"))
    errs = []
    for h in (1e-3, 5e-4):
        sc = Scenario(name="energy", arm=arm, duration=1.0, step=h, sample_period=0.01,
                      rho_inf=1.0, joint_values=np.array([-0.3, 0.5]),
                      joint_rates=np.array([0.5, -0.5]))
        model = sc.model()
        res = sc.run(model=model, advise=False)
        E = np.array([model.total_energy(q, v) for q, v in zip(res.q, res.v)])
        T = np.array([model.energy(q, v)["kinetic"] for q, v in zip(res.q, res.v)])
        errs.append(np.max(np.abs(E - E[0])) / np.max(T))
    assert errs[0] < 2e-6
    assert 3.5 < errs[0] / errs[1] < 4.5


def test_planar_arm_embedded_follows_the_planar_simulate():
    """thesis_example1 (vertical plane, gravity) with a joint PD, a set-point step and a
    torque pulse, fixed step 1 ms, rho_inf 0.9: the spatial run of the embedded arm equals
    the planar one (both generalized-alpha with restarts at the switches; the Newton
    tolerances, 1e-10, set the floor: measured 8.5e-12 rad, 1.1e-11 m)."""
    arm = load_arm("thesis_example1")
    sp0 = np.array([-0.3, 0.2])
    kp, kd = [200.0, 200.0], [20.0, 20.0]
    planar = scenario_from_dict({
        "arm": "thesis_example1", "duration": 1.0, "sample_period": 0.01,
        "initial": {"joint_angles_deg": np.degrees(sp0).tolist()},
        "control": {"pd": {"kp": kp, "kd": kd, "setpoints_deg": np.degrees(sp0).tolist()},
                    "setpoint_schedule": [{"time": 0.3,
                                           "setpoints_deg": (np.degrees(sp0) + 5).tolist()}]},
        "pulses": [{"joint": "joint1", "torque": 5.0, "start": 0.1, "end": 0.2}],
        "integrator": {"method": "fixed", "step": 1e-3, "rho_inf": 0.9}}).run(
            advise=False)  # both sides at one step: the step's own error is not compared
    sc = Scenario(name="embedded", arm=from_planar(arm), duration=1.0, step=1e-3,
                  sample_period=0.01, rho_inf=0.9, joint_values=sp0,
                  joint_rates=np.zeros(2),
                  pd=JointPD(np.array(kp), np.array(kd), sp0),
                  setpoint_schedule=((0.3, sp0 + np.radians(5), 0.0),),
                  pulses=(Pulse(0.1, 0.2, (5.0, 0.0)),))
    res = sc.run(advise=False)
    assert np.max(np.abs(res.joint_angles - planar.joint_angles)) < 1e-10
    assert np.max(np.abs(res.joint_rates - planar.joint_rates)) < 1e-8
    d = res.link_deflections()
    y = np.column_stack([d[lk.name]["y"] for lk in arm.links])
    assert np.max(np.abs(planar.tip_deflections)) > 0.1       # the run bends the links
    assert np.max(np.abs(y - planar.tip_deflections)) < 1e-10
    tip = res.tip_positions
    assert np.max(np.abs(tip[:, :2] - planar.tip_positions)) < 1e-9
    assert np.max(np.abs(tip[:, 2])) == 0.0
    assert np.max(np.abs(res.tau - planar.tau)) < 1e-6 * np.max(np.abs(planar.tau))


def test_setpoint_ramps_follow_the_planar_simulate():
    """The same embedded arm with a set-point step and then a ramp (0.4 s) in the schedule:
    ramps as the planar scenario's (kp (s - s0) + kd s' averaged over each sample period
    and held, a restart at every sample instant), the spatial run = the planar run."""
    arm = load_arm("thesis_example1")
    sp0 = np.array([-0.3, 0.2])
    kp, kd = [200.0, 200.0], [20.0, 20.0]
    sp1, sp2 = sp0 + np.radians(3), sp0 + np.radians([10.0, -6.0])
    planar = scenario_from_dict({
        "arm": "thesis_example1", "duration": 1.0, "sample_period": 0.01,
        "initial": {"joint_angles_deg": np.degrees(sp0).tolist()},
        "control": {"pd": {"kp": kp, "kd": kd, "setpoints_deg": np.degrees(sp0).tolist()},
                    "setpoint_schedule": [
                        {"time": 0.1, "setpoints_deg": np.degrees(sp1).tolist()},
                        {"time": 0.3, "setpoints_deg": np.degrees(sp2).tolist(),
                         "ramp": 0.4}]},
        "integrator": {"method": "fixed", "step": 1e-3, "rho_inf": 0.9}}).run(advise=False)
    sc = Scenario(name="embedded_ramp", arm=from_planar(arm), duration=1.0,
                  step=1e-3, sample_period=0.01, rho_inf=0.9, joint_values=sp0,
                  joint_rates=np.zeros(2),
                  pd=JointPD(np.array(kp), np.array(kd), sp0),
                  setpoint_schedule=((0.1, sp1, 0.0), (0.3, sp2, 0.4)))
    res = sc.run(advise=False)
    assert np.max(np.abs(res.joint_angles - planar.joint_angles)) < 1e-10
    assert np.max(np.abs(res.joint_angles[-1] - sp2)) < 0.05      # it follows the ramp
    # reported torques: the planar run gives the law at the sample instant, the spatial
    # one the input held over the next sample period (the ramp averaged over it)
    out = (res.t < 0.3) | (res.t > 0.71)
    assert np.max(np.abs(res.tau - planar.tau)[out]) < 1e-6 * np.max(np.abs(planar.tau))


def _base(**over):
    d = {"arm": "seed003_like_arm", "duration": 0.1, "step": 1e-3}
    d.update(over)
    return d


@pytest.mark.parametrize("data, field", [
    (_base(step=0.01, sample_period=0.005), "step"),
    (_base(duration=".inf"), "duration"),
    (_base(arm="no_such_arm"), "arm"),
    (_base(initial={"joint_values": [0.0]}), "initial.joint_values"),
    (_base(control={"pd": {"kp": [1, 1, -1], "kd": [0, 0, 0]}}), "control.pd.kp"),
    (_base(control={"setpoint_schedule": [{"time": 0.1, "setpoints": [0, 0, 0]}]}),
     "control.setpoint_schedule"),
    (_base(pulses=[{"joint": "joint9", "torque": 1.0, "start": 0.0, "end": 1.0}]),
     "pulses[0].joint"),
    (_base(pulses=[{"joint": 1, "force": 1.0, "start": 0.0, "end": 1.0}]),
     "pulses[0].force"),
    (_base(pulses=[{"joint": 1, "torque": 1.0, "start": 0.5, "end": 0.2}]),
     "pulses[0].end"),
    (_base(rho_inf=1.5), "rho_inf"),
    (_base(integrator={"method": "variable"}), "integrator.method"),
    (_base(integrator={"step": 1e-3}), "step"),      # top level or integrator, not both
    (_base(vars_per_link=4), "vars_per_link"),        # one grammar: planar-only fields
    (_base(control={"torque_table": {"t": [0], "torques": [[0, 0, 0]]}}), "control.torque_table"),
    (dict(_base(arm="thesis_three_link"), control={"pd45": {"kpp": [1] * 3}}),
     "control.pd45"),
    (dict(_base(arm="thesis_three_link"), control={"gravity_hold": True}), "control.gravity_hold"),
])
def test_bad_scenarios_name_the_field(data, field):
    with pytest.raises(ConfigError) as exc:
        scenario_from_dict(data, "bad.yaml")
    msg = str(exc.value)
    assert msg.startswith("bad.yaml: ") and f": {field}: got " in msg


def test_one_grammar_for_both_arm_kinds():
    """The integrator's keys at the top level or under ``integrator`` and the initial values
    as ``joint_values`` or ``joint_angles`` mean the same on a planar and a spatial arm."""
    for arm, n in (("thesis_three_link", 3), ("seed003_like_arm", 3)):
        top = scenario_from_dict({"arm": arm, "duration": 0.1, "method": "fixed",
                                  "step": 5e-4, "rho_inf": 0.5,
                                  "initial": {"joint_angles": [0.1] * n}})
        nested = scenario_from_dict({"arm": arm, "duration": 0.1, "integrator": {
            "method": "fixed", "step": 5e-4, "rho_inf": 0.5},
            "initial": {"joint_values_deg": [np.degrees(0.1)] * n}})
        for sc in (top, nested):
            assert (sc.method, sc.step, sc.rho_inf) == ("fixed", 5e-4, 0.5)
        np.testing.assert_allclose(top.joint_values, nested.joint_values, rtol=0, atol=1e-15)
        assert top.spatial == (arm == "seed003_like_arm")


def test_seed000_preset_starts_at_the_static_droop():
    """seed000_3d_pd_step: state static = the droop under gravity in the stiff (248 N m^2)
    plane, q L^4 / 8 EI + P L^3 / 3 EI = 11.33 um; it stays there (to 1e-12 m) until the
    set-point step at 0.1 s."""
    sc = load_scenario("seed000_3d_pd_step")
    res = dataclasses.replace(sc, duration=0.09).run(advise=False)
    L, EI, rhoA, P = 0.28, 248.0, 0.1289, 0.025607 * 9.81
    droop = rhoA * 9.81 * L ** 4 / (8 * EI) + P * L ** 3 / (3 * EI)
    w = res.link_deflections()["link1"]["z"]
    assert -w[0] == pytest.approx(droop, rel=1e-9)
    assert np.max(np.abs(res.q - res.q[0])) < 1e-12
    assert np.max(np.abs(res.tau)) == 0.0     # vertical joint axis: no holding torque


def test_a_payload_change_moves_the_pd_equilibrium_to_the_closed_form():
    """Pick and place: a rigid link (1 kg at 0.5 m) in the vertical plane held by a PD at
    0 rad; at 0.2 s a 0.5 kg payload is picked at its end frame. Before the change the
    link rests where kp (0 - q) = M g L cos q, after it (damped, 4 s) where kp (0 - q) =
    (M + m) g L cos q (measured 2.7e-14 and 4.8e-13 rad); a file's bad payload field is
    named."""
    from scipy.optimize import brentq
    g, L, M, m, kp = 9.81, 0.5, 1.0, 0.5, 200.0
    arm = spatial_arm_from_dict({"name": "pick", "gravity": [0.0, -g, 0.0], "links": [
        {"joint": {"name": "joint1", "a": L}, "end_body": {"mass": M}}]}, "pick.yaml")
    sc = Scenario(name="pick", arm=arm, duration=4.0, step=1e-3, sample_period=0.01,
                  rho_inf=0.9, joint_values=np.zeros(1), joint_rates=np.zeros(1),
                  start_static=True,
                  pd=JointPD(np.array([kp]), np.array([20.0]), np.zeros(1)),
                  payload_changes=((0.2, m, np.zeros((3, 3))),))
    res = sc.run(advise=False)
    q_before = brentq(lambda q: -kp * q - M * g * L * np.cos(q), -1.0, 0.0)
    q_after = brentq(lambda q: -kp * q - (M + m) * g * L * np.cos(q), -1.0, 0.0)
    assert abs(res.joint_angles[15, 0] - q_before) < 1e-9          # t = 0.15 s
    assert abs(res.joint_angles[-1, 0] - q_after) < 1e-6
    assert np.min(res.joint_angles[:, 0]) < q_after                  # it swung past
    with pytest.raises(ConfigError) as err:
        scenario_from_dict({"name": "p", "arm": "seed003_like_arm", "duration": 1.0,
                            "payload_changes": [{"time": 0.1, "mass": -1.0}]}, "p.yaml")
    assert "p.yaml" in str(err.value) and "payload_changes[0].mass" in str(err.value)


def test_a_tip_load_moves_the_pd_equilibrium_and_the_loop_equals_the_reference():
    """A rigid link (vertical axis, no gravity) held by a PD at 0 rad; from 0.1 s a force
    of 2 N along y at its tip: it settles where kp q = F L cos q; over the first steps
    after the load the compiled loop equals simulate_fixed with the force J^T F as a
    callback (1e-12)."""
    from scipy.optimize import brentq

    from flex_model.spatial import SpatialArmModel
    from flex_model.spatial.integrate import (joint_input_matrix, simulate_fixed,
                                              simulate_fixed_compiled)
    L, kp, F = 0.5, 200.0, np.array([0.0, 2.0, 0.0])
    arm = spatial_arm_from_dict({"name": "push", "gravity": [0.0, 0.0, 0.0], "links": [
        {"joint": {"name": "joint1", "a": L}, "end_body": {"mass": 1.0}}]}, "push.yaml")
    sc = Scenario(name="push", arm=arm, duration=3.0, step=1e-3, sample_period=0.01,
                  rho_inf=0.9, joint_values=np.zeros(1), joint_rates=np.zeros(1),
                  pd=JointPD(np.array([kp]), np.array([20.0]), np.zeros(1)),
                  pulses=(Pulse(0.1, np.inf, (), tuple(F)),))
    res = sc.run(advise=False)
    q_eq = brentq(lambda q: kp * q - F[1] * L * np.cos(q), 0.0, 1.0)
    assert abs(res.joint_angles[5, 0]) < 1e-15                    # before the load
    assert abs(res.joint_angles[-1, 0] - q_eq) < 1e-9
    model = SpatialArmModel(arm)
    model.K = model.K + kp * np.eye(1)
    D = 20.0 * np.eye(1)
    q0, v0 = np.array([0.01]), np.array([0.3])
    comp = simulate_fixed_compiled(model, q0, v0, 1e-3, 20, tip_force=F, damping=D)
    ref = simulate_fixed(model, q0, v0, 1e-3, 20, damping=D,
                         force=lambda t, q, v: model.tip_jacobian(q)[:3].T @ F)
    np.testing.assert_allclose(comp.q, ref.q, rtol=0, atol=1e-12)
    assert joint_input_matrix(model).shape == (1, 1)
