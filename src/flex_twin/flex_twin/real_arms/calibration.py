"""Calibration of a Quanser twin: bounded least squares on flex_model's effects.

Two stages on a documented split of the runs (:data:`CUBOULDER_SPLIT`):

1. servo, from rigid-bar runs: joint friction (Coulomb F_c, break-away F_s, viscous F_v),
   rotor inertia (scale of the handout's J_hub) and the motor torque constant (within
   its 5 % tolerance, K_e = K_t as in the handout);
2. link, from a subset of the flexible-link runs with the servo of stage 1: bending
   stiffness EI, modal damping (Rayleigh a of ``structural_damping``), tip mass, and the
   hub's Coulomb and break-away friction again (the flexible setup holds more).

With stick-slip the cost is rough (where the hub sticks jumps with the parameters), so
the search starts from the best point of a coarse grid and stays local.

The residual is the closed-loop replay error of every fit run, hub angle / 10 mrad and tip
deflection / 2 mm, sampled every 5 ms (``scipy.optimize.least_squares``, finite
differences, parameters scaled to their nominal values).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np
from scipy.optimize import least_squares

from flex_model.arm import ArmDescription
from flex_model.dynamics import FlexArmModel
from flex_model.effects import DCMotor, Gear, JointFriction, StructuralDamping
from flex_model.sensors import declared_tip_gauge, tip_gauge_entry, with_tip_gauge
from .replay import replay

#: which CU Boulder runs fit which stage; everything else is held out (validation)
CUBOULDER_SPLIT = {
    "servo_fit": ("rigidarm_K1_7", "rigidarm_k1k3_8", "Unit5_Rigid_trial1.csv"),
    "servo_holdout": ("rigidarm_K1_6", "rigidarm_K1_8", "rigidarm_K1_9", "rigidarm_k1k3_6",
                      "rigidarm_k1k3_7", "rigidarm_k1k3_9", "4PM_Group37_RigidArm_Unit1"),
    "link_fit": ("flexarm_K1_6", "flexarm_K1K2K3k4_6_-3_213_4", "4PM_Group37_FlexArm_Unit6"),
    "link_holdout": ("flexarm_k1k2_6_-3", "flexarm_K1K2_6_-5", "flexarm_K1K2K3_6_-3_213",
                     "flexarm_K1K2K3_6_-5_213", "flexarm_K1K2K3k4_6_-3_213_2",
                     "Unit7_Flex_trial1.csv", "flexibleArm_test_2", "flexibleArm_test_3",
                     "flexibleArm_test_4"),
}
HUB_SCALE = 0.01      # rad
TIP_SCALE = 0.002     # m
SUBSAMPLE = 5         # every 5 ms
SERVO_WINDOW = 5.0    # s of each rigid fit run (two steps)
#: fitted values that are fields of the first link's tip_deflection sensor
GAUGE_FIELDS = {"gauge_gain": "gain", "gauge_delay": "delay"}


@dataclass(frozen=True)
class FitParameter:
    """A fitted parameter: name, nominal value, bounds and start of the search (SI)."""

    name: str
    nominal: float
    lower: float
    upper: float
    start: float | None = None


#: the lab's tip gauge's fields, bounds and starts when they are fitted (``--gauge-gain``,
#: ``--gauge-delay``; a twin with a gauge starts from its values): the lab's gauge answers
#: the hub with 0.36-0.80 of the twins' link as logged, and read 45-80 ms late like one
#: mode with the twins' gain on three units, 0.25-0.45 of it on Hagenau's (python -m
#: studies.link_response)
GAUGE = {"gauge_gain": FitParameter("gauge_gain", 1.0, 0.3, 1.2, 0.7),
         "gauge_delay": FitParameter("gauge_delay", 0.0, 0.0, 0.15, 0.06)}


def with_gauge(params: list, gauge: tuple = ()) -> list:
    """Link-stage ``params`` plus the :data:`GAUGE` fields named in ``gauge``, EI and tip
    mass then free within x0.5-2 of their nominal (a lagging gauge moves the link's
    frequency the fit sees); ``params`` unchanged when ``gauge`` is empty."""
    unknown = [g for g in gauge if g not in GAUGE]
    if unknown:
        raise ValueError(f"gauge: got {unknown}; expected names among {sorted(GAUGE)}")
    return widened(params) + [GAUGE[g] for g in gauge] if gauge else params


def widened(params: list) -> list:
    """``params`` with EI and tip mass free within x0.5-2 of their nominal."""
    return [dataclasses.replace(p, lower=0.5 * p.nominal, upper=2.0 * p.nominal)
            if p.name in ("EI", "tip_mass") else p for p in params]


def gauge_options(gauge: tuple) -> str:
    """The command-line flags that fit ``gauge`` (names of :data:`GAUGE`), for a preset's
    header: ``("gauge_delay",)`` -> ``" --gauge-delay"``."""
    return "".join(f" --{g.replace('_', '-')}" for g in gauge)


def servo_parameters(arm: ArmDescription) -> list:
    """Stage 1 unknowns with their bounds (the handout has no friction)."""
    j = arm.joint_names[0]
    gear, motor = arm.effect("gear", j), arm.effect("dc_motor", j)
    kt = motor["torque_constant"]
    jr = gear["rotor_inertia"]
    # start: the best of a coarse grid J_r x {2.5, 3.5}, F_c {0.005, 0.02}, F_s {0.06, 0.1}
    return [FitParameter("coulomb", 0.0, 0.0, 0.5, 0.02),
            FitParameter("static_excess", 0.0, 0.0, 0.2, 0.04),
            FitParameter("viscous", 0.0, 0.0, 0.2, 0.001),
            FitParameter("rotor_inertia", jr, 0.3 * jr, 6.0 * jr, 3.5 * jr),
            FitParameter("torque_constant", kt, 0.95 * kt, 1.05 * kt)]


def link_parameters(arm: ArmDescription) -> list:
    """Stage 2 unknowns: EI within -50 %/+20 %, damping a, tip mass within +-50 %, and the
    hub friction again (F_c, F_s - F_c, started from stage 1): with the link mounted the
    hub stalls short of the reference at holding torques up to 0.06 N m, more than the
    rigid-bar runs show (flexarm_k1k2_6_-3)."""
    seg = arm.links[0].segments[0]
    ei = seg.dims["EI"][0]
    m = arm.payload_mass
    fr = arm.effect("joint_friction", arm.joint_names[0])
    fc, fs = (fr["coulomb"], fr["static"]) if fr is not None else (0.0, 0.0)
    return [FitParameter("EI", ei, 0.5 * ei, 1.2 * ei),
            FitParameter("rayleigh_mass", 0.0, 0.0, 5.0, 0.2),
            FitParameter("tip_mass", m, 0.5 * m, 1.5 * m),
            FitParameter("coulomb", fc, 0.0, 0.5, max(fc, 0.01)),
            FitParameter("static_excess", fs - fc, 0.0, 0.2, max(fs - fc, 0.01))]


def started_from(arm: ArmDescription, params: list) -> list:
    """``params`` started from the arm's current values of the friction (F_c, F_s - F_c,
    F_v), the link's Rayleigh damping, the rotor inertia and its tip gauge's gain and
    delay if it has one (a fit from a calibrated twin rather than from the handout), each
    clipped into its bounds."""
    j = arm.joint_names[0]
    now = {}
    fr = arm.effect("joint_friction", j)
    if fr is not None:
        now.update(coulomb=fr["coulomb"], static_excess=fr["static"] - fr["coulomb"],
                   viscous=fr["viscous"])
    damping = arm.effect("structural_damping", arm.links[0].name)
    if damping is not None:
        now["rayleigh_mass"] = damping["rayleigh_mass"]
    gear = arm.effect("gear", j)
    if gear is not None:
        now["rotor_inertia"] = gear["rotor_inertia"]
    gauge = declared_tip_gauge(arm, arm.links[0].name)
    if gauge is not None:
        now.update({k: getattr(gauge, f) for k, f in GAUGE_FIELDS.items()})
    return [dataclasses.replace(p, start=min(max(now[p.name], p.lower), p.upper))
            if p.name in now else p for p in params]


def apply_parameters(arm: ArmDescription, values: dict) -> ArmDescription:
    """The arm with fitted values (any subset of the stage 1 and 2 names) applied."""
    j = arm.joint_names[0]
    link = arm.links[0]
    effects = []
    if {"coulomb", "static_excess", "viscous"} & set(values):
        old = arm.effect("joint_friction", j)
        fv = values.get("viscous", old["viscous"] if old else 0.0)
        fc = values.get("coulomb", old["coulomb"] if old else 0.0)
        fs = fc + values.get("static_excess", (old["static"] - old["coulomb"]) if old else 0.0)
        effects.append(JointFriction(target=j, values=(fv, fc, fs, 0.01, 1e-4)))
    if "rotor_inertia" in values:
        gear = arm.effect("gear", j)
        effects.append(Gear(target=j, values=(gear["ratio"], values["rotor_inertia"])))
    if "torque_constant" in values:
        mot = arm.effect("dc_motor", j)
        v = list(mot.values)
        v[1] = v[2] = values["torque_constant"]
        effects.append(DCMotor(target=j, values=tuple(v)))
    if "rayleigh_mass" in values:
        effects.append(StructuralDamping(target=link.name,
                                         values=(0.0, values["rayleigh_mass"], 0.0)))
    out = arm.with_effects(*effects) if effects else arm
    if "EI" in values:
        seg = link.segments[0]
        dims = dict(seg.dims, EI=(values["EI"], values["EI"]))
        link = dataclasses.replace(link, segments=(dataclasses.replace(seg, dims=dims),))
        out = dataclasses.replace(out, links=(link,))
    if "tip_mass" in values:
        out = dataclasses.replace(out, payload_mass=values["tip_mass"])
    gauge = {f: values[k] for k, f in GAUGE_FIELDS.items() if k in values}
    return with_tip_gauge(out, link.name, **gauge) if gauge else out


def replay_residual(arm: ArmDescription, runs, make_policy: Callable,
                    t_final: float | None = None) -> np.ndarray:
    """Scaled replay errors of the runs (hub / HUB_SCALE, tip / TIP_SCALE)."""
    model = FlexArmModel(arm)
    parts = []
    for run in runs:
        n = len(run.t) if t_final is None else min(len(run.t),
                                                   int(round(t_final / run.dt)) + 1)
        try:
            r = replay(model, run, make_policy, t_final=t_final)
        except RuntimeError:  # a diverged trial point: a large, finite residual
            parts.append(np.full(len(run.t[:n:SUBSAMPLE]) * (1 + run.has_gauge), 1e3))
            continue
        parts.append(((r.twin_theta - run.theta[:n]) / HUB_SCALE)[::SUBSAMPLE])
        if run.has_gauge:
            parts.append(((r.twin_deflection - run.deflection[:n]) / TIP_SCALE)[::SUBSAMPLE])
    return np.concatenate(parts)


@dataclass
class CalibrationResult:
    """Fitted values, the arm with them, and the cost before and after."""

    stage: str
    values: dict
    arm: ArmDescription
    cost_nominal: float
    cost_fitted: float
    evaluations: int
    runs: tuple

    def as_dict(self) -> dict:
        return {"stage": self.stage, "values": self.values, "runs": list(self.runs),
                "rms_scaled_residual_start": self.cost_nominal,
                "rms_scaled_residual_fitted": self.cost_fitted,
                "evaluations": self.evaluations}


def fit_values(params: list, residual: Callable, max_nfev: int = 12,
               progress: Callable | None = None) -> tuple:
    """Bounded least squares of ``params`` (FitParameters) on ``residual(values)``, finite
    differences, parameters scaled to their starts; the cost is rough, so the best point
    evaluated is kept, not the last. Returns (values, RMS of that residual, evaluations)."""
    start = np.array([p.nominal if p.start is None else p.start for p in params])
    scale = np.array([max(abs(s), 1e-3 * p.upper) for s, p in zip(start, params)])
    lo = np.array([p.lower for p in params]) / scale
    hi = np.array([p.upper for p in params]) / scale
    x0 = np.clip(start / scale, lo, hi)
    names = [p.name for p in params]
    count = [0]
    best = [np.inf, x0]

    def fun(x):
        count[0] += 1
        vals = dict(zip(names, x * scale))
        r = residual(vals)
        cost = float(np.sqrt(np.mean(r ** 2)))
        if cost < best[0]:
            best[:] = [cost, x.copy()]
        if progress is not None:
            progress(count[0], cost, vals)
        return r

    least_squares(fun, x0, bounds=(lo, hi), diff_step=0.05, max_nfev=max_nfev, x_scale=1.0)
    return {n: float(v) for n, v in zip(names, best[1] * scale)}, best[0], count[0]


def calibrate(arm: ArmDescription, runs, params: list, make_policy: Callable, *,
              stage: str = "", t_final: float | None = None, max_nfev: int = 12,
              progress: Callable | None = None,
              arm_of: Callable | None = None) -> CalibrationResult:
    """:func:`fit_values` of ``params`` on the replay of ``runs``; ``arm_of(arm, values)``
    makes the trial arm (default :func:`apply_parameters`)."""
    arm_of = arm_of or apply_parameters
    r0 = replay_residual(arm, runs, make_policy, t_final)  # the uncalibrated twin
    values, cost, count = fit_values(
        params, lambda v: replay_residual(arm_of(arm, v), runs, make_policy, t_final),
        max_nfev, progress)
    return CalibrationResult(stage=stage, values=values, arm=arm_of(arm, values),
                             cost_nominal=float(np.sqrt(np.mean(r0 ** 2))),
                             cost_fitted=cost, evaluations=count,
                             runs=tuple(r.name for r in runs))


def calibrate_cuboulder(rigid_arm: ArmDescription, flexible_arm: ArmDescription, runs: dict,
                        make_policy: Callable, progress: Callable | None = None,
                        max_nfev: int = 12, gauge: tuple = (),
                        link_start: ArmDescription | None = None) -> tuple:
    """Stage 1 on the rigid fit runs, then stage 2 on the flexible fit runs (with ``gauge``,
    :func:`with_gauge`, also the lab's tip gauge's fields), from the handout's link or
    from ``link_start``'s link values (:func:`started_from`, the servo of stage 1 put in);
    returns (servo result, link result); the link result's arm is the calibrated twin."""
    servo = calibrate(rigid_arm, [runs[n] for n in CUBOULDER_SPLIT["servo_fit"]],
                      servo_parameters(rigid_arm), make_policy, stage="servo",
                      t_final=SERVO_WINDOW, max_nfev=max_nfev, progress=progress)
    servo_vals = dict(servo.values)
    if link_start is None:
        flex0 = apply_parameters(flexible_arm, servo_vals)
        params = with_gauge(link_parameters(flex0), gauge)
    else:   # the start's link stage (its friction and gauge too) on stage 1's servo
        own = {p.name for p in link_parameters(link_start)}
        flex0 = apply_parameters(link_start, {k: v for k, v in servo_vals.items()
                                              if k not in own})
        params = started_from(flex0, with_gauge(link_parameters(flex0), gauge))
    link = calibrate(flex0, [runs[n] for n in CUBOULDER_SPLIT["link_fit"]], params,
                     make_policy, stage="link", max_nfev=max_nfev, progress=progress)
    kept = declared_tip_gauge(flex0, flex0.links[0].name)   # the start's, where not fitted
    kept = {k: getattr(kept, f) for k, f in GAUGE_FIELDS.items()} if kept else {}
    link.values = {**servo_vals, **kept, **link.values}
    return servo, link


