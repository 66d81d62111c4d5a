"""Controller description for the diagnosis replay: a declarative YAML, validated on load.

The diagnosis replays a measured experiment in closed loop with the *same* controller as the
real arm, so the controller is part of the input. Two laws, each either digital (``timing:
sampled``, the default: sampled every ``period`` seconds, output held (zero-order hold)
until the next sample) or continuous (``timing: continuous``, no ``period``)::

    controller:
      law: pd                 # tau = kp (qset - q) - kd v + tau_ff   (thesis Eq. 95 form)
      kp: [200.0, 80.0]       # N m/rad per joint
      kd: [20.0, 8.0]         # N m s/rad per joint
      period: 0.002           # s, zero-order hold
      feedforward: gravity    # none | gravity | recorded

A continuous law (an analog controller, or a simulator's PD acting at every instant)::

    controller:
      law: pd
      timing: continuous      # sampled (default; needs period) | continuous (no period)
      kp: [625.0, 625.0]
      kd: [176.8, 176.8]
      feedforward: none

is evaluated inside the implicit integrator (the torque is a function of the state: its
stiffness Kp C and damping Kd C are in the generalized-alpha Newton matrix, the compiled
joint PD of :mod:`flex_model.integrators`), so a D term on an arm without hub inertia is
stable at the replay's step, where a sampled one diverges at any affordable period. The
reference ``qset`` and the feed-forward are held between the recording's samples. The
replay integrates a continuous law implicitly as a PD of each joint on its own angle and
rate: a continuous ``state_feedback`` may have gains only on q<i> of its own joint i (a
gain on a tip deflection w<i> or on another joint is refused with one line: use ``timing:
sampled``), and an arm with an ``actuator_delay`` effect or a delayed joint encoder is
refused with a continuous law (a delay of a continuous law is not a state function;
:func:`check_integrable`); the delay hypotheses are not screened then.

``feedforward``: ``none``; ``gravity``: the static gravity torque of the *nominal* arm,
undeformed, at the set-point qset (:meth:`ControllerDescription.feedforward`; the
controller knows only the nominal model); ``recorded``: the ``tau_ff<i>`` columns of the
data. ``q`` is the angle measured by the joint's encoder, which the controller uses: the
actuator coordinate of the model (``FlexArmModel.actuator_angles``: the link-side joint
angle, or the motor angle / n of an elastic joint), ``v`` its rate.

State feedback on named channels (e.g. a Quanser rotary flexible link, seed 003)::

    controller:
      law: state_feedback     # u = sum_c K_c (ref_c - y_c) - sum_c D_c dy_c/dt + u_ff
      period: 0.002
      output: voltage         # torque | voltage (a dc_motor joint takes volts)
      feedforward: none
      gains:                  # one row per joint; channels q<i> (joint angle), w<i> (tip
        - {q1: 20.0, w1: -40.0}          # deflection of link i, m); reference of w<i> is 0
      rate_gains:
        - {q1: 1.5, w1: 0.8}

so u = K1 (theta_ref - theta) + K2 (0 - d) - K3 theta_dot - K4 d_dot is
``gains: [{q1: K1, w1: K2}]``, ``rate_gains: [{q1: K3, w1: K4}]``. ``law: pd`` is the
special case gains = diag(kp), rate_gains = diag(kd) on the q channels.

In code the law is ``u = ff + Kp (r - C q_model) - Kd (C v_model)`` with ``C`` the rows of
the measured channels (:meth:`ControllerDescription.channel_matrix`), ``r`` the reference
(qset for q channels, 0 for w channels). :meth:`ControllerDescription.policy` gives the
``policy(t, x)`` of :func:`flex_model.simulate.simulate` for the same law (used to generate
synthetic data and to test the compiled replay against).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flex_model.config import Fields, read_yaml

LAWS = ("pd", "state_feedback")
TIMINGS = ("sampled", "continuous")
FEEDFORWARD = ("none", "gravity", "recorded")
OUTPUTS = ("torque", "voltage")
_CHANNEL = re.compile(r"^(q|w)([1-9][0-9]*)$")


@dataclass(frozen=True)
class ControllerDescription:
    """A linear feedback law on measured channels, sampled or continuous (see the module
    docstring); ``period`` is 0.0 for a continuous law."""

    law: str
    period: float
    gains: np.ndarray          # (n_joints, n_channels) on ``channels``
    rate_gains: np.ndarray     # (n_joints, n_channels)
    channels: tuple            # ("q1", "q2", "w1", ...)
    feedforward_mode: str = "none"
    output: str = "torque"
    source: str = "<memory>"
    timing: str = "sampled"

    @property
    def n_joints(self) -> int:
        return self.gains.shape[0]

    @property
    def continuous(self) -> bool:
        return self.timing == "continuous"

    def instant_period(self, sample_period: float) -> float:
        """The period of the instants at which the reference and feed-forward are read:
        the control period of a sampled law, the recording's sample period of a
        continuous one."""
        return float(sample_period) if self.continuous else self.period

    def joint_pd(self) -> tuple[np.ndarray, np.ndarray]:
        """(kp, kd) per joint of a continuous law (:func:`_continuous_refusal` checked that
        the law is one PD per joint on its own q channel)."""
        kp, kd = np.zeros(self.n_joints), np.zeros(self.n_joints)
        for c, name in enumerate(self.channels):
            j = int(name[1:]) - 1
            kp[j], kd[j] = self.gains[j, c], self.rate_gains[j, c]
        return kp, kd

    def channel_matrix(self, model) -> np.ndarray:
        """C (n_channels, nq): rows mapping the model's q to the measured channels."""
        C = np.zeros((len(self.channels), model.nq))
        for k, name in enumerate(self.channels):
            kind, i = name[0], int(name[1:]) - 1
            if i >= model.n_links:
                raise ValueError(f"{self.source}: controller channel {name}: the arm has "
                                 f"{model.n_links} links")
            if kind == "q":
                C[k] = model.Ga[i]
            else:
                C[k, model.tip_deflection_index(i)] = 1.0
        return C

    def reference(self, qset: np.ndarray) -> np.ndarray:
        """(n_samples, n_channels): qset on q channels, 0 on w channels."""
        qset = np.atleast_2d(qset)
        r = np.zeros((qset.shape[0], len(self.channels)))
        for k, name in enumerate(self.channels):
            if name[0] == "q":
                r[:, k] = qset[:, int(name[1:]) - 1]
        return r

    def feedforward(self, model, qset: np.ndarray, recorded=None) -> np.ndarray:
        """(n_samples, n_joints) feed-forward: zero, the nominal static gravity torque of the
        undeformed arm at qset (dU_g/dtheta, thesis Eq. 26 in joint coordinates), or the
        recorded ``tau_ff`` columns."""
        qset = np.atleast_2d(np.asarray(qset, float))
        n = qset.shape[0]
        if self.feedforward_mode == "none":
            return np.zeros((n, self.n_joints))
        if self.feedforward_mode == "recorded":
            if recorded is None:
                raise ValueError(f"{self.source}: controller.feedforward: 'recorded' needs "
                                 "tau_ff<i> columns in the data")
            return np.asarray(recorded, float).reshape(n, self.n_joints)
        T = model.joint_coordinate_matrix()
        rows = T[:, model.off].T          # d q / d theta
        out = np.empty((n, self.n_joints))
        cache = {}
        for k in range(n):
            key = tuple(np.round(qset[k], 12))
            if key not in cache:
                # model.q_from_joint_angles(qset[k]) with T computed once (it rebuilt T,
                # the links' section integrals, at every instant: 4 % of a diagnosis)
                z = np.zeros(model.nq)
                z[model.off] = qset[k]
                for m, i in enumerate(model.elastic_joints):
                    z[model.nq_arm + m] = qset[k][i]
                cache[key] = rows @ model.gravity_force(T @ z)
            out[k] = cache[key]
        return out

    def policy(self, model, t_ref, qset, ff=None):
        """``policy(t, x)`` for :func:`flex_model.simulate.simulate` (with
        ``control_period=self.period``): the law with the reference and feed-forward held
        from the latest sample of (t_ref, qset) at or before t.

        A continuous law: the policy is the part of the law that depends on time only,
        ff + kp r (held between the samples of t_ref), and the state part is the compiled
        joint PD ``policy.pd`` (:class:`flex_model.simulate.JointPD`, set-points 0),
        evaluated implicitly inside the integrator; pass both, with
        ``control_period=policy.control_period`` (the spacing of t_ref), or use
        :meth:`simulate_inputs`."""
        t_ref = np.asarray(t_ref, float)
        r = self.reference(qset)
        ff = self.feedforward(model, qset) if ff is None else np.asarray(ff, float)
        C = self.channel_matrix(model)
        nq = model.nq
        if self.continuous:
            from flex_model.simulate import JointPD
            kp, kd = self.joint_pd()
            held = ff + r @ self.gains.T

            def law(t, x):
                k = max(0, int(np.searchsorted(t_ref, t + 1e-9, side="right")) - 1)
                return held[k].copy()
            law.pd = JointPD(kp, kd, np.zeros(self.n_joints))
            law.control_period = float(t_ref[1] - t_ref[0]) if len(t_ref) > 1 else 1.0
            return law

        def law(t, x):
            k = max(0, int(np.searchsorted(t_ref, t + 1e-9, side="right")) - 1)
            return (ff[k] + self.gains @ (r[k] - C @ x[:nq])
                    - self.rate_gains @ (C @ x[nq:2 * nq]))   # x = [q; v; bristles z]
        return law

    def simulate_inputs(self, model, t_ref, qset, ff=None) -> dict:
        """The keyword arguments of :func:`flex_model.simulate.simulate` that run this law
        with the reference (t_ref, qset) held: ``policy``, ``control_period`` and, for a
        continuous law, ``pd``."""
        law = self.policy(model, t_ref, qset, ff)
        if self.continuous:
            return {"policy": law, "pd": law.pd, "control_period": law.control_period}
        return {"policy": law, "control_period": self.period}

    def command(self, model, x, r, ff, bias=None) -> np.ndarray:
        """(n, n_joints): the law's output at states x (n, 2 nq) with the reference r
        (n, n_channels) and feed-forward ff (n, n_joints) (the recorded ``tau<i>`` of a
        continuous law: its command at the sample, before any saturation)."""
        C = self.channel_matrix(model)
        nq = model.nq
        y = x[:, :nq] @ C.T + (0.0 if bias is None else np.asarray(bias, float))
        return ff + (r - y) @ self.gains.T - (x[:, nq:2 * nq] @ C.T) @ self.rate_gains.T


