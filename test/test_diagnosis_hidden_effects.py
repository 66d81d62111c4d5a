"""The synthetic cases of the diagnosis (issue 8): generator checks and an acceptance subset.

Generator: the nominal closed loop tracks its reference; the noise has the statistics asked
for; a hidden effect of known size changes the recording by the closed-form amount;
the files the diagnosis reads hold no truth. Acceptance: the diagnosis on a fixed-seed
subset meets the issue's targets and shows its mechanisms (pair check, stop rule, later
round under the gate, backlash refinement): the acceptance tier, which ``make test`` skips
and ``python bench/bench_acceptance.py`` runs (FLEX_TWIN_ACCEPTANCE=on; =full adds the
costliest five, :data:`EXTENDED`).
"""
from __future__ import annotations

import csv
import json
import os

import numpy as np
import pytest
import yaml

from flex_model.arm import load_arm
from flex_twin.diagnosis.controller import controller_from_dict, load_controller
from flex_twin.diagnosis.synthetic import (CASE_KINDS, HIDDEN_KINDS, controller_description,
                                            generate_case, nominal_arm_dict, _model)
from flex_twin.diagnosis.synthetic_signals import NoiseSpec, ar1, channel_noise

G = 9.81
RATE = 500.0
SEED = 8            # its references hold still for 2.7 s (fit) and 4.3 s (held out)
ACCEPTANCE_ENV = "FLEX_TWIN_ACCEPTANCE"             # "on": the subset; "full": all of it
TIMINGS_ENV = "FLEX_TWIN_DIAGNOSIS_TIMINGS"         # a path: the subset's timings, JSON
COLUMNS = ["t", "q1", "q2", "v1", "v2", "tau1", "tau2", "qset1", "qset2", "w1", "w2",
           "tip_x", "tip_y"]


@pytest.fixture(scope="module")
def healthy_quiet(tmp_path_factory):
    return generate_case("healthy", SEED, tmp_path_factory.mktemp("healthy"), noise="none")


@pytest.fixture(scope="module")
def healthy_start(tmp_path_factory):
    """The first 0.2 s: at rest in the static equilibrium under the controller."""
    return generate_case("healthy", SEED, tmp_path_factory.mktemp("start"), duration=0.2,
                         noise="none")


@pytest.fixture(scope="module")
def healthy_noisy(tmp_path_factory):
    return generate_case("healthy", SEED, tmp_path_factory.mktemp("noisy"), duration=6.0)


def _hold_ends(qset, min_hold):
    """Indices of the last sample of every hold of the reference lasting >= min_hold s."""
    still = np.all(np.diff(qset, axis=0) == 0.0, axis=1)
    ends, run = [], 0
    for k, s in enumerate(still):
        run = run + 1 if s else 0
        if run >= min_hold * RATE and (k + 1 == len(still) or not still[k + 1]):
            ends.append(k + 1)
    return ends


def _col(rec, name):
    return rec.data[:, rec.columns.index(name)]


def _cols(rec, kind):
    return np.column_stack([_col(rec, f"{kind}{i}") for i in (1, 2)])


# ------------------------------------------------------------------ the closed loop
def test_nominal_closed_loop_tracks_and_settles(healthy_quiet):
    """The healthy unit ends every hold of >= 2.5 s within 5 mrad of the reference (the
    PD's static error under the rigid-arm gravity feed-forward) and below 10 mrad/s (the
    first closed-loop mode, ~0.8 Hz, rings out over a few seconds); moves lag by the PD's
    kd / kp = 0.2 s (rms error < 0.08 rad)."""
    for rec in healthy_quiet.recordings.values():
        q, qset = _cols(rec, "q"), _cols(rec, "qset")
        ends = _hold_ends(qset, 2.5)
        assert ends
        for k in ends:
            assert np.max(np.abs(q[k] - qset[k])) < 5e-3
            assert np.max(np.abs(_cols(rec, "v")[k])) < 1e-2     # nearly at rest
        assert np.sqrt(np.mean((q - qset) ** 2)) < 0.08            # rad, over the whole run


