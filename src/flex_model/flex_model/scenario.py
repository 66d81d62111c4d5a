"""Simulation scenarios of every arm, one format and one loader (:func:`load_scenario`): a
declarative YAML file (arm, initial state, joint law, loads), validated on load with
one-line errors (file, field, value, what is allowed).

Example (shipped as preset ``thesis_three_link_pd``)::

    name: thesis_three_link_pd
    arm: thesis_three_link            # preset name or path (relative to this file); a
                                      # spatial arm (DH table, URDF side file): run by
                                      # flex_model.spatial.scenario.run_spatial
    vars_per_link: 4                  # optional override (planar arms)
    kinematics: second_order          # optional override (small_deflection: thesis Eq. 1;
                                      # exact: geometrically exact, simulate only)
    axial_vars: 0                     # optional, exact only: axial strain variables per
                                      # link (extensible links; 0: inextensible)
    gravity: true                     # false: no gravity
    duration: 10.0                    # s
    sample_period: 0.005              # s (default 0.01 s; spatial: 0.005 s or the duration)
    initial:
      joint_angles_deg: [-20, 20, -20]   # or joint_angles in rad (m on a prismatic joint);
                                      # joint_values(_deg) is the same field
      joint_rates_deg_s: [0, 0, 0]    # optional; or joint_rates in rad/s (m/s)
      state: undeformed               # or: static (start at the PD/clamped equilibrium)
    control:
      pd: {kp: [...], kd: [...], setpoints_deg: [...]}   # N m/rad, N m s/rad; or setpoints (rad)
      # spatial arms: pd45: {kpp, kpv, setpoints} (seed 000 Eq. 45) instead of pd, and
      # gravity_hold: true (the initial static state's holding torques)
      setpoint_schedule:              # steps and ramps of the PD set-points (needs pd)
        - {time: 1.0, setpoints_deg: [10, 0, 0]}               # a step at 1 s
        - {time: 2.0, setpoints_deg: [20, 0, 0], ramp: 0.5}    # a ramp over 2-2.5 s
      torque_table: {t: [0, 1, 2], torques: [[..], [..], [..]]}   # N m, linear in t (planar)
    pulses:                           # joint torque pulses on [start, end); end: .inf = on
      - {joint: joint1, torque: 1000.0, start: 3.0, end: 4.0}      # (force: N, prismatic)
      - {joint: joint2, torque: 5.0, start: 1.0, end: .inf}       # to the end of the run
    tip_loads:                        # tip force (N, base frame: 2 values, spatial 3) and,
      - {force: [0.0, -10.0], torque: 0.0, start: 0.0, end: 1.0}   # planar, torque (N m)
    payload_changes:                  # pick and place: the tip payload from a time on
      - {time: 2.0, mass: 0.5, inertia: 0.001}     # spatial: inertia 3 values or 3 x 3
    integrator: {method: variable, rtol: 1.0e-7}   # or {method: fixed, step: 1.0e-4,
                                                   #     rho_inf: 0.9, newton_tol: 1e-10}
    # (the integrator's keys are also taken at the top level: step: 1.0e-4; spatial arms
    # run the fixed mode only, default step 1 ms)

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
from .inputs import ramp_fraction
from .result import SimulationResult
from .simulate import JointPD, Pulse, fixed_step, simulate
from .statics import static_equilibrium

SCENARIO_DIR = PRESET_DIR / "scenarios"
SPATIAL_SCENARIO_DIR = PRESET_DIR / "spatial" / "scenarios"


@dataclass
class Scenario:
    """A validated scenario of either arm kind (a planar ArmDescription or a spatial
    SpatialArm); :meth:`run` simulates it and returns a
    :class:`flex_model.result.SimulationResult`. The arm-kind specifics are in
    :mod:`flex_model.simulate` (planar: variable, fixed or exact) and
    :mod:`flex_model.spatial.scenario` (spatial: the compiled fixed-step loop)."""

    name: str
    arm: object                     # ArmDescription (planar) or SpatialArm
    duration: float
    sample_period: float
    joint_values: np.ndarray        # initial joint values (rad; m on a prismatic joint)
    joint_rates: np.ndarray
    start_static: bool = False
    pd: JointPD | None = None
    pulses: list = ()               # inputs.Pulse: joint torques and tip loads
    method: str = "fixed"
    step: float | None = None
    rho_inf: float = 0.9            # fixed step: generalized-alpha spectral radius
    rtol: float = 1e-7              # variable step (planar)
    tol: float = 1e-10              # Newton tolerance (spatial)
    source: str = "<memory>"
    payload_changes: tuple = ()
    setpoint_schedule: tuple = ()   # (time, setpoints (rad), ramp (s)), increasing times
    torque_table: tuple | None = None   # (t, torques): linear in t (planar)
    gravity_hold: bool = False      # spatial: the initial state's holding torques

    @property
    def spatial(self) -> bool:
        return not isinstance(self.arm, ArmDescription)

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
                (y0, a0), (y1, a1) = ramp_fraction(t, t0, r), ramp_fraction(t + T, t0, r)
                tau += kp * delta * float(a1 - a0) / T + kd * delta * float(y1 - y0) / T
            return tau
        return pulses, ramp_torque

    def model(self):
        """The arm's model: FlexArmModel (planar) or SpatialArmModel."""
        if self.spatial:
            from .spatial.dynamics import SpatialArmModel
            return SpatialArmModel(self.arm)
        return FlexArmModel(self.arm)

    def step_size(self) -> float:
        """The fixed step the run takes (it divides the sample period; planar default
        1 ms, simulate.fixed_step)."""
        return fixed_step(self.sample_period, self.step)[0]

    def initial_state(self, model=None):
        """(q0, v0) of the model's coordinates."""
        model = model or self.model()
        if self.spatial:
            from .spatial.scenario import initial_state
            return initial_state(self, model)[:2]
        if self.start_static:
            if self.pd is not None:
                q0 = static_equilibrium(model, self.pd.setpoints, joints="pd",
                                        kp=self.pd.kp).q
            else:
                q0 = static_equilibrium(model, self.joint_values, joints="clamped").q
        else:
            q0 = model.q_from_joint_angles(self.joint_values)
        return q0, model.v_from_joint_rates(self.joint_rates)

    def run(self, progress=None, model=None, advise: bool = True) -> SimulationResult:
        """Simulate the scenario; with ``advise`` the result carries :meth:`advice` and a
        run estimated more than 2 % off (it runs the scenario's first second about 6 times
        over) is a ``UserWarning`` naming the setting to use (the CLI prints the same line
        itself)."""
        model = model or self.model()
        adv = self.advice(model) if advise else None
        if adv is not None and adv.warning:
            warnings.warn(adv.warning, stacklevel=2)
        if self.spatial:
            from .spatial.scenario import run_spatial
            res = run_spatial(self, model, progress)
        else:
            res = self._run_planar(model, progress)
        res.advice = adv
        return res

    def _run_planar(self, model, progress) -> SimulationResult:
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

    def with_finer_variables(self) -> "Scenario":
        """The scenario with twice the variables on every link (spatial: bending and
        torsion variables of every beam)."""
        if not self.spatial:
            return replace(self, arm=replace(self.arm, links=tuple(
                replace(lk, n_vars=2 * lk.n_vars) for lk in self.arm.links)))

        def finer(beam):
            return replace(beam, variables=2 * beam.variables,
                           torsion_variables=2 * beam.torsion_variables)
        links = tuple(lk if lk.flexible is None else replace(lk, flexible=finer(lk.flexible))
                      for lk in self.arm.links)
        return replace(self, arm=replace(self.arm, links=links))

    def advice(self, model=None, check: bool = True):
        """:func:`flex_model.step_advice.step_advice` for this scenario (planar: the arm's
        excited modes; spatial: none) and its a-posteriori estimate
        (step_advice.estimate_error over step_advice.probe_window: the run, the run at a
        quarter of the step (variable mode: rtol / 16) and that run with twice the
        variables, :meth:`with_finer_variables`); the variable mode keeps the modal rule's
        warning and is not checked where the arm is stiff for the explicit method; a
        spatial arm without a flexible link is not checked. ``check`` False: no estimate
        (fixed mode: no warning)."""
        from . import step_advice as sa
        model = model or self.model()
        h, fixed = self.step_size(), self.method == "fixed"
        if self.spatial:
            adv = sa.StepAdvice(None, None, h, None, None)
            beams = [lk.flexible for lk in self.arm.links if lk.flexible is not None]
            check = check and bool(beams)
            label = "/".join(str(nv) for nv in sorted({b.variables for b in beams})) + \
                " variables per bending plane"
        else:
            adv = sa.step_advice(model, self.pd.setpoints if self.pd is not None else
                                 self.joint_values, method=self.method, step=h,
                                 kp=None if self.pd is None else self.pd.kp)
            label = "/".join(str(nv) for nv in sorted({lk.n_vars for lk in self.arm.links})) \
                + " variables per link"
        if not check or (not fixed and adv.warning):   # explicit and stiff: not checked
            return adv if not fixed else replace(adv, warning=None)
        jumps = [p.start for p in self.pulses] + [t for t, _, _ in self.setpoint_schedule]
        window = sa.probe_window(self.duration, self.sample_period, jumps)
        finer = self.with_finer_variables()

        def tips(divisor, factor):   # variable mode: the error follows rtol (DOPRI)
            probe = replace(finer if factor > 1 else self, duration=window,
                            step=h / divisor if fixed else self.step,
                            rtol=self.rtol if fixed else self.rtol / divisor ** 2)
            return probe.run(model=None if factor > 1 else model,
                             advise=False).tip_deflections
        est = sa.estimate_error(tips, window)
        warning = sa.error_warning(est, h, label, rtol=None if fixed else self.rtol)
        return replace(adv, estimate=est, warning=warning)


