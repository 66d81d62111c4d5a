"""The spatial arm as the filter sees it (flex_model.estimation.plant for the planar one).

x = [q; v; p]; a = SpatialArmModel.acceleration(q, v, Q) with Q the joint commands through
``actuator_force`` (voltages on dc_motor joints) and the adapted parameters' forces.
Adapted: ``coulomb_friction:<joint>``, ``viscous_friction:<joint>`` (the joint's total: its
declared joint_friction is replaced by the estimator's, Stribeck excess kept) and
``link_stiffness:<link>`` (scale on the link's K block: EI and GJ); not the payload yet.

The equations are the compiled ones (spatial.compiled: M, c by the analytic Newton-Euler
pass). The spatial links' bending and torsion modes reach kHz (the two-link L arm of the
independent suite: 6.7 kHz against a 200 Hz sample rate): a linearly implicit step with a
held Jacobian diverges there, so the estimate moves by the model's own implicit step
(spatial.integrate.simulate_fixed_compiled: generalized-alpha, rho_inf 0.9, Newton, a
restart from the corrected state each sample) while the covariance moves with the held
Jacobian (flex_model.estimation.filter).
"""
from __future__ import annotations

import copy

import numpy as np

from ..effects.friction import friction_law
from ..spatial.compiled import pack, spatial_terms
from ..spatial.integrate import simulate_fixed_compiled
from .plant import parse_parameter


#: spectral radius of the generalized-alpha step at infinite frequency (the model node's
#: fixed step; 0 lets the Newton iteration fail on the corrected states)
RHO_INF = 0.9


