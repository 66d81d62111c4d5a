"""A spatial arm (issue 25) in the one model node (:class:`flex_model.ros.model_node.ModelNode`):
:class:`SpatialArm` steps the compiled loop (spatial/integrate.simulate_fixed_compiled)
period by period, continued from the previous one (periods under one held input equal one
run); a new command, set-point or payload restarts the method with a consistent
acceleration (``restart_on_change``: false continues through command and set-point
changes; a payload change always restarts). ``controller`` eq95 or eq45 (kp = n^2 kpv kpp,
kd = n^2 kpv, n the gear ratio) is the continuous PD tau = kp (s - theta_a) - kd theta_a'
+ command inside the compiled loop. Topics, limits and payloads: docs/ros.md ("Spatial
arms: one model node for every arm").
"""
from __future__ import annotations

import math

import numpy as np

from . import spatial as sr
from ..config import ConfigError
from ..solvers.status import refine
from .conversions import check_payload, finite_array
from .main import ParameterError, fmt


def load_arm_parameter(arm: str, planar: bool, kinematics: str = ""):
    """The SpatialArm named by the ``arm`` parameter (ParameterError naming it), with the
    ``kinematics`` parameter's kinematics ('': the arm file's)."""
    from dataclasses import replace
    from ..spatial.description import KINEMATICS
    from ..spatial.loader import load_spatial_arm
    if kinematics and kinematics not in KINEMATICS:
        raise ParameterError(f"parameter kinematics: got {kinematics!r}; expected one of "
                             f"{', '.join(KINEMATICS)} (empty: the arm file's)")
    try:
        if planar:
            from ..arm import load_arm
            from ..spatial.description import from_planar
            out = from_planar(load_arm(arm))
        else:
            out = load_spatial_arm(arm)
    except (ConfigError, ValueError, OSError) as exc:
        raise ParameterError(f"parameter arm: {exc}") from None
    return replace(out, kinematics=kinematics) if kinematics else out


def arm_mass(model) -> float:
    """Total mass of a spatial arm (kg): beams (rhoA ds at the Gauss points) and bodies."""
    m = sum(float(np.sum(b.mass_w)) for b in model.beams if b is not None)
    return m + sum(lk.root_body.mass + lk.end_body.mass for lk in model.arm.links)


def plausibility_limits(model) -> dict:
    """Automatic plausibility limits (the ``0`` of max_torque, max_payload_mass,
    max_payload_inertia), as the planar node's: from the arm's mass, the generalized
    inertia of joint 1 and the joint forces of gravity, all at zero joint values."""
    q = np.zeros(model.nq)
    inertia = float(model.mass_matrix(q)[model.off[0], model.off[0]])
    gravity = float(np.max(np.abs(model.gravity_force(q)[model.off])))
    return {"max_torque": max(100.0, 10.0 * gravity, 100.0 * inertia),
            "max_payload_mass": 10.0 * arm_mass(model),
            "max_payload_inertia": 10.0 * inertia}


