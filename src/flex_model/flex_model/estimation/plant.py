"""The model as the filter sees it: x = [q; v; p] with p the adapted slow parameters.

``PlanarPlant`` wraps a FlexArmModel: the state derivative is the compiled
``integrators.derivative`` (thesis Eq. 27 with every joint effect, a DC motor's voltage
included), the parameters change the data it is given (joint friction columns, the link's
stiffness block of K, the payload through ``set_payload``). ``SpatialPlant`` wraps a
SpatialArmModel (``acceleration`` with ``actuator_force``). Both give the outputs the
measurements read (flex_model.estimation.measurements) and the generalized-force map of the
process noise.

Parameter names (``adapt``): ``coulomb_friction:<joint>``, ``viscous_friction:<joint>``
(N m, N m s/rad, on the actuator coordinate, the joint's total), ``payload_mass`` (kg, at
the last link's tip), ``link_stiffness:<link>`` (scale on the link's EI: its first-mode
frequency scales with its square root). ``<joint>``/``<link>``: index or name.

The filter's joint friction is the arm's with its tanh regularization at least
``friction_smoothing`` (default 0.02 rad/s): the model's 1e-4-1e-6 rad/s make the Jacobian
at rest a stiff switch (the calibrated Quanser twin: lambda T = 89 at 1 kHz) that a
linearization held over samples cannot follow.
"""
from __future__ import annotations

import copy

import numpy as np

from ..inputs import JD_EPS, JD_FC, JD_FS, JD_FV, input_data
from ..integrators import derivative

PARAMETER_KINDS = ("coulomb_friction", "viscous_friction", "payload_mass", "link_stiffness")
#: lower bounds the adapted parameters are projected onto after each correction
PARAMETER_FLOOR = {"coulomb_friction": 0.0, "viscous_friction": 0.0, "payload_mass": 0.0,
                   "link_stiffness": 0.05}


def parse_parameter(name: str, joint_names, link_names) -> tuple[str, int]:
    """('kind', index) of an adapted parameter name such as 'coulomb_friction:0'."""
    kind, _, target = name.partition(":")
    if kind not in PARAMETER_KINDS:
        names = [k + ("" if k == "payload_mass" else ":<i>") for k in PARAMETER_KINDS]
        raise ValueError(f"adapt: got {name!r}; expected one of {', '.join(names)}")
    if kind == "payload_mass":
        return kind, -1
    names = list(link_names if kind == "link_stiffness" else joint_names)
    if target in names:
        return kind, names.index(target)
    if target.isdigit() and int(target) < len(names):
        return kind, int(target)
    raise ValueError(f"adapt: {name!r}: expected ':<index or name>' of one of {names}")


