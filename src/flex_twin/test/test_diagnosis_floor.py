"""The twin's own numerical and model-form floor on a run (issue 21, step 2).

Runs of the hub-less two-link arm (thesis Example 1, vertical plane) under the issue's
continuous PD with set-point steps, white sensor noise at the independent suite's levels;
made by the twin itself at its default setting, or by a finer twin (6 variables per link,
second_order kinematics, a 0.25 ms step)."""
import json

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel
from flex_twin.diagnosis.baseline import baseline_parameters
from flex_twin.diagnosis.controller import controller_from_dict
from flex_twin.diagnosis.engine import DEFAULT_GATE, diagnose
from flex_twin.diagnosis.evaluation import Context, SerialExecutor, cost, evaluate
from flex_twin.diagnosis.floor import FLOOR_TARGET, Setting, measure_floor
from flex_twin.diagnosis.recording import validate
from flex_twin.diagnosis.replay import initial_state, predict, simulate_closed_loop

ARM = load_arm("thesis_example1")
CTL = controller_from_dict({"controller": {"law": "pd", "timing": "continuous",
                                           "kp": [625.0, 625.0], "kd": [176.8, 176.8]}})
NOISE = {"q": 5e-5, "v": 5e-3, "tau": 0.05, "w": 2e-4, "tip": 1e-3}
T, DT = 8.0, 0.002


def _run(setting: Setting, seed: int):
    """A noisy recording of the arm at ``setting``: set-point steps every 2 s."""
    m = FlexArmModel(setting.arm(ARM))
    t = np.arange(int(round(T / DT)) + 1) * DT
    k = np.floor(t / 2.0)
    qset = np.column_stack([-1.5 + 0.15 * np.sin(1.7 * k), 0.2 * np.cos(2.3 * k)])
    X, tau = simulate_closed_loop(m, CTL, initial_state(m, qset[0]), T, qset,
                                  np.zeros_like(qset), sample_period=DT, dt=setting.dt)
    want = ["q1", "q2", "v1", "v2", "tau1", "tau2", "w1", "w2", "tip_x", "tip_y"]
    p = predict(m, X, tau, t, want)
    rng = np.random.default_rng(seed)
    ch = {c: p.channels[c] + NOISE["tip" if c.startswith("tip") else c[:-1]]
          * rng.standard_normal(len(t)) for c in want}
    for i in range(2):
        ch[f"qset{i + 1}"] = qset[:, i]
    return validate(t, ch, 2, f"run at {setting.label()}")


def _contexts(rec):
    score_from = rec.t[0] + 0.6 * (rec.t[-1] - rec.t[0])
    fit = rec.window(rec.t[0], score_from)
    params = baseline_parameters(ARM)
    ctx = Context.build(ARM, CTL, fit, params)
    return ctx, Context.build(ARM, CTL, rec, params, sigma=ctx.sigma, score_from=score_from)


def test_the_floor_is_zero_when_replay_and_data_share_the_discretization():
    rec = _run(Setting((2, 2), "small_deflection", 2e-3), seed=1)
    ctx, ctx_ho = _contexts(rec)
    fl = measure_floor(SerialExecutor(), ctx, ctx_ho)
    # the refined twin is further from a run the twin made: no refinement, no model form
    assert not fl.refined and not fl.changed and fl.sigma is None
    assert fl.J_reference["holdout"] > fl.J_default["holdout"]
    assert fl.model_form == {"fit": 0.0, "holdout": 0.0}
    assert fl.J_default["holdout"] < 1.2      # the healthy twin at its noise level


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_a_healthy_run_of_a_finer_model_is_no_material_discrepancy(tmp_path):
    rec = _run(Setting((6, 6), "second_order", 2.5e-4), seed=2)
    ctx, ctx_ho = _contexts(rec)
    # the default replay's own model-form error alone is material (the false
    # rotor inertia): J far above 1 + gate on the held-out part
    J_default = cost(evaluate((ctx_ho, np.ones(len(ctx.baseline_params)), [])))
    assert J_default - 1.0 > 10 * DEFAULT_GATE
    d = diagnose(ARM, CTL, rec, executor=SerialExecutor())
    assert d.verdict == "no material discrepancy" and d.accepted == []
    fl = d.floor
    assert fl.refined and fl.changed and fl.chosen.kinematics == "second_order"
    assert fl.own_error_default["holdout"] > 10 * DEFAULT_GATE
    assert fl.J_reference["holdout"] < fl.J_default["holdout"]
    assert 0.0 <= fl.model_form["holdout"] <= DEFAULT_GATE
    assert d.gate_effective == pytest.approx(DEFAULT_GATE + fl.model_form["holdout"])
    # the report states the floor (text and JSON)
    from flex_twin.diagnosis.report import write_report
    arm_yaml = tmp_path / "arm.yaml"
    from flex_model.arm import PRESET_DIR
    arm_yaml.write_text((PRESET_DIR / "thesis_example1.yaml").read_text())
    s = write_report(tmp_path / "out", arm_yaml, d, plots=False)
    js = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    assert js["floor"]["refined"] is True
    assert js["floor"]["model_form"]["holdout"] == pytest.approx(fl.model_form["holdout"])
    assert js["gate"]["model_form_holdout"] == pytest.approx(fl.model_form["holdout"])
    assert s["floor"]["own_error_default"]["holdout"] > 10 * DEFAULT_GATE
    md = (tmp_path / "out" / "report.md").read_text()
    assert "## Model-form floor" in md and "Model form (not a physical effect" in md
    # the diagnosed arm states the discretization the diagnosis chose
    assert "kinematics: second_order" in (tmp_path / "out" / "diagnosed_arm.yaml").read_text()
    assert FLOOR_TARGET < DEFAULT_GATE