def scenario_names(spatial: bool = False) -> list[str]:
    """The scenario presets of planar arms (``spatial``: of spatial arms)."""
    return sorted(p.stem for p in (SPATIAL_SCENARIO_DIR if spatial else SCENARIO_DIR)
                  .glob("*.yaml"))


def joint_index(f: Fields, key: str, arm) -> int:
    value = f.raw(key)
    names = arm.joint_names
    if isinstance(value, str) and value in names:
        return names.index(value)
    if isinstance(value, int) and not isinstance(value, bool) and 1 <= value <= len(names):
        return value - 1
    raise f.error(key, value, f"a joint name ({', '.join(names)}) or number 1..{len(names)}")


def load_scenario(name_or_path, vars_per_link: int | None = None):
    """Load and validate a scenario of either arm kind by path or preset name (the planar
    presets, then the spatial ones): :func:`scenario_from_dict`."""
    path = Path(name_or_path)
    if not (path.suffix in (".yaml", ".yml") or path.exists()) and \
            not (SCENARIO_DIR / f"{name_or_path}.yaml").exists() and \
            (SPATIAL_SCENARIO_DIR / f"{name_or_path}.yaml").exists():
        path = SPATIAL_SCENARIO_DIR / f"{name_or_path}.yaml"
    else:
        path = resolve_preset(name_or_path, SCENARIO_DIR)
    return scenario_from_dict(read_yaml(path), str(path), Path(path).parent, vars_per_link,
                              default_name=Path(path).stem)


