"""Synthetic diagnosis cases: closed-loop runs of a true arm with hidden effects (issue 8).

``generate_case(kind, seed, out_dir)`` writes what a user would hand the diagnosis:

- ``fit.csv``, ``holdout.csv``: two recordings of the same true unit with different
  excitation and noise (columns ``t, q<i>, v<i>, tau<i>, qset<i>, w<i>, tip_x, tip_y``:
  measured joint angle (rad) and rate (rad/s), the controller's torque command (N m), the
  reference (rad), the measured tip deflection of link i (m), the measured tip position (m));
- ``nominal_arm.yaml``: the nominal arm (loadable by :func:`flex_model.arm.load_arm`);
- ``controller.yaml``: the controller (``law: pd`` with gravity feed-forward, see
  :mod:`.synthetic_loop` for the exact law);

and ``truth.json`` (read only by the scoring, never by the diagnosis): the hidden effects
with their parameters, declared class (:data:`EQUIVALENT_KINDS`) and the parameters
scored (:data:`KEY_PARAMETERS`), the unit's scatter, the noise model and the whole true
arm description. Each recording starts at rest under the controller at qset(0) (static
equilibrium of the true arm, then 3 s of noiseless closed loop). The noise model is
:data:`.synthetic_signals.NOMINAL_NOISE` (white + AR(1) per channel, a 17-bit encoder,
torque ripple as process noise) scaled by ``noise``.

The arm is VALIDATION.md section B (thesis Example 1, two 2 m aluminium links) in the
vertical plane with gravity, with geared motors (ratio 100, 0.5 kg m^2 reflected per joint,
preset ``thesis_example1_motors``: a sampled PD needs hub inertia) and a 0.15 kg tool at
the tip. Controller: kp = (300, 100) N m/rad, kd = (60, 20) N m s/rad at 500 Hz, gravity
feed-forward (controller.yaml). Closed loop, linearized over the workspace: first mode
0.76-0.84 Hz with damping ratio 0.20-0.26 (0.15-0.20 with a 0.4 kg tool), second 5-7.3 Hz
with 0.08-0.23; after a 0.15 rad jog in 0.4 s the joints settle to 1 mrad in 4.6 s; a
larger kd settles faster but a 6 ms sensor delay then destabilises the rotor loop. The
true unit is the nominal arm with every nominal parameter scattered inside its
manufacturing tolerance (E, rho, section, payload, rotor inertia; NOMINAL_TOLERANCES,
truncated normal of sd tolerance / 2) and the hidden effect(s) of the case.

Kinds (CASE_KINDS), with the randomised magnitude (u: uniform):

- ``healthy``: scatter only;
- ``joint_friction`` (a joint): viscous u(0.5, 2) N m s/rad, Coulomb u(0.4, 1.5) N m,
  break-away 1-1.3 x Coulomb, Stribeck velocity u(0.02, 0.1) rad/s;
- ``joint_elasticity`` (a joint): gear stiffness log-u(300, 1500) N m/rad (locked-rotor
  mode 4-9 Hz), damping ratio u(0.05, 0.15) of that mode; the rotor inertia (0.5 kg m^2
  reflected) moves to the motor side of the spring, where the encoder sits (the
  controller's q is the actuator coordinate, flex_twin.diagnosis.controller);
- ``backlash`` (a joint): play half-width u(3, 8) mrad in a stiff gear spring (3000 N m/rad);
- ``structural_damping`` (a link): Rayleigh stiffness-proportional damping b u(10, 30) ms
  (zeta_k = b w_k / 2: +3-8 % at the 0.8 Hz closed-loop mode, +15-50 % at the 5-7 Hz
  one); realistic values of 1-5 ms stay below the noise with this excitation;
- ``gear`` (a joint): rotor inertia x u(1.4, 1.9) or x u(0.5, 0.7) (tolerance 5 %);
- ``payload``: tool mass 0.15 kg + u(0.05, 0.25) kg or - u(0.05, 0.1) kg (tolerance 1 %);
- ``stiffness`` (a link): E x u(1.15, 1.35) or x u(0.7, 0.85) (tolerance 5 %);
- ``torque_saturation`` (a joint): limit u(0.7, 0.9) x the smaller peak command of pilot
  runs of both recordings without the limit (moves saturate, and holds at poses whose
  gravity torque exceeds the limit sag: the arm is under-powered for its task);
- ``actuator_delay`` (a joint): 2 or 3 controller periods (4 or 6 ms; 2 ms is within the
  noise, 10 ms destabilises the rotor loop of kd = 60 N m s/rad);
- ``sensor_bias`` (a joint encoder): +-u(5, 15) mrad;
- ``sensor_delay`` (a joint's encoder and tachometer): 2 or 3 controller periods (4, 6 ms);
- ``contact_surface``: a compliant floor (stiffness u(300, 1500) N/m, damping u(5, 20) N s/m)
  u(10, 30) mm above the lowest reference tip point of either recording;
- ``base_tilt``: +-u(0.6, 2) deg;
- ``out_of_library:cogging`` (a joint): torque ripple once per motor revolution,
  u(0.4, 1.2) N m at the joint (cogging is not a hypothesis of the library);
- ``two:<kind>+<kind>``: two of the above on the same unit.

Left out, and why: ``dc_motor`` changes the command from torque to voltage (these runs
command torque; its back-EMF damping is viscous friction); ``timoshenko``: the links are
slender (beta ~ 1e4, thesis Remark 6), shear is immaterial at any realistic value;
``cogging`` is the out-of-library case.
"""
from __future__ import annotations

