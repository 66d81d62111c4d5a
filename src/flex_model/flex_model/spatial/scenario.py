"""Spatial simulation scenarios (issue 25): a YAML file, validated on load, run by the
compiled generalized-alpha loop (integrate.simulate_fixed_compiled).

The file format is the one of every scenario (:mod:`flex_model.scenario`, one loader:
``load_scenario``); its arm here is a spatial arm (a DH table, a URDF side file or a
spatial preset).

``pd45`` is seed 000's PD-like cascade, Eq. (45), in continuous time (as the seed's runs
and flex_control.step_response): on the motor angle n theta_a it is the joint PD
kp = n^2 K_pv K_pp, kd = n^2 K_pv (:func:`eq45_joint_gains`, n the ratio of the joint's
``gear`` effect), run as below. The PD law is thesis Eq. 95 with constant gains,
tau_i = kp_i (s_i(t) - theta_a) -
kd_i theta_a', evaluated inside the integrator: its -kp theta_a - kd theta_a' part is
stiffness and damping on the actuator coordinate theta_a (the joint, or the motor
coordinate behind an elastic gear: collocated), kp s(t) a joint torque. A set-point step
of delta is the torque step kp delta (as the planar scenario). With effort limits (URDF
``<limit effort>`` or a DH joint's ``effort``) the whole actuator torque (PD, holding
torques and pulses) is clipped to them inside the loop (integrate.simulate_fixed_compiled
``pd_clip``; without a PD the torques are). Pulses and set-point steps
are evaluated at mid-step, and the method restarts where one switches, as the planar
fixed-step mode does (simulate._run_fixed; integrators.restart_choice: the consistent
acceleration, or the part of the jump the step follows where the rest would kick modes
it cannot follow), so that a planar arm embedded in 3D follows the planar run.
"""
from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass

import numpy as np

from ..errors import SimulationDivergedError, StaticConvergenceError
from ..inputs import JointPD, ramp_fraction
from .description import SpatialArm
from .dynamics import SpatialArmModel
from .limits import joint_limits

#: tau = kp (s - theta_a) - kd theta_a' per joint (thesis Eq. 95, constant gains) on the
#: actuator coordinate: the planar scenario's JointPD
SpatialPD = JointPD


def eq45_joint_gains(arm: SpatialArm, kpp, kpv) -> tuple:
    """Seed 000's PD-like cascade, Eq. (45), tau_cmd = K_pv (K_pp (p_cmd - p) - p'), on the
    motor angle p = n theta_a with n the ratio of the joint's ``gear`` effect (1 without)
    and the joint torque n tau_cmd: at the joint the PD kp = n^2 K_pv K_pp, kd = n^2 K_pv
    (flex_control.laws.PDLikeCascade.joint_gains). Returns (kp, kd) per joint."""
    n = np.array([1.0 if arm.effect("gear", nm) is None else arm.effect("gear", nm)["ratio"]
                  for nm in arm.joint_names])
    kpp, kpv = np.asarray(kpp, float), np.asarray(kpv, float)
    return n * n * kpv * kpp, n * n * kpv


@dataclass(frozen=True)
class SpatialPulse:
    """A joint torque (N m) or force (N) on joint ``joint`` (index) for start <= t < end."""

    joint: int
    value: float
    start: float
    end: float


def _exact_tips(b, f, g) -> dict:
    """The tip's lateral displacements r_y(L), r_z(L) and their rates of link data ``b``
    (dynamics.BeamData with exact kinematics) at bending variables f and rates g (n, 2 nv)."""
    nv = b.nv
    y, z, yr, zr = (np.zeros(len(f)) for _ in range(4))
    for k, (fk, gk) in enumerate(zip(f, g)):
        r, Jv, Jw = (a[-1] for a in b.exact_points(fk[:nv], fk[nv:]))
        y[k], z[k] = r[1], r[2]
        yr[k], zr[k] = Jv[1:] @ gk[:nv] + Jw[1:] @ gk[nv:]
    return {"y": y, "z": z, "y_rate": yr, "z_rate": zr}


