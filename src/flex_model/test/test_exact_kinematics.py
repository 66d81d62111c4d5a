"""kinematics: exact (flex_model.exact_kinematics): closed forms, limits, conservation, the
Exudyn reference of the sagging seed-000 link, and the paths that must refuse it."""
import dataclasses

import numpy as np
import pytest
import scipy.linalg as sl
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, root

from flex_model.arm import arm_from_dict, load_arm
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_model.exact_kinematics import ExactKinematicsUnsupported
from flex_model.simulate import simulate

EI, M_PER_L, L = 0.70656, 0.1289, 0.28


def two_link(kinematics, n_vars=4):
    """Two unequal links with end masses and inertias (a chain exercises the recursion)."""
    link = {"length": 0.5, "section": {"shape": "explicit", "EI": 2.0, "m": 0.3},
            "variables": n_vars}
    return FlexArmModel(arm_from_dict({
        "name": "two", "gravity": [0.0, -9.81], "kinematics": kinematics,
        "payload": {"mass": 0.05, "inertia": 2e-5},
        "links": [dict(link, end_masses={"M_minus": 0.2, "M_plus": 0.1, "J_minus": 0.01,
                                         "J_plus": 1e-4}),
                  dict(link, length=0.4, end_masses={"M_minus": 0.05, "J_minus": 1e-3})]}))


def sag_model(kinematics, n_vars=4):
    """The seed-000 link on a free 5 kg m^2 hub in the vertical plane (issue 24, item 3;
    the case of bench/bench_exact_kinematics.py)."""
    arm = load_arm("seed000_real_arm", vars_per_link=n_vars)
    link = dataclasses.replace(arm.links[0], J_minus=5.0)
    arm = dataclasses.replace(arm, links=(link,), gravity=(0.0, -9.81))
    return FlexArmModel(arm.with_kinematics(kinematics))


def period_of_maxima(t, w):
    """Mean spacing of the maxima of w (each refined by a parabola), least squares."""
    k = np.flatnonzero((w[1:-1] > w[:-2]) & (w[1:-1] >= w[2:])) + 1
    y0, y1, y2 = w[k - 1], w[k], w[k + 1]
    tm = t[k] + 0.5 * (y0 - y2) / (y0 - 2 * y1 + y2) * (t[1] - t[0])
    return np.polyfit(np.arange(len(tm)), tm, 1)[0]


def test_uniformly_bent_link_lies_on_a_circle():
    """Closed form: w = kappa s^2 / 2 is in the span of the (Hermite) wavelets; read as the
    section angle phi = kappa s, the exact centre line is the arc of radius 1 / kappa: tip
    at (sin(kappa L), 1 - cos(kappa L)) / kappa and angle kappa L, bending energy
    EI kappa^2 L / 2. At kappa L = 1 rad second_order's tip is off by centimetres."""
    arm = arm_from_dict({"name": "arc", "gravity": [0, 0], "links": [
        {"length": L, "section": {"shape": "explicit", "EI": EI, "m": M_PER_L},
         "variables": 8}]})
    kappa = 1.0 / L
    z = np.linspace(0.0, L, 5)[1:]
    qf = np.ravel(np.column_stack([kappa * z ** 2 / 2, kappa * z]))
    exact = FlexArmModel(arm.with_kinematics("exact"))
    q = np.concatenate([[0.3], qf])  # the link's root turned by 0.3 rad
    tip = exact.link_origins(q)[-1]
    local = np.array([np.sin(kappa * L), 1.0 - np.cos(kappa * L)]) / kappa
    c, s = np.cos(0.3), np.sin(0.3)
    assert tip == pytest.approx([c * local[0] - s * local[1], s * local[0] + c * local[1]],
                                abs=1e-13)
    assert exact.tip_pose(q)[2] == pytest.approx(0.3 + kappa * L, abs=1e-14)
    assert exact.energy(q, np.zeros_like(q))["elastic"] == pytest.approx(
        0.5 * EI * kappa ** 2 * L, rel=1e-12)
    assert exact.tip_deflections(q)[0] == pytest.approx(local[1], abs=1e-13)
    shape = exact.shape(q, 5)[0]
    assert np.hypot(*(shape - exact.link_origins(q)[0]
                      - np.array([-s, c]) / kappa).T) == pytest.approx(1 / kappa, abs=1e-13)
    second = FlexArmModel(arm.with_kinematics("second_order"))
    assert np.hypot(*(second.link_origins(q)[-1] - tip)) > 0.01