def _arm(f: Fields, base_dir):
    """(arm, spatial): ``arm`` a preset name (planar first), a path (relative to
    ``base_dir``) or an inline mapping; a spatial arm has a ``convention`` (DH) or ``urdf``
    key or a ``joint`` in its links, or is a spatial preset."""
    from .spatial.description import is_spatial_arm
    from .spatial.loader import load_spatial_arm, spatial_arm_from_dict
    raw = f.raw("arm")
    if isinstance(raw, dict):
        links = raw.get("links") if isinstance(raw.get("links"), list) else []
        if "convention" in raw or "urdf" in raw or \
                any(isinstance(lk, dict) and "joint" in lk for lk in links):
            return spatial_arm_from_dict(raw, f"{f.source}: arm"), True
        return arm_from_dict(raw, f"{f.source}: arm"), False
    ref = f.string("arm")
    local = Path(base_dir or Path.cwd()) / ref
    ref = local if local.suffix in (".yaml", ".yml") and local.exists() else ref
    spatial = is_spatial_arm(ref)
    try:
        return (load_spatial_arm(ref) if spatial else load_arm(ref)), spatial
    except ConfigError as exc:
        if exc.path == "<preset>":
            from .arm import preset_names
            from .spatial.description import SPATIAL_PRESET_DIR
            known = preset_names() + sorted(p.stem for p in SPATIAL_PRESET_DIR.glob("*.yaml"))
            raise f.error("arm", str(ref), "an arm file or preset name (" + ", ".join(known)
                          + ")") from None
        raise