def _gain_rows(f: Fields, key: str, n_joints: int | None) -> list[dict]:
    rows = f.items(key, min_len=1)
    if n_joints is not None and len(rows) != n_joints:
        raise f.error(key, rows, f"one mapping per joint ({n_joints} rows)")
    out = []
    for j, raw in enumerate(rows):
        rf = Fields(raw, f.source, f"{f.sub(key)}[{j}]")
        for name in raw:
            if not isinstance(name, str) or not _CHANNEL.match(name):
                raise rf.error(str(name), raw[name], "channel names q<i> or w<i> (1-based)")
        out.append({name: rf.number(name) for name in raw})
        rf.done()
    return out


def controller_from_dict(data: dict, source: str = "<memory>") -> ControllerDescription:
    """Validate a parsed controller description; errors name the file and the field."""
    root = Fields(data, source, "")
    f = root.mapping("controller")
    root.done()
    law = f.string("law", choices=list(LAWS))
    timing = f.string("timing", "sampled", choices=list(TIMINGS))
    if timing == "continuous":
        if f.has("period"):
            raise f.error("period", f.raw("period"), "no period with timing: continuous "
                          "(a continuous law acts at every instant)")
        period = 0.0
    else:
        period = f.number("period", positive=True, max_value=1.0, unit="s")
    ffm = f.string("feedforward", "none", choices=list(FEEDFORWARD))
    if law == "pd":
        kp = f.vector("kp", unit="N m/rad")
        kd = f.vector("kd", len(kp), unit="N m s/rad")
        for key, vals in (("kp", kp), ("kd", kd)):
            if len(vals) == 0 or min(vals) < 0:
                raise f.error(key, vals, "a non-empty list of gains >= 0")
        output = f.string("output", "torque", choices=["torque"])
        n = len(kp)
        channels = tuple(f"q{i + 1}" for i in range(n))
        gains, rate = np.diag(kp), np.diag(kd)
    else:
        output = f.string("output", "torque", choices=list(OUTPUTS))
        rows = _gain_rows(f, "gains", None)
        rrows = _gain_rows(f, "rate_gains", len(rows))
        channels = tuple(sorted({c for r in rows + rrows for c in r},
                                key=lambda c: (c[0], int(c[1:]))))
        gains = np.array([[r.get(c, 0.0) for c in channels] for r in rows])
        rate = np.array([[r.get(c, 0.0) for c in channels] for r in rrows])
    f.done()
    c = ControllerDescription(law=law, period=period, gains=gains, rate_gains=rate,
                              channels=channels, feedforward_mode=ffm, output=output,
                              source=source, timing=timing)
    why = _continuous_refusal(c)
    if why:
        raise ValueError(f"{source}: {f.sub('timing')}: {why}")
    return c