class PlanarPlant:
    """x' = f(x, u) of a FlexArmModel with augmented parameters (constant: p' = 0)."""

    spatial = False

    def __init__(self, model, adapt=(), friction_smoothing: float = 0.02):
        if model.arm.kinematics == "exact":
            raise ValueError("estimation: kinematics: exact is not supported; use "
                             "small_deflection or second_order")
        if model.n_bristles:
            raise ValueError("estimation: stick_slip_friction is not supported (its "
                             "bristle states); model the joint with joint_friction")
        self.model = copy.copy(model)
        self.nq = model.nq
        self.n_joints = model.n_links
        self.n_links = model.n_links
        self.joint_names = list(model.arm.joint_names)
        self.link_names = [lk.name for lk in model.arm.links]
        self.params = [parse_parameter(a, self.joint_names, self.link_names) for a in adapt]
        self.param_names = list(adapt)
        self.smoothing = friction_smoothing
        self._u = np.zeros(self.n_joints)
        self._E = input_data(self.model, None, (), self._u)
        self._cached = (None, None, None)
        self._K0 = self.model.K.copy()
        self._jd0 = self.model.joint_data.copy()
        rubbing = self._jd0[:, JD_FV:JD_FS + 1].any(axis=1)   # the filter's friction: tanh
        self._jd0[rubbing, JD_EPS] = np.maximum(self._jd0[rubbing, JD_EPS], friction_smoothing)
        self._E = self._E._replace(joint_data=self._jd0)   # over at least friction_smoothing
        self._payload = self.model.payload
        self._P_cache = (self._payload[0], self.model.P)

    def nominal_parameters(self) -> np.ndarray:
        """The model's own values of the adapted parameters."""
        out = []
        for kind, i in self.params:
            out.append({"coulomb_friction": lambda: self._jd0[i, JD_FC],
                        "viscous_friction": lambda: self._jd0[i, JD_FV],
                        "payload_mass": lambda: self._payload[0],
                        "link_stiffness": lambda: 1.0}[kind]())
        return np.array(out, float)

    def _data(self, p):
        """(P, E) of the compiled derivative for parameter values p."""
        E = self._E
        if not self.params:
            return self.model.P, E
        K, jd, mass = self._K0, self._jd0, None
        for (kind, i), val in zip(self.params, p):
            if kind == "link_stiffness":
                K = K.copy() if K is self._K0 else K
                s = self.model.flex_slice(i)
                K[s, s] = val * self._K0[s, s]
            elif kind == "payload_mass":
                mass = val
            else:
                jd = jd.copy() if jd is self._jd0 else jd
                if kind == "coulomb_friction":  # keep the Stribeck excess F_s - F_c
                    jd[i, JD_FS] = jd[i, JD_FS] - jd[i, JD_FC] + val
                    jd[i, JD_FC] = val
                    declared = self._jd0[i, JD_FV:JD_FS + 1].any()   # (its eps is floored)
                    jd[i, JD_EPS] = jd[i, JD_EPS] if declared else self.smoothing
                else:
                    jd[i, JD_FV] = val
        E = E._replace(K=K, joint_data=jd)
        return self._payload_P(mass), E

    def _payload_P(self, mass):
        if mass is None:
            return self.model.P
        m0, P = self._P_cache
        if mass != m0:
            self.model.set_payload(max(float(mass), 0.0), self._payload[1])
            P = self.model.P
            self._P_cache = (mass, P)
        return P

    def derivative(self, x, u) -> np.ndarray:
        """[v; a; 0] at state x = [q; v; p] and input u (joint torques or voltages)."""
        nq = self.nq
        key = tuple(x[2 * nq:])
        if self._cached[0] != key:   # (P, E) for these parameter values
            P, E = self._data(x[2 * nq:])
            self._cached = (key, P, E)
        self._u[:] = u               # E.u, the held input, shared by every E
        out = np.zeros(len(x))
        out[:2 * nq] = derivative(0.0, np.ascontiguousarray(x[:2 * nq]), self._cached[1],
                                  self._cached[2])
        return out

    def momentum_terms(self, x, u) -> tuple[np.ndarray, np.ndarray]:
        """(Ga B v, Ga (B a + B' v)) at x = [q; v; p]: the actuator rows of the generalized
        momentum B(q) v and of its rate, a from Eq. 27 with the parameters of x (B' v by
        central differences along v)."""
        from ..kernels import mass_matrix
        nq = self.nq
        q, v = x[:nq], x[nq:2 * nq]
        a = self.derivative(x, u)[nq:2 * nq]
        P = self._cached[1]                     # the derivative's data for these parameters
        h = 1e-6 / max(float(np.abs(v).max()), 1e-6)
        dB = (mass_matrix(q + h * v, P) - mass_matrix(q - h * v, P)) / (2 * h)
        Ga = self.model.Ga
        return Ga @ (mass_matrix(q, P) @ v), Ga @ (mass_matrix(q, P) @ a + dB @ v)

    def inverse_mass(self, q, p) -> np.ndarray:
        """B(q)^-1 with the payload of p (the map of generalized force noise to a)."""
        P, _ = self._data(p)
        from ..kernels import mass_matrix
        return np.linalg.inv(mass_matrix(np.asarray(q, float), P))

    def actuator_map(self) -> np.ndarray:
        """(nq, n_joints): generalized force of a unit torque at each actuator."""
        return self.model.Ga.T

    def flex_indices(self) -> np.ndarray:
        return self.model.flex_indices

    def link_force_map(self, q) -> np.ndarray:
        """(nq, n_links): generalized force of a unit force at each link's tip, normal to
        the link's root tangent (J_i^T n_i, J_i by central differences of the origins)."""
        q = np.asarray(q, float)
        J = np.empty((self.n_links + 1, 2, self.nq))
        for j in range(self.nq):
            dq = np.zeros(self.nq)
            dq[j] = 1e-7
            J[:, :, j] = (self.model.link_origins(q + dq)
                          - self.model.link_origins(q - dq)) / 2e-7
        out = np.empty((self.nq, self.n_links))
        for i in range(self.n_links):
            a = q[self.model.alpha_index(i)]
            out[:, i] = J[i + 1].T @ np.array([-np.sin(a), np.cos(a)])
        return out

    # ---------------------------------------------------------------- outputs
    def joint_angles(self, q):
        return self.model.G @ q

    def joint_rates(self, v):
        return self.model.G @ v

    def motor_angle(self, q, i):
        return float(self.model.Ga[i] @ q * self.model.joint_data[i, 15])

    def tip_deflections(self, q) -> np.ndarray:
        return self.model.tip_deflections(q)

    def tip_position(self, q) -> np.ndarray:
        """(x, y, 0) of the arm's end (m)."""
        return np.append(self.model.link_origins(q)[-1], 0.0)

    def strain(self, q, i, position, surface_distance) -> float:
        curv = self.model.bases[i].curvature_matrix([position])[0]
        return float(-surface_distance * (q[self.model.flex_slice(i)] @ curv))

    def tip_acceleration(self, x, u) -> np.ndarray:
        """Specific force a_tip - g in the tip frame (x along the tip tangent)."""
        nq = self.nq
        a = self.derivative(x, u)[nq:2 * nq]
        return self.model.tip_specific_force(x[:nq], x[nq:2 * nq], a)

    # ---------------------------------------------------------- linear maps
    def angle_map(self) -> np.ndarray:
        """(n_joints, nq): joint angles = angle_map q (rates likewise from v)."""
        return self.model.G

    def deflection_map(self) -> np.ndarray:
        """(n_links, nq): link tip deflections = deflection_map q."""
        D = np.zeros((self.n_links, self.nq))
        for i in range(self.n_links):
            D[i, self.model.tip_deflection_index(i)] = 1.0
        return D

    def tip_jacobian(self, q) -> np.ndarray:
        """(3, nq): d tip position / d q (z row zero)."""
        return np.vstack([self.model.tip_jacobian(q), np.zeros((1, self.nq))])

    def tip_orientation(self, q) -> tuple:
        """(x, y, z, w): the tip tangent's rotation about z (FlexArmModel.tip_pose)."""
        from ..urdf import yaw_quaternion
        return yaw_quaternion(self.model.tip_pose(q)[2])

    def tip_pose_jacobian(self, q) -> np.ndarray:
        """(6, nq): d(tip position, rotation about x, y, z)/dq, base frame."""
        J = np.zeros((6, self.nq))
        J[:2] = self.model.tip_jacobian(q)
        J[5] = self.model.tip_torque_vector()   # d phi / dq = e_alpha_nu + R_nu
        return J

    def q_from_joint_angles(self, theta) -> np.ndarray:
        return self.model.q_from_joint_angles(theta)