def _arm_options(f: Fields, arm, spatial: bool, vars_per_link):
    """The arm with the scenario's ``vars_per_link`` (planar), ``kinematics`` and
    ``gravity``."""
    nv = f.integer("vars_per_link", 0, min_value=0, max_value=200)
    nv = vars_per_link if vars_per_link is not None else nv
    if spatial and nv:
        raise f.error("vars_per_link", nv, "no override on a spatial arm (its beams' "
                      "variables are set in the arm file)")
    if vars_per_link is not None or nv:
        if nv % 2:
            raise f.error("vars_per_link", nv, "an even integer >= 2")
        arm = arm.with_vars_per_link(nv)
    if f.has("kinematics"):
        kin = f.string("kinematics", choices=list(KINEMATICS))
        arm = replace(arm, kinematics=kin) if spatial else arm.with_kinematics(kin)
    if f.has("axial_vars"):
        if spatial:
            raise f.error("axial_vars", f.raw("axial_vars"), "planar arms with exact "
                          "kinematics only (spatial beams are inextensible)")
        arm = arm.with_axial_vars(f.integer("axial_vars", 0, min_value=0,
                                            max_value=AXIAL_VARS_MAX))
    if not spatial and arm.axial_vars:
        try:
            arm.check_axial()
        except ConfigError as exc:
            raise f.error("axial_vars", arm.axial_vars, exc.allowed) from None
    return arm if f.boolean("gravity", True) else arm.without_gravity()


def _initial(f: Fields, n: int, revolute: bool):
    """``initial``: (joint values (rad or m), rates (rad/s or m/s), static start). The
    values as ``joint_values`` or ``joint_angles`` (each also ``_deg``), the rates as
    ``joint_rates`` or ``joint_rates_deg_s``."""
    ini = f.mapping("initial", {})
    keys = [k for k in ("joint_values", "joint_angles") if ini.has(k) or ini.has(k + "_deg")]
    if len(keys) > 1:
        raise ini.error("joint_angles", ini.raw("joint_angles", None),
                        "'joint_values' or 'joint_angles', not both")
    q0 = ini.joint_vector((keys or ["joint_values"])[0], n, [0.0] * n, all_revolute=revolute)
    if ini.has("joint_rates") and ini.has("joint_rates_deg_s"):
        raise ini.error("joint_rates_deg_s", ini.raw("joint_rates_deg_s"),
                        "'joint_rates' (rad/s or m/s) or 'joint_rates_deg_s', not both")
    v0 = np.radians(ini.vector("joint_rates_deg_s", n, unit="deg/s")) \
        if ini.has("joint_rates_deg_s") else \
        np.array(ini.vector("joint_rates", n, [0.0] * n, unit="rad/s or m/s"), float)
    static = ini.string("state", "undeformed", choices=["undeformed", "static"]) == "static"
    ini.done(["joint_values", "joint_values_deg", "joint_angles", "joint_angles_deg",
              "joint_rates", "joint_rates_deg_s", "state"])
    return q0, v0, static


