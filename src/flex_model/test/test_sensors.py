"""Sensors: zero noise is the truth, bias shifts, gain scales, delay is late, quantisation
rounds; the accelerometer and the strain gauge against closed forms."""
import numpy as np
import pytest

from flex_model.arm import arm_from_dict, load_arm
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_model.sensors import Sensor, measure, tip_gauge, true_signal
from flex_model.simulate import JointPD, Pulse, simulate
from flex_model.statics import TipLoad, static_equilibrium


@pytest.fixture(scope="module")
def run():
    model = FlexArmModel(load_arm("thesis_example1", 4))
    th0 = np.array([0.2, -0.3])
    res = simulate(model, model.q_from_joint_angles([0.0, 0.0]), t_final=0.5,
                   sample_period=1e-3, pd=JointPD([300.0, 100.0], [10.0, 5.0], th0),
                   rtol=1e-10)
    return res


def test_encoder_without_noise_is_the_truth_and_bias_shifts(run):
    t, y = measure(Sensor("e", "joint_encoder", "joint2"), run)
    np.testing.assert_array_equal(y[:, 0], run.joint_angles[:, 1])
    t, yb = measure(Sensor("e", "joint_encoder", "joint2", bias=0.01), run)
    np.testing.assert_allclose(yb - y, 0.01, rtol=1e-12)


def test_tip_deflection_gauge_reads_gain_times_the_deflection(run):
    """A tip_deflection sensor of gain 0.5 and bias 1 mm on link 2: 0.5 d_tip + 0.001."""
    t, y = measure(Sensor("g", "tip_deflection", "link2", gain=0.5, bias=1e-3), run)
    np.testing.assert_allclose(y[:, 0], 0.5 * run.tip_deflections[:, 1] + 1e-3, rtol=1e-12)
    assert np.ptp(run.tip_deflections[:, 1]) > 1e-4   # the arm does deflect


def test_delay_returns_the_signal_late(run):
    t, y = measure(Sensor("e", "joint_encoder", "joint1", delay=0.02), run)
    k = int(round(0.02 / 1e-3))
    np.testing.assert_allclose(y[k:, 0], run.joint_angles[:-k, 0], rtol=1e-12, atol=1e-15)


def test_delayed_interpolates_and_holds_the_first_sample():
    """delayed(t, x, 0.25) of the ramp x = 2t on a 0.1 s grid: 2 (t - 0.25) between the
    samples, x[0] held before t = 0.25; columns kept; delay 0 is x itself; the tip gauge
    of an arm without one is exact."""
    from flex_model.sensors import delayed
    t = np.arange(0.0, 1.01, 0.1)
    x = np.column_stack([2 * t, -t])
    y = delayed(t, x, 0.25)
    np.testing.assert_allclose(y[3:], np.column_stack([2 * (t[3:] - 0.25), -(t[3:] - 0.25)]),
                               atol=1e-12)
    np.testing.assert_array_equal(y[:3], 0.0)
    assert delayed(t, x[:, 0], 0.25).shape == t.shape
    np.testing.assert_array_equal(delayed(t, x, 0.0), x)
    gauge = tip_gauge(load_arm("quanser_cuboulder_flexible"))
    assert (gauge.gain, gauge.delay) == (1.0, 0.0)


def test_quantisation_and_noise(run):
    t, y = measure(Sensor("e", "joint_encoder", "joint1", resolution=2 * np.pi / 4096), run)
    steps = y[:, 0] / (2 * np.pi / 4096)
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-9)
    assert np.max(np.abs(y[:, 0] - run.joint_angles[:, 0])) <= np.pi / 4096 + 1e-15
    t, yn = measure(Sensor("e", "joint_encoder", "joint1", noise=1e-3), run, seed=4)
    r = yn[:, 0] - run.joint_angles[:, 0]
    assert np.std(r) == pytest.approx(1e-3, rel=0.1) and abs(np.mean(r)) < 2e-4


def test_accelerometer_reads_minus_gravity_at_rest_and_centripetal_when_spinning():
    arm = arm_from_dict({"name": "stiff", "links": [{"length": 0.5, "section": {
        "shape": "explicit", "EI": 1e6, "m": 1.0}}], "gravity": [0.0, -9.81]})
    model = FlexArmModel(arm)
    q0 = static_equilibrium(model, joints="pd", kp=1e9).q  # balanced: truly at rest
    res = simulate(model, q0, t_final=0.01, sample_period=1e-3,
                   pd=JointPD([1e9], [0.0], [0.0]), method="fixed", dt=1e-4)
    f = true_signal(Sensor("a", "tip_accelerometer"), res)
    phi = model.tip_pose(q0)[2]  # the tip tangent of the sagging link
    np.testing.assert_allclose(f[-1], [9.81 * np.sin(phi), 9.81 * np.cos(phi)], atol=1e-9)
    spin = FlexArmModel(arm.without_gravity())
    w = 3.0
    res = simulate(spin, np.zeros(spin.nq), spin.v_from_joint_rates([w]), t_final=0.02,
                   sample_period=1e-3, method="fixed", dt=1e-5)
    f = true_signal(Sensor("a", "tip_accelerometer"), res)
    # centripetal acceleration w^2 (L - u) towards the joint; the stiff link barely bends
    np.testing.assert_allclose(f[:, 0], -w * w * 0.5, rtol=1e-4)


