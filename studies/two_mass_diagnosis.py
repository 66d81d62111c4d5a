"""The two-mass bench as a diagnosis case: record A (fit) and B (held out) as the inputs of
``flex-twin diagnose`` against the rigid nominal twin (coupling rigid, inertias summed).

The bench runs open loop (current multisine): the "controller" is ``law: pd`` with zero
gains and ``feedforward: recorded`` (tau_ff1 = K_t i, the measured current less its offset),
sampled at the record's 0.4 ms. Channels: q1 = the motor angle (the actuator coordinate:
the encoder the engine compares, ``FlexArmModel.actuator_angles``), v1 its central
difference, tau1 = tau_ff1, qset1 = q1 (unused with zero gains), and the load encoder as
the link-side encoder ql1, vl1 (angle, central difference). The rigid-body mode drifts
open loop, so the diagnosis runs with ``--segment`` (:data:`SEGMENT`, restarts from the
measured state):
a twin with an elastic coupling restarts with its load at ql1, vl1 and its motor at q1,
v1 (twisted as measured), a rigid one as before. The restarts take the first sample
itself (``# start_window:`` 2 samples, 0.8 ms) instead of the default 50-ms quadratic
fit: 50 ms are 3.8 periods of the 76 Hz mode, whose swing the fit averages away, while
the angles are 5-6 urad encoder steps and the speeds central differences, smooth enough
to start from directly.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from flex_twin.real_arms.two_mass_twin import TORQUE_CONSTANT, TwoMassParameters, arm_dict

from studies.two_mass_data import TwoMassRecord

#: restart period of the open-loop replay (s): 7.6 periods of the 76 Hz mode, short enough
#: that the rigid-body drift (bearing friction the twin lacks, the current's unexcited
#: 1-10 Hz content) does not dominate the angle residual (with 1-s segments a large
#: viscous friction, which damps that drift, outscored the coupling: docs/real-arms.md)
SEGMENT = 0.1
#: window of the restarts' state fit, in samples (the first sample itself; see above)
START_SAMPLES = 2


def recording_columns(rec: TwoMassRecord, duration: float | None = None) -> dict:
    """The engine's CSV columns (SI) of a record, optionally only its first seconds."""
    n = len(rec.t) if duration is None else int(round(duration * rec.fs)) + 1
    tau = TORQUE_CONSTANT * rec.current[:n]
    return {"t": rec.t[:n], "q1": rec.theta_m[:n], "v1": rec.omega_m[:n], "tau1": tau,
            "qset1": rec.theta_m[:n], "tau_ff1": tau, "ql1": rec.theta_l[:n],
            "vl1": rec.omega_l[:n]}


def controller_dict(rec: TwoMassRecord) -> dict:
    return {"controller": {"law": "pd", "kp": [0.0], "kd": [0.0], "period": rec.dt,
                           "feedforward": "recorded"}}


def write_csv(columns: dict, path, start_window: float | None = None) -> None:
    """The columns as the engine's CSV, with a ``# start_window:`` line when given (s)."""
    names = list(columns)
    data = np.column_stack([columns[k] for k in names])
    head = "" if start_window is None else f"# start_window: {start_window!r}\n"
    np.savetxt(path, data, delimiter=",", header=head + ",".join(names), comments="",
               fmt="%.9g")


def export_case(fit: TwoMassRecord, holdout: TwoMassRecord, nominal: TwoMassParameters,
                out_dir, duration: float | None = None) -> dict:
    """Write fit.csv, holdout.csv, controller.yaml and the rigid nominal_arm.yaml."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = {"data": out / "fit.csv", "holdout": out / "holdout.csv",
             "controller": out / "controller.yaml", "arm": out / "nominal_arm.yaml"}
    write_csv(recording_columns(fit, duration), paths["data"], START_SAMPLES * fit.dt)
    write_csv(recording_columns(holdout, duration), paths["holdout"],
              START_SAMPLES * holdout.dt)
    paths["controller"].write_text(yaml.safe_dump(controller_dict(fit), sort_keys=False))
    paths["arm"].write_text("# two-mass bench, rigid nominal twin (coupling rigid, J_m as a "
                            "gear rotor of ratio 1, J_l the load's root inertia)\n" +
                            yaml.safe_dump(arm_dict(nominal, elastic=False), sort_keys=False))
    return paths


def run_diagnosis(paths: dict, out_dir, segment: float = SEGMENT, workers=None,
                  plots: bool = True) -> dict:
    """``flex-twin diagnose`` on the exported case; returns the engine's summary."""
    from flex_twin.cluster import batch_executor
    from flex_twin.diagnosis.batch import RunSpec, diagnose_run
    run = RunSpec("two_mass_A", str(paths["data"]), str(paths["arm"]),
                  str(paths["controller"]), str(paths["holdout"]))
    with batch_executor(None, workers) as ex:
        return diagnose_run(run, str(out_dir), None, segment, plots, ex, progress=True,
                            floor=True)