def test_nominal_closed_loop_is_damped_over_the_workspace():
    """Linearized about the held poses (corners and centre of the workspace): the two
    lowest closed-loop modes have damping ratios >= 0.15 and >= 0.05 (thesis V.2 figures;
    the higher link modes keep only what the joints give them, as the links have no
    structural damping in the nominal)."""
    from flex_control.closed_loop import closed_loop_matrix, open_loop_jacobian
    from flex_model.statics import static_equilibrium
    from flex_twin.diagnosis.synthetic_signals import WORKSPACE
    arm = _model(nominal_arm_dict(), "nominal")
    ctl = controller_from_dict(controller_description())
    kp, kd = np.diag(ctl.gains), np.diag(ctl.rate_gains)
    for a in (WORKSPACE[0][0], -np.pi / 2, WORKSPACE[0][1]):
        for b in (WORKSPACE[1][0], 0.0, WORKSPACE[1][1]):
            theta = np.array([a, b])
            ff = ctl.feedforward(arm, theta)[0]
            st = static_equilibrium(arm, theta, joints="pd", kp=kp, joint_torques=ff)
            tau = ff + kp * (theta - arm.G @ st.q)
            A = closed_loop_matrix(*open_loop_jacobian(arm, st.q, np.zeros(arm.nq), tau),
                                   arm.G, kp, kd)
            lam = np.linalg.eigvals(A)
            assert np.max(lam.real) < 1e-6
            osc = sorted((l for l in lam if l.imag > 1e-6), key=abs)[:2]
            zeta = [-l.real / abs(l) for l in osc]
            assert zeta[0] >= 0.15 and zeta[1] >= 0.05, (theta, zeta)


# ------------------------------------------------------------------ noise statistics
def test_ar1_noise_has_the_asked_std_and_coefficient():
    rng = np.random.default_rng(1)
    x = ar1(rng, 200_000, 0.3, 0.95)
    assert np.std(x) == pytest.approx(0.3, rel=0.03)
    assert np.corrcoef(x[1:], x[:-1])[0, 1] == pytest.approx(0.95, abs=0.005)


def test_channel_noise_mixes_white_and_coloured():
    """lag-1 autocorrelation of white (s_w) + AR(1) (s_c, phi): s_c^2 phi / (s_w^2 + s_c^2)."""
    spec = NoiseSpec(white=2e-4, coloured=3e-4, corr_time=0.05)
    dt = 1 / RATE
    x = channel_noise(np.random.default_rng(2), 200_000, spec, dt)
    phi = np.exp(-dt / 0.05)
    assert np.std(x) == pytest.approx(np.hypot(2e-4, 3e-4), rel=0.03)
    assert np.corrcoef(x[1:], x[:-1])[0, 1] == pytest.approx(9 * phi / 13, abs=0.01)


def test_recorded_noise_matches_the_noise_model(healthy_noisy):
    """Measured minus true joint angles and rates: std of white + AR(1) + quantisation."""
    model = healthy_noisy.truth["noise_model"]
    rec = healthy_noisy.recordings["fit"]
    dq = _cols(rec, "q") - rec.true["joint_angles"]
    dv = _cols(rec, "v") - rec.true["joint_rates"]
    nq, nv = model["q"], model["v"]
    sq = np.sqrt(nq["white"] ** 2 + nq["coloured"] ** 2 + nq["resolution"] ** 2 / 12)
    # AR(1) with a 0.1 s correlation time: ~60 independent values in 6 s, 10 % on its std
    assert np.std(dq) == pytest.approx(sq, rel=0.15)
    assert np.std(dv) == pytest.approx(np.hypot(nv["white"], nv["coloured"]), rel=0.1)
    assert np.max(np.abs(dq)) < 8 * sq


# ------------------------------------------------------------------ hidden effects
def test_payload_changes_the_hold_torque_by_m_g_r(tmp_path, healthy_start):
    """At rest (the recordings start in static equilibrium) the joint-1 torque carries the
    weight moment of everything outboard: a heavier tool adds m g x_tip. The PD lets the
    pose sag a little; the rigid-arm moment of that sag is added (nominal model, tool
    removed). Left out: the arm's own weight moving with the extra bending (<= 6 %)."""
    case = generate_case("payload", SEED, tmp_path, duration=0.2, noise="none")
    bare = nominal_arm_dict()
    bare["payload"]["mass"] = 0.0
    arm, ctl = _model(bare, "bare"), controller_from_dict(controller_description())
    m_case = case.truth["hidden"][0]["parameters"]["mass"]
    m_healthy = case.truth["scatter"]["payload_mass"]
    assert abs(m_case - m_healthy) > 0.04
    for name in ("fit", "holdout"):
        a, b = case.recordings[name], healthy_start.recordings[name]
        sag = ctl.feedforward(arm, _cols(a, "q")[0])[0] - ctl.feedforward(arm, _cols(b, "q")[0])[0]
        expected = sag[0] + G * (m_case * _col(a, "tip_x")[0] - m_healthy * _col(b, "tip_x")[0])
        assert _col(a, "tau1")[0] - _col(b, "tau1")[0] == pytest.approx(expected, rel=0.08)


