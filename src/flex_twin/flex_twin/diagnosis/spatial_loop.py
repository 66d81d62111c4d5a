"""Spatial arms in the diagnosis engine (issue 44, item 4): the arm-model interface.

The engine (:mod:`.engine`) is the same for planar and spatial arms; what differs is what
a twin *is* and how it is replayed. A spatial arm (flex_model.spatial.SpatialArm) enters
through five small dispatches, each calling this module where the arm is spatial:

- :func:`predict` (evaluation.predict_channels): the closed-loop replay of the recording
  through a SpatialArmModel under the recorded reference. A continuous PD is put inside
  the implicit integrator (thesis Eq. 95: kp on the actuator coordinates in K, kd in D,
  kp qset(t) + ff as the joint torque, as spatial.scenario does; compiled
  generalized-alpha loop, spatial.integrate.simulate_fixed_compiled); a sampled PD reads
  the twin's actuator angle and rate at each control instant, its command held over the
  period (zero-order hold; each period restarts from the command jump's acceleration,
  integrators.restart_choice: the acceleration history carried across the jumps smears
  them, a first-order error in the step). The start: the measured joint angles and rates
  (replay.measured_start), the links in static equilibrium with the joints held.
  Channels: ``q<i>``, ``v<i>`` the actuator coordinate (the motor side of an elastic
  gear: a motor encoder), ``tau<i>`` the command, and per flexible link the tip's
  deflection in its root frame: ``w<i>`` along the beam's y (in-plane, EI_z), ``wz<i>``
  along z (out of plane, EI_y), ``phi<i>`` its twist (GJ).
- :func:`baseline_parameters` / :func:`apply_scales` (baseline.py): per link one scale
  of the section's stiffnesses (EI_y, EI_z, GJ: the material's E and G) and one of its
  mass (rhoA, rhoJ), within the planar baseline's tolerances.
- :func:`hypotheses` (hypotheses.library_hypotheses): per joint friction (with the width
  of its Coulomb transition: hypotheses.joint_friction, the planar arms' too) and the elastic
  gear (seed 003's joint type AE_xi: stiffness, damping and the motor-side inertia fitted
  together); per flexible link the bending stiffness **per plane** (``bending_stiffness_z``
  in-plane, ``bending_stiffness_y`` out of plane) and the torsion stiffness; the payload.
- :func:`apply` (Hypothesis.apply): those hypotheses on a spatial arm.
- :func:`link_variables` / :func:`with_variables` (floor.Setting): the model-form floor's
  refined twin (more variables per direction, second-order kinematics, a finer step).
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np

from flex_model.sections import SectionProfile

#: the spatial replay's largest step (s; batch.diagnose_run diagnoses spatial arms at it):
#: the engine's default 2 ms leaves a healthy Exudyn run of the spatial suite at J 3.4
#: (model form of the step: 1.35 at 1 ms, 0.81 at 0.5 ms, S-cont-healthy-s1), above the
#: gate on its own
MAX_STEP = 1e-3
#: the sampled law's periods restart at each command jump (False: carry the acceleration
#: history across it, as before 2026-12-07; bench/bench_spatial_sampled_replay.py)
SAMPLED_RESTART = True
#: the spatial hypotheses' kinds: link stiffness per plane and torsion (relative change)
PLANE_KINDS = {"bending_stiffness_z": "bend_v", "bending_stiffness_y": "bend_w",
               "torsion_stiffness": "torsion"}
#: the section quantity each kind changes (what the report states)
PLANE_NAMES = {"bending_stiffness_z": "EI_z", "bending_stiffness_y": "EI_y",
               "torsion_stiffness": "GJ"}


def is_spatial(arm) -> bool:
    from flex_model.spatial.description import SpatialArm
    return isinstance(arm, SpatialArm)


def with_effects(arm, *effects):
    """The spatial arm with these effects (replacing same type and target); a joint with
    a ``joint_elasticity`` gets its elastic gear (seed 003: gear ``elastic``)."""
    keep = tuple(e for e in arm.effects
                 if all((e.TYPE, e.target) != (n.TYPE, n.target) for n in effects))
    elastic = {e.target for e in effects if e.TYPE == "joint_elasticity"}
    links = tuple(dataclasses.replace(lk, joint=dataclasses.replace(lk.joint, gear="elastic"))
                  if lk.joint.name in elastic else lk for lk in arm.links)
    return dataclasses.replace(arm, effects=keep + tuple(effects), links=links)


def _scaled(profile: SectionProfile, stiffness=1.0, mass=1.0) -> SectionProfile:
    return SectionProfile([sg.scaled(stiffness, mass) for sg in profile.segments])


def _with_beam(arm, i: int, **profiles):
    links = list(arm.links)
    beam = dataclasses.replace(links[i].flexible, **profiles)
    links[i] = dataclasses.replace(links[i], flexible=beam)
    return dataclasses.replace(arm, links=tuple(links))


# ------------------------------------------------------------------ baseline

def baseline_parameters(arm, scale_parameter):
    """Per flexible link: ``<link>.EI`` (EI_y, EI_z, GJ together) and ``<link>.m`` (rhoA,
    rhoJ), the planar baseline's tolerances (thin-walled section, E and rho)."""
    from flex_model.effects import NOMINAL_TOLERANCES as T
    out = []
    for i, lk in enumerate(arm.links):
        if lk.flexible is None:
            continue
        out.append(scale_parameter(f"{lk.name}.EI", "EI", i, float(np.sqrt(
            T["E"] ** 2 + 10 * T["section"] ** 2))))
        out.append(scale_parameter(f"{lk.name}.m", "m", i, float(np.sqrt(
            T["rho"] ** 2 + 2 * T["section"] ** 2))))
    return out