class SpatialArm:
    """A spatial arm in the model node: its state (q, v, the method's accelerations), the
    held command and set-points, one compiled call per period, what the node publishes."""

    torque_unit = "N m (N)"
    has_setpoints = True
    has_imu = plugin = False
    stepper = None

    def __init__(self, node, p: dict):
        from ..spatial.dynamics import SpatialArmModel
        from ..spatial.limits import joint_limits
        from ..spatial.payload import payload_inertia
        self.node, self.p = node, p
        self.arm0 = load_arm_parameter(p["arm"], p["from_planar"],  # without payload
                                       p["kinematics"])
        self.payload0 = self.payload = payload_inertia(p["payload"])
        self.model = self._model_with(self.payload0)
        self.auto_limits = plausibility_limits(  # of the arm without the payload
            self.model if self.model.arm is self.arm0 else SpatialArmModel(self.arm0))
        self.name, self.names = self.arm.name, list(self.arm.joint_names)
        vec = {k: self._per_joint(k, p[k])
               for k in ("initial_joint_values", "kp", "kd", "setpoints", "kpp", "kpv")}
        self.period = 1.0 / p["rate"]
        self.per = max(1, int(math.ceil(self.period / p["max_step"] - 1e-9)))
        self.h = self.max_step = self.period / self.per
        self._controller(p, vec)
        self.limits = joint_limits(self.arm)
        self.effort = self.limits["effort"]
        self.q0, self.v0 = self._initial_state(vec["initial_joint_values"],
                                               p["start_static"])
        self.model0 = self.model
        self.outputs = sr.SpatialOutputs(self.model)
        self.deflection_names = self.outputs.names
        self.base_frame = self.base = sr.frame_name("base_link", p["frame_prefix"],
                                                    p["frame_id"])
        self.shape_labels = [lk.name for lk, b in zip(self.arm.links, self.model.beams)
                             if b is not None]
        self.shape_widths = (0.01, 0.003)
        self.reset()

    def _controller(self, p, vec) -> None:
        """The continuous in-loop PD (eq95, eq45) as stiffness and damping on the actuator
        coordinates; a plugin controller is refused with the reason."""
        law = p["controller"]
        if law not in ("", "none", "eq95", "eq45"):
            raise ParameterError(
                f"parameter controller: got {law!r} on the spatial arm {self.name}; expected "
                "none, eq95 or eq45 (the continuous PD in the compiled loop): an in-loop "
                "plugin controller steps the planar model only (flex_model.control_loop); "
                "run flex_control's controller node over effort_controller/commands instead")
        self.in_loop_pd = self.in_loop = law in ("eq95", "eq45")   # Eq. 45 is a PD too
        self.motor_joints = [self.names[j] for j, *_ in self.model.motors]
        if self.in_loop_pd and self.motor_joints:
            raise ParameterError(
                f"parameter controller: got {law} on an arm with dc_motor joints "
                f"({', '.join(self.motor_joints)}); expected none: their commands are "
                f"voltages, {law}'s PD gives torques")
        self.kp, self.kd = vec["kp"], vec["kd"]
        if law == "eq45":
            from ..spatial.scenario import eq45_joint_gains
            self.kp, self.kd = eq45_joint_gains(self.arm, vec["kpp"], vec["kpv"])
        self.setpoints0 = vec["setpoints"]
        self.act = self.model.actuator_index >= 0
        self.Kp, self.Dp = np.zeros((2, self.model.nq, self.model.nq))
        if self.in_loop_pd:
            for i, a in enumerate(self.model.actuator_index):
                if a >= 0:
                    self.Kp[a, a] += self.kp[i]
                    self.Dp[a, a] += self.kd[i]

    @property
    def arm(self):
        """The arm as simulated (with the current payload in its last end body)."""
        return self.model.arm

    @property
    def t(self) -> float:
        return self.steps * self.period

    def summary(self) -> str:
        m = self.payload0[0]
        motors = (f"; dc_motor joints {', '.join(self.motor_joints)}: their commands are "
                  "voltages (V), through the motor model") if self.motor_joints else ""
        return (f"spatial arm {self.name} ({self.model.nq} coordinates, joints "
                f"{', '.join(self.names)}), {self.per} step(s) of {self.h:.6g} s a period, "
                f"controller {self.p['controller'] or 'none'}, payload {fmt(m)} kg{motors}")

    def robot_description(self) -> str:
        return sr.skeleton_urdf(self.model, self.p["frame_prefix"], self.p["frame_id"])

    def _model_with(self, payload):
        from ..spatial.dynamics import SpatialArmModel
        from ..spatial.payload import with_payload
        return SpatialArmModel(with_payload(self.arm0, *payload))

    def _per_joint(self, name, values) -> np.ndarray:
        n = self.model.n_links
        if len(values) not in (1, n):
            raise ParameterError(f"parameter {name}: got {fmt(values)}; expected {n} values "
                                 f"(one per joint of {self.arm.name}) or one for all")
        return np.array(np.broadcast_to(np.asarray(values, float), (n,)))

    def _initial_state(self, values, static):
        """(q0, v0) as a scenario builds them (flex_model.scenario.Scenario.initial_state)."""
        from ..inputs import JointPD
        from ..scenario import Scenario
        sc = Scenario(name=self.arm.name, arm=self.arm, duration=1.0, step=self.h,
                      sample_period=self.period, rho_inf=self.p["rho_inf"],
                      joint_values=values, joint_rates=np.zeros(len(values)),
                      start_static=static,
                      pd=JointPD(self.kp, self.kd, self.setpoints0) if self.in_loop_pd
                      else None)
        try:
            q0, v0 = sc.initial_state(self.model)
        except (RuntimeError, np.linalg.LinAlgError) as exc:
            raise ParameterError(f"parameter start_static: no static state ({exc})") from None
        return q0, v0

    # ------------------------------------------------------------- inputs
    def reset(self) -> None:
        """The initial state, payload and set-points, a zero command, t = 0."""
        self.model, self.payload = self.model0, self.payload0
        self.q, self.v = self.q0.copy(), self.v0.copy()
        self.steps = 0
        self.u = np.zeros(self.model.n_links)
        self.setpoints = self.setpoints0.copy()
        self.acc = None   # the method's (a, abar): None restarts it

    def set_command(self, u) -> None:
        if self.p["restart_on_change"] and not np.array_equal(u, self.u):
            self.acc = None
        self.u = np.asarray(u, float)

    def zero_command(self) -> None:
        self.set_command(np.zeros(self.model.n_links))

    def stop(self) -> None:
        self.u = np.zeros(self.model.n_links)

    def set_setpoints(self, data) -> None:
        if not self.in_loop_pd:
            raise ValueError("no set-point controller (parameter controller is none)")
        s = finite_array(data, self.model.n_links, "set-points",
                         f"rad or m, one per joint: {', '.join(self.names)}")
        if self.p["restart_on_change"] and not np.array_equal(s, self.setpoints):
            self.acc = None
        self.setpoints = s

    def payload_from(self, data, limit):
        """(mass, 3 x 3 inertia) of a payload vector (spatial/payload.payload_inertia),
        within the plausibility limits (the largest principal inertia)."""
        from ..spatial.payload import payload_inertia
        m, inertia = payload_inertia(data)
        largest = float(np.max(np.linalg.eigvalsh(inertia)))
        check_payload(((m, "mass", "kg"), (largest, "largest principal inertia", "kg m^2")),
                      limit)
        return m, inertia

    def set_payload(self, payload) -> None:
        """The arm's model rebuilt with the payload in the last end body
        (spatial/payload.model_with_payload), the state kept, the method restarted."""
        from ..spatial.payload import model_with_payload
        self.model = model_with_payload(self.model0, self.arm0, *payload)
        self.payload, self.acc = payload, None

    def payload_text(self) -> str:
        m, inertia = self.payload
        return (f"{fmt(m)} kg, inertia diag {fmt(np.diag(inertia))} kg m^2 (end frame of "
                f"{self.arm.links[-1].name})")

    def close(self) -> None:
        """Nothing held outside the node's entities."""

    # ------------------------------------------------------------- stepping
    def open_loop(self) -> np.ndarray:
        """The joint torques of the period that are not the PD's feedback: the command,
        with the PD plus kp s."""
        return self.u + self.kp * self.setpoints if self.in_loop_pd else self.u

    def applied(self) -> np.ndarray:
        """The joint torques at the current state (joint_states' effort)."""
        if not self.in_loop_pd:
            return np.clip(self.u, -self.effort, self.effort)
        a = np.maximum(self.model.actuator_index, 0)
        fb = self.kp * self.q[a] + self.kd * self.v[a]
        return np.clip(self.open_loop() - np.where(self.act, fb, 0.0), -self.effort,
                       self.effort)

    def hold(self, dt: float) -> None:
        """The periods of ``dt`` (s) pass with the state held (brakes on)."""
        self.steps += max(1, int(round(dt / self.period)))

    def advance_refining(self, dt: float) -> int:
        """The periods of ``dt`` (s), each one compiled call; a period whose Newton fails
        is done again from the same state in more steps (solvers.status.refine). Returns
        the refinement needed (1: none); raises the first failure if every one fails."""
        def attempt(k):
            if k > 1:
                self.acc = None
            self._period(self.per * k)
        return max(refine(attempt) for _ in range(max(1, int(round(dt / self.period)))))

    def _period(self, n: int) -> None:
        """One period in ``n`` steps of the compiled loop, then the limit check."""
        from ..spatial import integrate
        K0 = self.model.K
        try:
            self.model.K = K0 + self.Kp
            pd = self.in_loop_pd
            run = integrate.simulate_fixed_compiled(
                self.model, self.q, self.v, self.period / n, n, joint_torques=self.open_loop(),
                rho_inf=self.p["rho_inf"], tol=self.p["newton_tol"],
                damping=self.Dp if pd else None, pd_clip=(self.kp, self.kd) if pd else None,
                acceleration=self.acc)
        finally:
            self.model.K = K0
        self.q, self.v = run.q[-1].copy(), run.v[-1].copy()
        self.acc = run.acceleration
        self.steps += 1
        self.check_limits()

    def check_limits(self) -> None:
        """Log the URDF position and velocity limit violations (positions: pushed back by
        the arm file's joint_stops where it has them, else only reported), at most once a
        second per joint and kind."""
        qj, vj = self.q[self.model.off], self.v[self.model.off]
        lim, drops = self.limits, self.node.drops
        how = "in the end stop (joint_stops)" if self.model.stops else \
            "reported, not enforced: the arm file has no joint_stops"
        for i in np.flatnonzero((qj < lim["lower"]) | (qj > lim["upper"])):
            drops.warning(f"joint {self.names[i]} at {fmt(qj[i])} outside its URDF "
                          f"limits [{fmt(lim['lower'][i])}, {fmt(lim['upper'][i])}] "
                          f"({how})", key=("position", i))
        for i in np.flatnonzero(np.abs(vj) > lim["velocity"]):
            drops.warning(f"joint {self.names[i]} rate {fmt(vj[i])} beyond its URDF "
                          f"velocity limit {fmt(lim['velocity'][i])} (reported, not "
                          "enforced)", key=("velocity", i))

    # ------------------------------------------------------------- outputs
    def joint_values(self) -> np.ndarray:
        off = self.model.off
        return np.concatenate([self.q[off], self.v[off], self.applied()])

    def deflection_values(self) -> np.ndarray:
        return self.outputs.deflections(self.q, self.v)

    def tip_values(self) -> np.ndarray:
        return self.outputs.tip_values(self.q, model=self.model)

    def shape_lines(self, points: int) -> list:
        return sr.centre_lines(self.model, self.q, points)

    def live(self, t: float) -> None:
        """No Foxglove live view of a spatial arm (parameter foxglove_port is refused)."""

    def tf_setup(self, tf_type) -> list:
        """/tf as message objects (ros_spatial.transforms); no static transforms."""
        from builtin_interfaces.msg import Time
        from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
        from std_msgs.msg import Header
        from types import SimpleNamespace
        self.tf_types = SimpleNamespace(TFMessage=tf_type, Time=Time, Header=Header,
                                        Quaternion=Quaternion, Transform=Transform,
                                        TransformStamped=TransformStamped, Vector3=Vector3)
        return []

    def tf_message(self, t: float):
        return self.tf_types.TFMessage(transforms=sr.transforms(
            self.tf_types, self.model, self.q, t, None, self.p["frame_prefix"],
            self.p["frame_id"]))
