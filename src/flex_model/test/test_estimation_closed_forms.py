"""The estimation filter (flex_model.estimation) against closed forms: on a single flexible
link at rest in a horizontal plane (linear to first order) the filter's Jacobian is the
model's -B^-1 K, its transition the matrix exponential to ROS2's order, its covariance the
stationary solution of the discrete Riccati equation (scipy.linalg.solve_discrete_are),
and on runs of the simulator with the assumed noise its NIS has the measurement dimension
as mean."""
import numpy as np
import pytest
from scipy.linalg import expm, solve_discrete_are

from flex_model.arm import arm_from_dict
from flex_model.dynamics import FlexArmModel
from flex_model.estimation import (Estimator, EstimatorSettings, Measurement,
                                   estimate_recording)
from flex_model.simulate import simulate

T = 1e-3


def _link(gravity=(0.0, 0.0), effects=()):
    """2 m aluminium tube (first mode ~5 Hz clamped), hub 0.05 kg m^2."""
    return FlexArmModel(arm_from_dict({"name": "one", "gravity": list(gravity), "links": [{
        "length": 2.0, "material": {"E": 6.4e10, "rho": 2700.0},
        "section": {"shape": "square_hollow", "side": 0.02, "wall": 0.001},
        "end_masses": {"J_minus": 0.05}}], "effects": list(effects)}))


def _estimator(model, **kw):
    ms = [Measurement("q1", "joint_angle", 0, std=1e-4),
          Measurement("w1", "tip_deflection", 0, std=1e-3)]
    s = EstimatorSettings(sample_period=T, torque_noise=0.05, modal_noise=0.02,
                          relinearize_every=0, **kw)
    return Estimator(model, ms, s)


def test_jacobian_at_rest_is_the_linear_model():
    model = _link()
    est = _estimator(model)
    nq = model.nq
    A = est._state_jacobian(np.zeros(1))
    Binv = np.linalg.inv(model.mass_matrix(np.zeros(nq)))
    assert np.allclose(A[:nq, nq:], np.eye(nq), atol=1e-9)
    assert np.allclose(A[nq:, :nq], -Binv @ model.K, rtol=1e-6, atol=1e-6 * np.abs(
        Binv @ model.K).max())
    # on the resolved modes (|lambda T| < 0.1: the rigid one and the first bending mode,
    # 5 Hz) the ROS2 transition is the matrix exponential to third order in lambda T
    est.relinearize(np.zeros(1))
    lam, V = np.linalg.eig(A)
    slow = (np.abs(lam * T) < 0.1) & (np.abs(lam) > 1e-3)  # the bending mode (5 Hz)
    assert slow.sum() == 2
    ref = V[:, slow] * np.exp(lam[slow] * T)
    # ROS2's stability function R(z) = (1 + (1 - 2g) z + (g^2 - 2g + 1/2) z^2) / (1 - g z)^2
    g, z = 1 + 1 / np.sqrt(2), lam[slow] * T
    R = (1 + (1 - 2 * g) * z + (g * g - 2 * g + 0.5) * z * z) / (1 - g * z) ** 2
    assert np.abs(est.F @ V[:, slow] - V[:, slow] * R).max() < 1e-9 * np.abs(ref).max()
    assert np.abs(R - np.exp(z)).max() < 2 * np.abs(z).max() ** 3   # second order: 1e-3
    assert np.abs(expm(A * T) @ V[:, slow] - ref).max() < 1e-9 * np.abs(ref).max()
    rigid = np.zeros(len(A))  # the rigid rotation at a rate: angle T, rate 1
    rigid[[0, nq]] = 1.0
    assert np.allclose(est.F @ rigid, expm(A * T) @ rigid, atol=1e-12)