def test_stiffness_scales_the_static_deflection_by_one_over_E(tmp_path, healthy_start):
    """A link's static tip deflection under gravity is proportional to 1 / EI."""
    case = generate_case("stiffness", SEED, tmp_path, duration=0.2, noise="none")
    hid = case.truth["hidden"][0]
    i = int(hid["target"][-1])
    ratio = case.truth["scatter"][hid["target"]]["E"] / hid["parameters"]["E"]
    assert abs(ratio - 1) > 0.1
    for name in ("fit", "holdout"):
        a, b = case.recordings[name], healthy_start.recordings[name]
        assert _col(a, f"w{i}")[0] / _col(b, f"w{i}")[0] == pytest.approx(ratio, rel=0.01)
        other = 3 - i
        assert _col(a, f"w{other}")[0] / _col(b, f"w{other}")[0] == pytest.approx(1, abs=0.03)


def test_encoder_bias_moves_the_arm_not_the_measurement(tmp_path, healthy_start):
    """The controller holds the biased measurement: the true joint angle moves by -bias,
    the measured one by the PD's static error only (gravity torque of the moved pose / kp)."""
    case = generate_case("sensor_bias", SEED, tmp_path, duration=0.2, noise="none")
    hid = case.truth["hidden"][0]
    j, bias = int(hid["target"][-1]) - 1, hid["parameters"]["bias"]
    for name in ("fit", "holdout"):
        a, b = case.recordings[name], healthy_start.recordings[name]
        d_true = a.true["joint_angles"][0, j] - b.true["joint_angles"][0, j]
        d_meas = _cols(a, "q")[0, j] - _cols(b, "q")[0, j]
        assert d_true == pytest.approx(-bias, rel=0.1)
        assert abs(d_meas) < 0.1 * abs(bias)


# ------------------------------------------------------------------ no truth leaks
def test_files_the_diagnosis_reads_hold_no_truth(tmp_path):
    a = generate_case("two:payload+joint_friction", 3, tmp_path / "a", duration=0.5)
    generate_case("healthy", 4, tmp_path / "b", duration=0.5)
    for name in ("nominal_arm.yaml", "controller.yaml"):   # identical for every unit
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    arm = load_arm(a.nominal_arm)
    assert [e.TYPE for e in arm.effects] == ["gear", "gear"] and arm.payload_mass == 0.15
    assert load_controller(a.controller).feedforward_mode == "gravity"
    for path in (a.fit_csv, a.holdout_csv):
        with open(path) as fh:
            assert next(csv.reader(fh)) == COLUMNS
    truth = json.loads(a.truth_json.read_text())
    assert [h["kind"] for h in truth["hidden"]] == ["payload", "joint_friction"]
    text = a.fit_csv.read_text() + a.holdout_csv.read_text()
    for h in truth["hidden"]:
        for v in h["parameters"].values():
            assert f"{v:.10g}" not in text
    assert yaml.safe_load(a.controller.read_text()) == controller_description()


def test_an_effect_of_a_pair_alone_keeps_its_magnitude_of_the_pair(tmp_path):
    """generate_case(only=j): the j-th hidden effect of a two-effect kind alone, as drawn in
    the pair (the per-effect visibility of the benchmark's two-effect runs)."""
    kind = "two:sensor_bias+joint_elasticity"
    pair = generate_case(kind, 1004, tmp_path / "pair", noise="none",
                         duration=0.2).truth["hidden"]
    for j in (0, 1):
        alone = generate_case(kind, 1004, tmp_path / f"only{j}", noise="none", duration=0.2,
                              only=j).truth["hidden"]
        assert alone == [pair[j]]


def test_every_kind_is_declared():
    assert set(CASE_KINDS) == {"healthy", "out_of_library:cogging", *HIDDEN_KINDS}
    with pytest.raises(ValueError, match="kind"):
        generate_case("two:backlash+joint_elasticity", 0, "/nonexistent")


# ------------------------------------------------------------------ acceptance subset
#: the fixed-seed runs of the issue's targets (kind, seed)
SUBSET = (("healthy", 1000), ("out_of_library:cogging", 1000), ("payload", 1001),
          ("joint_friction", 1000), ("sensor_bias", 1000))
#: every acceptance diagnosis (kind, seed, options of diagnose), the longest first
ACCEPTANCE = (("two:sensor_bias+joint_elasticity", 1004, {}),
              ("two:sensor_bias+joint_elasticity", 1005, {}),
              ("two:gear+torque_saturation", 1008, {}),
              ("backlash", 1007, {"max_effects": 1}),
              ("two:gear+torque_saturation", 1002, {}),
              ("contact_surface", 1005, {})) + tuple((k, s, {}) for k, s in SUBSET)