def _joint_law(ctl: Fields, arm, spatial: bool, q0, revolute: bool):
    """``control.pd`` (kp, kd, setpoints: thesis Eq. 95 with constant gains) or, on a
    spatial arm, ``control.pd45`` (seed 000's Eq. 45 gains kpp, kpv): a JointPD or None."""
    from .spatial.scenario import eq45_joint_gains
    if ctl.has("pd") and ctl.has("pd45"):
        raise ctl.error("pd45", ctl.raw("pd45"), "pd or pd45, not both (one joint law)")
    law = "pd45" if ctl.has("pd45") else "pd" if ctl.has("pd") else None
    if law is None:
        return None
    if law == "pd45" and not spatial:
        raise ctl.error("pd45", ctl.raw("pd45"), "pd (pd45 is for spatial arms)")
    n, p = arm.n_links, ctl.mapping(law)
    keys, units = (("kpp", "kpv"), ("1/s", "N m s/rad, motor side")) if law == "pd45" \
        else (("kp", "kd"), ("N m/rad or N/m", "N m s/rad or N s/m"))
    given = [np.array(p.vector(key, n, unit=u), float) for key, u in zip(keys, units)]
    for key, val in zip(keys, given):
        if np.any(val < 0):
            raise p.error(key, val.tolist(), "gains >= 0")
    kp, kd = eq45_joint_gains(arm, *given) if law == "pd45" else given
    locked = [lk.joint.name for lk in arm.links if spatial and lk.joint.motor == "locked"]
    for key, val, gain in zip(keys, given, (kp, kd)):
        bad = [nm for nm, x in zip(arm.joint_names, gain) if nm in locked and x != 0]
        if bad:
            raise p.error(key, val.tolist(), f"0 on the locked joints ({', '.join(bad)}: "
                          "a locked motor takes no torque)")
    sp = p.joint_vector("setpoints", n, list(q0), all_revolute=revolute)
    p.done(list(keys) + ["setpoints", "setpoints_deg"])
    return JointPD(kp, kd, sp)


def _torque_table(ctl: Fields, nl: int):
    """``control.torque_table``: (t, torques (len(t), nl)), linear in t (planar arms)."""
    tf = ctl.mapping("torque_table")
    tt = np.array(tf.vector("t", unit="s"))
    raw = tf.items("torques", min_len=len(tt))
    if len(raw) != len(tt) or len(tt) < 1:
        raise tf.error("torques", raw, f"one row of {nl} torques per time in t")
    rows = [Fields({"row": r}, tf.source, tf.sub("torques")).vector("row", nl, unit="N m")
            for r in raw]
    if np.any(np.diff(tt) <= 0):
        raise tf.error("t", tt.tolist(), "strictly increasing times")
    tf.done()
    return tt, np.array(rows)


def _pulses(f: Fields, arm, spatial: bool) -> list:
    """``pulses``: a joint torque (N m; ``force`` N on a prismatic joint) on [start, end)."""
    out = []
    for k, raw in enumerate(f.items("pulses", [])):
        pf = Fields(raw, f.source, f"pulses[{k}]")
        j = joint_index(pf, "joint", arm)
        joint = arm.links[j].joint if spatial else None
        if spatial and joint.motor == "locked":
            raise pf.error("joint", pf.raw("joint"), "a joint with an active motor (a "
                           "locked motor takes no torque)")
        key = "force" if spatial and joint.type == "prismatic" else "torque"
        other = "torque" if key == "force" else "force"
        if pf.has(other):
            raise pf.error(other, pf.raw(other), f"'{key}' ({arm.joint_names[j]})")
        value = pf.number(key, unit="N" if key == "force" else "N m")
        start, end = _interval(pf)
        pf.done(["joint", key, "start", "end"])
        tau = np.zeros(arm.n_links)
        tau[j] = value
        out.append(Pulse(start, end, tuple(tau)))
    return out