import copy
import json
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from flex_model.arm import arm_from_dict, resolve_preset
from flex_model.config import read_yaml
from flex_model.dynamics import FlexArmModel
from flex_model.effects import NOMINAL_TOLERANCES
from .controller import controller_from_dict
from .synthetic_loop import SensorFaults, record
from .synthetic_signals import noise_model, reference

HIDDEN_KINDS = ("joint_friction", "joint_elasticity", "backlash", "structural_damping", "gear",
                "payload", "stiffness", "torque_saturation", "actuator_delay", "sensor_bias",
                "sensor_delay", "contact_surface", "base_tilt")
CASE_KINDS = ("healthy",) + HIDDEN_KINDS + ("out_of_library:cogging",)

#: the hidden kinds a diagnosis may name instead and still be "in the declared class"
#: (flex_model.effects EQUIVALENT, in case-kind names)
EQUIVALENT_KINDS = {
    "joint_friction": ("joint_friction", "stick_slip_friction"),
    "joint_elasticity": ("joint_elasticity", "backlash", "stiffness"),
    "backlash": ("backlash", "joint_elasticity"),
    "structural_damping": ("structural_damping",),
    "gear": ("gear",),
    "payload": ("payload",),
    "stiffness": ("stiffness", "joint_elasticity"),
    "torque_saturation": ("torque_saturation",),
    "actuator_delay": ("actuator_delay", "sensor_delay"),
    "sensor_bias": ("sensor_bias", "base_tilt"),
    "sensor_delay": ("sensor_delay", "actuator_delay"),
    "contact_surface": ("contact_surface",),
    "base_tilt": ("base_tilt", "sensor_bias"),
}

#: the parameters compared with the fit ("fitted parameters within 10 % of the truth")
KEY_PARAMETERS = {
    "joint_friction": ("viscous", "coulomb"), "joint_elasticity": ("stiffness",),
    "backlash": ("half_width",), "structural_damping": ("rayleigh_stiffness",),
    "gear": ("rotor_inertia",), "payload": ("mass",), "stiffness": ("E",),
    "torque_saturation": ("limit",), "actuator_delay": ("delay",), "sensor_bias": ("bias",),
    "sensor_delay": ("delay",), "contact_surface": ("stiffness",), "base_tilt": ("angle",),
    "cogging": ("amplitude",),
}

NOMINAL_PAYLOAD = 0.15                 # kg, the tool at the tip
NOMINAL_E = 6.4e10                     # Pa, both links (thesis Example 1)
CONTROLLER = {"kp": (300.0, 100.0), "kd": (60.0, 20.0), "period": 0.002}


@dataclass
class Case:
    """Paths of a generated case and its truth (the recordings' true signals for tests)."""

    kind: str
    seed: int
    out_dir: Path
    fit_csv: Path
    holdout_csv: Path
    nominal_arm: Path
    controller: Path
    truth_json: Path
    truth: dict
    recordings: dict = field(default_factory=dict, repr=False)


