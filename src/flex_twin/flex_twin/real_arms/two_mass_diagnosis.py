"""The two-mass bench as a diagnosis case: record A (fit) and B (held out) as the inputs of
``flex-twin diagnose`` against the rigid nominal twin (coupling rigid, inertias summed).

The bench runs open loop (current multisine): the "controller" is ``law: pd`` with zero
gains and ``feedforward: recorded`` (tau_ff1 = K_t i, the measured current less its offset),
sampled at the record's 0.4 ms. Channels: q1 = the motor angle (the actuator coordinate:
the encoder the engine compares, ``FlexArmModel.actuator_angles``), v1 its central
difference, tau1 = tau_ff1, qset1 = q1 (unused with zero gains). The rigid-body mode drifts
open loop, so the diagnosis runs with ``--segment`` (restarts from the measured state).
The load encoder has no channel in the engine's CSV (w1 is a tip deflection): only the
motor side is seen, where the anti-resonance and resonance both show.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from .two_mass_data import TwoMassRecord
from .two_mass_twin import TORQUE_CONSTANT, TwoMassParameters, arm_dict

#: restart period of the open-loop replay (s): one excitation period
SEGMENT = 1.0


def recording_columns(rec: TwoMassRecord, duration: float | None = None) -> dict:
    """The engine's CSV columns (SI) of a record, optionally only its first seconds."""
    n = len(rec.t) if duration is None else int(round(duration * rec.fs)) + 1
    tau = TORQUE_CONSTANT * rec.current[:n]
    return {"t": rec.t[:n], "q1": rec.theta_m[:n], "v1": rec.omega_m[:n], "tau1": tau,
            "qset1": rec.theta_m[:n], "tau_ff1": tau}


def controller_dict(rec: TwoMassRecord) -> dict:
    return {"controller": {"law": "pd", "kp": [0.0], "kd": [0.0], "period": rec.dt,
                           "feedforward": "recorded"}}


def write_csv(columns: dict, path) -> None:
    names = list(columns)
    data = np.column_stack([columns[k] for k in names])
    np.savetxt(path, data, delimiter=",", header=",".join(names), comments="", fmt="%.9g")


def export_case(fit: TwoMassRecord, holdout: TwoMassRecord, nominal: TwoMassParameters,
                out_dir, duration: float | None = None) -> dict:
    """Write fit.csv, holdout.csv, controller.yaml and the rigid nominal_arm.yaml."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"data": out / "fit.csv", "holdout": out / "holdout.csv",
             "controller": out / "controller.yaml", "arm": out / "nominal_arm.yaml"}
    write_csv(recording_columns(fit, duration), paths["data"])
    write_csv(recording_columns(holdout, duration), paths["holdout"])
    paths["controller"].write_text(yaml.safe_dump(controller_dict(fit), sort_keys=False))
    paths["arm"].write_text("# two-mass bench, rigid nominal twin (coupling rigid, J_m as a "
                            "gear rotor of ratio 1, J_l the load's root inertia)\n" +
                            yaml.safe_dump(arm_dict(nominal, elastic=False), sort_keys=False))
    return paths


def run_diagnosis(paths: dict, out_dir, segment: float = SEGMENT, workers=None,
                  plots: bool = True) -> dict:
    """``flex-twin diagnose`` on the exported case; returns the engine's summary."""
    from ..cluster import batch_executor
    from ..diagnosis.batch import RunSpec, diagnose_run
    run = RunSpec("two_mass_A", str(paths["data"]), str(paths["arm"]),
                  str(paths["controller"]), str(paths["holdout"]))
    with batch_executor(None, workers) as ex:
        return diagnose_run(run, str(out_dir), None, segment, plots, ex, progress=True,
                            floor=True)