def _continuous_refusal(c: ControllerDescription) -> str:
    """Why the replay cannot integrate a continuous law ("" when it can): it integrates
    one PD per joint on that joint's own angle and rate (the compiled joint PD)."""
    if not c.continuous:
        return ""
    for G, what in ((c.gains, "gains"), (c.rate_gains, "rate_gains")):
        for j in range(c.n_joints):
            for k, name in enumerate(c.channels):
                if G[j, k] != 0.0 and name != f"q{j + 1}":
                    return (f"a continuous law with {what} on {name} for joint {j + 1}: the "
                            "replay integrates a continuous law implicitly only as a PD of "
                            "each joint on its own q<i> (use timing: sampled with a period)")
    return ""


def check_integrable(controller: ControllerDescription, arm) -> None:
    """Refuse (ValueError, one line) an arm the replay cannot run under the law: a
    continuous law with an actuator delay or a delayed joint encoder."""
    if not controller.continuous:
        return
    for j in arm.joint_names:
        d = arm.effect("actuator_delay", j)
        if d is not None and d.values[0] > 0:
            raise ValueError(f"{controller.source}: a continuous controller with the "
                             f"actuator_delay of {j} in the arm: the replay integrates a "
                             "continuous law implicitly and cannot delay it (describe the "
                             "controller as sampled, with its period)")
    for s in arm.sensors:
        if s.kind == "joint_encoder" and s.delay > 0:
            raise ValueError(f"{controller.source}: a continuous controller with a delayed "
                             f"joint encoder ({s.name}): the replay cannot delay a "
                             "continuous law (describe the controller as sampled)")


def load_controller(path) -> ControllerDescription:
    """Load and validate a controller YAML file."""
    path = Path(path)
    return controller_from_dict(read_yaml(path), str(path))


def controller_to_dict(c: ControllerDescription) -> dict:
    """The YAML mapping of a controller description (inverse of controller_from_dict)."""
    body = {"law": c.law, "feedforward": c.feedforward_mode}
    if c.continuous:
        body["timing"] = "continuous"
    else:
        body["period"] = c.period
    if c.law == "pd":
        body["kp"] = [float(c.gains[i, i]) for i in range(c.n_joints)]
        body["kd"] = [float(c.rate_gains[i, i]) for i in range(c.n_joints)]
    else:
        body["output"] = c.output
        body["gains"] = [{ch: float(g) for ch, g in zip(c.channels, row) if g}
                         for row in c.gains]
        body["rate_gains"] = [{ch: float(g) for ch, g in zip(c.channels, row) if g}
                              for row in c.rate_gains]
    return {"controller": body}