def nominal_arm_dict() -> dict:
    """The nominal arm description given to the diagnosis."""
    data = copy.deepcopy(read_yaml(resolve_preset("thesis_example1_motors")))
    for lk in data["links"]:  # YAML 1.1 reads 6.4e10 as a string
        lk["material"] = {k: float(v) for k, v in lk["material"].items()}
    data["name"] = "diagnosis_two_link"
    data["description"] = ("VALIDATION.md B arm (thesis Example 1) in the vertical plane, "
                           "geared motors, 0.15 kg tool: nominal of the synthetic cases")
    data["payload"] = {"mass": NOMINAL_PAYLOAD, "inertia": 0.0}
    return data


def _rng(seed: int, *tags) -> np.random.Generator:
    return np.random.default_rng([seed] + [zlib.crc32(str(t).encode()) for t in tags])


def parse_kind(kind: str) -> tuple:
    """The hidden kinds of a case kind: () healthy, ('cogging',) or one or two kinds."""
    if kind == "healthy":
        return ()
    if kind == "out_of_library:cogging":
        return ("cogging",)
    if kind.startswith("two:"):
        parts = tuple(kind[4:].split("+"))
        if len(parts) == 2 and all(p in HIDDEN_KINDS for p in parts) and parts[0] != parts[1] \
                and set(parts) != {"backlash", "joint_elasticity"}:
            return parts
    elif kind in HIDDEN_KINDS:
        return (kind,)
    raise ValueError(f"kind: got {kind!r}; expected one of {', '.join(CASE_KINDS)} or "
                     "'two:<kind>+<kind>' with two different hidden kinds (not backlash with "
                     "joint_elasticity)")


def _scatter(data: dict, rng) -> dict:
    """Every nominal parameter drawn inside its tolerance (truncated normal, sd tol / 2)."""
    def u():
        return float(np.clip(rng.normal(0.0, 0.5), -1.0, 1.0))
    tol = NOMINAL_TOLERANCES
    out = {}
    for lk in data["links"]:
        lk["material"]["E"] *= 1 + tol["E"] * u()
        lk["material"]["rho"] *= 1 + tol["rho"] * u()
        for dim in ("side", "wall"):
            lk["section"][dim] *= 1 + tol["section"] * u()
        out[lk["name"]] = {"E": lk["material"]["E"], "rho": lk["material"]["rho"],
                           "side": lk["section"]["side"], "wall": lk["section"]["wall"]}
    data["payload"]["mass"] *= 1 + tol["payload"] * u()
    out["payload_mass"] = data["payload"]["mass"]
    for eff in data["effects"]:
        eff["rotor_inertia"] *= 1 + 0.05 * u()  # gear rotor inertia tolerance (effects.Gear)
        out[f"{eff['joint']}_rotor_inertia"] = eff["rotor_inertia"]
    return out


def _gear(data, joint):
    return next(e for e in data["effects"] if e["type"] == "gear" and e["joint"] == joint)


