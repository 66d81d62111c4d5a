"""Diagnose a recording: a synthetic unit with a hidden change of its tool, named by the twin.

flex_twin.diagnosis.synthetic writes what a user hands the diagnosis (docs/diagnosis.md):
two closed-loop recordings (fit and held out) of a "true" thesis Example 1 arm with geared
motors whose parameters scatter within tolerance and whose tool is not the nominal 0.15 kg
(seed 1001: a lighter one), plus the nominal arm and the controller (PD with gravity
feed-forward). The diagnosis replays the recordings on the nominal twin in closed loop,
recalibrates within tolerance and fits the library's effects that pass its screening.
Prints the verdict, the named effects and the tool mass: nominal, diagnosed (the updated
twin's) and hidden (truth.json, which the diagnosis never reads).

    python examples/diagnose_recording.py             # 12 s recordings
    FLEX_TWIN_EXAMPLES_QUICK=1 python examples/diagnose_recording.py   # 4 s, 1 candidate
"""
import json
import os

from flex_model.arm import load_arm
from flex_twin.diagnosis.controller import load_controller
from flex_twin.diagnosis.engine import diagnose
from flex_twin.diagnosis.sources import load_recording
from flex_twin.diagnosis.synthetic import generate_case

quick = bool(os.environ.get("FLEX_TWIN_EXAMPLES_QUICK"))
case = generate_case("payload", seed=1001, out_dir="diagnosis_case",
                     duration=4.0 if quick else 12.0)          # s of each recording
arm = load_arm(case.nominal_arm)
result = diagnose(arm, load_controller(case.controller),
                  load_recording(case.fit_csv, arm.n_links),
                  load_recording(case.holdout_csv, arm.n_links),
                  top=1 if quick else 4, floor=not quick)
print("verdict:", result.verdict)
print("named:", ", ".join(f"{c.kind}@{c.target}" if c.target else c.kind for c in result.accepted))
hidden_mass = json.loads(case.truth_json.read_text())["true_arm"]["payload"]["mass"]
print(f"tool mass (kg): nominal {arm.payload_mass:.4f}, diagnosed {result.twin.payload_mass:.4f}, "
      f"hidden {hidden_mass:.4f}")
