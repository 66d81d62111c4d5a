"""Simulation scenarios: a declarative YAML file (arm, initial state, joint law, loads).

Example (shipped as preset ``thesis_three_link_pd``)::

    name: thesis_three_link_pd
    arm: thesis_three_link            # preset name or path (relative to this file)
    vars_per_link: 4                  # optional override
    kinematics: second_order          # optional override (small_deflection: thesis Eq. 1;
                                      # exact: geometrically exact, simulate only)
    axial_vars: 0                     # optional, exact only: axial strain variables per
                                      # link (extensible links; 0: inextensible)
    gravity: true                     # false: no gravity
    duration: 10.0                    # s
    sample_period: 0.005              # s
    initial:
      joint_angles_deg: [-20, 20, -20]   # or joint_angles in rad (every angle key: either)
      joint_rates_deg_s: [0, 0, 0]    # optional
      state: undeformed               # or: static (start at the PD/clamped equilibrium)
    control:
      pd: {kp: [...], kd: [...], setpoints_deg: [...]}   # N m/rad, N m s/rad; or setpoints (rad)
      setpoint_schedule:              # steps and ramps of the PD set-points (needs pd)
        - {time: 1.0, setpoints_deg: [10, 0, 0]}               # a step at 1 s
        - {time: 2.0, setpoints_deg: [20, 0, 0], ramp: 0.5}    # a ramp over 2-2.5 s
      torque_table: {t: [0, 1, 2], torques: [[..], [..], [..]]}   # N m, linear in t
    pulses:                           # joint torque pulses on [start, end); end: .inf = on
      - {joint: joint1, torque: 1000.0, start: 3.0, end: 4.0}
      - {joint: joint2, torque: 5.0, start: 1.0, end: .inf}       # to the end of the run
    tip_loads:                        # tip force (N, base frame) / torque (N m) on [start, end)
      - {force: [0.0, -10.0], torque: 0.0, start: 0.0, end: 1.0}
    payload_changes:                  # pick and place: the tip payload from a time on
      - {time: 2.0, mass: 0.5, inertia: 0.001}
    integrator: {method: variable, rtol: 1.0e-7}   # or {method: fixed, step: 1.0e-4,
                                                   #     rho_inf: 0.9}

A set-point schedule is the PD of thesis Eq. 27 with a moving set-point s(t): the torque
``kp (s(t) - theta) + kd (s'(t) - theta')``, i.e. the constant-set-point PD plus
``kp (s(t) - s(0)) + kd s'(t)``. Steps enter as torque steps at their instant (exact: the
fixed-step method restarts there); ramps as that torque averaged over each sample period
and held (exact on average; the kd term is the ramp's rate).
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .arm import (AXIAL_VARS_MAX, KINEMATICS, PRESET_DIR, ArmDescription, arm_from_dict,
                  load_arm, resolve_preset)
from .config import ConfigError, Fields, read_yaml
from .dynamics import FlexArmModel
from .simulate import JointPD, Pulse, SimulationResult, fixed_step, simulate
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
    setpoint_schedule: tuple = ()   # (time, setpoints (rad), ramp (s)), increasing times
    rho_inf: float = 0.9            # fixed step: generalized-alpha spectral radius

    def setpoint_inputs(self):
        """(pulses, policy or None): the schedule's steps as torque pulses to the end of the
        run, its ramps as a policy (the ramp torque averaged over each sample period)."""
        if not self.setpoint_schedule:
            return [], None
        kp, kd = np.asarray(self.pd.kp, float), np.asarray(self.pd.kd, float)
        prev = np.asarray(self.pd.setpoints, float)
        end = self.duration + self.sample_period
        pulses, ramps = [], []
        for t, sp, ramp in self.setpoint_schedule:
            delta = np.asarray(sp, float) - prev
            prev = np.asarray(sp, float)
            if ramp > 0:
                ramps.append((t, ramp, delta))
            else:
                pulses.append(Pulse(t, max(end, t + self.sample_period), tuple(kp * delta)))
        if not ramps:
            return pulses, None
        T = self.sample_period

        def ramp_torque(t, x):
            """kp times the mean of the ramps over [t, t + T] + kd times their mean rate."""
            tau = np.zeros(len(kp))
            for t0, r, delta in ramps:
                def frac(tt):  # the ramp's fraction at tt, and its integral from t0
                    y = min(max((tt - t0) / r, 0.0), 1.0)
                    area = 0.0 if tt <= t0 else (
                        (tt - t0) ** 2 / (2 * r) if tt <= t0 + r else r / 2 + (tt - t0 - r))
                    return y, area
                (y0, a0), (y1, a1) = frac(t), frac(t + T)
                tau += kp * delta * (a1 - a0) / T + kd * delta * (y1 - y0) / T
            return tau
        return pulses, ramp_torque

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

    def run(self, progress=None, model: FlexArmModel | None = None,
            advise: bool = True) -> SimulationResult:
        """Simulate the scenario; with ``advise`` a run estimated more than 2 % off
        (:meth:`advice`; it runs the scenario's first second about 6 times over) is a
        ``UserWarning`` naming the setting to use (the CLI prints the same line itself)."""
        model = model or self.model()
        if advise:
            warning = self.advice(model).warning
            if warning:
                warnings.warn(warning, stacklevel=2)
        q0, v0 = self.initial_state(model)
        policy = None
        if self.torque_table is not None:
            tt, torques = self.torque_table
            policy = lambda t, x: np.array([np.interp(t, tt, col)  # noqa: E731
                                            for col in torques.T])
        sp_pulses, ramps = self.setpoint_inputs()
        if ramps is not None:
            policy = ramps if policy is None else (
                lambda t, x, table=policy: table(t, x) + ramps(t, x))
        # end: .inf = to the end of the run
        end = self.duration + self.sample_period
        pulses = [p if np.isfinite(p.end) else replace(p, end=max(end, p.start + end))
                  for p in self.pulses] + sp_pulses
        return simulate(model, q0, v0, t_final=self.duration, sample_period=self.sample_period,
                        pd=self.pd, pulses=pulses, policy=policy, method=self.method,
                        rtol=self.rtol, dt=self.step, rho_inf=self.rho_inf,
                        payload_changes=self.payload_changes, progress=progress)

    def advice(self, model: FlexArmModel | None = None, check: bool = True):
        """:func:`flex_model.step_advice.step_advice` (the arm's excited modes) for this
        scenario; its warning is the a-posteriori estimate (step_advice.estimate_error
        over step_advice.probe_window: the run, the run at a quarter of the step (variable
        mode: rtol / 16) and that run with twice the variables per link; the variable mode
        keeps the modal rule's warning and is not checked where the arm is stiff for the
        explicit method). ``check`` False: no estimate (fixed mode: no warning)."""
        from . import step_advice as sa
        model = model or self.model()
        h = fixed_step(self.sample_period, self.step)[0]   # the step simulate takes
        adv = sa.step_advice(model, self.pd.setpoints if self.pd is not None else self.theta0,
                             method=self.method, step=h,
                             kp=None if self.pd is None else self.pd.kp)
        fixed = self.method == "fixed"
        if not check or (not fixed and adv.warning):   # explicit and stiff: not checked
            return adv if not fixed else replace(adv, warning=None)
        jumps = [p.start for p in self.pulses] + [t for t, _, _ in self.setpoint_schedule]
        window = sa.probe_window(self.duration, self.sample_period, jumps)
        finer = replace(self.arm, links=tuple(replace(lk, n_vars=2 * lk.n_vars)
                                              for lk in self.arm.links))

        def tips(divisor, factor):   # variable mode: the error follows rtol (DOPRI)
            probe = replace(self, duration=window, step=h / divisor if fixed else self.step,
                            rtol=self.rtol if fixed else self.rtol / divisor ** 2,
                            arm=finer if factor > 1 else self.arm)
            return probe.run(model=None if factor > 1 else model,
                             advise=False).tip_deflections
        est = sa.estimate_error(tips, window)
        nv = sorted({lk.n_vars for lk in self.arm.links})
        label = f"{'/'.join(map(str, nv))} variables per link"
        warning = sa.error_warning(est, h, label, rtol=None if fixed else self.rtol)
        return replace(adv, estimate=est, warning=warning)


def scenario_names() -> list[str]:
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.yaml"))


def joint_index(f: Fields, key: str, arm: ArmDescription) -> int:
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
        arm = arm.with_kinematics(f.string("kinematics", choices=list(KINEMATICS)))
    if f.has("axial_vars"):
        arm = arm.with_axial_vars(f.integer("axial_vars", 0, min_value=0,
                                            max_value=AXIAL_VARS_MAX))
    if arm.axial_vars:
        try:
            arm.check_axial()
        except ConfigError as exc:
            raise f.error("axial_vars", arm.axial_vars, exc.allowed) from None
    if not f.boolean("gravity", True):
        arm = arm.without_gravity()
    nl = arm.n_links
    if is_inf(f.raw("duration", 1.0)):
        raise f.error("duration", f.raw("duration"), "a finite time > 0 s (a simulation "
                      "ends; for an open-ended run start the model node: flex-twin up)")
    duration = f.number("duration", positive=True, unit="s")
    sample = f.number("sample_period", 0.01, positive=True, unit="s")
    if sample > duration:
        raise f.error("sample_period", sample, f"at most the duration ({duration} s)")
    ini = f.mapping("initial", {})
    theta0 = ini.joint_vector("joint_angles", nl, [0.0] * nl)
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
        sp = p.joint_vector("setpoints", nl, list(theta0))
        p.done()
        pd = JointPD(kp, kd, sp)
    schedule = setpoint_schedule(ctl, nl, pd is not None, "control.pd")
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
        j = joint_index(pf, "joint", arm)
        tau = np.zeros(nl)
        tau[j] = pf.number("torque", unit="N m")
        start, end = pf.number("start", nonnegative=True), _end(pf)
        if end <= start:
            raise pf.error("end", end, f"a time after start ({start} s)")
        pf.done()
        pulses.append(Pulse(start, end, tuple(tau)))
    for k, raw in enumerate(f.items("tip_loads", [])):
        lf = Fields(raw, src, f"tip_loads[{k}]")
        force = tuple(lf.vector("force", 2, [0.0, 0.0], unit="N"))
        torque = lf.number("torque", 0.0, unit="N m")
        start, end = lf.number("start", nonnegative=True), _end(lf)
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
    rho_inf = integ.number("rho_inf", 0.9, min_value=0.0, max_value=1.0)
    integ.done()
    f.done()
    return Scenario(name=name, arm=arm, duration=duration, sample_period=sample,
                    theta0=theta0, dtheta0=dtheta0, start_static=start_static, pd=pd,
                    torque_table=table, pulses=pulses, method=method, rtol=rtol, step=step,
                    source=src, payload_changes=tuple(changes),
                    setpoint_schedule=schedule, rho_inf=rho_inf)


def setpoint_schedule(ctl: Fields, n: int, has_pd: bool, pd_field: str,
                      all_revolute: bool = True) -> tuple:
    """``control.setpoint_schedule`` of either scenario format: (time, set-points in SI,
    ramp) per entry, strictly increasing times, none inside the previous ramp."""
    schedule = []
    for k, raw in enumerate(ctl.items("setpoint_schedule", [])):
        sf = Fields(raw, ctl.source, f"{ctl.sub('setpoint_schedule')}[{k}]")
        if not has_pd:
            raise ctl.error("setpoint_schedule", raw, f"{pd_field} as well (the schedule "
                            "moves the PD's set-points)")
        t = sf.number("time", nonnegative=True, unit="s")
        ramp = sf.number("ramp", 0.0, nonnegative=True, unit="s")
        if schedule and (t <= schedule[-1][0] or t < schedule[-1][0] + schedule[-1][2]):
            t0, r0 = schedule[-1][0], schedule[-1][2]
            raise sf.error("time", t, f"a time >= {t0 + r0:.6g} s (the end of the previous "
                           "ramp)" if r0 > 0 else f"a time > {t0:.6g} s (the previous step)")
        schedule.append((t, sf.joint_vector("setpoints", n, all_revolute=all_revolute), ramp))
        sf.done(["time", "setpoints", "setpoints_deg", "ramp"])
    return tuple(schedule)


def is_inf(value) -> bool:
    if isinstance(value, str):
        value = value.strip().lower()
        return value in (".inf", "inf", "+.inf", "+inf", "infinity")
    return isinstance(value, float) and math.isinf(value) and value > 0


def _end(f: Fields) -> float:
    """``end`` of a pulse or tip load: a time >= 0 s, or .inf (to the end of the run)."""
    if is_inf(f.raw("end")):
        return math.inf
    return f.number("end", nonnegative=True, unit="s (or .inf: to the end of the run)")
