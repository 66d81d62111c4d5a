"""Control laws: Eq. (45) cascade and Eq. (95) PD against their closed forms."""
import numpy as np
import pytest

from flex_model.dynamics import FlexArmModel
from flex_model.simulate import JointPD, simulate

from flex_control.gain_schedule import GainSchedule
from flex_control.laws import (DecentralizedPD, PDLikeCascade, ReferenceSampler, as_policy,
                               hold_reference, joint_vector)
from flex_control.step_response import geared_arm

J2 = ["joint1", "joint2"]


def test_eq45_motor_side_cascade_closed_form():
    c = PDLikeCascade(hold_reference(["j"], [np.radians(30)]))
    theta, dtheta = np.radians(10), 0.2
    # tau_cmd = K_pv (K_pp (n theta_cmd - n theta) - n theta_dot), tau_joint = n tau_cmd
    tau_m = 50 * (70 * 50 * np.radians(20) - 50 * 0.2)
    assert c.motor_torque(0.0, [theta], [dtheta])[0] == pytest.approx(tau_m, rel=1e-14)
    assert c.torque(0.0, [theta], [dtheta])[0] == pytest.approx(50 * tau_m, rel=1e-14)
    kp, kd = c.joint_gains
    assert kp[0] == 2500 * 50 * 70 and kd[0] == 2500 * 50


def test_eq45_limits_and_validation():
    c = PDLikeCascade(hold_reference(["j"], [1.0]), torque_limits=7.5)
    assert c.torque(0.0, [0.0], [0.0])[0] == 7.5
    assert c.torque(0.0, [2.0], [0.0])[0] == -7.5
    with pytest.raises(ValueError, match=r"kpv: got \[-1.0\]; expected finite values > 0"):
        PDLikeCascade(hold_reference(["j"], [0.0]), kpv=-1.0)
    with pytest.raises(ValueError, match="torque_limits: got 3 values; expected 1 or 1"):
        PDLikeCascade(hold_reference(["j"], [0.0]), torque_limits=[1, 2, 3])


def test_eq95_closed_form_feedforward_and_trajectory_sample():
    from flex_model.trajectory import JointTrajectoryData
    ref = JointTrajectoryData(J2, t=[0.0, 2.0], positions=[[0.0, 0.0], [1.0, -1.0]],
                              velocities=[[0.5, -0.5], [0.5, -0.5]],
                              accelerations=np.zeros((2, 2)), efforts=[[1.0, 2.0], [3.0, 4.0]])
    c = DecentralizedPD(ref, h=[2.0, 0.5], a=[3.0, 4.0])
    th, dth = np.array([0.4, -0.6]), np.array([0.1, -0.2])
    tau = c.torque(1.0, th, dth)
    want = np.array([2.0, 3.0]) + np.array([2.0, 0.5]) * (
        np.array([9.0, 16.0]) * (np.array([0.5, -0.5]) - th)
        + np.sqrt(2) * np.array([3.0, 4.0]) * (np.array([0.5, -0.5]) - dth))
    np.testing.assert_allclose(tau, want, rtol=1e-14)
    c_noff = DecentralizedPD(ref, h=[2.0, 0.5], a=[3.0, 4.0], feedforward=False)
    np.testing.assert_allclose(c_noff.torque(1.0, th, dth), want - [2.0, 3.0], rtol=1e-13)


def test_eq95_with_schedule_uses_interpolated_gains():
    sched = GainSchedule(joint_names=J2, theta=[[0.0, 0.0], [1.0, 0.0]],
                         h=[[1.0, 1.0], [3.0, 3.0]], a=[[2.0, 2.0], [2.0, 2.0]])
    c = DecentralizedPD(hold_reference(J2, [0.5, 0.1]), schedule=sched)
    h, a = c.gains([0.5, 0.0])        # equidistant from both points: the mean
    np.testing.assert_allclose(h, [2.0, 2.0])
    tau = c.torque(0.0, [0.5, 0.0], [0.0, 0.0])
    np.testing.assert_allclose(tau, [0.0, 2.0 * 4.0 * 0.1])
    with pytest.raises(ValueError, match=r"schedule.joint_names: got \['a', 'b'\]"):
        DecentralizedPD(hold_reference(J2, [0, 0]), schedule=GainSchedule(
            joint_names=["a", "b"], theta=[[0, 0]], h=[[1, 1]], a=[[1, 1]]))


@pytest.mark.parametrize("field,value,match", [
    ("positions", [0.0], "positions: got 1 values; expected 2"),
    ("positions", [np.nan, 0.0], r"positions: got \[nan, 0.0\]; expected finite values"),
    ("velocities", [0.0, np.inf], r"velocities: got \[0.0, inf\]; expected finite values"),
])
def test_inputs_are_checked(field, value, match):
    c = DecentralizedPD(hold_reference(J2, [0, 0]), h=1.0, a=1.0)
    args = {"positions": [0.0, 0.0], "velocities": [0.0, 0.0], field: value}
    with pytest.raises(ValueError, match=match):
        c.torque(0.0, args["positions"], args["velocities"])


def test_reference_with_other_joint_names_is_rejected():
    c = DecentralizedPD(hold_reference(J2, [0, 0]), h=1.0, a=1.0)
    with pytest.raises(ValueError, match=r"joint_names: got \['joint1', 'elbow'\]"):
        c.set_reference(hold_reference(["joint1", "elbow"], [0, 0]))
    with pytest.raises(ValueError, match="h: got"):
        DecentralizedPD(hold_reference(J2, [0, 0]), h=[0.0, 1.0], a=1.0)
    assert joint_vector("x", 3, 1).tolist() == [3.0]


def test_eq45_as_sampled_policy_matches_continuous_pd():
    """The controller object as a simulate() policy (ZOH at 10 us, 8 x below the 80 us
    stability bound of the velocity loop) reproduces the continuous Eq. (45) PD."""
    model = FlexArmModel(geared_arm("seed000_real_arm", vars_per_link=2))
    ctrl = PDLikeCascade(hold_reference(model.arm.joint_names, [np.radians(30)]))
    q0 = model.q_from_joint_angles([np.radians(10)])
    kp, kd = ctrl.joint_gains
    cont = simulate(model, q0, t_final=0.03, sample_period=1e-3,
                    pd=JointPD(kp, kd, np.array([np.radians(30)])), method="fixed", dt=1e-5)
    pol = simulate(model, q0, t_final=0.03, sample_period=1e-3, policy=as_policy(ctrl, model),
                   control_period=1e-5, method="fixed", dt=1e-5)
    # first-order joint response with time constant 1/K_pp: 10 + 20 (1 - e^{-70 t}) deg
    th = np.degrees(cont.joint_angles[:, 0])
    np.testing.assert_allclose(th, 10 + 20 * (1 - np.exp(-70 * cont.t)), atol=0.05)
    np.testing.assert_allclose(np.degrees(pol.joint_angles[:, 0]), th, atol=0.02)


def test_reference_sampler_equals_trajectory_sample(section_f_quasi_static):
    data = section_f_quasi_static
    sampler = ReferenceSampler(data)
    for t in np.concatenate([[-1.0, 0.0, 15.0, 20.0], np.random.default_rng(2).uniform(0, 15,
                                                                                       50)]):
        p, v, _, e = data.sample(t)
        got = sampler(t)
        np.testing.assert_allclose(got[0], p, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(got[1], v, rtol=1e-13, atol=1e-15)
        np.testing.assert_allclose(got[2], e, rtol=1e-13, atol=1e-15)
