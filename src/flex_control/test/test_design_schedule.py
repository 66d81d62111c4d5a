"""Cyclic coordinate ascent, the gain-scheduled design and the schedule file."""
import numpy as np
import pytest

from flex_model.config import ConfigError

from flex_control.closed_loop import (EigenSummary, NominalTrajectory, closed_loop_matrix,
                                      eigen_summary, open_loop_jacobian, pd_gains)
from flex_control.design import (DesignSettings, cyclic_coordinate_ascent, design_cost,
                                 design_schedule)
from flex_control.gain_schedule import SCHEDULE_FORMAT, GainSchedule

J2 = ("joint1", "joint2")


def test_cyclic_coordinate_ascent_finds_the_maximum_within_bounds():
    def f(x):   # concave in log coordinates, maximum at (3, 0.5, 7)
        return -np.sum((np.log(x) - np.log([3.0, 0.5, 7.0])) ** 2)

    res = cyclic_coordinate_ascent(f, [1.0, 1.0, 1.0], [0.1] * 3, [10.0] * 3)
    np.testing.assert_allclose(res.x, [3.0, 0.5, 7.0], rtol=0.01)
    bounded = cyclic_coordinate_ascent(f, [1.0, 1.0, 1.0], [0.1] * 3, [2.0, 10.0, 10.0])
    assert bounded.x[0] == 2.0 and bounded.x[1] == pytest.approx(0.5, rel=0.01)


def test_design_cost_prefers_any_stable_loop():
    stable = EigenSummary(zeta_min=0.05, tau_max=2.0, decay_rate=0.5)
    assert design_cost(stable) == pytest.approx(np.log(0.05) - np.log(2.0))
    assert design_cost(stable, tau_weight=0.0) == pytest.approx(np.log(0.05))
    worse = EigenSummary(zeta_min=-0.1, tau_max=np.inf, decay_rate=-0.3)
    less_bad = EigenSummary(zeta_min=-0.01, tau_max=np.inf, decay_rate=-0.01)
    tiny = EigenSummary(zeta_min=1e-12, tau_max=1e9, decay_rate=1e-9)
    assert design_cost(worse) < design_cost(less_bad) < design_cost(tiny)


@pytest.fixture(scope="module")
def design(section_f_model, section_f_quasi_static):
    return design_schedule(section_f_model, section_f_quasi_static,
                           DesignSettings(n_points=6))


def test_design_is_stabilizing_and_beats_the_thesis_constant_gains(
        design, section_f_model, section_f_quasi_static):
    model = section_f_model
    assert design.stabilizing and len(design.points) == 6
    nom = NominalTrajectory.from_data(model, section_f_quasi_static)
    kp25, kd25 = pd_gains(np.full(2, 25.0), np.full(2, 5.0))
    for p in design.points:
        assert np.all((0.01 <= p.h) & (p.h <= 100)) and np.all((0.1 <= p.a) & (p.a <= 20))
        q, v, tau, _, _ = nom.at(p.t)
        A0, Bu = open_loop_jacobian(model, q, v, tau)
        kp, kd = pd_gains(p.h, p.a)
        s = eigen_summary(closed_loop_matrix(A0, Bu, model.G, kp, kd))
        assert s.zeta_min == pytest.approx(p.zeta_min, rel=1e-9)
        # the optimum is at least as good as h = 25, a = 5 (thesis V.3) at every point
        s25 = eigen_summary(closed_loop_matrix(A0, Bu, model.G, kp25, kd25))
        assert p.cost >= design_cost(s25)
        assert p.zeta_min > 5 * s25.zeta_min and p.tau_max < s25.tau_max
    # the points are where the schedule says, at the nominal rigid coordinates
    np.testing.assert_allclose(design.schedule.t, np.linspace(0, 15, 6))
    np.testing.assert_allclose(design.schedule.theta[2], nom.at(6.0)[3])


def test_schedule_equals_designed_gains_at_the_points(design):
    sched = design.schedule
    for k, p in enumerate(design.points):
        h, a = sched.gains(sched.theta[k])
        np.testing.assert_array_equal(h, p.h)
        np.testing.assert_array_equal(a, p.a)