def apply_scales(arm, params, scales):
    """The spatial arm with the baseline scales applied."""
    for p, s in zip(params, scales):
        b = arm.links[p.index].flexible
        st, ms = (float(s), 1.0) if p.kind == "EI" else (1.0, float(s))
        arm = _with_beam(arm, p.index, bend_v=_scaled(b.bend_v, st, ms),
                         bend_w=_scaled(b.bend_w, st, ms), torsion=_scaled(b.torsion, st, ms))
    return arm


# ------------------------------------------------------------------ hypotheses

def hypotheses(arm, rec, make, motor, friction) -> list:
    """The spatial hypotheses (module docstring); ``make``: hypotheses._h, ``motor``: the
    motor-side inertia's unit, range and probe (hypotheses.MOTOR_*), ``friction``: the
    joint friction hypothesis of a joint (hypotheses.joint_friction). Scales from the
    recording's torque and rate levels, as the planar library's."""
    MOTOR_INERTIA, MOTOR_RANGE, MOTOR_PROBE = motor
    taus, rates = rec.stack("tau"), rec.stack("v")
    out = []
    for j, name in enumerate(arm.joint_names):
        trms = max(float(np.sqrt(np.mean(taus[:, j] ** 2))), 1e-3)
        wrms = max(float(np.sqrt(np.mean(rates[:, j] ** 2))), 1e-3)
        k_ref = trms / 5e-3            # 5 mrad of twist at the rms torque
        out.append(friction(name, trms, wrms))
        out.append(make("joint_elasticity", name, ("stiffness", "damping", "motor_inertia"),
                        (k_ref, k_ref * 5e-3, MOTOR_INERTIA), (0, 0, 1),
                        (1e3, 100, MOTOR_RANGE),
                        [(1.0, 1.0, 1.0), (5.0, 1.0, 1.0), (1.0, 1.0, MOTOR_PROBE)],
                        probes=[(1.0, 0.0, 1.0), (1.0, 1.0, 1.0), (1.0, 0.0, MOTOR_PROBE)],
                        inverse=(True, False, False), off_at=(0.0, 0.0, 1.0)))
    for lk in arm.links:
        if lk.flexible is None:
            continue
        for kind in PLANE_KINDS:
            if kind == "torsion_stiffness" and not lk.flexible.torsion_variables:
                continue
            out.append(make(kind, lk.name, ("relative_change",), (0.1,), (-7,), (20,),
                            [(0.0,)], probes=[(-2.0,), (1.0,)]))
    out.append(make("payload", "", ("mass",), (0.1,), (-arm.payload.mass / 0.1,), (100,),
                    [(0.0,)], (1.0,)))
    return out