#: the costliest mechanism diagnoses (about 310 of the subset's 710 CPU-s, 2026-12-03;
#: backlash 1007 and gear + saturation 1002 since the engine re-fits the named effects
#: after each round and fits two screened pairs, which made the default run 6 minutes):
#: out of the default run; ACCEPTANCE_ENV=full runs them too (before a change of the
#: engine's search: docs/diagnosis.md, speed)
EXTENDED = {("two:sensor_bias+joint_elasticity", 1004),
            ("two:sensor_bias+joint_elasticity", 1005), ("two:gear+torque_saturation", 1008),
            ("backlash", 1007), ("two:gear+torque_saturation", 1002)}
FULL = os.environ.get(ACCEPTANCE_ENV) == "full"
RUN = tuple(a for a in ACCEPTANCE if FULL or (a[0], a[1]) not in EXTENDED)
#: the acceptance tier (conftest.py): {len(RUN)} diagnoses, about 4 minutes on 2 cores
acceptance_tier = pytest.mark.acceptance
skip_extended = pytest.mark.skipif(
    not FULL, reason=f"one of the costliest acceptance diagnoses: {ACCEPTANCE_ENV}=full "
                     "runs it (about 2 minutes of CPU each)")


def _diagnose_serially(kind, seed, out, options):
    """One diagnosis without the model-form floor: these runs are made by the twin's own
    equations at the replay's discretization, so their floor is zero by construction (it
    measured 0 on all of them and doubled the fixture's time); test_diagnosis_floor.py and
    the independent suite's test exercise the floor."""
    from bench import diagnosis_scoring
    from flex_twin.diagnosis.evaluation import SerialExecutor
    return diagnosis_scoring.run_one(kind, seed, out, "nominal", False,
                                     executor=SerialExecutor(), **{"floor": False, **options})


@pytest.fixture(scope="module")
def acceptance(tmp_path_factory):
    """Every acceptance diagnosis, {(kind, seed): scored run}: one per core at a time,
    each on its core (alone, a diagnosis keeps the 2 cores busy about 80 % of its time; an executor
    maps in order, so the diagnosis computes the same with any)."""
    from flex_twin.diagnosis.evaluation import default_executor
    out = str(tmp_path_factory.mktemp("acceptance"))
    pool = default_executor()   # a process per core (serial on one core)
    try:
        futs = {(k, s): pool.submit(_diagnose_serially, k, s, out, o) for k, s, o in RUN}
        runs = {key: f.result() for key, f in futs.items()}
    finally:
        if hasattr(pool, "shutdown"):
            pool.shutdown()
    assert all("error" not in r for r in runs.values()), \
        {key: r["error"] for key, r in runs.items() if "error" in r}
    if os.environ.get(TIMINGS_ENV):   # wall and CPU seconds per diagnosis, for the docs
        with open(os.environ[TIMINGS_ENV], "w") as fh:
            json.dump({f"{k}@{s}": {c: r.get(c) for c in ("generate_cpu_s", "diagnose_s",
                                                         "diagnose_cpu_s", "verdict")}
                       for (k, s), r in runs.items()}, fh, indent=1)
    return runs


@acceptance_tier
def test_acceptance_subset(acceptance):
    """Fixed seeds: healthy -> none; cogging -> unexplained or none; payload, friction and
    encoder bias named with their parameters within 20 % and the held-out error reduced
    >= 70 % (contact: seed 1005 below; more healthy runs: the engine's and the independent
    suite's tests; every kind and seed: bench/bench_diagnosis.py)."""
    from bench.diagnosis_scoring import OK_OUT_OF_LIBRARY
    runs = [acceptance[key] for key in SUBSET]
    assert runs[0]["verdict"] == "no material discrepancy"
    assert runs[1]["verdict"] in OK_OUT_OF_LIBRARY
    for r in runs[2:]:
        assert r["right"] == [True] and all(r["in_class"]), r
        assert max(r["param_errors"]) < 0.2
        assert r["holdout_reduction"] >= 0.7


@acceptance_tier
@skip_extended
def test_acceptance_two_effects_that_a_single_compensates(acceptance):
    """Encoder bias and gear elasticity on joint 2 (seed 1004): alone, joint 1's elasticity
    explains most of it; the pair check after the first pick names both, each within
    5 %, and nothing else."""
    r = acceptance["two:sensor_bias+joint_elasticity", 1004]
    assert r["verdict"] == "named", r
    assert r["right"] == [True, True] and r["in_class"] == [True, True], r
    assert max(r["param_errors"]) < 0.05 and r["holdout_reduction"] >= 0.9