def test_strain_gauge_of_a_cantilever_under_a_tip_force():
    """epsilon(z) = -c F (L - z) / EI for a tip force F (Euler-Bernoulli, exact)."""
    arm = load_arm("thesis_example1", 4).without_gravity()
    model = FlexArmModel(arm)
    F = 2.0
    r = static_equilibrium(model, joints="clamped", load=TipLoad(force=(0.0, F)), linear=True)
    res = simulate(model, r.q, t_final=0.002, sample_period=1e-3,
                   pulses=[Pulse(0.0, 1.0, (), (0.0, F))], pd=JointPD([1e12, 1e12], [0, 0],
                                                                     [0, 0]),
                   method="fixed", dt=1e-6)
    ei = arm.links[1].segments[0].properties(0.0)[0]
    c = 0.01
    eps = true_signal(Sensor("g", "strain_gauge", "link2", position=0.7,
                             surface_distance=c), res)
    assert eps[0, 0] == pytest.approx(-c * F * (2.0 - 0.7) / ei, rel=1e-8)
    eps1 = true_signal(Sensor("g", "strain_gauge", "link1", position=0.3,
                              surface_distance=c), res)
    assert eps1[0, 0] == pytest.approx(-c * F * (4.0 - 0.3) / ei, rel=1e-8)


def test_sensors_in_the_arm_description():
    data = {"name": "s", "links": [{"length": 1.0, "section": {"shape": "explicit",
                                                               "EI": 1.0, "m": 1.0}}],
            "sensors": [{"kind": "joint_encoder", "joint": "joint1", "resolution": 0.001},
                        {"kind": "strain_gauge", "link": "link1", "position": 0.2,
                         "surface_distance": 0.005}]}
    arm = arm_from_dict(data, "arm.yaml")
    assert [s.kind for s in arm.sensors] == ["joint_encoder", "strain_gauge"]
    assert arm.sensors[0].resolution == 0.001 and arm.sensors[1].name == "link1/strain_gauge"
    assert tip_gauge(arm).gain == 1.0
    data["sensors"].append({"kind": "tip_deflection", "link": "link1", "gain": 0.45})
    assert tip_gauge(arm_from_dict(data, "arm.yaml")).gain == 0.45
    data["sensors"][-1]["gain"] = 0.0
    with pytest.raises(ConfigError, match=r"arm.yaml: sensors\[2\].gain: got 0"):
        arm_from_dict(data, "arm.yaml")
    data["sensors"].pop()
    data["sensors"][0]["joint"] = "joint7"
    with pytest.raises(ConfigError, match=r"arm.yaml: sensors\[0\].joint: got 'joint7'"):
        arm_from_dict(data, "arm.yaml")


def test_a_tip_gauge_entry_is_found_or_declared_exact_in_place():
    """tip_gauge_entry: the link's declared tip_deflection entry itself (fields kept), else a
    new exact one appended; other links' and other kinds' entries untouched."""
    from flex_model.sensors import tip_gauge_entry
    sensors = [{"kind": "joint_encoder", "joint": "j1"},
               {"kind": "tip_deflection", "link": "link2", "delay": 0.05}]
    assert tip_gauge_entry(sensors, "link2") is sensors[1] and sensors[1]["delay"] == 0.05
    new = tip_gauge_entry(sensors, "link1")
    assert new == {"name": "tip_gauge", "kind": "tip_deflection", "link": "link1"}
    assert len(sensors) == 3 and sensors[2] is new


def test_with_tip_gauge_replaces_the_declared_gauge_or_adds_an_exact_one():
    """with_tip_gauge: a declared gauge gets the new field and keeps the others, in one
    sensor, not two; without one an exact gauge with that field is added."""
    import dataclasses
    from flex_model.arm import load_arm
    from flex_model.sensors import Sensor, declared_tip_gauge, with_tip_gauge
    arm = load_arm("quanser_cuboulder_calibrated")
    n = len(arm.sensors)
    lagged = with_tip_gauge(arm, "link1", gain=0.7)
    g = declared_tip_gauge(lagged, "link1")
    assert (g.gain, g.delay, g.name) == (0.7, 0.03741, "tip_gauge") and len(lagged.sensors) == n
    bare = dataclasses.replace(arm, sensors=tuple(s for s in arm.sensors
                                                  if s.kind != "tip_deflection"))
    new = declared_tip_gauge(with_tip_gauge(bare, "link1", delay=0.05), "link1")
    assert new == Sensor("tip_gauge", "tip_deflection", "link1", delay=0.05)
    assert len(with_tip_gauge(bare, "link1", delay=0.05).sensors) == n