def apply(hyp, arm, v, friction):
    """(arm with the hypothesis ``hyp`` at its values ``v``, None); ``friction``: the
    joint_friction effect's parameters of a friction hypothesis
    (hypotheses.friction_values)."""
    from flex_model.effects import EFFECT_TYPES as E
    k = hyp.kind
    if k == "payload":
        return dataclasses.replace(arm, payload=dataclasses.replace(
            arm.payload, mass=arm.payload.mass + float(v[0]))), None
    if k in PLANE_KINDS:
        i = [lk.name for lk in arm.links].index(hyp.target)
        field = PLANE_KINDS[k]
        prof = getattr(arm.links[i].flexible, field)
        return _with_beam(arm, i, **{field: _scaled(prof, 1.0 + float(v[0]))}), None
    if k == "joint_friction":
        return with_effects(arm, E[k](hyp.target, friction)), None
    if k == "joint_elasticity":
        if not np.isfinite(v[0]):
            return arm, None
        return with_effects(arm, E[k](hyp.target, (v[0], v[1], v[2]))), None
    raise ValueError(f"hypothesis {k} is not defined for spatial arms")


def physical(hyp, v, w, twin):
    """(names, values, half-widths) of a plane hypothesis: the section value it states
    (EI_y, EI_z or GJ at the link's root); else None."""
    if hyp.kind not in PLANE_KINDS:
        return None
    lk = next(lk for lk in twin.links if lk.name == hyp.target)
    value = getattr(lk.flexible, PLANE_KINDS[hyp.kind]).segments[0].dims["EI"][0]
    return (PLANE_NAMES[hyp.kind],), [float(value)], [float(value) * w[0]
                                                      / max(1.0 + v[0], 1e-9)]


# ------------------------------------------------------------------ floor settings

def link_variables(arm) -> tuple:
    return tuple(lk.flexible.variables if lk.flexible is not None else 0 for lk in arm.links)


def with_variables(arm, variables, kinematics):
    """The spatial arm with ``variables`` per bending direction and for the twist on every
    flexible link (the floor's refinement), and the kinematics."""
    links = tuple(lk if lk.flexible is None else dataclasses.replace(
        lk, flexible=dataclasses.replace(lk.flexible, variables=n, torsion_variables=(
            n if lk.flexible.torsion_variables else 0))) for lk, n in zip(arm.links, variables))
    return dataclasses.replace(arm, links=links, kinematics=kinematics)


# ------------------------------------------------------------------ replay

def _start(model, q0, v0):
    from flex_model.spatial.analysis import static_equilibrium
    q = static_equilibrium(model, q0).q
    v = np.zeros(model.nq)
    v[model.off] = v0
    for i, m in enumerate(model.motor_index):
        if m >= 0:
            q[m], v[m] = q0[i], v0[i]
    return q, v


def _channels(model, Q, V, tau) -> dict:
    act = model.actuator_index
    ch = {}
    for i in range(model.n_links):
        ch[f"q{i + 1}"], ch[f"v{i + 1}"], ch[f"tau{i + 1}"] = Q[:, act[i]], V[:, act[i]], \
            tau[:, i]
    names = [lk.name for lk in model.arm.links]
    d = [model.tip_deflections(q) for q in Q]
    for i, name in enumerate(names):
        if name in d[0]:
            for key, kind in (("v", "w"), ("w", "wz"), ("phi", "phi")):
                ch[f"{kind}{i + 1}"] = np.array([x[name][key] for x in d])
    return ch


def _continuous(model, ctl, q0, v0, qset, ff, h, per, n):
    from flex_model.spatial.integrate import simulate_fixed_compiled
    kp, kd = ctl.joint_pd()
    act = model.actuator_index
    m = copy.copy(model)
    m.K = model.K.copy()
    D = np.zeros_like(model.K)
    for i, a in enumerate(act):
        m.K[a, a] += kp[i]
        D[a, a] += kd[i]
    k = np.arange(n * per) // per            # row r: the step from t_r to t_{r+1}
    u = kp * qset[k] + ff[k]
    run = simulate_fixed_compiled(m, q0, v0, h, n * per, joint_torques=u, damping=D,
                                  rho_inf=0.9, tol=1e-8)
    Q, V = run.q[::per], run.v[::per]
    tau = ff[:n + 1] + kp * (qset[:n + 1] - Q[:, act]) - kd * V[:, act]
    return Q, V, tau