def _cantilever_tip(kinematics, n_vars, load):
    """Static tip (x, y) and angle of a clamped link under a dead tip load (0, -load) N:
    K q = J_tip^T F solved for the deformation variables."""
    m = FlexArmModel(arm_from_dict({"name": "c", "gravity": [0, 0], "kinematics": kinematics,
                                    "links": [{"length": L, "section": {
                                        "shape": "explicit", "EI": EI, "m": M_PER_L},
                                        "variables": n_vars}]}))
    f = m.flex_indices
    F = np.array([0.0, -load])

    def residual(qf):
        q = np.zeros(m.nq)
        q[f] = qf
        return (m.K @ q - m.tip_jacobian(q).T @ F)[f]
    sol = root(residual, np.zeros(len(f)), tol=1e-14)
    assert np.max(np.abs(residual(sol.x))) < 1e-9 * load * L
    q = np.zeros(m.nq)
    q[f] = sol.x
    return m.link_origins(q)[-1], m.tip_pose(q)[2]


def test_large_deflection_cantilever_is_the_elastica():
    """Closed form (up to an ODE): a cantilever under a dead tip load P L^2 / EI = 2 (tip
    angle 45 deg) against the elastica EI theta'' = P cos(theta), theta(0) = 0,
    theta'(L) = 0, solved here by shooting (scipy, rtol 1e-12). Exact kinematics with 8
    variables: tip within 1e-6 m and 1e-5 rad (measured 8e-7 m, 3e-6 rad; 16 variables
    5e-8 m: the error falls as h^4); second_order is centimetres off."""
    P = 2.0 * EI / L ** 2

    def shoot(k0):
        return solve_ivp(lambda s, y: [y[1], P / EI * np.cos(y[0]), np.cos(y[0]),
                                       np.sin(y[0])], (0, L), [0, k0, 0, 0], rtol=1e-12,
                         atol=1e-14).y[:, -1]
    ref = shoot(brentq(lambda k: shoot(k)[1], -1.01 * P * L / EI, -1e-6))
    tip, angle = _cantilever_tip("exact", 8, P)
    assert np.hypot(*(tip - ref[2:])) < 1e-6
    assert angle == pytest.approx(ref[0], abs=1e-5)
    tip2, _ = _cantilever_tip("second_order", 8, P)
    assert np.hypot(*(tip2 - ref[2:])) > 0.01


def test_equals_second_order_at_small_deflections():
    """B(0) and K are those of second_order (the zero-sag frequencies agree to 1e-9), and
    B(q) differs by O(q^2) only (the kinematics agree to the second order)."""
    m2, me = sag_model("second_order", 8), sag_model("exact", 8)
    q0 = np.zeros(me.nq)
    w2 = sl.eigh(m2.K, m2.mass_matrix(q0), eigvals_only=True)[1:]
    we = sl.eigh(me.K, me.mass_matrix(q0), eigvals_only=True)[1:]
    assert np.sqrt(we) == pytest.approx(np.sqrt(w2), rel=1e-9)
    q = np.random.default_rng(1).normal(size=me.nq) * 0.05
    d = [np.max(np.abs(me.mass_matrix(e * q) - m2.mass_matrix(e * q))) for e in (1e-1, 1e-2)]
    assert d[0] / d[1] == pytest.approx(100.0, rel=0.02)


@pytest.mark.parametrize("scale", [0.02, 0.3])
def test_bias_is_the_lagrangian_and_compiled_equals_numpy(scale, lagrange_bias):
    """c(q, v) = dB/dt v - 1/2 d(v^T B v)/dq + dU_g/dq by central differences of B and U
    (a check of the sweep's Jacobians and convective terms independent of their
    derivation), on two links with end masses; the compiled sweep equals the NumPy one;
    the tip Jacobian is the derivative of the tip position."""
    m = two_link("exact")
    rng = np.random.default_rng(2)
    q = rng.normal(size=m.nq) * scale
    v = rng.normal(size=m.nq)
    c = m.bias(q, v)
    assert np.max(np.abs(c - lagrange_bias(m, q, v))) < 1e-7 * np.max(np.abs(c))
    B1, c1 = m._exact.mass_and_bias(q, v, 0.0, -9.81)
    B2, c2 = m._exact.mass_and_bias_numpy(q, v, 0.0, -9.81)
    assert np.max(np.abs(B1 - B2)) < 1e-14 and np.max(np.abs(c1 - c2)) < 1e-12
    h = 1e-6
    Jn = np.array([(m.link_origins(q + h * e)[-1] - m.link_origins(q - h * e)[-1]) / (2 * h)
                   for e in np.eye(m.nq)]).T
    assert np.max(np.abs(m.tip_jacobian(q) - Jn)) < 1e-8