def test_covariance_converges_to_the_discrete_riccati_solution():
    """Linearized once at rest and fed zero readings, the filter's predicted covariance
    is the stabilizing solution of P = F P F' - F P H' (H P H' + R)^-1 H P F' + Q_d."""
    est = _estimator(_link())
    est.reset(np.zeros(est.plant.nq))
    for _ in range(4000):
        est.step(np.zeros(1), np.zeros(2))
    R = np.diag(est.R)
    P = solve_discrete_are(est.F.T, est.H.T, est.Qd, R)
    assert np.abs(est.P - P).max() < 1e-9 * np.abs(P).max()
    K = P @ est.H.T @ np.linalg.inv(est.H @ P @ est.H.T + R)
    Pp = est.P
    Kf = Pp @ est.H.T @ np.linalg.inv(est.H @ Pp @ est.H.T + R)
    assert np.abs(K - Kf).max() < 1e-9 * np.abs(K).max()


def _run(n, std_tau=0.05, seed=7):
    """A dopri5 run of the link under a random torque held per sample: (model, result,
    torques, rng)."""
    model = _link()
    rng = np.random.default_rng(seed)
    taus = rng.normal(0.0, std_tau, n + 1)
    res = simulate(model, np.zeros(model.nq), t_final=n * T, sample_period=T,
                   policy=lambda t, x: np.array([taus[min(int(round(t / T)), n)]]),
                   control_period=T)
    return model, res, taus, rng


def test_nis_mean_is_the_measurement_dimension_on_data_with_the_assumed_noise():
    """The simulator's own run (dopri5, not the filter's ROS2) under a random torque held
    per sample with the filter's torque noise, read with the filter's sensor noise: NIS
    mean 2 (chi2 with 2 dof: 2 +- 0.1 over 3000 samples) and ~95 % inside the bound."""
    n, std_tau = 3000, 0.05
    model, res, taus, rng = _run(n, std_tau)
    y = np.column_stack([res.joint_angles[:, 0] + rng.normal(0, 1e-4, n + 1),
                         res.tip_deflections[:, 0] + rng.normal(0, 1e-3, n + 1)])
    ms = [Measurement("q1", "joint_angle", 0, std=1e-4),
          Measurement("w1", "tip_deflection", 0, std=1e-3)]
    s = EstimatorSettings(sample_period=T, torque_noise=std_tau, modal_noise=0.0,
                          initial_angle_std=1e-4, initial_deflection_std=1e-3,
                          initial_rate_std=1e-3)
    r = estimate_recording(model, res.t, taus[:, None], y, ms, s, q0=np.zeros(model.nq))
    assert r.summary["nis_mean"] == pytest.approx(2.0, abs=0.15)
    assert 0.93 < r.summary["nis_95_fraction"] < 0.97
    err = r.tip_deflections[:, 0] - res.tip_deflections[:, 0]
    inside = np.abs(err) <= 1.96 * r.tip_deflections_std[:, 0]
    assert 0.9 < inside.mean() <= 1.0


def test_missing_and_delayed_readings():
    """NaN readings are skipped (NIS dimension 1), and the settings refuse bad values."""
    est = _estimator(_link())
    est.reset(np.zeros(est.plant.nq))
    s = est.step(np.zeros(1), np.array([0.0, np.nan]))
    assert s.nis_dof == 1 and np.isnan(s.innovation[1])
    with pytest.raises(ValueError, match="sample_period"):
        EstimatorSettings(sample_period=0.0)
    with pytest.raises(ValueError, match="adapt"):
        Estimator(_link(), [], EstimatorSettings(adapt=("stiction:0",)))
    with pytest.raises(ValueError, match="kind"):
        Measurement("x", "gyro")