def _sampled(model, ctl, q0, v0, qset, ff, h, per, n_periods, stride):
    """The sampled PD: ``per`` steps per control period, the state every ``stride``
    steps (the recording's samples). Each period restarts at its command's jump
    (``restart_from``): on S-samp500-healthy-s1 at 1 ms the nominal twin's J 1.73 -> 1.11,
    noise-free against Exudyn at 0.125 ms 1.29 -> 0.54 (docs/diagnosis.md)."""
    from flex_model.spatial.integrate import simulate_fixed_compiled
    kp, kd = ctl.joint_pd() if ctl.law == "pd" else (np.diag(ctl.gains),
                                                     np.diag(ctl.rate_gains))
    act = model.actuator_index
    q, v, acc = q0, v0, None
    Qs, Vs, cmds = [q0], [v0], []
    for k in range(n_periods):
        cmd = ff[k] + kp * (qset[k] - q[act]) - kd * v[act]
        cmds.append(cmd)
        run = simulate_fixed_compiled(model, q, v, h, per, joint_torques=cmd, rho_inf=0.9,
                                      tol=1e-8, **{"restart_from" if SAMPLED_RESTART
                                                   else "acceleration": acc})
        acc = run.acceleration
        Qs += list(run.q[1:])
        Vs += list(run.v[1:])
        q, v = run.q[-1], run.v[-1]
    cmds.append(ff[n_periods] + kp * (qset[n_periods] - q[act]) - kd * v[act])
    Q, V = np.array(Qs)[::stride], np.array(Vs)[::stride]
    per_sample = np.array(cmds)[(np.arange(len(Q)) * stride) // per]
    return Q, V, per_sample


def predict(ctx, arm, window):
    """The twin's channels on the context's recording (module docstring); ``window``:
    the start's fit window (s, replay.measured_start)."""
    from flex_model.spatial.dynamics import SpatialArmModel
    from .replay import Prediction, measured_start, zero_order_hold
    rec, ctl = ctx.rec, ctx.controller
    dt = min(ctx.dt, MAX_STEP)
    model = SpatialArmModel(arm)
    q0, v0 = measured_start(rec, window)
    x_q, x_v = _start(model, q0, v0)
    t_rel = rec.t - rec.t[0]
    n = len(rec.t) - 1
    if ctl.continuous:
        per = max(1, int(np.ceil(rec.dt / dt - 1e-9)))
        qset = rec.stack("qset")
        Q, V, tau = _continuous(model, ctl, x_q, x_v, qset, ctx.ff, rec.dt / per, per, n)
    else:
        period = ctl.period
        per = max(1, int(np.ceil(period / dt - 1e-9)))
        h = period / per
        stride = int(round(rec.dt / h))
        n_periods = int(round(t_rel[-1] / period))
        instants = np.arange(n_periods + 1) * period
        qset = zero_order_hold(t_rel, rec.stack("qset"), instants)
        Q, V, tau = _sampled(model, ctl, x_q, x_v, qset, ctx.ff, h, per, n_periods, stride)
    m = min(len(Q), len(rec.t))
    ch = _channels(model, Q[:m], V[:m], tau[:m])
    want = rec.residual_channels
    return Prediction(t=rec.t[:m], channels={k: ch[k] for k in want}, q=Q[:m], v=V[:m])


def feedforward(ctl, rec, n_instants):
    """The feed-forward at the control instants of a spatial arm: none, or recorded (a
    gravity feed-forward of a spatial arm is not modelled here: one-line refusal)."""
    if ctl.feedforward_mode == "none":
        return np.zeros((n_instants, ctl.n_joints))
    raise ValueError(f"{ctl.source}: feedforward {ctl.feedforward_mode!r} on a spatial arm: "
                     "the spatial replay takes feedforward: none")