def test_schedule_interpolation_is_continuous_and_bounded(design):
    sched = design.schedule
    rng = np.random.default_rng(1)
    lo, hi = sched.theta.min(0) - 0.2, sched.theta.max(0) + 0.2
    h_rng = sched.h.max(0) - sched.h.min(0)
    for _ in range(200):
        th = rng.uniform(lo, hi)
        d = rng.normal(size=2)
        d *= 1e-7 / np.linalg.norm(d)
        h0, a0 = sched.gains(th)
        h1, a1 = sched.gains(th + d)
        assert np.all(np.abs(h1 - h0) <= 1e-3 * h_rng)       # no jumps
        assert np.all(h0 >= sched.h.min(0) - 1e-12) and np.all(h0 <= sched.h.max(0) + 1e-12)
        assert np.all(a0 >= sched.a.min(0) - 1e-12) and np.all(a0 <= sched.a.max(0) + 1e-12)
    # approaching a design point, the gains tend to its gains (continuity at the nodes)
    k = 3
    for eps in (1e-2, 1e-4, 1e-6):
        h, _ = sched.gains(sched.theta[k] + eps)
        assert np.max(np.abs(h - sched.h[k])) < 30 * eps * np.max(h_rng) / \
            np.min(np.linalg.norm(np.delete(sched.theta, k, 0) - sched.theta[k], axis=1))


def test_schedule_with_deflections():
    s = GainSchedule(joint_names=J2, theta=[[0.0, 0.0], [0.0, 0.0]], h=[[1, 1], [3, 3]],
                     a=[[1, 1], [1, 1]], deflections=[[0.0, 0.0], [0.1, 0.0]],
                     deflection_weight=10.0)
    np.testing.assert_allclose(s.gains([0, 0], [0.1, 0.0])[0], [3, 3])
    np.testing.assert_allclose(s.gains([0, 0], [0.05, 0.0])[0], [2, 2])
    with pytest.raises(ValueError, match="deflections: got 1 values; expected 2"):
        s.gains([0, 0], [0.1])


def test_schedule_yaml_round_trip(design, tmp_path):
    path = design.schedule.save(tmp_path / "schedule.yaml")
    back = GainSchedule.load(path)
    for name in ("theta", "h", "a", "t", "deflections"):
        np.testing.assert_array_equal(getattr(back, name), getattr(design.schedule, name))
    assert back.joint_names == J2 and back.info["arm"] == "thesis_example1"


def _write(tmp_path, text):
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return p


@pytest.mark.parametrize("body,match", [
    ("format: other\njoint_names: [a]\npoints: [{theta_rad: [0], h: [1], a: [1]}]",
     f"format: got 'other'; expected '{SCHEDULE_FORMAT}'"),
    (f"format: {SCHEDULE_FORMAT}\njoint_names: [a]\n"
     "points: [{theta_rad: [0], h: [1], a: [1]}, {theta_rad: [1], h: [0.0], a: [1]}]",
     r"points\[1\]\.h\[0\]: got 0\.0; expected a gain > 0"),
    (f"format: {SCHEDULE_FORMAT}\njoint_names: [a, b]\npoints: [{{theta_rad: [0], h: [1, 1], "
     "a: [1, 1]}]", r"points\[0\]\.theta_rad: got \[0\]; expected a list of 2 numbers"),
    (f"format: {SCHEDULE_FORMAT}\njoint_names: [a]\npoints: [{{theta_rad: [0], h: [1], "
     "a: [1], gain: 3}]", r"points\[0\]\.gain: got 3; expected no such field"),
    (f"format: {SCHEDULE_FORMAT}\njoint_names: [a]\ninterpolation: "
     "{deflection_weight_rad_per_m: 2}\npoints: [{theta_rad: [0], h: [1], a: [1]}]",
     "interpolation.deflection_weight_rad_per_m: got 2.0; expected 0 unless every point"),
    (f"format: {SCHEDULE_FORMAT}\njoint_names: [a]\npoints: []",
     r"points: got \[\]; expected a list with at least 1 entries"),
])
def test_schedule_file_errors_name_the_field(tmp_path, body, match):
    with pytest.raises(ConfigError, match=match) as err:
        GainSchedule.load(_write(tmp_path, body))
    assert str(tmp_path / "s.yaml") in str(err.value)