@acceptance_tier
@skip_extended
def test_acceptance_two_effects_that_mask_each_other_are_screened_as_a_pair(acceptance):
    """Encoder bias of -11.9 mrad and a soft gear spring (393 N m/rad) on joint 2 (seed
    1005): they offset each other's static deflection, the bias alone is not among the 4
    screened singles and no single explains the data (unexplained before the pair
    screening); the linearized pair screening puts the pair first and its fit names both,
    each within 5 %."""
    r = acceptance["two:sensor_bias+joint_elasticity", 1005]
    assert r["verdict"] == "named", r
    assert r["right"] == [True, True] and r["in_class"] == [True, True], r
    assert max(r["param_errors"]) < 0.05 and r["holdout_reduction"] >= 0.9


@acceptance_tier
@skip_extended
def test_acceptance_a_lighter_rotor_next_to_a_saturation(acceptance):
    """Rotor inertia x0.59 on joint 2 and the drive of joint 2 saturated (seed 1008): the
    saturation is named first (held-out J 19, fit 2.0); a gear probed only heavier and
    scored without re-fitting the saturation's limit made both recordings worse and was
    never fitted. Probed lighter too and scored with the limit and the scales re-fitted,
    the gear is named, each within 5 %, and the held-out excess is within the gate."""
    r = acceptance["two:gear+torque_saturation", 1008]
    assert r["verdict"] == "named", r
    assert sorted(n["kind"] for n in r["named"]) == ["gear", "torque_saturation"], r
    assert r["right"] == [True, True] and r["in_class"] == [True, True], r
    assert max(r["param_errors"]) < 0.05 and r["holdout_reduction"] >= 0.99


@acceptance_tier
def test_acceptance_nothing_is_named_for_what_only_the_held_out_run_shows(acceptance):
    """Contact floor (seed 1005): the fitted contact explains the fit recording to its noise
    level (J - 1 = 0.06) and leaves a held-out excess (the held-out run presses harder).
    Before the rule that a further effect needs evidence on the fit recording too, a 2 ms
    sensor delay was named for it (0.77 of the held-out excess, 0.2 of the fit one's); now
    the contact alone, the rest unexplained."""
    r = acceptance["contact_surface", 1005]
    assert [n["kind"] for n in r["named"]] == ["contact_surface"], r
    assert r["verdict"] == "named + unexplained discrepancy", r
    assert r["stop"].startswith("fit recording explained to its noise level"), r
    assert max(r["param_errors"]) < 0.1 and r["holdout_reduction"] >= 0.99


@acceptance_tier
@skip_extended
def test_acceptance_a_second_effect_below_the_gate_on_the_fit_recording(acceptance):
    """Gear on joint 2 (rotor inertia x1.6) and drive saturation on joint 1 (seed 1002):
    after the saturation the fit recording's excess is 0.25, under the gate, the held-out
    one 2.4 (the held-out run saturates longer). The gear explains 0.78 of the held-out excess and
    0.26 of the fit recording's J, more than min_share of the gate: both are named, each
    within 5 %."""
    r = acceptance["two:gear+torque_saturation", 1002]
    assert sorted(n["kind"] for n in r["named"]) == ["gear", "torque_saturation"], r
    assert r["right"] == [True, True] and r["in_class"] == [True, True], r
    assert max(r["param_errors"]) < 0.05 and r["holdout_reduction"] >= 0.99


@acceptance_tier
@skip_extended
def test_acceptance_backlash_is_named_not_its_spring(acceptance):
    """Backlash of 6.85 mrad in joint 1's gear spring (3000 N m/rad, damping 6.9 N m s/rad;
    seed 1007). The backlash hypothesis frees the spring's damping as the joint elasticity
    does (without it the elasticity fitted better: J 5.7 against 7.2 on the fit recording,
    and the undamped backlash diverged on the held-out one), and a Newton step that stalls
    on the dead zone's corner is retried in substeps: the first round names the backlash,
    not its class-mate, its play within 25 % (5.9 mrad), the held-out error cut by >= 90 %
    (one effect: the later rounds of the benchmark run name nothing more)."""
    r = acceptance["backlash", 1007]
    assert [n["kind"] for n in r["named"]] == ["backlash"], r
    assert r["right"] == [True] and r["in_class"] == [True], r
    assert max(r["param_errors"]) < 0.25 and r["holdout_reduction"] >= 0.9