def _tip_loads(f: Fields, spatial: bool) -> list:
    """``tip_loads``: a tip force (N, base frame; 3 values on a spatial arm) and, planar,
    a tip torque (N m) on [start, end)."""
    out = []
    for k, raw in enumerate(f.items("tip_loads", [])):
        lf = Fields(raw, f.source, f"tip_loads[{k}]")
        force = lf.vector("force", 3, unit="N, base frame") if spatial else \
            lf.vector("force", 2, [0.0, 0.0], unit="N, base frame")
        torque = 0.0 if spatial else lf.number("torque", 0.0, unit="N m")
        start, end = _interval(lf)
        lf.done(["force", "start", "end"] + ([] if spatial else ["torque"]))
        out.append(Pulse(start, end, (), tuple(force), torque))
    return out


def _payload_changes(f: Fields, spatial: bool, duration: float) -> tuple:
    """``payload_changes``: (time, mass kg, inertia: planar kg m^2 about the tip, spatial
    3 x 3 about the end frame origin), increasing times within the run."""
    from .spatial.description import rigid_body
    out = []
    for k, raw in enumerate(f.items("payload_changes", [])):
        if not isinstance(raw, dict):
            raise f.error("payload_changes", raw, "a list of {time, mass, inertia} mappings")
        cf = Fields(raw, f.source, f"payload_changes[{k}]")
        tc = cf.number("time", nonnegative=True, unit="s")
        if spatial and (tc >= duration or (out and tc <= out[-1][0])):
            raise cf.error("time", tc, f"a time in [0, {duration:g}) s, increasing")
        if not spatial:
            out.append((tc, cf.number("mass", nonnegative=True, unit="kg"),
                        cf.number("inertia", 0.0, nonnegative=True, unit="kg m^2")))
            cf.done()
            continue
        body = Fields({key: val for key, val in raw.items() if key != "time"}, f.source,
                      f"payload_changes[{k}]")
        rb = rigid_body(body)
        if any(rb.offset):
            raise body.error("offset", list(rb.offset), "no offset (the payload sits at the "
                             "last link's end frame origin; move the frame or use the arm "
                             "file's payload)")
        out.append((tc, rb.mass, np.asarray(rb.inertia, float)))
    return tuple(out)


def _integrator(f: Fields, spatial: bool, sample: float) -> dict:
    """``integrator: {method, step, rho_inf, rtol, newton_tol}`` (each key also accepted at
    the top level): variable (planar, DOPRI, rtol) or fixed (generalized-alpha)."""
    integ = f.mapping("integrator", {})
    top = [k for k in ("method", "step", "rho_inf", "rtol", "newton_tol") if f.has(k)]
    for k in top:
        if integ.has(k):
            raise f.error(k, f.raw(k), f"'{k}' or 'integrator.{k}', not both")
    src = Fields({**integ.data, **{k: f.raw(k) for k in top}}, f.source,
                 "integrator" if f.has("integrator") else "")
    method = src.string("method", "fixed" if spatial else "variable",
                        choices=["fixed"] if spatial else ["variable", "fixed"])
    step = src.number("step", 1e-3 if spatial else 0.0, nonnegative=not spatial,
                      positive=spatial, unit="s") or None
    if spatial and step > sample:
        raise src.error("step", step, f"a step at most the sample period ({sample} s)")
    out = dict(method=method, step=step,
               rho_inf=src.number("rho_inf", 0.9, min_value=0.0, max_value=1.0),
               rtol=src.number("rtol", 1e-7, positive=True, max_value=1e-2),
               tol=src.number("newton_tol", 1e-10, positive=True, max_value=1e-4))
    src.done(["method", "step", "rho_inf", "rtol", "newton_tol"])
    return out


