"""The hypotheses of the diagnosis: effects of flex_model.effects with 1-3 free parameters.

Each effect type of the library (``Effect.LIBRARY``) that can act on a torque-controlled
planar arm becomes one hypothesis per target (joint, link or arm), with the parameters the
fit frees, their bounds and scales taken from the data (torque and speed levels), and the
equivalence class the effect declares (``Effect.EQUIVALENT``; a named effect counts as
right when it is the hidden one or in its class). Parameters not freed keep their "off"
or a stated fixed value:

==================== ========================================= ===========================
hypothesis           free parameters                           fixed
==================== ========================================= ===========================
joint_friction       viscous, coulomb, static - coulomb,       Stribeck velocity 0.05 rad/s
                     regularization (the width of the Coulomb
                     transition, from 1e-3 rad/s up:
                     :func:`joint_friction`)
stick_slip_friction  viscous, coulomb, static - coulomb        Stribeck velocity 0.05 rad/s,
                     (voltage command: coulomb, static -       pre-sliding F_s / sigma_0
                     coulomb; viscous 0, see below)            1 mrad, elastic fraction 0.5,
                                                               bristle damping
                                                               2 sqrt(sigma_0 J_j)
gear                 rotor_inertia (ratio of the nominal, or 1)
joint_elasticity     stiffness (fitted as a compliance),       motor_inertia: the gear's
                     damping; motor_inertia where no gear      n^2 J_r (moved there)
                     declares a rotor
backlash             half_width, stiffness and damping of its  smoothing 1e-4
                     spring (the gear's, as joint_elasticity)
torque_saturation    limit
actuator_delay       delay (quantized to the control period)
structural_damping   rayleigh_stiffness                        (internal friction: same
                                                               class)
base_tilt            angle
contact_surface      y (floor height), stiffness, damping      x 0, normal up
payload              mass (arm field, not an effect)
sensor_bias          bias of the joint encoder (seen by the controller too)
sensor_delay         delay of the joint encoder and rate (whole control periods)
gauge_delay          delay of a link's tip-deflection gauge    in steps of 10 control
                     and its rate, read by the law too         periods; only for a link
                                                               whose ``tip_deflection``
                                                               sensor the arm declares
stiffness            relative change of a link's E beyond its tolerance
==================== ========================================= ===========================

``stick_slip_friction`` (elasto-plastic, Dupont et al. 2002) is in the class of
``joint_friction``: in sliding the two are one law (the same three levels), they differ
near rest, where the tanh-regularized law creeps at eps atanh(tau / F_s) and cannot keep
the place where a joint stuck, the elasto-plastic one holds it within its pre-sliding
displacement. The fit names the one that explains more. The pre-sliding displacement is
fixed (a joint encoder rarely resolves it); the bristle damping is critical for the
apparent inertia J_j of the joint (everything else free) at the recording's first pose.

Under a voltage command (a ``dc_motor`` joint) the joint's viscous damping is the motor's
back-EMF damping n^2 K_t K_e / R (the baseline recalibrates it within tolerance; the
``dc_motor`` effect declares it equivalent to viscous friction): the stick-slip hypothesis
then frees only the sticking, ``coulomb`` and ``static_excess`` (viscous 0; a viscous
excess is ``joint_friction``'s), and its probes are break-away torques stated in N m at the
joint, F_s = :data:`SLIP_BREAKAWAY` x the joint torque T = g tau_rms that the measured
command's rms gives at stall (g = n K_t / R, :func:`command_gain`), sliding at F_c =
:data:`SLIP_SLIDING` F_s (the Quanser SRV02's gearbox: T 0.032-0.037 N m on the CU Boulder
runs, break-away 0.064-0.078 N m in the holds, docs/real-arms.md). In volts, the scales
of the torque-commanded arms (0.1 x the rms command) put the probes at 0.16 N m s/rad
of viscous friction (twice the back-EMF damping), where a fit of one step's hold
reproduces the hold with a viscous term that does not transfer to the next step.

The delays are not screened under a continuous law (the replay cannot delay it).
Left out: ``dc_motor`` under a torque command (its parameters act only on a voltage
command), ``timoshenko`` (slender links: beta >> 100, no measurable effect), ``cogging``
(``LIBRARY = False``: the out-of-library case).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from flex_model.effects import EFFECT_TYPES
from flex_model.sensors import Sensor, declared_tip_gauge, with_tip_gauge
from . import spatial_loop

#: the friction hypothesis's least regularization eps (rad/s; x = 0 of its width) and
#: its width per unit of x: eps = FRICTION_EPS + FRICTION_WIDTH x (:func:`joint_friction`)
FRICTION_EPS = 1e-3
FRICTION_WIDTH = 0.01
STRIBECK_VELOCITY = 0.05
MOTOR_INERTIA = 1e-3
#: an elastic joint without a declared rotor: its motor-side inertia in units of
#: MOTOR_INERTIA up to this, probed (and started) at MOTOR_PROBE
MOTOR_RANGE = 1e4
MOTOR_PROBE = 30.0
BACKLASH_SMOOTHING = 1e-4
#: stick_slip_friction: the pre-sliding displacement F_s / sigma_0 (rad) and the elastic
#: (drift-free) share of it (Dupont's z_ba sigma_0 / F_c)
PRESLIDING = 1e-3
ELASTIC_FRACTION = 0.5
#: stick-slip probes under a voltage command: break-away F_s in units of the joint torque
#: T = g tau_rms, and the sliding level's share F_c / F_s
SLIP_BREAKAWAY = (1.0, 1.5, 2.0)
SLIP_SLIDING = 0.6
#: gauge_delay's step in control periods (a strain gauge's chain lags tens of ms: the
#: Quanser lab's 45-80 ms, python -m studies.link_response)
GAUGE_DELAY_STEP = 10


@dataclass(frozen=True)
class Hypothesis:
    """An effect on a target with free parameters (values = x * scale)."""

    kind: str
    target: str
    names: tuple
    scale: tuple
    lower: tuple          # bounds of x (scaled)
    upper: tuple
    starts: tuple         # start points of x (multi-start where non-convex)
    probes: tuple         # x of the screening probes
    discrete: bool = False  # delays: x in whole control periods
    linear: bool = True   # screening by the linearized fit (else: the best probe's cost)
    inverse: tuple = ()   # per parameter: value = scale / x (a compliance; x = 0: rigid)
    fit_from_probe: bool = True   # the fit starts at the best probe, then the starts
    off_at: tuple = ()    # x of the "off" value when it is not 0 (see :meth:`off`)
    fixed: tuple = ()     # fixed values the effect needs (stick-slip: the joint inertia)

    @property
    def label(self) -> str:
        return f"{self.kind}@{self.target}" if self.target else self.kind

    def values(self, x) -> np.ndarray:
        v = np.asarray(x, float) * np.asarray(self.scale)
        for k, inv in enumerate(self.inverse):
            if inv:
                v[k] = self.scale[k] / x[k] if x[k] > 0 else np.inf
        return v

    def value_halfwidths(self, x, half) -> np.ndarray:
        """Half-widths of the parameter intervals for half-widths ``half`` of x."""
        w = np.abs(np.asarray(half, float) * np.asarray(self.scale))
        for k, inv in enumerate(self.inverse):
            if inv:
                w[k] = self.scale[k] * half[k] / max(x[k], 1e-300) ** 2
        return w

    def off(self) -> np.ndarray:
        """x of the "off" value (no effect): 0 unless declared (a saturation's upper bound,
        a gear's nominal rotor inertia)."""
        return np.array(self.off_at, float) if self.off_at else np.zeros(len(self.names))

    def physical(self, values, halfwidths, twin) -> tuple[tuple, list, list]:
        """(names, values, half-widths) as the updated arm states them: friction's
        break-away torque ``static`` (coulomb + excess), a link's Young's modulus ``E``."""
        v, w = list(values), list(halfwidths)
        if self.kind == "joint_friction":   # with its width (:func:`joint_friction`)
            return ("viscous", "coulomb", "static", "regularization"), \
                [v[0], v[1], v[1] + v[2], FRICTION_EPS + v[3]], \
                [w[0], w[1], float(np.hypot(w[1], w[2])), w[3]]
        plane = spatial_loop.physical(self, v, w, twin)
        if plane is not None:
            return plane
        if self.names == ("coulomb", "static_excess"):   # sticking only: viscous 0
            return ("coulomb", "static"), [v[0], v[0] + v[1]], \
                [w[0], float(np.hypot(w[0], w[1]))]
        if self.kind == "stick_slip_friction":
            return ("viscous", "coulomb", "static"), [v[0], v[1], v[1] + v[2]], \
                [w[0], w[1], float(np.hypot(w[1], w[2]))]
        if self.kind == "stiffness":
            seg = next(lk for lk in twin.links if lk.name == self.target).segments[0]
            if seg.shape == "explicit":  # no Young's modulus: the link's E I at its root
                name, value = "EI", seg.dims["EI"][0]
            else:
                name, value = "E", seg.E
            return (name,), [value], [value * w[0] / max(1.0 + v[0], 1e-9)]
        return self.names, v, w

    def apply(self, arm, x):
        """(arm with the effect, sensors bias vector or None)."""
        v = self.values(x)
        if spatial_loop.is_spatial(arm):
            return spatial_loop.apply(self, arm, v, friction_values(v)
                                      if self.kind == "joint_friction" else None)
        E = EFFECT_TYPES
        k = self.kind
        if k == "payload":
            return dataclasses.replace(arm, payload_mass=arm.payload_mass + v[0]), None
        if k in ("sensor_bias", "sensor_delay"):
            field = "bias" if k == "sensor_bias" else "delay"
            s = Sensor(name=f"{self.target}/joint_encoder", kind="joint_encoder",
                       target=self.target, **{field: float(v[0])})
            return dataclasses.replace(arm, sensors=arm.sensors + (s,)), None
        if k == "gauge_delay":
            return with_tip_gauge(arm, self.target, delay=float(v[0])), None
        if k == "stiffness":
            i = [lk.name for lk in arm.links].index(self.target)
            links = list(arm.links)
            links[i] = dataclasses.replace(links[i], segments=tuple(
                sg.scaled(stiffness=1.0 + v[0]) for sg in links[i].segments))
            return dataclasses.replace(arm, links=tuple(links)), None
        if k == "joint_friction":
            eff = (E[k](self.target, friction_values(v)),)
        elif k == "stick_slip_friction":
            levels = v if len(v) == 3 else np.concatenate([[0.0], v])   # viscous 0
            eff = (E[k](self.target, stick_slip_values(levels, self.fixed[0])),)
        elif k == "gear":
            old = arm.effect("gear", self.target)
            ratio = old["ratio"] if old else 1.0
            eff = (E[k](self.target, (ratio, v[0])),)
        elif k in ("joint_elasticity", "backlash"):
            stiffness = v[0] if k == "joint_elasticity" else v[1]
            if not np.isfinite(stiffness):
                return arm, None
            # the rotor of the joint's gear moves to the motor side of the spring: the
            # motor coordinate carries n^2 J_r (a bare motor coordinate under the sampled
            # PD would need a far shorter period)
            gear = arm.effect("gear", self.target)
            jm = v[2] if k == "joint_elasticity" and len(v) == 3 else MOTOR_INERTIA
            eff = ()
            if gear is not None and gear["rotor_inertia"] > 0:
                jm = gear["ratio"] ** 2 * gear["rotor_inertia"]
                eff = (dataclasses.replace(gear, values=(gear["ratio"], 0.0)),)
            eff += (E["joint_elasticity"](self.target, (stiffness, v[1] if k ==
                                                        "joint_elasticity" else v[2], jm)),)
            if k == "backlash":
                eff += (E[k](self.target, (v[0], BACKLASH_SMOOTHING)),)
        elif k == "torque_saturation":
            eff = (E[k](self.target, (v[0],)),)
        elif k == "actuator_delay":
            eff = (E[k](self.target, (v[0],)),)
        elif k == "structural_damping":
            eff = (E[k](self.target, (0.0, 0.0, v[0])),)
        elif k == "base_tilt":
            eff = (E[k]("", (v[0],)),)
        elif k == "contact_surface":
            eff = (E[k]("", (0.0, v[0], np.pi / 2, v[1], v[2])),)
        else:
            raise ValueError(f"unknown hypothesis {k}")
        return arm.with_effects(*eff), None

    def effect_dicts(self, arm, x) -> list:
        """The ``effects:``/``sensors:`` entries of the updated arm YAML for the fitted x."""
        values = self.values(x)
        probe, _ = self.apply(arm, x)
        if self.kind == "payload":
            return []
        if self.kind in ("sensor_bias", "sensor_delay"):
            field = "bias" if self.kind == "sensor_bias" else "delay"
            return [{"sensor": {"kind": "joint_encoder", "joint": self.target,
                                field: float(values[0])}}]
        if self.kind == "gauge_delay":
            return [{"sensor": {"kind": "tip_deflection", "link": self.target,
                                "delay": float(values[0])}}]
        if self.kind == "stiffness":
            return [{"link_stiffness": {"link": self.target,
                                        "relative_change": float(values[0])}}]
        out = []
        new = [e for e in probe.effects if e not in arm.effects]
        for e in new:
            d = {"type": e.TYPE}
            if e.TARGET in ("joint", "link"):
                d[e.TARGET] = e.target
            for p, val in zip(e.PARAMETERS, e.values):
                if val != p.off and np.isfinite(val):
                    d[p.name] = float(val)
            out.append(d)
        return out


@dataclass(frozen=True)
class HypothesisPair:
    """Two hypotheses fitted jointly: effects that mask each other, so that neither alone
    explains the held-out data (an encoder bias and a joint elasticity both move the tip
    under gravity). x is the first's parameters followed by the second's."""

    first: Hypothesis
    second: Hypothesis
    discrete = False
    fit_from_probe = True

    @property
    def label(self) -> str:
        return f"{self.first.label}+{self.second.label}"

    @property
    def names(self) -> tuple:
        return self.first.names + self.second.names

    @property
    def lower(self) -> tuple:
        return self.first.lower + self.second.lower

    @property
    def upper(self) -> tuple:
        return self.first.upper + self.second.upper

    @property
    def starts(self) -> tuple:
        return (self.first.starts[0] + self.second.starts[0],)

    def off(self) -> np.ndarray:
        return np.concatenate([self.first.off(), self.second.off()])

    def parts(self, x) -> list:
        """[(hypothesis, its x), ...]."""
        n = len(self.first.names)
        x = np.asarray(x, float)
        return [(self.first, x[:n]), (self.second, x[n:])]

    def apply(self, arm, x):
        (a, xa), (b, xb) = self.parts(x)
        return b.apply(a.apply(arm, xa)[0], xb)


def joint_friction(joint, trms, wrms) -> Hypothesis:
    """Joint friction with the width of its Coulomb transition, on planar and spatial arms
    alike: viscous, Coulomb, the Stribeck excess and the regularization eps of
    tanh(w / eps) (flex_model.effects.friction_law), eps = :data:`FRICTION_EPS` +
    :data:`FRICTION_WIDTH` x, x in [0, 10]; scales from the joint's rms torque ``trms``
    and rate ``wrms``. The speed over which a joint's Coulomb torque builds up
    (pre-sliding, lubrication) is the joint's, not known beforehand: held at 1 mrad/s
    against the independent suites' 0.02 rad/s the law is mis-shaped at the low speeds
    every set-point step passes through, and the fitted levels compensate (planar suite:
    viscous 28-73 % high, Coulomb 29-54 % low; spatial
    S-samp500-two-bending-link2-z+joint_friction2-s2: the friction's remainder hid link
    2's softer EI_z)."""
    return _h("joint_friction", joint, ("viscous", "coulomb", "static_excess",
                                        "regularization"),
              (0.1 * trms / wrms, 0.1 * trms, 0.1 * trms, FRICTION_WIDTH), (0, 0, 0, 0),
              (50, 20, 20, 10), [(1.0, 1.0, 0.3, 1.0)],
              probes=[(1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0),
                      (0.0, 1.0, 0.0, 2.0)])


def friction_values(v) -> tuple:
    """The joint_friction effect's parameters (viscous, coulomb, static, Stribeck
    velocity, regularization) of the :func:`joint_friction` hypothesis's values ``v``."""
    return (v[0], v[1], v[1] + v[2], STRIBECK_VELOCITY, FRICTION_EPS + float(v[3]))


def stick_slip_values(v, inertia) -> tuple:
    """The stick_slip_friction parameters (flex_model.effects.stick_slip) of the
    hypothesis' values (viscous, coulomb, static excess) on a joint of apparent inertia
    ``inertia``: Stribeck velocity :data:`STRIBECK_VELOCITY`, pre-sliding displacement
    F_s / sigma_0 = :data:`PRESLIDING`, critically damped bristles."""
    fv, fc, fs = v[0], v[1], v[1] + v[2]
    fc = max(fc, 1e-3 * fs)   # a break-away needs a sliding level > 0 (the effect's check)
    sigma0 = min(max(fs / PRESLIDING, 1e-3), 1e12)
    return (fv, fc, fs, STRIBECK_VELOCITY, sigma0, 2.0 * np.sqrt(sigma0 * inertia),
            ELASTIC_FRACTION)


def command_gain(arm, controller, joint: str) -> float:
    """N m at the joint per unit of command: 1 under a torque command; under a voltage
    command into a ``dc_motor`` the stall torque per volt n K_t / R (n: the gear's ratio)."""
    motor = arm.effect("dc_motor", joint)
    if getattr(controller, "output", "torque") != "voltage" or motor is None:
        return 1.0
    gear = arm.effect("gear", joint)
    n = gear["ratio"] if gear is not None else 1.0
    return float(n * motor["torque_constant"] / motor["resistance"])


def _slip_probes(torque) -> list:
    """Sticking-only probe points (x = coulomb, static excess in units of ``torque``) at
    the break-away levels :data:`SLIP_BREAKAWAY` x ``torque``, sliding at
    :data:`SLIP_SLIDING` of it."""
    return [(SLIP_SLIDING * m, (1.0 - SLIP_SLIDING) * m) for m in SLIP_BREAKAWAY]


def joint_inertias(arm, theta) -> np.ndarray:
    """Apparent inertia of every joint at the joint angles ``theta`` with everything else
    free, 1 / (G B^-1 G^T)_jj (kg m^2): what a stiff bristle spring at the joint moves."""
    from flex_model.dynamics import FlexArmModel
    m = FlexArmModel(arm)
    B = m.mass_matrix(m.q_from_joint_angles(np.asarray(theta, float)))
    return 1.0 / np.einsum("ij,ji->i", m.Ga, np.linalg.solve(B, m.Ga.T))


def parts_of(hyp, x) -> list:
    """[(hypothesis, x), ...] of a hypothesis or a pair."""
    return hyp.parts(x) if isinstance(hyp, HypothesisPair) else [(hyp, np.asarray(x, float))]


def _h(kind, target, names, scale, lower, upper, starts, probe=None, probes=None,
       discrete=False, linear=True, inverse=(), fit_from_probe=True, off_at=(), fixed=()):
    """A hypothesis; ``probe`` (one value per parameter) gives one probe per parameter
    from the off value, ``probes`` lists whole probe points."""
    if probes is None:
        probes = []
        for k, p in enumerate(probe):
            x = [0.0] * len(names)
            x[k] = p
            probes.append(x)
    return Hypothesis(kind, target, tuple(names), tuple(float(s) for s in scale),
                      tuple(lower), tuple(upper), tuple(tuple(s) for s in starts),
                      tuple(tuple(p) for p in probes), discrete, linear, tuple(inverse),
                      fit_from_probe, tuple(off_at), tuple(fixed))


def _elasticity(joint, k_ref, has_rotor) -> Hypothesis:
    """The joint elasticity of a joint: stiffness (as a compliance) and damping of the
    spring (seed 002 Eqs. 11-14), and, behind a joint whose nominal arm declares no rotor,
    the motor-side inertia fitted with them (issue 44; seed 003's elastic joint carries its
    rotor): from :data:`MOTOR_INERTIA` (x = 1) up to 10 kg m^2. A gear's rotor is the
    motor side's, n^2 J_r, known within its tolerance (:meth:`Hypothesis.apply`)."""
    if has_rotor:
        return _h("joint_elasticity", joint, ("stiffness", "damping"), (k_ref, k_ref * 5e-3),
                  (0, 0), (1e3, 100), [(1.0, 1.0), (5.0, 1.0)],
                  probes=[(1.0, 0.0), (1.0, 1.0)], inverse=(True, False))
    return _h("joint_elasticity", joint, ("stiffness", "damping", "motor_inertia"),
              (k_ref, k_ref * 5e-3, MOTOR_INERTIA), (0, 0, 1), (1e3, 100, MOTOR_RANGE),
              [(1.0, 1.0, 1.0), (5.0, 1.0, 1.0), (1.0, 1.0, MOTOR_PROBE)],
              probes=[(1.0, 0.0, 1.0), (1.0, 1.0, 1.0), (1.0, 0.0, MOTOR_PROBE)],
              inverse=(True, False, False), off_at=(0.0, 0.0, 1.0))


def library_hypotheses(arm, rec, controller, exclude=(), twin_peaks=None) -> list[Hypothesis]:
    """Every hypothesis for this arm and recording (scales from the measured torque and
    speed levels); ``exclude``: labels already accepted; ``twin_peaks``: the largest
    command of the current twin per joint (the torque a saturation would clip; default:
    the measured command's). A spatial arm: :func:`.spatial_loop.hypotheses`."""
    if spatial_loop.is_spatial(arm):
        out = spatial_loop.hypotheses(arm, rec, _h, (MOTOR_INERTIA, MOTOR_RANGE, MOTOR_PROBE),
                                      joint_friction)
        return [h for h in out if h.label not in exclude]
    taus = rec.stack("tau")
    rates = rec.stack("v")
    out = []
    inertia = joint_inertias(arm, rec.stack("q")[0])
    for j, name in enumerate(arm.joint_names):
        tmax = max(float(np.max(np.abs(taus[:, j])) if twin_peaks is None
                         else twin_peaks[j]), 1e-3)
        trms = max(float(np.sqrt(np.mean(taus[:, j] ** 2))), 1e-3)
        wrms = max(float(np.sqrt(np.mean(rates[:, j] ** 2))), 1e-3)
        rotor = arm.effect("gear", name)
        has_rotor = bool(rotor and rotor["rotor_inertia"])
        k_ref = max(trms, 1.0) / 5e-3          # 5 mrad of twist at the rms torque
        friction_scale = (0.1 * trms / wrms, 0.1 * trms, 0.1 * trms)
        gain = command_gain(arm, controller, name)
        if gain == 1.0:
            # sticking is not linear in the levels: screened by its probes' costs
            slip = _h("stick_slip_friction", name, ("viscous", "coulomb", "static_excess"),
                      friction_scale, (0, 0, 0), (50, 20, 20),
                      [(1.0, 1.0, 0.3), (0.3, 3.0, 1.0)],
                      probes=[(1.0, 1.0, 0.3), (0.3, 3.0, 1.0)], linear=False,
                      fixed=(float(inertia[j]),))
        else:   # volts: the sticking levels alone, in units of the joint torque (N m)
            t_joint = gain * trms
            probes = _slip_probes(t_joint)
            slip = _h("stick_slip_friction", name, ("coulomb", "static_excess"),
                      (t_joint, t_joint), (0, 0), (20 * SLIP_SLIDING, 20),
                      [probes[0], probes[-1]], probes=probes, linear=False,
                      fixed=(float(inertia[j]),))
        out += [
            joint_friction(name, trms, wrms),
            slip,
            # a rotor lighter or heavier than the nominal one: probes on both sides
            _h("gear", name, ("rotor_inertia",),
               ((rotor["rotor_inertia"] if has_rotor else 0.1),),
               (0.2,), (20,), [(1.0,)], probes=[(0.6,), (1.5,)], linear=False,
               off_at=(1.0,) if has_rotor else ()),
            _elasticity(name, k_ref, has_rotor),
            # probes without damping (they screen the play better), fits from the
            # damped starts (from the probes the search stays near the undamped corner)
            _h("backlash", name, ("half_width", "stiffness", "damping"),
               (1e-3, 5 * k_ref, k_ref * 5e-3), (0, 0, 0), (100, 100, 100),
               [(5.0, 1.0, 1.0), (2.0, 1.0, 1.0)],
               probes=[(2.0, 1.0, 0.0), (5.0, 1.0, 0.0)], linear=False,
               inverse=(False, True, False), fit_from_probe=False),
            _h("torque_saturation", name, ("limit",), (tmax,), (0.05,), (1.5,),
               [(0.8,), (0.6,)], probes=[(0.95,), (0.85,), (0.75,), (0.6,), (0.45,),
                                         (0.3,), (0.2,), (0.12,)],
               linear=False, off_at=(1.5,)),
            _h("actuator_delay", name, ("delay",), (controller.period,), (0,), (25,),
               [(1.0,)], (2.0,), discrete=True),
            _h("sensor_bias", name, ("bias",), (1e-3,), (-100,), (100,), [(0.0,)], (1.0,)),
            _h("sensor_delay", name, ("delay",), (controller.period,), (0,), (25,),
               [(1.0,)], (2.0,), discrete=True),
        ]
    for i, lk in enumerate(arm.links):
        if rec.has(f"w{i + 1}") and declared_tip_gauge(arm, lk.name) is not None:
            out.append(_h("gauge_delay", lk.name, ("delay",),
                          (GAUGE_DELAY_STEP * controller.period,), (0,), (15,), [(1.0,)],
                          (6.0,), discrete=True))
        # probes on both sides: over a 20 s run a softer link's ringing drifts in phase,
        # which a +10 % probe's linearization does not reach (independent suite,
        # A-cont-stiffness-m1-s2: E -20 % screened 0.026 from +10 %, 0.72 from -20 %;
        # the root joint's elasticity, 0.36, had been named instead)
        out.append(_h("stiffness", lk.name, ("relative_change",), (0.1,), (-7,), (20,),
                      [(0.0,)], probes=[(-2.0,), (1.0,)]))
        out.append(_h("structural_damping", lk.name, ("rayleigh_stiffness",), (1e-2,),
                      (0,), (100,), [(1.0,)], (1.0,)))
    out.append(_h("base_tilt", "", ("angle",), (0.01,), (-20,), (20,), [(0.0,)], (1.0,)))
    out.append(_h("payload", "", ("mass",), (0.1,), (-arm.payload_mass / 0.1,), (100,),
                  [(0.0,)], (1.0,)))
    if rec.has("tip_y"):
        ymin = float(np.min(rec.channels["tip_y"]))
        out.append(_h("contact_surface", "", ("y", "stiffness", "damping"), (1.0, 1e3, 10.0),
                      (ymin - 0.02, 0.01, 0.0), (ymin + 0.06, 100, 10),
                      [(ymin + 0.01, 1.0, 1.0), (ymin + 0.02, 0.3, 1.0)],
                      probes=[(ymin + 0.01, 1.0, 1.0), (ymin + 0.02, 0.3, 1.0)],
                      linear=False))
    if controller.continuous:   # a continuous law is not delayed in the replay
        out = [h for h in out if h.kind not in ("actuator_delay", "sensor_delay",
                                                "gauge_delay")]
    return [h for h in out if h.label not in exclude]
