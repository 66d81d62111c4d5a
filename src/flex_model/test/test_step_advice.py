"""The step and variables advice (flex_model.step_advice.estimate_error through
Scenario.advice and SpatialScenario.advice, issue 47): it warns where a run was measured
more than 2 % off an independent converged run (a much smaller step, more variables) and
is quiet where the run was within 1 %, planar and spatial (bench/bench_step_advice.py
runs the sweep of the acceptance).
"""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from flex_model.arm import PRESET_DIR
from flex_model.config import read_yaml
from flex_model.scenario import scenario_from_dict
from flex_model.spatial.scenario import load_spatial_scenario
from flex_model.step_advice import ErrorEstimate, error_warning, estimate_error, tip_error


def _tapered(nv: int, step: float, duration: float = 0.3):
    """Thesis Example 4 (tapered steel links) with a 10 kg payload, a 10 deg step."""
    arm = read_yaml(PRESET_DIR / "thesis_example4.yaml")
    arm["payload"] = {"mass": 10.0, "inertia": 0.05}
    return scenario_from_dict({
        "name": "tapered_payload", "arm": arm, "vars_per_link": nv,
        "duration": duration, "sample_period": 5e-3,
        "initial": {"joint_angles_deg": [0.0, 0.0], "state": "static"},
        "control": {"pd": {"kp": [2.0e4, 5.0e3], "kd": [2.0e3, 5.0e2]},
                    "setpoint_schedule": [{"time": 0.05, "setpoints_deg": [10.0, 0.0]}]},
        "integrator": {"method": "fixed", "step": step}})


def _spatial(step: float, nv: int = 2, duration: float = 0.3):
    assert nv in (2, 4)
    """seed003_like_pd_step, shortened (its pulse moved to 0.2-0.25 s)."""
    sc = load_spatial_scenario("seed003_like_pd_step")
    pulse = dataclasses.replace(sc.pulses[0], start=0.2, end=0.25)
    sc = dataclasses.replace(sc, duration=duration, step=step, pulses=(pulse,))
    return sc.with_finer_variables() if nv == 4 else sc


def test_the_estimate_is_the_distance_to_the_refined_run():
    """x(d, f) = x* + c / d^2 + e / f^2 (step divided by d, variables times f): the
    total is the distance of x(1, 1) to x(4, 2), per link as a share of its largest."""
    t = np.linspace(0.0, 1.0, 40)
    exact = np.column_stack([np.sin(3 * t), 0.01 * t])
    c, e = np.array([0.02, 1e-4]), np.array([0.01, 3e-4])
    est = estimate_error(lambda d, f: exact + c / d ** 2 + e / f ** 2, window=1.0)
    ref = exact + c / 16 + e / 4
    scale = np.abs(ref).max(axis=0)
    assert est.total == pytest.approx(np.max((15 / 16 * c + 3 / 4 * e) / scale), rel=1e-12)
    assert est.step_error == pytest.approx(np.max(15 / 16 * c / np.abs(exact + c / 16 + e)
                                                  .max(axis=0)), rel=1e-12)
    assert tip_error(ref, ref) == 0.0
    quiet = ErrorEstimate(0.014, 0.01, 0.004, 1.0, 0.1)
    assert error_warning(quiet, 1e-3, "4 variables per link") is None
    loud = ErrorEstimate(0.08, 0.04, 0.04, 1.0, 0.1)
    msg = error_warning(loud, 1e-3, "4 variables per link")
    assert "about 8 % off" in msg and "a step of 0.00025 s or less" in msg and \
        "4x the variables" in msg


def _measured(make, fine):
    """The run's tip error against an independent converged run ``fine``."""
    return tip_error(make.run(advise=False).tip_deflections,
                     fine.run(advise=False).tip_deflections)


def test_planar_warns_where_the_run_is_off_and_is_quiet_where_it_is_not():
    """Tapered two-link arm with payload: 2 variables per link at 5 ms are more than 2 %
    off a 1/8 ms run with 8 variables (4.7 % over 0.5 s in the bench); 4 variables at
    1.25 ms are within 1.2 %... and 8 at 1.25 ms within 1 %."""
    fine = _tapered(8, 1.25e-3 / 8)
    off, ok = _tapered(2, 5e-3), _tapered(8, 1.25e-3)
    assert _measured(off, fine) > 0.02
    assert _measured(ok, fine) < 0.01
    adv = off.advice()
    assert adv.warning is not None and adv.estimate.total > 0.015
    assert "2 variables per link" in adv.warning
    assert ok.advice().warning is None
    with pytest.warns(UserWarning):     # Scenario.run gives the same line in Python
        off.run()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ok.run()


def test_spatial_warns_where_the_run_is_off_and_is_quiet_where_it_is_not():
    """seed003_like_pd_step: 2.5 ms is more than 2 % off a 1/32 ms run with 4 variables
    per plane (12.5 % in the bench), 0.3125 ms within 1 %."""
    fine = _spatial(2.5e-3 / 32, nv=4)
    ref = fine.tips()
    off, ok = _spatial(2.5e-3), _spatial(3.125e-4)
    assert tip_error(off.tips(), ref) > 0.02
    assert tip_error(ok.tips(), ref) < 0.01
    warning, est = off.advice()
    assert warning is not None and "variables per bending plane" in warning
    assert est.total > 0.015 and est.cost_s > 0
    assert ok.advice()[0] is None
