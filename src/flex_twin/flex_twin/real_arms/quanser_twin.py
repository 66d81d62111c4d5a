"""The Quanser twins: which arm description goes with which lab run, and the entry point
that hands a run to the diagnosis (recording + nominal arm + controller description).

Arm presets (``flex_model/presets``): ``quanser_cuboulder_flexible`` / ``_rigid`` (handout
values; EI from f_c = 1.8 Hz), ``quanser_cuboulder_calibrated`` (written by
``flex-twin real-arm calibrate``) and ``quanser_ucmerced`` (Quanser manual values).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from flex_model.arm import ArmDescription, load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from .quanser_data import CUBOULDER, UCMERCED, LabRun, read_cuboulder_file, read_ucmerced

NOMINAL_PRESETS = {("cuboulder", "flexible"): "quanser_cuboulder_flexible",
                   ("cuboulder", "rigid"): "quanser_cuboulder_rigid",
                   ("ucmerced", "flexible"): "quanser_ucmerced"}
CALIBRATED_PRESETS = {("cuboulder", "flexible"): "quanser_cuboulder_calibrated",
                      ("cuboulder", "rigid"): "quanser_cuboulder_rigid_calibrated"}


def stiffness_for_frequency(arm: ArmDescription, f_clamped: float) -> float:
    """EI (N m^2) of the arm's single uniform ``explicit`` link that makes the model's first
    clamped-hub frequency ``f_clamped`` (Hz): f1 is proportional to sqrt(EI) at fixed mass
    and tip mass, so one modal analysis at the arm's EI gives it exactly."""
    f1 = natural_modes(FlexArmModel(arm), joints="clamped").frequencies_hz[0]
    ei = arm.links[0].segments[0].dims["EI"][0]
    return float(ei * (f_clamped / f1) ** 2)


def load_lab_run(path) -> LabRun:
    """A lab run from a CU Boulder log file or the UC Merced folder."""
    path = Path(path)
    if path.is_dir():
        if not (path / "data_alpha.mat").exists():
            raise ValueError(f"{path}: a directory without data_alpha.mat (UC Merced) ")
        return read_ucmerced(path, nominal_arm_for("ucmerced", "flexible").links[0].length)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such lab file")
    return read_cuboulder_file(path)


def nominal_arm_for(lab: str, kind: str) -> ArmDescription:
    """The handout (nominal) arm of a lab and run kind."""
    try:
        return load_arm(NOMINAL_PRESETS[(lab, kind)])
    except KeyError:
        raise ValueError(f"no Quanser arm for lab {lab!r}, kind {kind!r}; known: "
                         f"{sorted(NOMINAL_PRESETS)}") from None


def calibrated_arm_for(lab: str, kind: str) -> ArmDescription | None:
    """The calibrated arm of a lab and run kind, if a calibrated preset exists."""
    name = CALIBRATED_PRESETS.get((lab, kind))
    if name is None:
        return None
    try:
        return load_arm(name)
    except ValueError:
        return None


def stored_calibrated_arm(kind: str, lab: str = "cuboulder") -> ArmDescription:
    """:func:`calibrated_arm_for`, or a ValueError that names the missing preset and the
    command that writes it."""
    arm = calibrated_arm_for(lab, kind)
    if arm is None:
        raise ValueError(f"no {CALIBRATED_PRESETS.get((lab, kind), f'calibrated {kind} twin')}"
                         " preset: run flex-twin real-arm calibrate")
    return arm


def controller_description(run: LabRun) -> dict:
    """The lab's control law of a run as data (what flex_control.state_feedback needs)."""
    return {"law": "tip_state_feedback",
            "equation": "V = K1 (theta_ref - theta) + K2 (0 - d) - K3 theta_dot - K4 d_dot",
            "gains": [float(k) for k in run.gains], "gauge_sign": run.gauge_sign(),
            "gauge_bias_m": run.gauge_bias(), "output": "voltage (V) of joint1",
            "reference_t": run.t, "reference": run.reference,
            "policy_factory": "flex_control.state_feedback:lab_policy_factory"}


def diagnosis_case(path) -> dict:
    """What ``flex-twin diagnose`` needs for a lab run: the recording, the nominal arm and
    the controller. ``recording`` holds t, hub angle, tip deflection in the twin's sign
    (gauge sign applied, bias removed) and the voltage, SI units."""
    run = load_lab_run(path)
    sign, bias = run.gauge_sign(), run.gauge_bias()
    rec = {"t": run.t, "joint1/angle": run.theta, "joint1/rate": run.theta_rate,
           "joint1/voltage": run.voltage, "reference": run.reference}
    if run.has_gauge:
        rec["link1/tip_deflection"] = sign * (run.deflection - bias)
    return {"run": run, "recording": rec, "arm": nominal_arm_for(run.lab, run.kind),
            "controller": controller_description(run), "sample_period": run.dt}


def data_root(path=None) -> Path:
    """The folder of the real data: ``path``, or ``../shared/data/real`` beside the cwd."""
    root = Path(path) if path else Path.cwd().parent / "shared" / "data" / "real"
    if not (root / CUBOULDER).is_dir():
        raise FileNotFoundError(f"{root}: no {CUBOULDER} folder (give --data DIR, the "
                                "folder holding the labs' data)")
    return root


def ucmerced_dir(root: Path) -> Path:
    return Path(root) / UCMERCED


def hub_inertia(arm: ArmDescription) -> float:
    """n^2 J_r + J_minus of the link (kg m^2): the servo's joint-side inertia."""
    gear = arm.effect("gear", arm.joint_names[0])
    return float(gear["ratio"] ** 2 * gear["rotor_inertia"] + arm.links[0].J_minus)


def closed_loop_frf(model: FlexArmModel, kp: float, f_hz) -> dict:
    """Frequency responses of the twin under V = kp (r - theta): r -> theta (closed loop)
    and V -> theta (plant), from the hinged-hub linearization (viscous friction only;
    back-EMF damping included). Returns complex arrays."""
    from flex_model.modes import linearize
    lin = linearize(model, joints="hinged")
    jd = model.joint_data[0]
    col = {n: k for k, n in enumerate(model.JOINT_DATA)}
    gain = jd[col["ratio"]] * jd[col["Kt"]] / jd[col["R"]]  # torque per volt at rest
    b = lin.B[:, 0] * gain
    c = lin.C[0]
    s = 2j * np.pi * np.asarray(f_hz, float)
    n = lin.A.shape[0]
    plant = np.array([c @ np.linalg.solve(si * np.eye(n) - lin.A, b) for si in s])
    return {"plant": plant, "closed": kp * plant / (1 + kp * plant)}
