"""The step and variables advice (flex_model.step_advice.estimate_error through
Scenario.advice on planar and spatial arms, issue 47): it warns where a run was measured
more than 2 % off an independent converged run (a much smaller step, more variables) and
is quiet where the run was within 1 %, planar and spatial (bench/bench_step_advice.py
runs the sweep of the acceptance).
"""
from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from flex_model.scenario import scenario_from_dict
from flex_model.scenario import load_scenario
from flex_model.step_advice import ErrorEstimate, error_warning, estimate_error, tip_error


def _sag(nv: int, step: float, kinematics: str = "small_deflection", duration: float = 0.5):
    """A 1 m aluminium tube (20 x 1 mm, 0.2 kg at its tip) on a heavy hub (2 kg m^2) held
    by a PD, started undeformed and horizontal: it sags (bench/bench_step_advice.py)."""
    arm = {"name": "sag_heavy_hub", "gravity": [0.0, -9.81],
           "links": [{"name": "link1", "length": 1.0,
                      "material": {"E": 6.4e10, "rho": 2700.0},
                      "section": {"shape": "square_hollow", "side": 0.020, "wall": 0.001},
                      "variables": 2, "end_masses": {"J_minus": 2.0, "M_plus": 0.2}}],
           "joints": [{"name": "joint1"}]}
    return scenario_from_dict({
        "name": "sag", "arm": arm, "vars_per_link": nv, "kinematics": kinematics,
        "duration": duration, "sample_period": 1e-2,
        "control": {"pd": {"kp": [500.0], "kd": [100.0]}},
        "integrator": {"method": "fixed", "step": step}})


def _spatial(step: float, nv: int = 2, duration: float = 0.2):
    """seed003_like_pd_step, shortened to its set-point step (at 0.1 s, no pulse)."""
    assert nv in (2, 4)
    sc = dataclasses.replace(load_scenario("seed003_like_pd_step"),
                             duration=duration, step=step, pulses=())
    return sc.with_finer_variables() if nv == 4 else sc


def test_the_estimate_is_the_distance_to_the_refined_run():
    """x(d, f) = x* + c / d^2 + e / f^2 (step divided by d, variables times f): the
    total is the distance of x(1, 1) to x(4, 2), per link as a share of its largest."""
    t = np.linspace(0.0, 1.0, 40)
    exact = np.column_stack([np.sin(3 * t), 0.1 * t])
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
        "2x the variables" in msg


def test_planar_warns_where_the_run_is_off_and_is_quiet_where_it_is_not():
    """The sagging link: 5 ms is more than 2 % off a 1/8 ms run with 8
    variables (4.4 %), 1.25 ms within 1 %; Scenario.run gives the same line in Python."""
    ref = _sag(8, 1.25e-3 / 8).run(advise=False).tip_deflections
    off, ok = _sag(2, 5e-3), _sag(2, 1.25e-3)
    assert tip_error(off.run(advise=False).tip_deflections, ref) > 0.02
    assert tip_error(ok.run(advise=False).tip_deflections, ref) < 0.01
    adv = off.advice()
    assert adv.warning is not None and adv.estimate.total > 0.015
    assert "2 variables per link" in adv.warning and "for 2 % use a step of" in adv.warning
    assert ok.advice().warning is None
    with pytest.warns(UserWarning) as record:
        off.run()
    assert [str(w.message) for w in record][0].startswith("the tip deflections are about")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        ok.run()


def test_spatial_warns_where_the_run_is_off_and_is_quiet_where_it_is_not():
    """seed003_like_pd_step: 2.5 ms is more than 2 % off a 1/16 ms run with 4 variables
    per plane (12.6 % over 0.5 s in the bench), 0.625 ms within 1 %."""
    ref = _spatial(2.5e-3 / 16, nv=4).run(advise=False).tip_deflections
    off, ok = _spatial(2.5e-3), _spatial(6.25e-4)
    assert tip_error(off.run(advise=False).tip_deflections, ref) > 0.02
    assert tip_error(ok.run(advise=False).tip_deflections, ref) < 0.01
    adv = off.advice()
    assert adv.warning is not None and "variables per bending plane" in adv.warning
    assert adv.estimate.total > 0.015 and adv.estimate.cost_s > 0
    assert ok.advice().warning is None


def test_the_variable_step_mode_is_checked_with_a_finer_rtol():
    """The sagging link with 4 variables, variable step: rtol 1e-2 is 39 % off the fine
    fixed-step run, rtol 1e-3 within 0.2 % (bench/bench_step_advice.py --variable)."""
    ref = _sag(8, 1.25e-3 / 8).run(advise=False).tip_deflections
    off, ok = (dataclasses.replace(_sag(4, 1e-3), method="variable", rtol=r)
               for r in (1e-2, 1e-3))
    assert tip_error(off.run(advise=False).tip_deflections, ref) > 0.02
    assert tip_error(ok.run(advise=False).tip_deflections, ref) < 0.01
    warning = off.advice().warning
    assert warning is not None and "at rtol 0.01" in warning and "use rtol" in warning
    assert ok.advice().warning is None