def test_energy_conserved_without_damping():
    """Two links swinging under gravity from a bent start, no damping, no torque: the total
    energy drifts by less than 1e-8 of the energy exchanged (rtol 1e-12, ~3 periods of
    the first flexible mode)."""
    m = two_link("exact")
    q0 = np.zeros(m.nq)
    q0[m.flex_indices] = 0.02
    q0[m.alpha_index(1)] = 0.5
    res = simulate(m, q0, t_final=0.15, sample_period=0.005, rtol=1e-12)
    e = np.array([sum(m.energy(q, v).values()) for q, v in zip(res.q, res.v)])
    swing = np.ptp([m.energy(q, v)["kinetic"] for q, v in zip(res.q, res.v)])
    assert swing > 0.05
    assert np.max(np.abs(e - e[0])) < 1e-8 * swing


#: Exudyn 1.13.6 (ObjectANCFCable2D, 32 elements, generalized-alpha rho_inf = 1, h = 5e-5
#: s, EA = 1e6 N) on the same case over 3 s, the period of the tip deflection's maxima as
#: here: ``python bench/exact_kinematics_exudyn.py --nel 32 --h 5e-5 --summary`` (16
#: elements at 1e-4 s: 0.1181222; 8 at 1e-4: 0.1181213; EA 1e5 or 1e7: within 2e-7)
EXUDYN_PERIOD_3S = 0.11812313


@pytest.mark.acceptance
def test_sag_period_against_exudyn():
    """The seed-000 link sagging under gravity (issue 24, item 3), 4 variables, fixed step
    2.5e-4 s over 3 s: the exact kinematics' period within 1e-5 s of Exudyn's
    geometrically exact ANCF cable (stored figure above); second_order's period is longer
    by more than 2e-5 s (at 1e-4 s: exact -3.3e-6 s, second_order +3.9e-5 s). The
    acceptance tier (python bench/bench_acceptance.py): 24000 steps, the slowest test of
    make test on a fresh clone (55 s of a worker)."""
    periods = {}
    for kin in ("second_order", "exact"):
        m = sag_model(kin)
        res = simulate(m, np.zeros(m.nq), t_final=3.0, sample_period=2.5e-4,
                       method="fixed", dt=2.5e-4)
        periods[kin] = period_of_maxima(res.t, res.tip_deflections[:, 0])
    assert abs(periods["exact"] - EXUDYN_PERIOD_3S) < 1e-5
    assert periods["second_order"] - EXUDYN_PERIOD_3S > 2e-5


def test_fixed_step_follows_the_variable_step():
    """The exact model's fixed step (its own generalized-alpha) at 1e-4 s stays within
    1 % of the deflection of the variable step (rtol 1e-9) over two periods, with a PD on
    the joint, a torque pulse and a tip force pulse."""
    from flex_model.simulate import JointPD, Pulse
    m = sag_model("exact")
    pd = JointPD(kp=[20.0], kd=[2.0], setpoints=[0.2])
    pulses = (Pulse(start=0.05, end=0.08, joint_torques=np.array([0.5])),
              Pulse(start=0.1, end=0.12, tip_force=np.array([0.0, -0.5])))
    kw = dict(t_final=0.24, sample_period=1e-3, pd=pd, pulses=pulses)
    var = simulate(m, np.zeros(m.nq), rtol=1e-9, **kw)
    fix = simulate(m, np.zeros(m.nq), method="fixed", dt=1e-4, **kw)
    w = var.tip_deflections[:, 0]
    assert np.max(np.abs(fix.tip_deflections[:, 0] - w)) < 0.01 * np.ptp(w)
    assert np.max(np.abs(fix.joint_angles - var.joint_angles)) < 1e-3


