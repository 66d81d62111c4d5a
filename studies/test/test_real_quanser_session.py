"""Issue 22: what the sessions' friction spread costs a twin of fixed levels, on the
issue's run (../shared; skips with a reason when absent)."""
import dataclasses

import numpy as np
import pytest

from flex_model.dynamics import FlexArmModel
from flex_twin.real_arms import quanser_data as qd
from flex_twin.real_arms.quanser_twin import calibrated_arm_for
from flex_twin.real_arms.replay import replay
from studies.session_friction import choice_end, compare, with_stick_slip
from studies.stick_slip_study import hold_stick_spread

state_feedback = pytest.importorskip("flex_control.state_feedback")


def _issue_run(root):
    path = next(p for p in qd.cuboulder_files(root) if p.name == "flexarm_k1k2_6_-3")
    return qd.read_cuboulder_file(path)


def test_the_first_step_chooses_the_sessions_friction_and_the_rest_of_the_run_follows(
        cuboulder_root):
    """flexarm_k1k2_6_-3: the lab hub sticks 35-65 mrad short after its steps. The
    stick-slip twin of the link fit's levels (F_c 0.04, F_s 0.055 N m) reaches the
    reference and scores 0.0560 rad hub RMS after the first step. Chosen on the first step
    (0-3.07 s) alone, F_c is 0.08 N m, and on the rest of the run, which the choice did not
    see, hub RMS 0.0251 rad and tip RMS 3.27 mm (fixed: 4.44 mm)."""
    run = _issue_run(cuboulder_root)
    row = compare(calibrated_arm_for("cuboulder", "flexible"), run, 0.04, 0.055)
    assert row["scored_from_s"] == pytest.approx(run.t[choice_end(run)]) == \
        pytest.approx(3.074)
    assert row["session_coulomb"] == 0.08
    table = row["choice_table"]
    assert min(table.values()) == table["0.08"] < 0.5 * table["0.04"]
    assert row["calibrated"]["hub_rms_rad"] == pytest.approx(0.0555, abs=1e-3)
    assert row["fixed"]["hub_rms_rad"] == pytest.approx(0.0560, abs=1e-3)
    assert row["session"]["hub_rms_rad"] == pytest.approx(0.0251, abs=1e-3)
    assert row["fixed"]["tip_rms_m"] == pytest.approx(4.44e-3, abs=1e-4)
    assert row["session"]["tip_rms_m"] == pytest.approx(3.27e-3, abs=1e-4)


def test_where_the_twin_sticks_moves_by_tens_of_milliradians_with_a_tenth_more_friction(
        cuboulder_root):
    """Why a fixed twin misses the holds: on the issue's run the lab stops 65, 35, 65, 38
    mrad short; the stick-slip twin (F_s = F_c) stops 57-72 mrad short at F_c 0.08 N m and
    72-95 mrad at 0.09 (+12 %), a shift of 15-24 mrad per hold. To place the holds within
    10 mrad a twin needs the session's level to a few per cent, while the levels that the
    held-out runs' first steps choose range over 0.02-0.09 N m."""
    run = _issue_run(cuboulder_root)
    arm = calibrated_arm_for("cuboulder", "flexible")
    holds = {}
    for fc in (0.08, 0.09):
        r = replay(FlexArmModel(with_stick_slip(arm, coulomb=fc, static=fc)), run,
                   state_feedback.lab_policy_factory)
        twin = dataclasses.replace(run, theta=r.twin_theta)
        holds[fc] = np.array(hold_stick_spread(twin)["offsets_rad"])
    np.testing.assert_allclose(hold_stick_spread(run)["offsets_rad"],
                               [0.065, -0.035, 0.065, -0.038], atol=1e-3)
    np.testing.assert_allclose(holds[0.08], [0.057, -0.066, 0.070, -0.072], atol=2e-3)
    shift = np.abs(holds[0.09]) - np.abs(holds[0.08])
    assert np.all(shift > 0.014) and np.all(shift < 0.026)


def test_a_run_too_short_after_its_second_step_is_not_scored(cuboulder_root):
    """flexarm_K1K2K3_6_-3_213 steps at 4.06 and 9.06 s of 10 s: 0.94 s after the second
    step, less than one 2.5 s hold, mostly the step's transient: no session score."""
    path = next(p for p in qd.cuboulder_files(cuboulder_root)
                if p.name == "flexarm_K1K2K3_6_-3_213")
    with pytest.raises(ValueError, match="0.94 s after its step 2"):
        choice_end(qd.read_cuboulder_file(path))


def test_a_constant_hub_torque_chosen_on_the_first_period_places_both_directions(
        cuboulder_root):
    """flexarm_K1K2_6_-5 stops 59 and 65 mrad short after its up-steps, 15 and 28 after its
    down-steps. Chosen on its first period (0-6.185 s, one up- and one down-step) F_c alone
    (0.07 N m) leaves 0.0192 rad hub RMS on the rest; F_c with a voltage offset (0.07 N m,
    -0.15 V = -24 mN m at the hub) 0.0085 rad, under the aim (fixed levels: 0.062)."""
    path = next(p for p in qd.cuboulder_files(cuboulder_root) if p.name == "flexarm_K1K2_6_-5")
    row = compare(calibrated_arm_for("cuboulder", "flexible"), qd.read_cuboulder_file(path),
                  0.04, 0.055, steps=2, offsets=(-0.2, -0.15, -0.1, 0.0),
                  levels=(0.06, 0.07, 0.08))
    assert row["scored_from_s"] == pytest.approx(6.185, abs=1e-3)
    assert (row["session_coulomb"], row["session_offset_coulomb"]) == (0.07, 0.07)
    assert row["session_offset_V"] == -0.15
    assert row["fixed"]["hub_rms_rad"] == pytest.approx(0.0618, abs=1e-3)
    assert row["session"]["hub_rms_rad"] == pytest.approx(0.0192, abs=1e-3)
    assert row["session_offset"]["hub_rms_rad"] == pytest.approx(0.0085, abs=5e-4)