def test_readings_are_the_sensor_models_and_a_delay_is_read_against_its_time():
    """The filter's readings at a state are flex_model.sensors' signals (joint encoder,
    strain gauge, tip position, tip gauge); a tip gauge 5 ms late, declared, keeps
    the NIS at its dimension, undeclared it does not."""
    from flex_model.estimation import measurements as meas
    from flex_model.sensors import Sensor, true_signal
    n = 1500
    model, res, taus, rng = _run(n)
    est = _estimator(model)
    k = 700
    x = np.concatenate([res.q[k], res.v[k]])
    ms = [Measurement("q", "joint_angle", 0),
          Measurement("e", "strain", 0, position=0.5, surface_distance=0.01),
          Measurement("x", "tip_position", component=0),
          Measurement("y", "tip_position", component=1),
          Measurement("w", "tip_deflection", 0)]
    got = meas.outputs(ms, est.plant, x, taus[k:k + 1])
    sensors = [Sensor("q", "joint_encoder", "joint1"),
               Sensor("e", "strain_gauge", "link1", position=0.5, surface_distance=0.01),
               Sensor("t", "tip_position"), Sensor("w", "tip_deflection", "link1")]
    want = np.concatenate([true_signal(sn, res)[k] for sn in sensors])
    assert np.allclose(got, want, rtol=1e-12, atol=1e-15)
    d = 5
    w = np.concatenate([np.full(d, res.tip_deflections[0, 0]), res.tip_deflections[:-d, 0]])
    y = np.column_stack([res.joint_angles[:, 0] + rng.normal(0, 1e-4, n + 1),
                         w + rng.normal(0, 1e-4, n + 1)])
    nis = []
    for delay in (d * T, 0.0):
        ms = [Measurement("q1", "joint_angle", 0, std=1e-4),
              Measurement("w1", "tip_deflection", 0, std=1e-4, delay=delay)]
        s = EstimatorSettings(sample_period=T, torque_noise=0.05, initial_angle_std=1e-4,
                              initial_deflection_std=1e-4, initial_rate_std=1e-3)
        r = estimate_recording(model, res.t, taus[:, None], y, ms, s, q0=np.zeros(model.nq))
        nis.append(r.summary["nis_mean"])
    assert nis[0] == pytest.approx(2.0, abs=0.3)
    assert nis[1] > nis[0] + 0.2          # 2.33 against 2.01


def test_a_voltage_driven_arm_is_estimated_through_its_motor_model():
    """The calibrated Quanser twin (DC motor, gear, friction) simulated at 1 kHz under a
    2 Hz +-2 V square wave, read by its quantized encoder alone: the filter, fed the
    voltage, follows the link's tip deflection within 5 % of its peak (its own model, its
    friction smoothed to 0.02 rad/s: a check of the motor and friction paths)."""
    from flex_model.arm import load_arm
    model = FlexArmModel(load_arm("quanser_cuboulder_calibrated"))
    n, T2 = 1500, 1e-3
    volts = np.where((np.arange(n + 1) * T2) % 0.5 < 0.25, 2.0, -2.0)
    res = simulate(model, np.zeros(model.nq), t_final=n * T2, sample_period=T2,
                   policy=lambda t, x: np.array([volts[min(int(round(t / T2)), n)]]),
                   control_period=T2)
    q = 0.0015339808
    y = np.round(res.joint_angles[:, :1] / q) * q
    ms = [Measurement("enc", "joint_angle", 0, std=0.0, quantum=q)]
    s = EstimatorSettings(sample_period=T2, torque_noise=0.02, modal_noise=0.01)
    r = estimate_recording(model, res.t, volts[:, None], y, ms, s, q0=np.zeros(model.nq))
    err = r.tip_deflections[:, 0] - res.tip_deflections[:, 0]
    assert np.sqrt(np.mean(err ** 2)) < 0.05 * np.abs(res.tip_deflections[:, 0]).max()


