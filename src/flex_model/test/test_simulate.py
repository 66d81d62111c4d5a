"""Time integration: conservation, agreement of the two schemes, the section E reference."""
import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.scenario import load_scenario
from flex_model.simulate import JointPD, Pulse, SimulationDivergedError, simulate

# Exudyn reference of VALIDATION.md section E (shared/reference/section_E_reference_exudyn.csv):
# relative joint angles (deg) at 3.5 s and 5 s, and max |w| per link (m) over 10 s
REF_Q_DEG = {3.5: (-28.2216, 10.9477, -21.9604), 5.0: (-30.9270, 14.8047, -21.0418)}
REF_MAX_W = (0.1453, 0.0779, 0.0245)


def three_link(nv):
    m = FlexArmModel(load_arm("thesis_three_link", nv))
    th0 = np.radians([-20.0, 20.0, -20.0])
    return m, th0, m.q_from_joint_angles(th0)


def total_energy(model, res):
    return np.array([sum(model.energy(q, v).values()) for q, v in zip(res.q, res.v)])


def test_energy_conserved_section_E_8_vars():
    """No damping, no input (hinged joints), gravity: the arm falls and swings for 5 s
    (kinetic energy up to 807 J; the drift is ~1e-12 of it, at 10 s too)."""
    model, _, q0 = three_link(8)
    res = simulate(model, q0, t_final=5.0, sample_period=0.05, rtol=1e-8)
    E = total_energy(model, res)
    kinetic = np.array([model.energy(q, v)["kinetic"] for q, v in zip(res.q, res.v)])
    assert kinetic.max() > 100.0  # it really moved
    assert np.max(np.abs(E - E[0])) / kinetic.max() < 1e-6


def test_pd_energy_balance():
    """With PD joints the energy lost equals the work of the damper: int Kd theta_dot^2."""
    model, th0, q0 = three_link(2)
    kd = np.array([250.0, 250.0, 250.0])
    pd = JointPD(np.full(3, 5e3), kd, th0)
    res = simulate(model, q0, t_final=2.0, sample_period=1e-3, pd=pd, rtol=1e-10)
    spring = np.array([0.5 * np.sum(5e3 * (th - th0) ** 2) for th in res.joint_angles])
    E = total_energy(model, res) + spring
    power = np.sum(kd * res.joint_rates**2, axis=1)
    trapezoids = 0.5 * (power[1:] + power[:-1]) * np.diff(res.t)
    dissipated = np.concatenate([[0], np.cumsum(trapezoids)])
    assert np.max(np.abs(E - E[0] + dissipated)) / dissipated[-1] < 1e-5


def test_fixed_step_converges_to_variable_step_at_second_order():
    model, th0, q0 = three_link(4)
    pd = JointPD(np.full(3, 5e3), np.full(3, 250.0), th0)
    kw = dict(t_final=5.0, sample_period=0.01, pd=pd,
              pulses=[Pulse(3.0, 4.0, (1000.0, 0.0, 0.0))])
    ref = simulate(model, q0, rtol=1e-10, **kw).tip_positions
    errs = []
    for dt in (2e-3, 1e-3, 5e-4):
        res = simulate(model, q0, method="fixed", dt=dt, **kw)
        errs.append(np.max(np.hypot(*(res.tip_positions - ref).T)))
    assert errs[1] < 0.1e-3            # < 0.1 mm at the model node's 1 ms step
    assert errs[0] / errs[2] > 5.0     # second order: 16 in the limit, first order: 4


def test_section_E_against_exudyn_reference():
    """Joint angles and deflections against the geometrically exact reference.

    The small-deflection model of the thesis omits the axial shortening of the bent links
    (geometric stiffening); measured: joint angles within 0.015 deg at 3.5 s and 0.073 deg
    at 5 s (the gap grows as a slow phase drift), largest deflections within 1.2 %.
    """
    sc = load_scenario("thesis_three_link_pd", vars_per_link=4)
    res = sc.run(advise=False)   # the step advice's check is not this test's
    for t, q_ref in REF_Q_DEG.items():
        k = int(round(t / sc.sample_period))
        np.testing.assert_allclose(np.degrees(res.joint_angles[k]), q_ref,
                                   atol=0.02 if t < 4 else 0.08)
    np.testing.assert_allclose(np.max(np.abs(res.tip_deflections), axis=0), REF_MAX_W,
                               rtol=0.02)