def test_paths_that_cannot_take_it_refuse_in_one_line():
    m = sag_model("exact")
    q0 = np.zeros(m.nq)
    with pytest.raises(ExactKinematicsUnsupported, match="kinematics: exact .*second_order"):
        m.P  # the compiled kernels' data: the stepper, control loop, node, replay read it
    from flex_model.stepper import Stepper
    with pytest.raises(ExactKinematicsUnsupported, match="kinematics: exact"):
        Stepper(m, q0)
    modal = load_arm("seed000_real_arm")
    modal = dataclasses.replace(modal, links=(dataclasses.replace(
        modal.links[0], discretization="assumed_modes", n_vars=2),), kinematics="exact")
    with pytest.raises(ExactKinematicsUnsupported, match="wavelet"):
        FlexArmModel(modal)
    with pytest.raises(ConfigError, match="kinematics"):
        load_arm("seed000_real_arm").with_kinematics("elastica")


def _hubless_exact(step, duration=0.04, jump=0.02, deg=15.0, nv=8):
    """Issue 24's hub-less arm (thesis Example 1, PD 625 / 176.8), exact kinematics, ``nv``
    variables per link, a set-point step of ``deg`` on joint 2 at ``jump``."""
    from flex_model.scenario import scenario_from_dict
    sc = scenario_from_dict({
        "name": "hubless", "arm": "thesis_example1", "vars_per_link": nv,
        "kinematics": "exact", "duration": duration, "sample_period": 1e-3,
        "initial": {"joint_angles_deg": [0.0, 0.0], "state": "static"},
        "control": {"pd": {"kp": [625.0, 625.0], "kd": [176.8, 176.8],
                           "setpoints_deg": [0.0, 0.0]},
                    "setpoint_schedule": [{"time": jump, "setpoints_deg": [0.0, deg]}]},
        "integrator": {"method": "fixed", "step": step, "rho_inf": 0.9}})
    return sc.run(advise=False)


def test_hubless_set_point_step_has_no_first_step_lag():
    """The hub-less root takes the torque jump kp dtheta on its damper at once: joint 2's
    rate jumps to kp dtheta / kd = 0.925 rad/s (1 ms later within 1.5 %). One
    generalized-alpha step puts only beta / gamma (1/2 at rho_inf 0.9) of h dv into the
    position, a lag of h dv / 2 = 0.0265 deg at 1 ms the PD then carries for ~0.3 s
    (issue 47; measured 0.0269 deg before simulate._exact_jump_step). At 1 ms the joint
    angles now stay within 0.002 deg of a 1/64 ms run (0.0002 deg measured)."""
    fine, coarse = _hubless_exact(1e-3 / 64), _hubless_exact(1e-3)
    dv = 625.0 * np.radians(15.0) / 176.8
    after = 21   # samples every 1 ms; the jump at 0.02 s
    assert coarse.joint_rates[after, 1] == pytest.approx(dv, rel=0.015)
    assert fine.joint_rates[after, 1] == pytest.approx(dv, rel=0.015)
    lag = np.degrees(np.abs(coarse.joint_angles - fine.joint_angles)[after:].max())
    assert lag < 0.002, lag


def test_hubless_set_point_step_converges_in_the_step(monkeypatch):
    """At 16 variables the step cannot follow the damper-held root modes (time constants
    1e-8 / 1e-7 s) at any step one would take: the restart filters at 1/32 and 1/64 ms too
    (exact_kinematics.restart_acceleration; it went consistent there, whose O(h^2 kd /
    J_root) kick left 0.0022 deg between the two, issue 47), and the two runs agree to
    1.3e-6 deg and 0.006 mm of link 2's deflection in the 20 ms after the step (consistent:
    0.036 mm)."""
    import flex_model.exact_kinematics as ek
    keep, flags = ek.restart_acceleration, []

    def spy(*args):
        a1, filtered = keep(*args)
        flags.append(filtered)
        return a1, filtered
    monkeypatch.setattr(ek, "restart_acceleration", spy)
    runs = [_hubless_exact(1e-3 / k, nv=16) for k in (32, 64)]
    assert flags == [True, True]
    dq = np.degrees(np.abs(runs[0].joint_angles - runs[1].joint_angles).max())
    dw = np.abs(runs[0].tip_deflections - runs[1].tip_deflections).max()
    assert dq < 2e-5, dq
    assert dw < 2e-5, dw