def _hide(kind: str, data: dict, rng, faults: dict) -> dict:
    """Add one hidden effect to the true arm's description; returns its truth entry."""
    joint = ["joint1", "joint2"][rng.integers(2)]
    link = ["link1", "link2"][rng.integers(2)]
    sign = rng.choice([-1.0, 1.0])
    entry = {"kind": kind, "target": "", "parameters": {}}
    effects = data["effects"]
    if kind == "joint_friction":
        fc = rng.uniform(0.4, 1.5)
        p = {"viscous": rng.uniform(0.5, 2.0), "coulomb": fc, "static": fc * rng.uniform(1, 1.3),
             "stribeck_velocity": rng.uniform(0.02, 0.1)}
        effects.append({"type": kind, "joint": joint, **p})
        entry.update(target=joint, parameters=p)
    elif kind in ("joint_elasticity", "backlash", "cogging"):
        gear = _gear(data, joint)
        if kind == "cogging":
            p = {"amplitude": rng.uniform(0.4, 1.2), "periods": 1.0,
                 "phase": rng.uniform(-np.pi, np.pi)}
            effects.append({"type": "cogging", "joint": joint, **p})
        else:
            jm = gear["ratio"] ** 2 * gear["rotor_inertia"]  # the rotor, on the motor side
            k = float(np.exp(rng.uniform(np.log(300), np.log(1500)))) if kind != "backlash" \
                else 3000.0
            zeta = rng.uniform(0.05, 0.15)
            spring = {"stiffness": k, "damping": 2 * zeta * np.sqrt(k * jm), "motor_inertia": jm}
            gear["rotor_inertia"] = 0.0
            effects.append({"type": "joint_elasticity", "joint": joint, **spring})
            p = spring
            if kind == "backlash":
                p = {"half_width": rng.uniform(0.003, 0.008), "smoothing": 5e-4}
                effects.append({"type": "backlash", "joint": joint, **p})
                entry["carrier"] = {"joint_elasticity": spring}
        entry.update(target=joint, parameters=p)
    elif kind == "structural_damping":
        p = {"rayleigh_stiffness": rng.uniform(0.01, 0.03)}
        effects.append({"type": kind, "link": link, **p})
        entry.update(target=link, parameters=p)
    elif kind == "gear":
        gear = _gear(data, joint)
        f = rng.uniform(1.4, 1.9) if sign > 0 else rng.uniform(0.5, 0.7)
        gear["rotor_inertia"] *= f
        entry.update(target=joint, parameters={"rotor_inertia": gear["rotor_inertia"]})
    elif kind == "payload":
        dm = rng.uniform(0.05, 0.25) if sign > 0 else -rng.uniform(0.05, 0.1)
        data["payload"]["mass"] = NOMINAL_PAYLOAD + dm
        entry["parameters"] = {"mass": data["payload"]["mass"]}
    elif kind == "stiffness":
        lk = next(lk for lk in data["links"] if lk["name"] == link)
        f = rng.uniform(1.15, 1.35) if sign > 0 else rng.uniform(0.7, 0.85)
        lk["material"]["E"] = NOMINAL_E * f
        entry.update(target=link, parameters={"E": lk["material"]["E"]})
    elif kind == "torque_saturation":
        entry.update(target=joint, parameters={"fraction": rng.uniform(0.7, 0.9)})
    elif kind == "actuator_delay":
        p = {"delay": int(rng.integers(2, 4)) * CONTROLLER["period"]}
        effects.append({"type": kind, "joint": joint, **p})
        entry.update(target=joint, parameters=p)
    elif kind == "sensor_bias":
        p = {"bias": sign * rng.uniform(0.005, 0.015)}
        faults["bias"][int(joint[-1]) - 1] = p["bias"]
        entry.update(target=joint, parameters=p)
    elif kind == "sensor_delay":
        p = {"delay": int(rng.integers(2, 4)) * CONTROLLER["period"]}
        faults["delay"][int(joint[-1]) - 1] = p["delay"]
        entry.update(target=joint, parameters=p)
    elif kind == "contact_surface":
        p = {"depth": rng.uniform(0.01, 0.03), "stiffness": rng.uniform(300, 1500),
             "damping": rng.uniform(5, 20)}
        entry["parameters"] = p
    elif kind == "base_tilt":
        p = {"angle": sign * np.radians(rng.uniform(0.6, 2.0))}
        effects.append({"type": kind, **p})
        entry["parameters"] = p
    entry["class"] = list(EQUIVALENT_KINDS.get(kind, ()))
    entry["key_parameters"] = list(KEY_PARAMETERS[kind])
    entry["parameters"] = {k: float(v) for k, v in entry["parameters"].items()}
    return entry


def _tip_rigid_y(qset) -> np.ndarray:
    """y of the rigid two-link arm's tip at the reference (2 m links)."""
    a1 = qset[:, 0]
    return 2.0 * np.sin(a1) + 2.0 * np.sin(a1 + qset[:, 1])


def _add_contact(true: dict, entry: dict, refs: dict) -> None:
    """A floor ``depth`` above the lowest rigid reference tip point of either recording, so
    that both touch it."""
    lowest = max(float(np.min(_tip_rigid_y(qset))) for _, qset in refs.values())
    p = entry["parameters"]
    p.update(x=0.0, y=lowest + p["depth"], normal_angle=float(np.pi / 2))
    true["effects"].append({"type": "contact_surface", "x": 0.0, "y": p["y"],
                            "normal_angle": p["normal_angle"], "stiffness": p["stiffness"],
                            "damping": p["damping"]})