def test_the_tip_pose_and_its_covariance():
    """Planar: the orientation is the tip tangent's yaw (FlexArmModel.tip_pose), the 6 x 6
    pose covariance holds the position's 3 x 3 and, on the yaw, the variance of
    alpha + gamma_tip; a finite-difference check of the pose Jacobian."""
    model = _link()
    est = _estimator(model)
    q0 = model.q_from_joint_angles([0.3], flex=np.array([0.01, 0.004]))
    est.reset(q0)
    s = est.step(np.zeros(1), np.array([0.3, 0.01]))
    phi = model.tip_pose(s.q)[2]
    assert np.allclose(s.tip_orientation, [0, 0, np.sin(phi / 2), np.cos(phi / 2)])
    C = s.tip_pose_cov
    assert np.allclose(C[:3, :3], s.tip_position_cov, rtol=1e-12, atol=0)
    e = np.zeros(model.nq)
    for k in range(model.nq):
        dq = np.zeros(model.nq)
        dq[k] = 1e-7
        e[k] = (model.tip_pose(s.q + dq)[2] - model.tip_pose(s.q - dq)[2]) / 2e-7
    Pq = s.state_cov[:model.nq, :model.nq]
    assert C[5, 5] == pytest.approx(e @ Pq @ e, rel=1e-6)
    assert np.all(np.linalg.eigvalsh(0.5 * (C + C.T)) > -1e-15)


def test_spatial_noise_per_bending_plane_and_twist():
    """The spatial link-tip force noise per bending plane ((n_links, 2): v, w) and the tip
    twist moment: each std^2 on its own tip variable and nowhere else (a scalar: both
    planes alike, no twist); bad shapes are refused in one line."""
    from pathlib import Path
    from flex_model.spatial.dynamics import SpatialArmModel
    from flex_model.spatial.loader import load_spatial_arm
    arm = Path(__file__).resolve().parents[3] / "test" / "data" / "spatial_independent"
    model = SpatialArmModel(load_spatial_arm(arm / "arm.yaml"))
    ms = [Measurement(f"q{i + 1}", "joint_angle", i, std=1e-5) for i in range(2)]

    def force_cov(**kw):
        est = Estimator(model, ms, EstimatorSettings(torque_noise=0.0, **kw))
        N, W = est._noise_input()
        return (N * W) @ N.T, est.plant
    C, plant = force_cov(modal_noise=[[0.5, 0.02], [0.3, 0.01]], twist_noise=[0.004, 0.0])
    D = plant.deflection_map()   # rows: link-major v, w, twist of the tip
    tip = [int(np.flatnonzero(row)[0]) for row in D]
    expect = [0.5, 0.02, 0.004, 0.3, 0.01, 0.0]
    assert np.allclose(np.diag(C)[tip], np.square(expect), rtol=1e-12, atol=0)
    assert np.count_nonzero(C) == 5 and np.count_nonzero(C - np.diag(np.diag(C))) == 0
    C1, _ = force_cov(modal_noise=0.5)
    assert np.allclose(np.diag(C1)[tip], np.square([0.5, 0.5, 0, 0.5, 0.5, 0]))
    with pytest.raises(ValueError, match="modal_noise: got shape"):
        force_cov(modal_noise=[[0.5, 0.1, 0.1], [0.5, 0.1, 0.1]])
    with pytest.raises(ValueError, match="twist_noise: planar"):
        Estimator(_link(), ms[:1], EstimatorSettings(twist_noise=0.1))._noise_input()


def _friction_change_run(c, t1=1.5, t2=2.5, seed=3):
    """The link under a 1 Hz torque (1 N m) and a small random one, a viscous joint
    friction c appearing at t1 (dopri5 in two parts): (times, torques, readings)."""
    rng = np.random.default_rng(seed)
    n = int(round(t2 / T))
    t = np.arange(n + 1) * T
    taus = np.sin(2 * np.pi * t) + rng.normal(0.0, 0.05, n + 1)
    pol = [lambda tt, x, k0=k0: np.array([taus[min(int(round(tt / T)) + k0, n)]])
           for k0 in (0, int(round(t1 / T)))]
    a = simulate(_link(), np.zeros(_link().nq), t_final=t1, sample_period=T, policy=pol[0],
                 control_period=T)
    m2 = _link(effects=[{"type": "joint_friction", "joint": _link().arm.joint_names[0],
                         "viscous": c}])
    b = simulate(m2, a.q[-1], a.v[-1], t_final=t2 - t1, sample_period=T, policy=pol[1],
                 control_period=T)
    q = np.concatenate([a.joint_angles[:, 0], b.joint_angles[1:, 0]])
    w = np.concatenate([a.tip_deflections[:, 0], b.tip_deflections[1:, 0]])
    y = np.column_stack([q + rng.normal(0, 1e-4, n + 1), w + rng.normal(0, 1e-3, n + 1)])
    return t, taus, y


