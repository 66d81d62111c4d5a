"""Simulation scenarios: a declarative YAML file (arm, initial state, joint law, loads).

Example (shipped as preset ``thesis_three_link_pd``)::

    name: thesis_three_link_pd
    arm: thesis_three_link            # preset name or path (relative to this file)
    vars_per_link: 4                  # optional override
    kinematics: second_order          # optional override (small_deflection: thesis Eq. 1)
    gravity: true                     # false: no gravity
    duration: 10.0                    # s
    sample_period: 0.005              # s
    initial:
      joint_angles_deg: [-20, 20, -20]
      joint_rates_deg_s: [0, 0, 0]    # optional
      state: undeformed               # or: static (start at the PD/clamped equilibrium)
    control:
      pd: {kp: [...], kd: [...], setpoints_deg: [...]}       # N m/rad, N m s/rad
      torque_table: {t: [0, 1, 2], torques: [[..], [..], [..]]}   # N m, linear in t
    pulses:                           # joint torque pulses on [start, end)
      - {joint: joint1, torque: 1000.0, start: 3.0, end: 4.0}
    tip_loads:                        # tip force (N, base frame) / torque (N m) on [start, end)
      - {force: [0.0, -10.0], torque: 0.0, start: 0.0, end: 1.0}
    payload_changes:                  # pick and place: the tip payload from a time on
      - {time: 2.0, mass: 0.5, inertia: 0.001}
    integrator: {method: variable, rtol: 1.0e-7}   # or {method: fixed, step: 1.0e-4}
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .arm import PRESET_DIR, ArmDescription, arm_from_dict, load_arm, resolve_preset
from .config import ConfigError, Fields, read_yaml
from .dynamics import FlexArmModel
from .simulate import JointPD, Pulse, SimulationResult, simulate
from .statics import static_equilibrium

SCENARIO_DIR = PRESET_DIR / "scenarios"


@dataclass
class Scenario:
    """A validated scenario; :meth:`run` simulates it."""

    name: str
    arm: ArmDescription
    duration: float
    sample_period: float
    theta0: np.ndarray
    dtheta0: np.ndarray
    start_static: bool
    pd: JointPD | None
    torque_table: tuple | None
    pulses: list
    method: str
    rtol: float
    step: float | None
    source: str
    payload_changes: tuple = ()

    def model(self) -> FlexArmModel:
        return FlexArmModel(self.arm)

    def initial_state(self, model: FlexArmModel):
        if self.start_static:
            if self.pd is not None:
                q0 = static_equilibrium(model, self.pd.setpoints, joints="pd",
                                        kp=self.pd.kp).q
            else:
                q0 = static_equilibrium(model, self.theta0, joints="clamped").q
        else:
            q0 = model.q_from_joint_angles(self.theta0)
        return q0, model.v_from_joint_rates(self.dtheta0)

    def run(self, progress=None, model: FlexArmModel | None = None) -> SimulationResult:
        model = model or self.model()
        q0, v0 = self.initial_state(model)
        policy = None
        if self.torque_table is not None:
            tt, torques = self.torque_table
            policy = lambda t, x: np.array([np.interp(t, tt, col)  # noqa: E731
                                            for col in torques.T])
        return simulate(model, q0, v0, t_final=self.duration, sample_period=self.sample_period,
                        pd=self.pd, pulses=self.pulses, policy=policy, method=self.method,
                        rtol=self.rtol, dt=self.step, payload_changes=self.payload_changes,
                        progress=progress)


def scenario_names() -> list[str]:
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml"))


def _joint_index(f: Fields, key: str, arm: ArmDescription) -> int:
    value = f.raw(key)
    names = arm.joint_names
    if isinstance(value, str) and value in names:
        return names.index(value)
    if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= len(names):
        return value - 1
    raise f.error(key, value, f"a joint name ({', '.join(names)}) or number 1..{len(names)}")


def load_scenario(name_or_path, vars_per_link: int | None = None) -> Scenario:
    """Load and validate a scenario by preset name or path."""
    path = resolve_preset(name_or_path, SCENARIO_DIR)
    return scenario_from_dict(read_yaml(path), str(path), Path(path).parent, vars_per_link,
                              default_name=Path(path).stem)


def scenario_from_dict(data: dict, source: str = "<memory>", base_dir: Path | None = None,
                       vars_per_link: int | None = None,
                       default_name: str = "scenario") -> Scenario:
    """Validate a scenario mapping (the YAML's content). ``arm`` is a preset name, a path
    (relative to ``base_dir``) or an inline arm mapping (:func:`flex_model.arm.arm_from_dict`);
    errors name ``source`` and the field."""
    src = source
    f = Fields(data, src, "")
    name = f.string("name", default_name)
    if isinstance(f.raw("arm"), dict):
        arm = arm_from_dict(f.raw("arm"), f"{src}: arm")
    else:
        arm_ref = f.string("arm")
        local = Path(base_dir or Path.cwd()) / arm_ref
        try:
            arm = load_arm(local if local.suffix in (".yaml", ".yml") and local.exists()
                           else arm_ref)
        except ConfigError as exc:
            if exc.path == "<preset>":
                raise f.error("arm", arm_ref, exc.allowed) from None
            raise
    nv = f.integer("vars_per_link", 0, min_value=0, max_value=200)
    nv = vars_per_link if vars_per_link is not None else nv
    if vars_per_link is not None or nv:
        if nv % 2:
            raise f.error("vars_per_link", nv, "an even integer >= 2")
        arm = arm.with_vars_per_link(nv)
    if f.has("kinematics"):
        arm = arm.with_kinematics(f.string("kinematics", choices=["small_deflection",
                                                                  "second_order"]))
    if not f.boolean("gravity", True):
        arm = arm.without_gravity()
    nl = arm.n_links
    duration = f.number("duration", positive=True, unit="s")
    sample = f.number("sample_period", 0.01, positive=True, unit="s")
    if sample > duration:
        raise f.error("sample_period", sample, f"at most the duration ({duration} s)")
    ini = f.mapping("initial", {})
    theta0 = np.radians(ini.vector("joint_angles_deg", nl, [0.0] * nl, unit="deg"))
    dtheta0 = np.radians(ini.vector("joint_rates_deg_s", nl, [0.0] * nl, unit="deg/s"))
    start_static = ini.string("state", "undeformed", choices=["undeformed", "static"]) == \
        "static"
    ini.done()
    ctl = f.mapping("control", {})
    pd = None
    if ctl.has("pd"):
        p = ctl.mapping("pd")
        kp = np.array(p.vector("kp", nl, unit="N m/rad"))
        kd = np.array(p.vector("kd", nl, unit="N m s/rad"))
        for key, val in (("kp", kp), ("kd", kd)):
            if np.any(val < 0):
                raise p.error(key, val.tolist(), "gains >= 0")
        sp = np.radians(p.vector("setpoints_deg", nl, list(np.degrees(theta0)), unit="deg"))
        p.done()
        pd = JointPD(kp, kd, sp)
    table = None
    if ctl.has("torque_table"):
        tf = ctl.mapping("torque_table")
        tt = np.array(tf.vector("t", unit="s"))
        raw = tf.items("torques", min_len=len(tt))
        if len(raw) != len(tt) or len(tt) < 1:
            raise tf.error("torques", raw, f"one row of {nl} torques per time in t")
        rows = [Fields({"row": r}, src, tf.sub("torques")).vector("row", nl, unit="N m")
                for r in raw]
        if np.any(np.diff(tt) <= 0):
            raise tf.error("t", tt.tolist(), "strictly increasing times")
        tf.done()
        table = (tt, np.array(rows))
    ctl.done()
    pulses = []
    for k, raw in enumerate(f.items("pulses", [])):
        pf = Fields(raw, src, f"pulses[{k}]")
        j = _joint_index(pf, "joint", arm)
        tau = np.zeros(nl)
        tau[j] = pf.number("torque", unit="N m")
        start, end = pf.number("start", nonnegative=True), pf.number("end", nonnegative=True)
        if end <= start:
            raise pf.error("end", end, f"a time after start ({start} s)")
        pf.done()
        pulses.append(Pulse(start, end, tuple(tau)))
    for k, raw in enumerate(f.items("tip_loads", [])):
        lf = Fields(raw, src, f"tip_loads[{k}]")
        force = tuple(lf.vector("force", 2, [0.0, 0.0], unit="N"))
        torque = lf.number("torque", 0.0, unit="N m")
        start, end = lf.number("start", nonnegative=True), lf.number("end", nonnegative=True)
        if end <= start:
            raise lf.error("end", end, f"a time after start ({start} s)")
        lf.done()
        pulses.append(Pulse(start, end, (), force, torque))
    changes = []
    for k, raw in enumerate(f.items("payload_changes", [])):
        cf = Fields(raw, src, f"payload_changes[{k}]")
        changes.append((cf.number("time", nonnegative=True, unit="s"),
                        cf.number("mass", nonnegative=True, unit="kg"),
                        cf.number("inertia", 0.0, nonnegative=True, unit="kg m^2")))
        cf.done()
    integ = f.mapping("integrator", {})
    method = integ.string("method", "variable", choices=["variable", "fixed"])
    rtol = integ.number("rtol", 1e-7, positive=True, max_value=1e-2)
    step = integ.number("step", 0.0, nonnegative=True, unit="s") or None
    integ.done()
    f.done()
    return Scenario(name=name, arm=arm, duration=duration, sample_period=sample,
                    theta0=theta0, dtheta0=dtheta0, start_static=start_static, pd=pd,
                    torque_table=table, pulses=pulses, method=method, rtol=rtol, step=step,
                    source=src, payload_changes=tuple(changes))