class SpatialPlant:
    """x' = f(x, u) of a SpatialArmModel with augmented parameters (p' = 0)."""

    spatial = True

    def __init__(self, model, adapt=(), friction_smoothing: float = 0.02):
        self.model = copy.copy(model)
        self.nq = model.nq
        self.n_joints = self.n_links = model.n_links
        self.joint_names = list(model.arm.joint_names)
        self.link_names = [lk.name for lk in model.arm.links]
        self.params = [parse_parameter(a, self.joint_names, self.link_names) for a in adapt]
        if any(k == "payload_mass" for k, _ in self.params):
            raise ValueError("adapt: payload_mass is not estimated on spatial arms yet; "
                             "use a planar arm or leave it out")
        self.param_names = list(adapt)
        self.smoothing = friction_smoothing
        fr = {a: f for a, f in model.friction}
        self._fric = {}  # joint -> [fv, fc, fs - fc, ws, eps] of the estimator's law
        for kind, i in self.params:
            if "friction" not in kind or i in self._fric:
                continue
            a = int(model.actuator_index[i])
            f = fr.get(a)
            fv, fc, fs, ws, eps = f.values if f is not None else (0, 0, 0, 0.01, 0)
            self._fric[i] = [fv, fc, fs - fc, ws, max(eps, friction_smoothing)]
        replaced = {int(model.actuator_index[i]) for i in self._fric}
        self._fixed_friction = [(a, f) for a, f in model.friction if a not in replaced]
        self._K0 = model.K.copy()
        self._apply(self.nominal_parameters())
        self._data = self.model._compiled_data = pack(self.model)

    def nominal_parameters(self) -> np.ndarray:
        out = []
        for kind, i in self.params:
            out.append(self._fric[i][0] if kind == "viscous_friction" else
                       self._fric[i][1] if kind == "coulomb_friction" else 1.0)
        return np.array(out, float)

    def _apply(self, p) -> None:
        """The parameter values p into the model's K and friction list (what both the
        Python and the compiled equations read)."""
        p = tuple(np.asarray(p, float))
        if getattr(self, "_applied", None) == p:
            return
        K = self._K0.copy()
        law = {i: list(c) for i, c in self._fric.items()}
        for (kind, i), val in zip(self.params, p):
            if kind == "viscous_friction":
                law[i][0] = val
            elif kind == "coulomb_friction":
                law[i][1] = val
            else:
                s = self.model.flex_slice(i)
                K[s, s] = val * self._K0[s, s]
        self.model.K = K
        self.model.friction = self._fixed_friction + [
            (int(self.model.actuator_index[i]), _Friction(fv, fc, fc + dfs, ws, eps))
            for i, (fv, fc, dfs, ws, eps) in law.items()]
        self._applied = p

    def derivative(self, x, u) -> np.ndarray:
        nq = self.nq
        q, v = x[:nq], x[nq:2 * nq]
        self._apply(x[2 * nq:])
        m = self.model
        M, c = spatial_terms(self._data, q, v)
        rhs = m.actuator_force(u, v)[0] + m.effect_force(v, q) - c - m.K @ q - m.D @ v
        free = m.free_indices
        out = np.zeros(len(x))
        out[:nq] = v
        out[nq + free] = np.linalg.solve(M[np.ix_(free, free)], rhs[free])
        return out

    def step(self, x, u, T) -> np.ndarray:
        """x after one sample T under u: the model's generalized-alpha step (Newton),
        restarted from x (consistent acceleration); parameters held."""
        nq = self.nq
        self._apply(x[2 * nq:])
        r = simulate_fixed_compiled(self.model, x[:nq], x[nq:2 * nq], T, 1,
                                    joint_torques=np.asarray(u, float), rho_inf=RHO_INF)
        return np.concatenate([r.q[-1], r.v[-1], x[2 * nq:]])

    def inverse_mass(self, q, p) -> np.ndarray:
        free = self.model.free_indices
        M = spatial_terms(self._data, q, np.zeros(self.nq))[0]
        out = np.zeros((self.nq, self.nq))
        out[np.ix_(free, free)] = np.linalg.inv(M[np.ix_(free, free)])
        return out

    def actuator_map(self) -> np.ndarray:
        N = np.zeros((self.nq, self.n_joints))
        for i, a in enumerate(self.model.actuator_index):
            if a >= 0:
                N[a, i] = 1.0
        return N

    def flex_indices(self) -> np.ndarray:
        idx = [np.arange(self.nq)[self.model.flex_slice(i)] for i in range(self.n_links)]
        return np.concatenate(idx).astype(int) if idx else np.zeros(0, int)

    def link_force_map(self, q) -> np.ndarray:
        """(nq, 2 n_links): a unit force on each flexible link's tip deflection variables
        v and w (the force at its tip in the link frame, without the joints' reaction)."""
        out = np.zeros((self.nq, 2 * self.n_links))
        for i, b in enumerate(self.model.beams):
            if b is not None:
                s = self.model.flex_slice(i).start
                out[s + b.tip_v, 2 * i] = out[s + b.tip_w, 2 * i + 1] = 1.0
        return out

    def link_moment_map(self) -> np.ndarray:
        """(nq, n_links): a unit moment about each flexible link's axis on its tip twist
        variable (zero for a link without torsion variables)."""
        out = np.zeros((self.nq, self.n_links))
        for i, b in enumerate(self.model.beams):
            if b is not None and b.tip_phi is not None:
                out[self.model.flex_slice(i).start + b.tip_phi, i] = 1.0
        return out

    # ---------------------------------------------------------------- outputs
    def joint_angles(self, q):
        return np.asarray(q)[self.model.off]

    def joint_rates(self, v):
        return np.asarray(v)[self.model.off]

    def motor_angle(self, q, i):
        g = self.model.arm.effect("gear", self.joint_names[i])
        a = self.model.actuator_index[i]
        return float((1.0 if g is None else g["ratio"]) * q[a if a >= 0 else self.model.off[i]])

    def tip_deflections(self, q) -> np.ndarray:
        """(n_links, 3): tip v, w (m) and twist phi (rad) of every link (0: rigid)."""
        return (self.deflection_map() @ np.asarray(q, float)).reshape(self.n_links, 3)

    def tip_position(self, q) -> np.ndarray:
        return self.model.tip_position(q)

    def tip_jacobian(self, q) -> np.ndarray:
        return self.model.tip_jacobian(q)[:3]

    def tip_orientation(self, q) -> tuple:
        """(x, y, z, w) of the end frame's rotation (base frame)."""
        from ..urdf import quaternion_from_matrix
        return quaternion_from_matrix(np.real(self.model.tip_frame(q).R))

    def tip_pose_jacobian(self, q) -> np.ndarray:
        """(6, nq): the end frame's linear and angular velocity per q-dot."""
        return self.model.tip_jacobian(q)

    def angle_map(self) -> np.ndarray:
        G = np.zeros((self.n_joints, self.nq))
        G[np.arange(self.n_joints), self.model.off] = 1.0
        return G

    def deflection_map(self) -> np.ndarray:
        """(3 n_links, nq): link-major (v, w, twist) tip deflections = map q."""
        D = np.zeros((3 * self.n_links, self.nq))
        for i, b in enumerate(self.model.beams):
            if b is None:
                continue
            s = self.model.flex_slice(i).start
            D[3 * i, s + b.tip_v] = D[3 * i + 1, s + b.tip_w] = 1.0
            if b.tip_phi is not None:
                D[3 * i + 2, s + b.tip_phi] = 1.0
        return D

    def q_from_joint_angles(self, theta) -> np.ndarray:
        q = np.zeros(self.nq)
        q[self.model.off] = theta
        for i, m in enumerate(self.model.motor_index):
            if m >= 0:
                q[m] = theta[i]
        return q


class _Friction:
    """A joint friction law with the adapted values (JointFriction's torque and values,
    as SpatialArmModel.friction and the compiled loop read them)."""

    def __init__(self, fv, fc, fs, ws, eps):
        self.values = (float(fv), float(fc), float(fs), float(ws), float(eps))

    def torque(self, w):
        return friction_law(w, *self.values)[0]