def scenario_from_dict(data: dict, source: str = "<memory>", base_dir: Path | None = None,
                       vars_per_link: int | None = None, default_name: str = "scenario"):
    """Validate a scenario mapping (the YAML's content) of either arm kind, one grammar:
    errors name ``source``, the field, the value and what is allowed: a
    :class:`Scenario` of a planar or a spatial arm (:func:`_arm`); fields one kind has no
    meaning for are refused."""
    f = Fields(data, source, "")
    name = f.string("name", default_name)
    arm, spatial = _arm(f, base_dir)
    motors = [e.target for e in arm.effects if e.TYPE == "dc_motor"] if spatial else []
    if motors:
        raise f.error("arm", arm.name, "an arm without dc_motor effects (on "
                      f"{', '.join(motors)}): a spatial scenario drives joint torques; "
                      "voltage commands run through integrate.simulate_fixed_compiled")
    arm = _arm_options(f, arm, spatial, vars_per_link)
    n = arm.n_links
    revolute = not spatial or all(lk.joint.type != "prismatic" for lk in arm.links)
    if is_inf(f.raw("duration", 1.0)):
        raise f.error("duration", f.raw("duration"), "a finite time > 0 s (a simulation "
                      "ends; for an open-ended run start the model node: flex-twin up)")
    duration = f.number("duration", positive=True, unit="s")
    sample = f.number("sample_period", min(0.005, duration) if spatial else 0.01,
                      positive=True, unit="s")
    if sample > duration:
        raise f.error("sample_period", sample, f"at most the duration ({duration} s)")
    integ = _integrator(f, spatial, sample)
    q0, v0, static = _initial(f, n, revolute)
    ctl = f.mapping("control", {})
    hold = spatial and ctl.boolean("gravity_hold", False)
    pd = _joint_law(ctl, arm, spatial, q0, revolute)
    schedule = setpoint_schedule(ctl, n, pd is not None, "control.pd" + (" or pd45" if
                                 spatial else ""), all_revolute=revolute)
    table = None if spatial or not ctl.has("torque_table") else _torque_table(ctl, n)
    ctl.done(["pd", "setpoint_schedule"] + (["gravity_hold", "pd45"] if spatial else
                                            ["torque_table"]))
    pulses, loads = _pulses(f, arm, spatial), _tip_loads(f, spatial)
    changes = _payload_changes(f, spatial, duration)
    f.done(["name", "arm", "vars_per_link", "kinematics", "axial_vars", "gravity", "duration",
            "sample_period", "integrator", "method", "step", "rho_inf", "rtol", "newton_tol",
            "initial", "control", "pulses", "tip_loads", "payload_changes"])
    return Scenario(name=name, arm=arm, duration=duration, sample_period=sample,
                    joint_values=q0, joint_rates=v0, start_static=static, pd=pd,
                    torque_table=table, pulses=pulses + loads, method=integ["method"],
                    rtol=integ["rtol"], step=integ["step"], tol=integ["tol"], source=source,
                    payload_changes=changes, setpoint_schedule=schedule,
                    rho_inf=integ["rho_inf"], gravity_hold=hold)


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


def _interval(f: Fields) -> tuple:
    """(start, end) of a pulse or a tip load: end after start, ``.inf`` to the run's end."""
    start = f.number("start", nonnegative=True, unit="s")
    end = math.inf if is_inf(f.raw("end")) else \
        f.number("end", nonnegative=True, unit="s (or .inf: to the end of the run)")
    if end <= start:
        raise f.error("end", end, f"a time after start ({start} s)")
    return start, end