def calibrated_dict(nominal: dict, values: dict, name: str) -> dict:
    """A nominal arm description (parsed YAML) with the fitted values written in."""
    out = {**nominal, "name": name,
           "description": f"{nominal.get('description', name)}; calibrated (issue 9)"}
    effects = []
    replaced = {"joint_friction"} if "coulomb" in values else set()
    replaced |= {"structural_damping"} if "rayleigh_mass" in values else set()
    for e in nominal.get("effects", []):
        e = dict(e)
        if e["type"] in replaced:   # a calibrated description refitted: the new values
            continue
        if e["type"] == "gear" and "rotor_inertia" in values:
            e["rotor_inertia"] = float(f"{values['rotor_inertia']:.5g}")
        if e["type"] == "dc_motor" and "torque_constant" in values:
            e["torque_constant"] = e["back_emf_constant"] = float(
                f"{values['torque_constant']:.5g}")
        effects.append(e)
    j = nominal["joints"][0]["name"]
    if "coulomb" in values:
        fc = values["coulomb"]
        effects.append({"type": "joint_friction", "joint": j,
                        "viscous": float(f"{values.get('viscous', 0.0):.4g}"),
                        "coulomb": float(f"{fc:.4g}"),
                        "static": float(f"{fc + values.get('static_excess', 0.0):.4g}"),
                        "stribeck_velocity": 0.01, "regularization": 1e-4})
    links = [dict(lk) for lk in nominal["links"]]
    if "rayleigh_mass" in values:
        effects.append({"type": "structural_damping", "link": links[0]["name"],
                        "rayleigh_mass": float(f"{values['rayleigh_mass']:.4g}")})
    if "EI" in values:
        links[0]["section"] = {**links[0]["section"], "EI": float(f"{values['EI']:.5g}")}
    if "tip_mass" in values:
        out["payload"] = {**nominal.get("payload", {}),
                          "mass": float(f"{values['tip_mass']:.4g}")}
    if any(k in values for k in GAUGE_FIELDS):
        sensors = [dict(x) for x in nominal.get("sensors", [])]
        tip_gauge_entry(sensors, links[0]["name"]).update(
            {f: float(f"{values[k]:.4g}") for k, f in GAUGE_FIELDS.items() if k in values})
        out["sensors"] = sensors
    out["links"], out["effects"] = links, effects
    return out


