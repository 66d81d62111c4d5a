"""The step advice (flex_model.step_advice) on issue 24's hub-less two-link arm
(bench/bench_stiff_hubless.py: thesis Example 1 without hub inertia, second_order, PD
625 / 176.8, a 15 deg set-point step on joint 2): it warns where a fixed step was measured
more than 1 % off a converged run (1/32 ms) and is quiet where it was within 1 %.

Measured (tip deflections of links 1 / 2 over 0.3 s, % of each link's largest; with
today's consistent restart at the step / with the filtered one of
integrators.restart_acceleration):
16 variables per link at 0.125 ms: 181 / 685 % / 0.06 / 0.16 %; 8 variables at 1 ms:
Newton fails / 0.34 / 1.38 %; 8 variables at 0.125 ms: 0.09 / 0.36 % / 0.04 / 0.23 %;
4 variables at 0.25 ms: 0.04 / 0.51 % / 0.08 / 0.61 %.
"""
from __future__ import annotations

import pytest

from flex_model.scenario import scenario_from_dict


def _advice(nv: int, step: float):
    sc = scenario_from_dict({
        "name": "hubless", "arm": "thesis_example1", "vars_per_link": nv,
        "kinematics": "second_order", "duration": 0.3, "sample_period": 1e-3,
        "control": {"pd": {"kp": [625.0, 625.0], "kd": [176.8, 176.8]},
                    "setpoint_schedule": [{"time": 0.1, "setpoints_deg": [0.0, 15.0]}]},
        "integrator": {"method": "fixed", "step": step}})
    return sc.advice()


@pytest.mark.parametrize("nv, step, f_x", [(16, 1.25e-4, 6287.0), (8, 1e-3, 1706.0)])
def test_the_advice_warns_where_the_step_was_measured_off(nv, step, f_x):
    adv = _advice(nv, step)
    assert adv.highest_excited_mode_hz == pytest.approx(f_x, rel=1e-3)
    assert adv.warning is not None
    assert f"mode at {adv.highest_excited_mode_hz:.4g} Hz" in adv.warning
    assert f"step of {adv.step_needed_s:.2g} s or less" in adv.warning
    assert adv.step_needed_s == pytest.approx(0.25 / f_x, rel=1e-3)


@pytest.mark.parametrize("nv, step", [(8, 1.25e-4), (4, 2.5e-4)])
def test_the_advice_is_quiet_where_the_step_was_measured_within_1_percent(nv, step):
    adv = _advice(nv, step)
    assert adv.warning is None and adv.step_needed_s >= step


def test_scenario_run_warns_with_the_advice_in_python():
    """Scenario.run gives the advice as a UserWarning (users outside the CLI see it too),
    and not when the step resolves the arm or with advise=False (the CLI prints it)."""
    import warnings

    sc = scenario_from_dict({
        "name": "hubless", "arm": "thesis_example1", "vars_per_link": 4,
        "kinematics": "second_order", "duration": 0.002, "sample_period": 1e-3,
        "control": {"pd": {"kp": [625.0, 625.0], "kd": [176.8, 176.8]}},
        "integrator": {"method": "fixed", "step": 1e-3}})
    warning = sc.advice().warning
    assert warning is not None
    with pytest.warns(UserWarning) as record:
        sc.run()
    assert [str(w.message) for w in record] == [warning]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sc.run(advise=False)
        sc.step = 2.5e-4
        sc.run()