@dataclass
class SpatialScenario:
    name: str
    arm: SpatialArm
    duration: float
    step: float
    sample_period: float
    rho_inf: float
    joint_values: np.ndarray
    joint_rates: np.ndarray
    start_static: bool = False
    gravity_hold: bool = False
    pd: SpatialPD | None = None
    setpoint_schedule: tuple = ()        # (time, setpoints), increasing times
    pulses: tuple = ()
    tol: float = 1e-10
    source: str = "<memory>"
    #: (time, mass kg, 3 x 3 inertia kg m^2 about the end frame origin): from that time the
    #: payload at the last link's end frame (replacing the previous change's; the arm
    #: file's own payload stays), spatial/payload.py
    payload_changes: tuple = ()
    #: (force (3), start, end): a force (N, base frame) at the tip (the origin of the last
    #: link's end frame) on [start, end), as the pulses: evaluated at mid-step, a restart
    #: at its edges
    tip_loads: tuple = ()

    method = "fixed"    # the one method (not a field): the compiled generalized-alpha loop

    # ------------------------------------------------------------ model and grid
    def model(self) -> SpatialArmModel:
        return SpatialArmModel(self.arm)

    def grid(self):
        """(h, steps per sample, samples): the step divides the sample period (as the
        planar fixed mode: h = sample_period / ceil(sample_period / step))."""
        per = max(1, int(math.ceil(self.sample_period / self.step - 1e-9)))
        n_samples = int(round(self.duration / self.sample_period))
        return self.sample_period / per, per, n_samples

    def pd_matrices(self, model: SpatialArmModel):
        """(K_pd, D_pd): the PD's stiffness and damping on the actuator coordinates."""
        Kp, Dp = np.zeros((model.nq, model.nq)), np.zeros((model.nq, model.nq))
        if self.pd is not None:
            for i, a in enumerate(model.actuator_index):
                if a >= 0:
                    Kp[a, a] += self.pd.kp[i]
                    Dp[a, a] += self.pd.kd[i]
        return Kp, Dp

    # ------------------------------------------------------------ initial state
    def holding_torques(self, model: SpatialArmModel) -> np.ndarray:
        """Joint torques that hold the arm at its initial joint values under gravity:
        the joint rows of K q + dU_g/dq - Q_const at the equilibrium with the joints held
        (analysis.static_equilibrium)."""
        from .analysis import static_equilibrium
        q = static_equilibrium(model, self.joint_values).q
        r = model.K @ q + model.gravity_force(q) - model.Q_const - model.contact_load(q)
        return np.where(model.actuator_index >= 0, r[model.off], 0.0)

    def initial_state(self, model: SpatialArmModel):
        """(q0, v0, u_hold): the start and the constant holding torques (zero without
        ``gravity_hold``)."""
        hold = self.holding_torques(model) if self.gravity_hold else np.zeros(model.n_links)
        v0 = np.zeros(model.nq)
        v0[model.off] = self.joint_rates
        for i, m in enumerate(model.motor_index):
            if m >= 0:
                v0[m] = self.joint_rates[i]
        if not self.start_static:
            q0 = np.zeros(model.nq)
            q0[model.off] = self.joint_values
            for i, m in enumerate(model.motor_index):
                if m >= 0:
                    q0[m] = self.joint_values[i]
            return q0, v0, hold
        if self.pd is not None:
            u = hold + self.pd.kp * self.pd.setpoints
            q0 = pd_static_equilibrium(model, *self.pd_matrices(model)[:1], u,
                                       start=self.pd.setpoints)
            act = model.actuator_index
            need = np.where(act >= 0, u - self.pd.kp * q0[np.maximum(act, 0)], 0.0)
            effort = joint_limits(model.arm)["effort"]
            over = np.flatnonzero(np.abs(need) > effort)
            if len(over):       # the loop clips the PD: that start would not be at rest
                j = int(over[0])
                raise ValueError(
                    f"{self.name}: the PD's static start needs {need[j]:.6g} N m (or N) on "
                    f"{self.arm.joint_names[j]}, beyond its effort limit {effort[j]:.6g}; "
                    "start undeformed, or change the set-points or the gains")
            return q0, v0, hold
        from .analysis import static_equilibrium
        q0 = static_equilibrium(model, self.joint_values).q
        gaps = {qi: (half, smooth) for qi, _, _, _, half, smooth, _ in model.backlash}
        for i, m in enumerate(model.motor_index):   # elastic gears: the spring carries
            if m >= 0:                               # the holding torque
                e = self.arm.effect("joint_elasticity", self.arm.links[i].joint.name)
                x = hold[i] / e["stiffness"]
                if model.off[i] in gaps:             # backlash: k dz(x) = hold
                    x = _dead_zone_inverse(x, *gaps[model.off[i]])
                q0[m] = q0[model.off[i]] + x
        return q0, v0, hold

    # ------------------------------------------------------------ inputs
    def open_loop(self, t, hold, t_sample=None) -> np.ndarray:
        """The joint torques at times t (n,) that are not the PD's feedback: holding
        torques, pulses and kp s(t) (n, n_joints); a ramp of the set-point schedule is
        kp (s - s0) + kd s' averaged over the sample period that starts at ``t_sample``
        (default t) and held over it, as the planar scenario's ramps
        (flex_model.scenario.Scenario.setpoint_inputs)."""
        t = np.asarray(t, float)
        tk = t if t_sample is None else np.asarray(t_sample, float)
        u = np.broadcast_to(np.asarray(hold, float), (len(t), self.arm.n_links)).copy()
        for p in self.pulses:
            u[(p.start <= t) & (t < p.end), p.joint] += p.value
        if self.pd is not None:
            u += self.pd.kp * self.pd.setpoints
            prev = self.pd.setpoints
            T = self.sample_period
            for entry in self.setpoint_schedule:
                ts, sp = entry[0], entry[1]
                ramp = entry[2] if len(entry) > 2 else 0.0
                delta = np.asarray(sp, float) - prev
                prev = np.asarray(sp, float)
                if ramp <= 0.0:
                    u[t >= ts] += self.pd.kp * delta
                    continue
                (y0, a0), (y1, a1) = ramp_fraction(tk, ts, ramp), ramp_fraction(tk + T, ts, ramp)
                u += np.outer((a1 - a0) / T, self.pd.kp * delta) + \
                    np.outer((y1 - y0) / T, self.pd.kd * delta)
        return u

    @property
    def has_ramps(self) -> bool:
        return any(len(e) > 2 and e[2] > 0.0 for e in self.setpoint_schedule)

    def switch_steps(self, h: float, n_total: int) -> list[int]:
        """Step indices where an input switches (the method restarts there): pulse edges,
        set-point steps and, with ramps, every sample instant (as the planar fixed mode
        restarts at its policy instants)."""
        times = [t for p in self.pulses for t in (p.start, p.end)] + \
            [t for _, a, b in self.tip_loads for t in (a, b)] + \
            [e[0] for e in self.setpoint_schedule] + [c[0] for c in self.payload_changes]
        steps = {int(round(t / h)) for t in times if math.isfinite(t) and
                 0 < round(t / h) < n_total}
        if self.has_ramps:
            per = max(1, int(round(self.sample_period / h)))
            steps |= set(range(per, n_total, per))
        return sorted(steps)

    # ------------------------------------------------------------ run
    def run(self, model: SpatialArmModel | None = None, progress=None,
            duration: float | None = None, advise: bool = False) -> "SpatialSimulation":
        """Integrate (compiled generalized-alpha); ``duration`` overrides the scenario's
        (e.g. a short first run that loads the numba cache); ``advise``: a run estimated
        more than 2 % off (:meth:`advice`) is a ``UserWarning``, as the planar run's."""
        from .integrate import simulate_fixed_compiled
        model = model or self.model()
        warning = self.advice(model).warning if advise else None
        if warning:
            warnings.warn(warning, stacklevel=2)
        h, per, n_samples = self.grid()
        if duration is not None:
            n_samples = max(1, int(round(duration / self.sample_period)))
        n_total = n_samples * per
        q, v, hold = self.initial_state(model)
        Kp, Dp = self.pd_matrices(model)
        t_mid = h * (np.arange(n_total) + 0.5)
        u = self.open_loop(t_mid, hold, t_sample=h * per * (np.arange(n_total) // per))
        tipf = None
        if self.tip_loads:
            tipf = np.zeros((n_total, 3))
            for force, a, b in self.tip_loads:
                tipf[(a <= t_mid) & (t_mid < b)] += force
        bounds = self.switch_steps(h, n_total) + [n_total]
        from .payload import model_with_payload
        # the model of each payload change (a shallow copy with the end body replaced)
        changes = [(int(round(tc / h)), model_with_payload(model, self.arm, m, inertia))
                   for tc, m, inertia in self.payload_changes]
        K0 = model.K
        qs, vs, iters, start, acc = [q[None]], [v[None]], 0, 0, None
        try:
            model.K = K0 + Kp     # the PD's stiffness, for this run only
            for _, m in changes:
                m.K = model.K
            for stop in bounds:   # a restart at every switch (integrators.restart_choice)
                cur = model
                for step_c, m in changes:
                    if step_c <= start:
                        cur = m
                try:
                    run = simulate_fixed_compiled(
                        cur, q, v, h, stop - start, joint_torques=u[start:stop],
                        rho_inf=self.rho_inf, tol=self.tol, damping=Dp,
                        pd_clip=None if self.pd is None else (self.pd.kp, self.pd.kd),
                        tip_force=None if tipf is None else tipf[start:stop],
                        restart_from=acc)
                except SimulationDivergedError as exc:   # the segment's time -> the run's
                    raise SimulationDivergedError(
                        f"{self.name}: Newton did not converge in the step after t = "
                        f"{start * h:.6g} s + ({exc}); reduce the step or the input") from None
                qs.append(run.q[1:])
                vs.append(run.v[1:])
                iters += run.newton_iterations
                q, v = run.q[-1].copy(), run.v[-1].copy()
                acc = run.acceleration   # the restart at the next switch starts from it
                start = stop
                if progress is not None:
                    progress(stop * h, n_total * h)
        finally:
            model.K = K0
        Q, V = np.concatenate(qs)[::per], np.concatenate(vs)[::per]
        t = h * per * np.arange(len(Q))
        a_idx = np.maximum(model.actuator_index, 0)
        tau = self.open_loop(t, hold)
        if self.pd is not None:
            act = model.actuator_index >= 0
            tau -= np.where(act, self.pd.kp * Q[:, a_idx] + self.pd.kd * V[:, a_idx], 0.0)
        effort = joint_limits(model.arm)["effort"]
        tau = np.where(model.actuator_index >= 0, np.clip(tau, -effort, effort), 0.0)
        return SpatialSimulation(model=model, t=t, q=Q, v=V, tau=tau,
                                 stats={"dt": h, "steps": n_total, "newton_iterations": iters,
                                        "restarts": len(bounds) - 1})

    # ------------------------------------------------------------ advice
    def tips(self, model: SpatialArmModel | None = None) -> np.ndarray:
        """(samples, flexible links, 2) tip deflections y, z of a run (m)."""
        d = self.run(model=model).tip_deflections()
        return np.stack([np.column_stack([v["y"], v["z"]]) for v in d.values()], axis=1)

    def with_finer_variables(self) -> "SpatialScenario":
        """The scenario with twice the variables (bending and torsion) on every beam."""
        def finer(beam):
            return dataclasses.replace(beam, variables=2 * beam.variables,
                                       torsion_variables=2 * beam.torsion_variables)
        links = tuple(lk if lk.flexible is None else
                      dataclasses.replace(lk, flexible=finer(lk.flexible))
                      for lk in self.arm.links)
        return dataclasses.replace(self, arm=dataclasses.replace(self.arm, links=links))

    def advice(self, model: SpatialArmModel | None = None, check: bool = True):
        """step_advice.StepAdvice with the a-posteriori estimate of the planar scenario
        (flex_model.scenario.Scenario.advice) over step_advice.probe_window: the run, the
        run at a quarter of the step and that run with twice the variables (``check``
        False, or no flexible link: no estimate, no warning)."""
        from .. import step_advice as sa
        h = self.grid()[0]
        none = sa.StepAdvice(None, None, h, None, None)
        jumps = [p.start for p in self.pulses] + [e[0] for e in self.setpoint_schedule] + \
            [a for _, a, _ in self.tip_loads]
        window = sa.probe_window(self.duration, self.sample_period, jumps)
        beams = [lk.flexible for lk in self.arm.links if lk.flexible is not None]
        if not beams or not check:
            return none
        finer = self.with_finer_variables()

        def tips(divisor, factor):
            sc = dataclasses.replace(finer if factor > 1 else self, duration=window,
                                     step=h / divisor)
            return sc.tips(None if factor > 1 else model)
        est = sa.estimate_error(tips, window)
        nv = sorted({b.variables for b in beams})
        label = f"{'/'.join(map(str, nv))} variables per bending plane"
        return dataclasses.replace(none, warning=sa.error_warning(est, h, label),
                                   estimate=est)


def _dead_zone_inverse(y: float, half: float, smooth: float) -> float:
    """x with integrators.dead_zone(x, half, smooth) = y (Newton from y + sign(y) half;
    dz is increasing)."""
    from ..integrators import dead_zone
    if y == 0.0:
        return 0.0
    x = y + np.sign(y) * half
    for _ in range(100):
        dz, slope = dead_zone(x, half, smooth)
        dx = (dz - y) / max(slope, 1e-300)
        x -= dx
        if abs(dx) <= 1e-15 * max(1.0, abs(x)):
            break
    return float(x)


def pd_static_equilibrium(model: SpatialArmModel, K_pd, u, start=None, tol: float = 1e-13,
                          max_iter: int = 40) -> np.ndarray:
    """q with (K + K_pd) q + dU_g/dq - Q_const - J^T F_c = H u (all free coordinates; the
    spring balance of the PD, thesis Eq. 95 at rest; F_c the force of a contact surface
    at the tip): Newton with the tangent K + K_pd + d^2 U_g/dq^2 (+ k J^T n n^T J in
    contact) from joint values ``start``."""
    from .integrate import joint_input_matrix
    q = np.zeros(model.nq)
    if start is not None:
        q[model.off] = start
        for i, m in enumerate(model.motor_index):
            if m >= 0:
                q[m] = start[i]
    free = model.free_indices
    Kt0 = model.K + K_pd
    f = joint_input_matrix(model) @ np.asarray(u, float) + model.Q_const
    for _ in range(max_iter):
        r = (f - Kt0 @ q - model.gravity_force(q) + model.contact_load(q)
             + model.stop_load(q) + model.curvature_load(q))[free]
        Kt = (Kt0 + model.gravity_stiffness(q) + model.contact_tangent(q)[0]
              + model.stop_tangent(q)[0] + model.curvature_tangent(q))[np.ix_(free, free)]
        dq = np.linalg.solve(Kt, r)
        q[free] += dq
        if np.max(np.abs(dq)) < tol * max(1.0, np.max(np.abs(q))):
            return q
    raise StaticConvergenceError(f"no PD equilibrium after {max_iter} Newton steps")


@dataclass
class SpatialSimulation:
    """Samples of a spatial run: t (n), q, v (n, nq), joint torques tau (n, n_joints)."""

    model: SpatialArmModel
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    tau: np.ndarray
    stats: dict

    @property
    def joint_values(self) -> np.ndarray:
        return self.q[:, self.model.off]

    @property
    def joint_rates(self) -> np.ndarray:
        return self.v[:, self.model.off]

    def tip_deflections(self) -> dict:
        """{link name: {'y', 'z', 'twist', 'y_rate', 'z_rate', 'twist_rate'}} (n,) arrays
        at the tip of every flexible link (m, rad): v along the beam's y, w along its z,
        the twist phi (Eq. 19); with exact kinematics the tip's r_y(L), r_z(L) (exact.py)."""
        m = self.model
        out = {}
        for i, (lk, b) in enumerate(zip(m.arm.links, m.beams)):
            if b is None:
                continue
            s = m.flex_slice(i).start
            iv, iw = s + b.tip_v, s + b.tip_w
            d = {"y": self.q[:, iv], "z": self.q[:, iw],
                 "y_rate": self.v[:, iv], "z_rate": self.v[:, iw]}
            if b.rule is not None:
                d = _exact_tips(b, self.q[:, s:s + 2 * b.nv], self.v[:, s:s + 2 * b.nv])
            if b.tip_phi is not None:
                d["twist"], d["twist_rate"] = self.q[:, s + b.tip_phi], self.v[:, s + b.tip_phi]
            else:
                d["twist"] = d["twist_rate"] = np.zeros(len(self.t))
            out[lk.name] = d
        return out

    def tip_positions(self) -> np.ndarray:
        """(n, 3) end-frame origin of the last link, base frame (m)."""
        return np.array([self.model.tip_position(q) for q in self.q])

    def contact_forces(self) -> np.ndarray:
        """(n, 3) force of the contact surface on the tip (N, base frame; zeros without
        one): SpatialArmModel.contact_force at the samples."""
        return np.array([self.model.contact_force(q, v) for q, v in zip(self.q, self.v)])

    def table(self):
        """CSV columns and data: t, joint values q<i>, rates v<i>, torques tau<i>, per
        flexible link <link>_tip_deflection_y|z and <link>_tip_twist, tip_x|y|z, and
        contact_fx|fy|fz with a contact surface."""
        n = self.model.n_links
        names = (["t"] + [f"q{i + 1}" for i in range(n)] + [f"v{i + 1}" for i in range(n)]
                 + [f"tau{i + 1}" for i in range(n)])
        cols = [self.t[:, None], self.joint_values, self.joint_rates, self.tau]
        for name, d in self.tip_deflections().items():
            names += [f"{name}_tip_deflection_y", f"{name}_tip_deflection_z",
                      f"{name}_tip_twist"]
            cols.append(np.column_stack([d["y"], d["z"], d["twist"]]))
        names += ["tip_x", "tip_y", "tip_z"]
        cols.append(self.tip_positions())
        if self.model.contact is not None:
            names += ["contact_fx", "contact_fy", "contact_fz"]
            cols.append(self.contact_forces())
        return names, np.column_stack(cols)

    def summary(self) -> dict:
        """The run's figures (``flex-twin simulate``; as SimulationResult.summary): final
        joint values and tip, max |tip deflection| per flexible link (mm, mrad)."""
        defl = {k: {"y_mm": float(1e3 * np.max(np.abs(d["y"]))),
                    "z_mm": float(1e3 * np.max(np.abs(d["z"]))),
                    "twist_mrad": float(1e3 * np.max(np.abs(d["twist"])))}
                for k, d in self.tip_deflections().items()}
        return {"spatial": True, "coordinates": int(self.model.nq),
                "newton_iterations": self.stats["newton_iterations"],
                "joint_names": self.model.arm.joint_names,
                "final_joint_values": self.joint_values[-1].tolist(),
                "final_tip_m": self.tip_positions()[-1].tolist(),
                "max_abs_tip_deflection": defl}

    def to_csv(self, path) -> None:
        names, data = self.table()
        np.savetxt(path, data, delimiter=",", header=",".join(names), comments="",
                   fmt="%.17g")