def write_preset(data: dict, path, origin: str, result: CalibrationResult) -> Path:
    """A calibrated arm description as YAML, headed by where it comes from (``origin``) and
    its fit (runs, scaled residual before and after), validated as any preset."""
    import yaml

    from flex_model.arm import arm_from_dict
    from flex_model.config import read_yaml
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"# {data['name']}: {origin}\n# fit runs: {', '.join(result.runs)}; "
                    f"scaled RMS residual {result.cost_nominal:.3f} -> "
                    f"{result.cost_fitted:.3f}\n" + yaml.safe_dump(data, sort_keys=False))
    arm_from_dict(read_yaml(path), str(path))
    return path


def write_calibrated_presets(servo: CalibrationResult, link: CalibrationResult,
                             out_dir, options: str = "") -> list:
    """quanser_cuboulder_rigid_calibrated.yaml and quanser_cuboulder_calibrated.yaml (the
    flexible one's header names the ``calibrate`` ``options`` that made it)."""
    from flex_model.arm import resolve_preset
    from flex_model.config import read_yaml
    paths = []
    for nominal, name, res in (("quanser_cuboulder_rigid", "quanser_cuboulder_rigid_calibrated",
                                servo), ("quanser_cuboulder_flexible",
                                         "quanser_cuboulder_calibrated", link)):
        data = calibrated_dict(read_yaml(resolve_preset(nominal)), res.values, name)
        paths.append(write_preset(data, Path(out_dir) / f"{name}.yaml",
                                  f"{nominal} calibrated by flex-twin real-arm calibrate"
                                  f"{options if res is link else ''} (issue 9)", res))
    return paths
