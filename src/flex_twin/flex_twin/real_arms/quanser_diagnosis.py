"""A Quanser lab run as the input of ``flex-twin diagnose`` (issue 9, step 3).

:func:`export_run` writes what :mod:`flex_twin.diagnosis` reads, from
:func:`.quanser_twin.diagnosis_case`:

- the recording CSV (:mod:`flex_twin.diagnosis.recording`): ``q1`` hub angle (rad), ``v1``
  its logged rate, ``tau1`` the logged voltage (the command of the ``dc_motor`` joint, V),
  ``qset1`` the reference, ``w1`` the tip deflection in the twin's sign (gauge sign
  applied, bias removed) and ``tau_ff1`` the constant -K2 * bias (below);
- the controller YAML: the lab law V = K1 (r - theta) + K2 (0 - d) - K3 theta_dot -
  K4 d_dot on the twin's channels. The lab's d is ``s w + b`` (gauge sign s, bias b), so
  ``gains: [{q1: K1, w1: s K2}]``, ``rate_gains: [{q1: K3, w1: s K4}]`` and the constant
  -K2 b enters as the recorded feed-forward; period = the log's sample period;
- the nominal arm YAML: the handout preset as it is.

Runs without a gauge signal (rigid bar, ``flexibleArm_test_1``) have no ``w1`` and a
q-only law (the lab's law saw d = 0).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from flex_model.arm import resolve_preset
from flex_model.config import read_yaml
from flex_model.sensors import tip_gauge_entry
from .quanser_data import CUBOULDER
from .quanser_twin import NOMINAL_PRESETS, diagnosis_case

#: fit run of the diagnosis and its default held-out run (CUBOULDER_SPLIT link_fit):
#: no held-out run of the split has the fit runs' law, and the engine replays both
#: recordings with one controller, so the default held-out data are the last 40 % of the
#: fit run (the engine's own default)
DEFAULT_RUN = "flexarm_K1_6"
#: restarts of the replay (s) from the measured hub angle and rate (multiple shooting,
#: ``flex-twin diagnose --segment``): every segment of a hold starts where the lab hub
#: stuck, so a twin without sticking slides back within 0.5 s and the sticking's signature
#: is in every segment; a whole-run replay of a symmetric friction stops short on both
#: sides where the lab stuck on one (flexarm_K1_6). With it the stick-slip friction is
#: named on the K1, K1K2 and K1K2K3 runs (issue 22; docs/real-arms.md)
SEGMENT = 0.5


def recording_columns(case: dict) -> dict:
    """The CSV columns (name -> array, SI) of a diagnosis case."""
    run, rec = case["run"], case["recording"]
    cols = {"t": rec["t"], "q1": rec["joint1/angle"], "v1": rec["joint1/rate"],
            "tau1": rec["joint1/voltage"], "qset1": rec["reference"]}
    if "link1/tip_deflection" in rec:
        cols["w1"] = rec["link1/tip_deflection"]
    k2 = float(run.gains[1]) if run.has_gauge else 0.0
    cols["tau_ff1"] = np.full(len(rec["t"]), -k2 * run.gauge_bias())
    return cols


def controller_dict(case: dict) -> dict:
    """The controller YAML mapping (flex_twin.diagnosis.controller) of the run's law."""
    run = case["run"]
    k1, k2, k3, k4 = (float(k) for k in run.gains)
    gains, rates = {"q1": k1}, {"q1": k3}
    if run.has_gauge:
        s = run.gauge_sign()
        gains["w1"], rates["w1"] = s * k2 + 0.0, s * k4 + 0.0  # no -0.0
    return {"controller": {"law": "state_feedback", "period": float(case["sample_period"]),
                           "output": "voltage", "feedforward": "recorded",
                           "gains": [gains], "rate_gains": [rates]}}


def nominal_arm_dict(case: dict) -> dict:
    """The nominal arm YAML mapping of the run (the handout preset), its tip gauge
    declared (an exact ``tip_deflection`` sensor, unless the preset declares one) where the
    run logs one: the diagnosis may then fit its lag (``gauge_delay``)."""
    run = case["run"]
    data = read_yaml(resolve_preset(NOMINAL_PRESETS[(run.lab, run.kind)]))
    if run.has_gauge:
        tip_gauge_entry(data.setdefault("sensors", []), data["links"][0].get("name", "link1"))
    return data


def write_csv(columns: dict, path) -> None:
    """The recording CSV (17 significant digits: the lab values round-trip exactly)."""
    names = list(columns)
    np.savetxt(path, np.column_stack([columns[n] for n in names]), delimiter=",",
               header=",".join(names), comments="", fmt="%.17g")


def export_run(path, out_dir, stem: str | None = None) -> dict:
    """Write ``<stem>.csv``, ``<stem>_controller.yaml`` and the nominal arm
    ``nominal_arm.yaml`` into ``out_dir``; return their paths and the case."""
    case = diagnosis_case(path)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    stem = stem or case["run"].name.replace(".", "_")
    paths = {"data": out / f"{stem}.csv", "controller": out / f"{stem}_controller.yaml",
             "arm": out / "nominal_arm.yaml"}
    write_csv(recording_columns(case), paths["data"])
    paths["controller"].write_text(yaml.safe_dump(controller_dict(case), sort_keys=False))
    paths["arm"].write_text(f"# {case['run'].lab} {case['run'].kind}: nominal arm for the "
                            "diagnosis (flex_twin.real_arms.quanser_diagnosis)\n"
                            + yaml.safe_dump(nominal_arm_dict(case), sort_keys=False))
    return {"paths": paths, "case": case}


def run_path(name_or_path, root: Path) -> Path:
    """A lab file: an existing lab file or UC Merced folder (with ``data_alpha.mat``), or a
    CU Boulder run name under the data root (a directory of that name in the working
    directory, say an earlier output folder, is not taken for the run)."""
    p = Path(name_or_path)
    if p.is_file() or (p / "data_alpha.mat").is_file():
        return p
    hits = sorted((Path(root) / CUBOULDER).glob(f"*/**/{name_or_path}"))
    if not hits:
        raise FileNotFoundError(f"{name_or_path}: neither a file nor a CU Boulder run name "
                                f"under {Path(root) / CUBOULDER}")
    return hits[0]


def same_law(a: dict, b: dict) -> bool:
    """Whether two runs' controller mappings are the same law (one controller replays
    both recordings in the diagnosis)."""
    return a["controller"] == b["controller"]
