"""Joint limits honoured on spatial arms (issue 25): the position limits as end stops
(description.JointStops, ``joint_stops`` in a DH file or a URDF side file) and the in-loop
PD's torque clipped to the effort limits (integrate.simulate_fixed_compiled ``pd_clip``).
Closed forms of a link bouncing off a stop and resting on it under gravity, energy with
the stop's potential, the compiled loop against the Python reference, a saturated PD
against DOP853 with the saturation written by hand, and the validation of the files."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from flex_model.config import ConfigError, read_yaml
from flex_model.inputs import JointPD
from flex_model.scenario import Scenario
from flex_model.spatial.description import SPATIAL_PRESET_DIR, JointStops
from flex_model.spatial.loader import load_spatial_arm, spatial_arm_from_dict
from flex_model.spatial.dynamics import SpatialArmModel
from flex_model.spatial.integrate import (joint_input_matrix, simulate_fixed,
                                          simulate_fixed_compiled, simulate_variable)

L, M_END = 0.5, 1.0
J = M_END * L * L          # inertia about the joint of the rigid link's end mass


def _arm(k=1.0e3, c=0.0, *, lower=-0.2, upper=0.2, gravity=(0.0, 0.0, 0.0),
         flexible=False, effort=None, stops=True, transition=1e-3) -> dict:
    """One revolute link about z (a = L, end mass 1 kg) with limits [lower, upper]."""
    joint = {"name": "joint1", "a": L, "lower": lower, "upper": upper}
    if effort is not None:
        joint["effort"] = effort
    link = {"name": "link1", "joint": joint, "end_body": {"mass": M_END}}
    if flexible:      # with a hub: a torque step on a hub-less strip is badly conditioned
        link["flexible"] = {"section": {"EI_y": 20.0, "EI_z": 20.0, "GJ": 15.0, "rhoA": 0.2,
                                        "rhoJ": 1e-5}, "variables": 4}
        link["root_body"] = {"mass": 0.5, "inertia": [0.01, 0.01, 0.05]}
    out = {"name": "stop_link", "gravity": list(gravity), "links": [link]}
    if stops:
        out["joint_stops"] = {"stiffness": k, "damping": c, "transition": transition}
    return out


def _model(**kw) -> SpatialArmModel:
    return SpatialArmModel(spatial_arm_from_dict(_arm(**kw), "stop_link.yaml"))


def test_elastic_bounce_off_the_upper_stop_is_the_closed_form():
    """Rigid link at w0 = 1 rad/s into the upper stop (k = 1e3 N m/rad, no damping): it
    reaches 0.2 rad at t = 0.2 s, stays in contact half a period pi sqrt(J / k) and leaves
    at -w0; the largest penetration is w0 sqrt(J / k). DOP853 (a kink in the force at the
    limit: error control handles it), then the compiled loop at 0.1 ms with rho_inf 1."""
    model = _model(transition=1e-9)     # a sharp stop: the closed form
    w = np.sqrt(1.0e3 / J)
    t_out = 0.2 + np.pi / w + 0.05
    q0, v0 = np.zeros(model.nq), np.zeros(model.nq)
    v0[0] = 1.0
    ts = np.linspace(0.0, t_out, 2001)
    run = simulate_variable(model, q0, v0, ts, rtol=1e-12, atol=1e-14)
    assert abs(run.q[-1, 0] - (0.2 - 0.05)) < 1e-7
    assert abs(run.v[-1, 0] + 1.0) < 1e-7
    assert abs(np.max(run.q[:, 0]) - (0.2 + 1.0 / w)) < 1e-6
    E = np.array([model.total_energy(q, v) for q, v in zip(run.q, run.v)])
    assert np.max(np.abs(E - 0.5 * J)) < 1e-9 * 0.5 * J
    stop_e = np.array([model.energy(q, v)["stops"] for q, v in zip(run.q, run.v)])
    assert np.max(stop_e) > 0.99 * 0.5 * J        # all the energy in the stop at the peak
    h = 1e-4
    n = int(round(t_out / h))
    comp = simulate_fixed_compiled(model, q0, v0, h, n, rho_inf=1.0)
    assert abs(comp.q[-1, 0] - (0.2 - 0.05)) < 2e-4
    assert abs(comp.v[-1, 0] + 1.0) < 5e-3


def test_link_rests_on_the_lower_stop_under_gravity():
    """Gravity in the plane of motion (-y): the link falls onto the lower stop at -0.3 rad
    and, damped by the stop (c = 5 N m s/rad), rests where k (d - s / 2) = m g L cos q
    (d = lower - q beyond the 1 mrad transition s)."""
    g = 9.81
    model = _model(k=1.0e3, c=5.0, lower=-0.3, upper=0.3, gravity=(0.0, -g, 0.0))
    q0, v0 = np.zeros(model.nq), np.zeros(model.nq)
    run = simulate_fixed_compiled(model, q0, v0, 1e-3, 6000)
    q = run.q[-1, 0]
    assert abs(run.v[-1, 0]) < 1e-9
    assert abs(1.0e3 * (-0.3 - q - 0.5e-3) - M_END * g * L * np.cos(q)) < 1e-9
    assert 5.0e-3 < -0.3 - q < 5.5e-3


def test_compiled_loop_equals_the_python_reference_through_both_stops():
    """Flexible link (with a hub) and damped stops, torques driving it into the upper and
    then the lower limit over 40 steps of 2 ms: compiled loop = simulate_fixed (same
    Newton count)."""
    model = _model(k=2.0e3, c=3.0, flexible=True, lower=-0.01, upper=0.01)
    q0, v0 = np.zeros(model.nq), np.zeros(model.nq)
    v0[0] = 2.0
    tau = np.zeros((40, 1))
    tau[10:] = -8.0
    ref = simulate_fixed(model, q0, v0, 2e-3, 40, joint_commands=tau)
    comp = simulate_fixed_compiled(model, q0, v0, 2e-3, 40, joint_torques=tau)
    assert np.max(ref.q[:, 0]) > 0.01 and np.min(ref.q[:, 0]) < -0.01   # both stops act
    assert np.max(np.abs(comp.q - ref.q)) < 1e-12
    assert np.max(np.abs(comp.v - ref.v)) < 1e-10
    assert comp.newton_iterations == ref.newton_iterations


def test_saturated_pd_follows_the_clipped_law_written_by_hand():
    """Eq. 95 PD (kp 200, kd 20) on the rigid link with effort 1 N m and a 0.5 rad
    set-point: the loop's clipped PD (pd_clip) equals DOP853 with the force
    clip(kp (s - q) - kd q', -1, 1) written out (1e-6 rad at 0.1 ms); while saturated the
    link accelerates at effort / J; the scenario's reported torque stays within the
    limit and is the clipped law."""
    kp, kd, s = 200.0, 20.0, 0.5
    model = _model(effort=1.0, lower=-1.0, upper=1.0)
    q0, v0 = np.zeros(model.nq), np.zeros(model.nq)
    H = joint_input_matrix(model)

    def force(t, q, v):
        return H @ np.clip([kp * (s - q[0]) - kd * v[0]], -1.0, 1.0)

    ts = np.linspace(0.0, 1.5, 301)
    ref = simulate_variable(model, q0, v0, ts, force=force, rtol=1e-12, atol=1e-14)
    sc = Scenario(name="saturated_pd", arm=model.arm, duration=1.5, step=1e-4,
                  sample_period=5e-3, rho_inf=1.0, joint_values=np.zeros(1),
                  joint_rates=np.zeros(1), start_static=False,
                  pd=JointPD(np.array([kp]), np.array([kd]), np.array([s])))
    res = sc.run(model=model, advise=False)
    assert np.max(np.abs(res.q[:, 0] - ref.q[:, 0])) < 1e-6
    early = ts <= 0.2         # saturated: q = t^2 / (2 J) (kp (s - q) - kd q' > 1)
    assert np.max(np.abs(ref.q[early, 0] - ts[early] ** 2 / (2 * J))) < 1e-9
    assert np.max(np.abs(res.tau)) <= 1.0
    law = np.clip(kp * (s - res.q[:, 0]) - kd * res.v[:, 0], -1.0, 1.0)
    assert np.max(np.abs(res.tau[:, 0] - law)) < 1e-12
    assert abs(res.q[-1, 0] - s) < 1e-3          # it still reaches the set-point
    free = sc.run(advise=False, model=model.__class__(dataclasses.replace(
        model.arm, links=(dataclasses.replace(model.arm.links[0], joint=dataclasses.replace(
            model.arm.links[0].joint, effort=np.inf)),))))
    assert np.max(np.abs(free.tau)) > 50.0        # unclipped: the 100 N m step of kp s


def test_urdf_side_file_makes_the_urdf_limits_stops():
    """The UR5-like side file with joint_stops: one stop per joint at the URDF limits
    (+-2 pi, elbow +-pi); 10 mrad beyond the elbow's limit it pushes back with
    k (d - s / 2) (the default transition s = 1 mrad)."""
    data = read_yaml(SPATIAL_PRESET_DIR / "ur5_like_flexible_forearm.yaml")
    data["urdf"] = str(SPATIAL_PRESET_DIR / "ur5_like_arm.urdf")
    data["joint_stops"] = {"stiffness": 1.0e5, "damping": 100.0}
    arm = spatial_arm_from_dict(data, "side.yaml")
    assert arm.joint_stops == JointStops(1.0e5, 100.0, 1.0e-3)
    model = SpatialArmModel(arm)
    assert len(model.stops) == 6
    elbow = [s for s in model.stops if s[0] == model.off[2]][0]
    assert elbow[1:3] == pytest.approx((-3.141593, 3.141593), abs=0)
    q = np.zeros(model.nq)
    q[model.off[2]] = 3.141593 + 0.01
    assert model.stop_load(q)[model.off[2]] == pytest.approx(-1.0e5 * (0.01 - 0.5e-3),
                                                             rel=1e-9)
    plain = SpatialArmModel(load_spatial_arm("ur5_like_flexible_forearm"))
    assert plain.stops == [] and plain.arm.joint_stops is None


@pytest.mark.parametrize("mutate, field, text", [
    (lambda d: d["joint_stops"].update(stiffness=-1.0), "joint_stops.stiffness", "> 0"),
    (lambda d: d["joint_stops"].update(damping=-1.0), "joint_stops.damping", ">= 0"),
    (lambda d: d["joint_stops"].update(friction=1.0), "joint_stops", "stiffness"),
    (lambda d: d["links"][0]["joint"].update(lower=0.5), "links[0].joint.lower", "upper"),
    (lambda d: d["links"][0]["joint"].update(effort=-1.0), "links[0].joint.effort", ">= 0"),
    (lambda d: [d["links"][0]["joint"].pop(k) for k in ("lower", "upper")], "joint_stops",
     "finite lower or upper"),
    (lambda d: d["links"][0]["joint"].update(motor="locked"), "joint_stops",
     "a locked rigid joint does not move"),
])
def test_bad_stop_files_name_the_field(mutate, field, text):
    data = _arm()
    mutate(data)
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_dict(data, "bad.yaml")
    msg = str(err.value)
    assert "bad.yaml" in msg and field in msg and text in msg, msg


def test_a_pd_start_beyond_the_effort_limit_is_refused():
    """The PD's static start under gravity needs m g L = 4.9 N m at the joint; with an
    effort limit of 1 N m the loop clips the PD, so that start would not be at rest: the
    scenario says so, naming the joint and both torques."""
    model = _model(effort=1.0, lower=-1.0, upper=1.0, gravity=(0.0, -9.81, 0.0))
    sc = Scenario(name="held_pd", arm=model.arm, duration=0.1, step=1e-3,
                  sample_period=5e-3, rho_inf=0.9, joint_values=np.zeros(1),
                  joint_rates=np.zeros(1), start_static=True,
                  pd=JointPD(np.array([1e3]), np.array([10.0]), np.zeros(1)))
    with pytest.raises(ValueError, match="joint1, beyond its effort limit 1"):
        sc.run(model=model, advise=False)