def test_covariance_resetting_follows_a_friction_change():
    """A viscous friction of 0.5 N m s/rad appears at 1.5 s; the filter adapts it with a
    small random walk (0.01 per sqrt(s)). With covariance resetting (the NIS per reading
    over 0.2 s above 2) it is within 10 % 1 s after the change (0.529 measured); without,
    the same walk leaves it at 64 % (0.322: the walk cannot move it); no reset before."""
    c, t1 = 0.5, 1.5
    t, taus, y = _friction_change_run(c, t1)
    ms = [Measurement("q1", "joint_angle", 0, std=1e-4),
          Measurement("w1", "tip_deflection", 0, std=1e-3)]
    out = {}
    for thr in (0.0, 2.0):
        s = EstimatorSettings(sample_period=T, torque_noise=0.05, modal_noise=0.02,
                              adapt=("viscous_friction:0",),
                              adapt_std={"viscous_friction:0": 1.0},
                              adapt_walk={"viscous_friction:0": 0.01}, adapt_reset_nis=thr)
        est = Estimator(_link(), ms, s)
        est.reset(np.zeros(est.plant.nq))
        fv = [est.step([u], yy).parameters["viscous_friction:0"] for u, yy in zip(taus, y)]
        out[thr] = (fv[-1], est.resets)
    assert t[-1] == pytest.approx(t1 + 1.0)
    assert out[2.0][0] == pytest.approx(c, rel=0.10)
    assert out[0.0][0] < 0.7 * c
    assert out[2.0][1] and min(out[2.0][1]) > t1 and not out[0.0][1]


def test_horizon_fit_follows_a_friction_change():
    """The same change, the viscous friction fitted by least squares on the actuator row's
    momentum balance over the last 0.5 s (blocks of 0.05 s) instead of a random walk: near
    0 before the change once the filter has settled (0.59 in the first 0.1 s from its zero
    start, then below 0.01), within 5 % of 0.5 N m s/rad 1 s after it (0.501 measured;
    0.5 s of data after the change fill the window); the filter considers it (no gain
    moves it: it changes only at blocks' ends) and its std is the fit's (0.0075). The fit
    alone: adapt_spread 0 (with the default the fit's moves widen the band, and here its
    jitter before the change too: the joint rate's std 5 x, the settled fit 0.025 against
    0.008; docs/estimation.md)."""
    c, t1 = 0.5, 1.5
    t, taus, y = _friction_change_run(c, t1)
    ms = [Measurement("q1", "joint_angle", 0, std=1e-4),
          Measurement("w1", "tip_deflection", 0, std=1e-3)]
    s = EstimatorSettings(sample_period=T, torque_noise=0.05, modal_noise=0.02,
                          adapt=("viscous_friction:0",), adapt_horizon=0.5,
                          adapt_block=0.05, adapt_spread=0.0)
    est = Estimator(_link(), ms, s)
    est.reset(np.zeros(est.plant.nq))
    out = [est.step([u], yy) for u, yy in zip(taus, y)]
    fv = np.array([o.parameters["viscous_friction:0"] for o in out])
    sd = np.array([o.parameter_std["viscous_friction:0"] for o in out])
    settled = (t > 0.3) & (t < t1)
    assert np.abs(fv[settled]).max() < 0.05 * c
    assert fv[-1] == pytest.approx(c, rel=0.05)
    assert np.count_nonzero(np.diff(fv)) <= len(t) // int(round(0.05 / T))
    assert 0 < sd[-1] < 0.05 * c
    with pytest.raises(ValueError, match="adapt_horizon"):
        EstimatorSettings(adapt_horizon=1.0, adapt_reset_nis=2.0)