def _add_saturation(true, entry, nominal_model, law, refs, levels, faults, seed) -> None:
    """A torque limit below the smaller peak command of pilot runs of both recordings
    without the limit."""
    j = int(entry["target"][-1]) - 1
    model = _model(true, "true unit")
    peaks = []
    for name, (t, qset) in refs.items():
        pilot = record(model, nominal_model, law, t, qset, levels, faults,
                       _rng(seed, "noise", name))
        peaks.append(float(np.max(np.abs(pilot.data[:, 5 + j]))))
    peak = min(peaks)
    p = entry["parameters"]
    p["limit"] = p["fraction"] * peak
    true["effects"].append({"type": "torque_saturation", "joint": entry["target"],
                            "limit": p["limit"]})


def controller_description() -> dict:
    """controller.yaml of the synthetic cases (flex_twin.diagnosis.controller schema)."""
    return {"controller": {"law": "pd", "kp": list(CONTROLLER["kp"]),
                           "kd": list(CONTROLLER["kd"]), "period": CONTROLLER["period"],
                           "feedforward": "gravity"}}


def _model(data: dict, source: str) -> FlexArmModel:
    return FlexArmModel(arm_from_dict(copy.deepcopy(data), source))


def generate_case(kind: str, seed: int, out_dir, duration: float = 20.0, rate: float = 500.0,
                  noise="nominal", only: int | None = None) -> Case:
    """Write a synthetic case (see the module docstring) to ``out_dir`` and return it.

    ``noise``: a level of :data:`.synthetic_signals.NOISE_LEVELS` ("none", "low",
    "nominal", "high") or a factor on the nominal noise. The same ``seed`` gives the same
    unit scatter, excitation and noise for every kind (a case differs from ``healthy`` of
    the same seed by its hidden effects only). ``only``: keep the hidden effect of that
    index alone (of a two-effect kind: with the magnitude it has in the pair).
    """
    hidden = parse_kind(kind)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    nominal = nominal_arm_dict()
    nominal_model = _model(nominal, "nominal_arm.yaml")
    controller = controller_description()
    law = controller_from_dict(controller, "controller.yaml")
    true = copy.deepcopy(nominal)
    true["name"] = "true_unit"
    scatter = _scatter(true, _rng(seed, "scatter"))
    sensor = {"bias": np.zeros(2), "delay": np.zeros(2)}
    entries = [_hide(k, true, _rng(seed, "hidden", k, j), sensor) for j, k in enumerate(hidden)
               if only is None or j == only]
    refs = {name: reference(_rng(seed, "reference", name), duration, rate)
            for name in ("fit", "holdout")}
    levels = noise_model(noise)
    faults = SensorFaults(bias=sensor["bias"],
                          delay=np.round(sensor["delay"] * rate).astype(int))
    for e in entries:
        if e["kind"] == "contact_surface":
            _add_contact(true, e, refs)
    for e in entries:
        if e["kind"] == "torque_saturation":
            _add_saturation(true, e, nominal_model, law, refs, levels, faults, seed)
    true_model = _model(true, "true unit")
    recordings = {name: record(true_model, nominal_model, law, t, qset, levels, faults,
                               _rng(seed, "noise", name)) for name, (t, qset) in refs.items()}
    case = Case(kind=kind, seed=seed, out_dir=out, fit_csv=out / "fit.csv",
                holdout_csv=out / "holdout.csv", nominal_arm=out / "nominal_arm.yaml",
                controller=out / "controller.yaml", truth_json=out / "truth.json",
                truth={}, recordings=recordings)
    recordings["fit"].to_csv(case.fit_csv)
    recordings["holdout"].to_csv(case.holdout_csv)
    case.nominal_arm.write_text(yaml.safe_dump(nominal, sort_keys=False))
    case.controller.write_text(yaml.safe_dump(controller, sort_keys=False))
    expected = "none" if not hidden else ("unexplained_or_none" if hidden == ("cogging",)
                                          else "named")
    case.truth = {"kind": kind, "seed": seed, "duration": duration, "rate": rate,
                  "noise": noise, "noise_model": {k: s.as_dict() for k, s in levels.items()},
                  "expected": expected, "hidden": entries, "scatter": scatter,
                  "true_arm": true}
    case.truth_json.write_text(json.dumps(case.truth, indent=1, default=float))
    return case