def test_pulse_momentum_kick_on_a_rigid_like_link():
    """A joint torque pulse on a very stiff link changes its angular momentum by tau dt."""
    model = FlexArmModel(load_arm("thesis_single_link", 2))
    model = FlexArmModel(model.arm.__class__(**{**model.arm.__dict__}))
    res = simulate(model, np.zeros(model.nq), t_final=0.2, sample_period=1e-3,
                   pulses=[Pulse(0.05, 0.1, (2.0,))], rtol=1e-10)
    # angular momentum about the joint = (B v)[alpha] for a hinged link at rest before
    k = int(round(0.15 / 1e-3))
    momentum = (model.mass_matrix(res.q[k]) @ res.v[k])[0]
    assert momentum == pytest.approx(2.0 * 0.05, rel=1e-6)


def test_divergence_names_time_and_variable():
    model, th0, q0 = three_link(2)
    with pytest.raises(SimulationDivergedError, match=r"t = .* s: state variable link\d/"):
        simulate(model, q0, t_final=1.0, sample_period=0.01, method="fixed", dt=0.01,
                 pd=JointPD(np.full(3, -1e9), np.zeros(3), th0))


def test_policy_torque_holds_arm_against_gravity():
    """A policy returning the static gravity torques keeps the clamped-equivalent pose."""
    from flex_model.statics import static_equilibrium
    model, th0, _ = three_link(2)
    eq = static_equilibrium(model, th0, joints="clamped")
    r = model.gravity_force(eq.q) + model.K @ eq.q
    tau = np.linalg.lstsq(model.G.T, r, rcond=None)[0]
    res = simulate(model, eq.q, t_final=0.5, sample_period=0.01, policy=lambda t, x: tau,
                   control_period=1e-3, method="fixed")
    np.testing.assert_allclose(res.joint_angles[-1], th0, atol=1e-7)
    np.testing.assert_allclose(res.tau[-1], tau, rtol=1e-12)


# VALIDATION.md section E: tip of link 3 (m) at 3.5, 5, 10 s; joint angles (deg) at 10 s
REF_TIP3 = {3.5: (6.11544, -4.15557), 5.0: (6.29235, -3.91276), 10.0: (6.09177, -4.21345)}
REF_Q_10 = (-32.698405, 13.968268, -21.338937)


def run_second_order_section_E(nv=4):
    sc = load_scenario("thesis_three_link_pd", vars_per_link=nv)
    sc.arm = sc.arm.with_kinematics("second_order")
    sc.method, sc.step = "fixed", 5e-4
    return sc, sc.run(advise=False)   # the step advice's check is not this test's


def test_second_order_section_E_matches_geometrically_exact_reference():
    """With the axial shortening (geometric stiffening) the model meets the reference:
    measured 0.37, 1.06, 1.64 mm at 3.5, 5, 10 s and 0.008 deg at 10 s."""
    sc, res = run_second_order_section_E()
    tips = res.link_tips()[:, 2]
    for t, ref in REF_TIP3.items():
        k = int(round(t / sc.sample_period))
        assert 1e3 * np.hypot(*(tips[k] - ref)) < 2.5
    np.testing.assert_allclose(np.degrees(res.joint_angles[-1]), REF_Q_10, atol=0.02)


def test_second_order_section_E_whole_run(shared_dir):
    ref = np.loadtxt(shared_dir / "reference" / "section_E_reference_exudyn.csv",
                     delimiter=",", skiprows=1)
    sc, res = run_second_order_section_E()
    k = np.rint(ref[:, 0] / sc.sample_period).astype(int)
    dq = np.degrees(res.joint_angles[k]) - ref[:, 10:13]
    assert np.abs(dq).max() < 0.02                                   # deg, whole run
    assert 1e3 * np.max(np.hypot(*(res.link_tips()[k, 2] - ref[:, 5:7]).T)) < 3.0  # mm
    assert 1e3 * np.abs(res.tip_deflections[k] - ref[:, 7:10]).max() < 0.6           # mm


def test_second_order_energy_conserved():
    model = FlexArmModel(load_arm("thesis_three_link", 4).with_kinematics("second_order"))
    q0 = model.q_from_joint_angles(np.radians([-20.0, 20.0, -20.0]))
    res = simulate(model, q0, t_final=2.0, sample_period=0.02, rtol=1e-8)
    E = total_energy(model, res)
    kinetic = np.array([model.energy(q, v)["kinetic"] for q, v in zip(res.q, res.v)])
    assert np.max(np.abs(E - E[0])) / kinetic.max() < 1e-6
