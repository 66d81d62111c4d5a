"""Admissible nominal input (thesis V.1) on the section F task (thesis V.3), open loop and
with the PD of Eq. (95) in the loop (VALIDATION.md section F)."""
import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.simulate import JointPD, simulate
from flex_model.statics import TipLoad, static_residual
from flex_planner import SECTION_F_TIMES, SECTION_F_WAYPOINTS, plan, plan_tip_path
from flex_planner.nominal_input import NominalInputSolver


@pytest.fixture(scope="module")
def model():
    return FlexArmModel(load_arm("thesis_example1"))


@pytest.fixture(scope="module")
def section_f(model):
    return plan(model, SECTION_F_WAYPOINTS, SECTION_F_TIMES, sample_period=1e-3)


def test_T_puts_the_torques_in_the_last_n_equations_only(model, section_f):
    solver = NominalInputSolver(model)
    H = model.input_matrix()
    T = np.hstack([solver.H_perp, H])                    # T = [H_perp  H]
    np.testing.assert_allclose(solver.H_perp.T @ H, 0.0, atol=1e-15)
    assert np.linalg.cond(T) < 10.0
    # the homogeneous equations hold along the plan (N; torques are ~10 N m)
    assert section_f.nominal.balance_residual < 1e-8
    # and H tau supplies exactly what the equations of motion need at every sample
    nom = section_f.nominal
    for k in range(0, len(nom.t), 2500):
        need = (model.inverse_dynamics(nom.q[k], nom.v[k], nom.a[k]) + model.K @ nom.q[k]
                + model.D @ nom.v[k])
        np.testing.assert_allclose(H @ nom.tau[k], need, atol=1e-8)


def test_plan_fields_are_consistent(model, section_f):
    traj = section_f.trajectory
    assert len(traj.t) == 15001 and traj.t[-1] == 15.0
    np.testing.assert_allclose(traj.q_nominal @ model.G.T, traj.positions, atol=1e-12)
    np.testing.assert_allclose(traj.q_nominal[0], section_f.poses[0].q, atol=1e-12)
    for tk, pose in zip(SECTION_F_TIMES, section_f.poses):
        k = int(round(tk / 1e-3))
        np.testing.assert_allclose(traj.positions[k], pose.joint_angles, atol=1e-12)
    np.testing.assert_allclose(traj.velocities[[0, -1]], 0.0, atol=1e-12)  # rest to rest
    tips = np.array([model.link_origins(q)[-1] for q in traj.q_nominal[::1000]])
    np.testing.assert_allclose(tips, traj.tip[::1000], atol=1e-12)
    # the plain interface returns the same trajectory
    again = plan_tip_path(model, SECTION_F_WAYPOINTS, SECTION_F_TIMES, sample_period=0.01)
    np.testing.assert_allclose(again.efforts, traj.efforts[::10], atol=1e-9)


def test_holding_still_needs_exactly_the_static_holding_torque(model):
    held = plan(model, [SECTION_F_WAYPOINTS[1]] * 2, [0.0, 2.0], sample_period=0.01)
    q = held.poses[0].q
    residual = static_residual(model, q, np.zeros(2), TipLoad())
    holding = np.linalg.lstsq(model.G.T, -residual, rcond=None)[0]
    np.testing.assert_allclose(held.trajectory.efforts, np.tile(holding, (201, 1)), atol=1e-9)
    np.testing.assert_allclose(held.trajectory.q_nominal, np.tile(q, (201, 1)), atol=1e-12)


def test_open_loop_nominal_torque_reproduces_the_planned_joints(model, section_f):
    """The nominal torques, applied open loop (held every 1 ms), over the first second."""
    traj = section_f.trajectory

    def feedforward(t, x):
        return np.array([np.interp(t, traj.t, traj.efforts[:, i]) for i in range(2)])

    sim = simulate(model, traj.q_nominal[0], t_final=1.0, sample_period=1e-3,
                   policy=feedforward, control_period=1e-3, method="fixed", dt=1e-3)
    error = np.max(np.abs(sim.joint_angles - traj.positions[:len(sim.t)]))
    assert error < 1e-3          # rad (measured: 2.7e-5)
    assert np.max(np.abs(sim.tip_positions - traj.tip[:len(sim.t)])) < 1e-3     # m


def test_eq95_pd_in_the_loop_passes_every_waypoint(model, section_f):
    """tau = tau_nom + h (a^2 (theta_hat - theta) + sqrt(2) a (theta_hat' - theta')),
    h = 25, a = 5 (thesis Eq. 95, V.3), over the whole 15 s task. The PD part runs in the
    integrator (JointPD, zero set-point), the reference terms and tau_nom are the held
    input every 1 ms."""
    traj = section_f.trajectory
    h, a = 25.0, 5.0
    kp, kd = h * a * a, h * np.sqrt(2.0) * a
    pd = JointPD(kp=np.full(2, kp), kd=np.full(2, kd), setpoints=np.zeros(2))

    def reference(t, x):
        theta_hat, rate_hat, _, tau_nominal = traj.sample(t)
        return tau_nominal + kp * theta_hat + kd * rate_hat

    sim = simulate(model, traj.q_nominal[0], t_final=15.0, sample_period=1e-3, pd=pd,
                   policy=reference, control_period=1e-3, method="fixed", dt=1e-3)
    for tk, p in zip(SECTION_F_TIMES, SECTION_F_WAYPOINTS):
        k = int(round(tk / 1e-3))
        assert np.linalg.norm(sim.tip_positions[k] - p) < 5e-3        # m (measured: <= 0.6 mm)
    assert np.max(np.abs(sim.joint_angles - traj.positions)) < 1e-4


def test_tracking_error_vanishes_as_the_motion_slows(model):
    """Thesis IV.2: the static inversion regulates exactly; the tracking error of the
    nominal tip at the waypoints tends to zero with the motion velocity."""
    worst = []
    for slow in (1.0, 4.0):
        traj = plan_tip_path(model, SECTION_F_WAYPOINTS, SECTION_F_TIMES * slow,
                             sample_period=0.01)
        worst.append(max(np.linalg.norm(traj.tip[np.argmin(np.abs(traj.t - tk))] - p)
                         for tk, p in zip(SECTION_F_TIMES * slow, SECTION_F_WAYPOINTS)))
    assert worst[0] > 1e-4 and worst[1] < 0.2 * worst[0]


@pytest.mark.parametrize("kwargs, message", [
    ({"waypoints": [[0.0, 1.0]]}, r"waypoints: got shape \(1, 2\); expected \(N, 2\)"),
    ({"waypoints": [[-1.0, -1.0], [np.nan, 0.0]]}, r"waypoints\[1\]: got \[nan, 0.0\]"),
    ({"times": [0.0, 5.0, 5.0, 15.0]}, r"times\[2\]: got 5.0 s after 5.0 s"),
    ({"elbow": "left"}, r"elbow: got 'left'; expected one of up, down"),
    ({"sample_period": 0.0}, r"sample_period: got 0.0; expected a time > 0 s"),
])
def test_bad_requests_name_the_field(model, kwargs, message):
    args = {"waypoints": SECTION_F_WAYPOINTS, "times": SECTION_F_TIMES}
    args.update(kwargs)
    if len(args["waypoints"]) != len(SECTION_F_WAYPOINTS) and "times" not in kwargs:
        args["times"] = SECTION_F_TIMES[:len(args["waypoints"])]
    with pytest.raises(ValueError, match=message):
        plan_tip_path(model, args.pop("waypoints"), args.pop("times"), **args)
