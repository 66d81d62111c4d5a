"""SpatialArmModel: equations of motion of a spatial flexible arm (Lagrange, Gauss quadrature).

    M(q) a + c(q, v) + K q = Q

``q = [q_1, f_1, ..., q_n, f_n]``: joint variable q_i (rad or m) and, for a flexible link,
f_i = [v-variables, w-variables, phi-variables] of the wavelet basis of thesis Ch. II
(basis.py, one basis per bending plane with its EI; the same Hermite wavelets for the
torsion angle, whose root rate phi'(0) is free). The kinetic energy is that of point
masses rhoA ds at the Gauss points of the centre line, the sections' polar mass moment
rhoJ ds about the beam axis (torsional rotary inertia), with ``rotary_inertia`` also the
bending rotary inertia rho I_y ds, rho I_z ds about the section's y and z axes (a Rayleigh
beam; Euler-Bernoulli without it: description.FlexibleBeam) and the rigid root/end bodies:

    M = sum m Jp^T Jp + sum Jw^T I Jw,
    c = sum m Jp^T (dJp/dt v) + sum Jw^T (I dJw/dt v + w x I w) - sum m Jp^T g,

the Newton-Euler form of Lagrange's equations (equal to the Christoffel form for these
kinetic energies); dJ/dt v is computed **exactly by a complex step** of the kinematics
(J(q + i h v), h = 1e-20: no truncation, no cancellation). K is block diagonal: the
bending blocks are the basis's int EI w'' w''^T (thesis Eq. 14) per plane, the torsion
block int GJ phi' phi'^T.

Joint effects (flex_model.effects, the planar classes and YAML names; seed 003's joint
options, description.SpatialJoint):

- ``joint_elasticity`` on an active motor adds a motor coordinate theta_m (after all the
  link coordinates, in joint order; link-side units) with the constant inertia
  ``motor_inertia`` and the spring-damper k_t (theta_m - q_i) + b_t (theta_m' - q_i')
  (seed 002 Eqs. 11-14, seed 003's C_xi, B_xi) in K and D; the joint torque then acts on
  theta_m. With a **locked** motor theta_m = ``locked_at`` (seed 003 Eq. 6, type LE):
  the spring goes to ground, K_ii += k_t, Q_i += k_t locked_at, D_ii += b_t.
- A locked motor behind a rigid gear (type LR, Eq. 10) holds its joint: q_i is
  ``held`` (its acceleration is zero; removed from the modes).
- ``gear`` (ratio n, rotor_inertia J_r): an axisymmetric rotor about the joint axis e
  on the stator (the frame before the joint motion), spinning at n theta_a relative to
  it (theta_a the joint, or the motor coordinate of an elastic joint; 0 when locked):
  omega_r = omega_s + n theta_a' e, inertia J_r e e^T, so M += J_r a a^T with
  a = Jw_s^T e + n e_a (seed 000 Eq. 35 in 3D, with the stator's rotation and the
  gyroscopic torque J_r (e . omega_r) omega_s x e).
- ``joint_friction``: tau_f(theta_a') (viscous, Coulomb, Stribeck, tanh-regularized,
  effects.friction.JointFriction.torque) on the actuator coordinate theta_a.
- ``dc_motor`` (R, K_t, K_e, i_max, V_max; seed 003 Eqs. 43, 48 with the armature
  inductance neglected, as the planar model): the joint's command is a voltage V and
  tau = n K_t clip((clip(V, V_max) - K_e n theta_a') / R, i_max), n the ratio of a
  ``gear`` on the joint (1 without; its rotor_inertia is the armature inertia), then
  clipped to the URDF effort limit (:meth:`SpatialArmModel.actuator_force`).

- ``backlash`` (half_width b_g, smoothing; needs the joint's elastic gear): the gear
  spring gets the planar dead zone (effects.joint_elasticity.Backlash,
  integrators.dead_zone): tau_s = k_t dz(x) + b_t dz'(x) x', x = theta_m - q_i (theta_m
  = locked_at for a locked motor). K and D keep the engaged (linear) spring, so statics,
  modes, the planner and the PD equilibria see the engaged gear; the dynamics add the
  correction k_t (dz(x) - x) + b_t (dz'(x) - 1) x' (:meth:`SpatialArmModel.effect_force`
  with q) and its tangent in the Newton matrix (:meth:`SpatialArmModel.backlash_tangent`).

Link effects:

- ``structural_damping`` (thesis Eqs. 35-36 and Rayleigh, effects.structural_damping):
  D_link += k_a S1 per bending plane (S1 = int w' w'^T dz of that plane's basis: the
  weak form of -k_a d^3 d / dt dz^2, Eq. 35; not on the twist: k_a is a bending
  coefficient, N s) + a M_ff + b K_ff on the link's whole deformation block (both
  planes and the twist), M_ff the link's clamped deformation inertia: the deformation
  block of the mass matrix of the link alone at rest (its beam and end body, joint
  clamped; not the arm's payload), as the planar M_ff (beam + M+, J+, no payload). For a
  single flexible link with clamped joints and no payload the modal damping ratios are
  zeta_k = a / (2 w_k) + b w_k / 2 in every plane.

Arm effects:

- ``contact_surface`` (seed 003's environment force, effects.contact: a plane through
  p0 with unit normal n into the free side, stiffness k, damping c): with the tip p
  (the origin of the last link's end frame, :meth:`SpatialArmModel.tip_frame`) and its
  translational Jacobian J, delta = -n . (p - p0) and, for delta > 0,
  F = max(0, k delta - c n . J v) n (zero otherwise), the generalized force J^T F
  (:meth:`SpatialArmModel.effect_force` with q; the force itself:
  :meth:`SpatialArmModel.contact_force`). The Newton matrix takes its tangent
  k J^T n n^T J, c J^T n n^T J while the force acts (:meth:`SpatialArmModel.contact_tangent`;
  the dJ/dq terms are left out), the energy the potential k delta^2 / 2.
- ``joint_stops`` (description.JointStops, the joints' position limits as end stops): a
  spring-damper on the joint variable beyond a limit, applied smoothly through a
  transition region (:meth:`SpatialArmModel.stop_load`, in
  :meth:`SpatialArmModel.effect_force` with q; its tangent on the diagonal,
  :meth:`SpatialArmModel.stop_tangent`; its potential in the energy as "stops").

Kinematics ``second_order`` (arm option, the planar model's name): a bent inextensible
beam's points move back along its axis by the axial shortening
u(s) = 1/2 (f_v^T S_v(s) f_v + f_w^T S_w(s) f_w), S(s) = int_0^s w' w'^T (both planes;
basis.LinkBasis.shortening_matrix): the centre line at (s - u(s), v(s), w(s)) and the tip
frame's origin at (L - u(L), v, w) (the section rotations stay those of Eq. 19). It enters
M, c and gravity through the points' positions and Jacobians (the complex step gives the
velocity terms, centrifugal stiffening included); a planar second_order arm embedded by
from_planar has the planar model's equations.

Arm data: ``payload`` (a rigid body in the last link's end frame) is lumped with the last
link's end body (parallel-axis theorem, :func:`combine_bodies`).
"""
from __future__ import annotations

import numpy as np

from ..basis import link_basis
from ..effects.friction import friction_law
from ..integrators import dead_zone, dead_zone_energy
from .description import SpatialArm
from .exact import curvature_energies, dense_rule, tangent_rule, tangents
from .kinematics import P_AUX, Frame, cross, point_jacobians, rot_x, rot_y, rot_z, skew

_XI, _WXI = np.polynomial.legendre.leggauss(6)
_H = 1e-20   # complex step


def dead_zone_curvature(x: float, half: float, smooth: float) -> float:
    """d^2 dz / dx^2 of integrators.dead_zone: s^2 / 2 (1 / r_+^3 - 1 / r_-^3)."""
    rp = np.hypot(x - half, smooth)
    rm = np.hypot(x + half, smooth)
    return float(0.5 * smooth * smooth * (1.0 / rp ** 3 - 1.0 / rm ** 3))


def combine_bodies(a, b):
    """One rigid body (mass, centre, inertia about the centre) equal to the bodies ``a``
    and ``b`` (each (mass, centre (3), inertia (3 x 3)) or None) fixed in one frame:
    the parallel-axis theorem I = sum I_k + m_k (|d_k|^2 E - d_k d_k^T), d_k = c_k - c."""
    if a is None or b is None:
        return a if b is None else b
    m = a[0] + b[0]
    c = (a[0] * a[1] + b[0] * b[1]) / m if m > 0 else 0.5 * (a[1] + b[1])
    inertia = np.zeros((3, 3))
    for mk, ck, Ik in (a, b):
        d = ck - c
        inertia += Ik + mk * (d @ d * np.eye(3) - np.outer(d, d))
    return m, c, inertia


class BeamData:
    """Sampled bases of one flexible link at its Gauss points (and constant blocks)."""

    def __init__(self, beam):
        self.beam = beam
        L = beam.length
        nv, nt = beam.variables, beam.torsion_variables
        # torsion is a second-order problem: only phi(0) = 0 is clamped, the root twist rate
        # phi'(0) is a variable (first), before the wavelet pairs
        nt = nt + 1 if nt else 0
        self.nv, self.nt = nv, nt
        self.bv = link_basis(beam.bend_v, nv // 2)
        self.bw = link_basis(beam.bend_w, nv // 2)
        self.bt = link_basis(beam.torsion, nt // 2) if nt else None
        h1 = self.bt.nodes[1] if nt else 1.0
        # the torsion basis's own nodes too: its Hermite pieces (and the root function on
        # [0, h1]) have kinked slopes there; with more torsion than bending intervals a
        # Gauss rule across them left int GJ phi'^2 inexact (2.3 % on a shaft's frequency)
        cuts = [self.bv.nodes, self.bw.nodes, beam.bend_v.breaks, beam.bend_w.breaks,
                beam.torsion.breaks] + ([self.bt.nodes] if nt else [])
        cuts = np.unique(np.round(np.concatenate(cuts), 14))
        # tapered sections: non-polynomial wavelets (moments of 1/EI), finer quadrature
        tapered = any(sg.tapered for p in (beam.bend_v, beam.bend_w, beam.torsion)
                      for sg in p.segments)
        sub = 8 if tapered else 1
        z, w = [], []
        for a, b in zip(cuts[:-1], cuts[1:]):
            for a1, b1 in zip(np.linspace(a, b, sub + 1)[:-1], np.linspace(a, b, sub + 1)[1:]):
                z.append(a1 + 0.5 * (b1 - a1) * (_XI + 1.0))
                w.append(0.5 * (b1 - a1) * _WXI)
        self.z, self.w = np.concatenate(z), np.concatenate(w)
        self.mass_w = self.w * beam.bend_v.properties(self.z)[1]        # rhoA ds
        gj, rhoj, _ = beam.torsion.properties(self.z)
        self.polar_w = self.w * rhoj                                      # rhoJ ds
        #: bending rotary inertia (rho I_y ds, rho I_z ds) per point, rho I = rhoJ EI /
        #: (EI_y + EI_z) (description.FlexibleBeam.rotary_inertia); None without
        self.rotary = None
        if beam.rotary_inertia:
            eiz, eiy = beam.bend_v.properties(self.z)[0], beam.bend_w.properties(self.z)[0]
            self.rotary = np.column_stack([eiy, eiz]) * (self.polar_w / (eiy + eiz))[:, None]
        self.Wv, self.dWv = self.bv.shape_matrix(self.z), self.bv.slope_matrix(self.z)
        self.Ww, self.dWw = self.bw.shape_matrix(self.z), self.bw.slope_matrix(self.z)
        n = 2 * nv + nt
        self.n = n
        K = np.zeros((n, n))
        K[:nv, :nv] = self.bv.K
        K[nv:2 * nv, nv:2 * nv] = self.bw.K
        if nt:
            xi = np.clip(self.z / h1, 0.0, 1.0)
            root = np.where(self.z < h1, self.z * (1 - xi) ** 2, 0.0)      # Hermite, phi'(0)
            droot = np.where(self.z < h1, (1 - xi) * (1 - 3 * xi), 0.0)
            self.Pt = np.column_stack([root, self.bt.shape_matrix(self.z)])
            dPt = np.column_stack([droot, self.bt.slope_matrix(self.z)])
            K[2 * nv:, 2 * nv:] = (dPt * (self.w * gj)[:, None]).T @ dPt
            self._coupling(dPt, gj)
        else:
            self.Pt = np.zeros((len(self.z), 0))
            self.coupling = None
        self._gj = gj
        self.K = 0.5 * (K + K.T)
        self.length = L
        # tip: deflection and slope are the last pair of each basis (clamped root)
        self.tip_v, self.tip_dv = nv - 2, nv - 1
        self.tip_w, self.tip_dw = nv + nv - 2, nv + nv - 1
        self.tip_phi = 2 * nv + nt - 2 if nt else None
        self.P = P_AUX if beam.placement == "aux_z" else np.eye(3)
        #: second_order kinematics: S(z) = int_0^z w' w'^T ds of each plane at the mass
        #: points and at the tip (None: small deflections)
        self.Sv = self.Sw = self.SvL = self.SwL = None
        #: exact kinematics (exact.py): the tangent rule (nodes, weights, nfull, rows of
        #: the mass points and the tip), the slopes at the nodes, C; None otherwise
        self.rule = None

    def _coupling(self, dPt, gj):
        """The point samples of curvature_coupling: F (5, points, n) maps the link's
        variables to (phi', v', w'', phi, v''); the weights GJ ds, EI_y ds, EI_z ds."""
        nv, npt = self.nv, len(self.z)
        F = np.zeros((5, npt, self.n))
        F[0, :, 2 * nv:] = dPt
        F[1, :, :nv] = self.dWv
        F[2, :, nv:2 * nv] = self.bw.curvature_matrix(self.z)
        F[3, :, 2 * nv:] = self.Pt
        F[4, :, :nv] = self.bv.curvature_matrix(self.z)
        eiz, eiy = (p.properties(self.z)[0] for p in (self.beam.bend_v, self.beam.bend_w))
        self.coupling = (F, self.w * gj, self.w * eiy, self.w * eiz)

    def curvature_coupling(self, f):
        """(U, dU/df, d^2U/df^2): the second-order part of the strain energy 1/2 int
        (GJ k_x^2 + EI_y k_y^2 + EI_z k_z^2) ds beyond the quadratic one of K, with the
        curvatures of the section rotation Ry(-w') Rz(v') Rx(phi) (Eq. 19 with the twist
        about the centre line's tangent) to second order: k_x = phi' - v' w'',
        k_y = -(w'' - phi v''), k_z = v'' + phi w''. Per point, x = (phi', v', w'', phi,
        v''): u = GJ (-x0 x1 x2 + x1^2 x2^2 / 2) + (EI_z - EI_y) x3 x4 x2
        + (EI_y x4^2 + EI_z x2^2) x3^2 / 2."""
        F, g, y, z = self.coupling
        if self.rule is not None:      # exact kinematics: the exact curvatures (exact.py)
            X = np.ascontiguousarray((F @ f).T)
            DU, H = np.zeros_like(X), np.zeros(X.shape + (5,))
            U = curvature_energies(X, g, y, z, DU, H)
            Hq = np.einsum("kpn,pkl,lpm->nm", F, H, F)
            return float(U), np.einsum("kpn,pk->n", F, DU), 0.5 * (Hq + Hq.T)
        a, b, c, p, e = F @ f                           # (n_points,) each
        dz = z - y
        U = float(np.sum(g * (-a * b * c + 0.5 * b * b * c * c) + dz * p * e * c
                         + 0.5 * p * p * (y * e * e + z * c * c)))
        du = np.array([-g * b * c, g * (-a * c + b * c * c),
                       g * (-a * b + b * b * c) + dz * p * e + z * p * p * c,
                       dz * e * c + p * (y * e * e + z * c * c), dz * p * c + y * p * p * e])
        h = np.zeros((5, 5, len(g)))
        h[0, 1], h[0, 2] = -g * c, -g * b
        h[1, 1], h[1, 2] = g * c * c, g * (2 * b * c - a)
        h[2, 2], h[2, 3], h[2, 4] = g * b * b + z * p * p, dz * e + 2 * z * p * c, dz * p
        h[3, 3], h[3, 4] = y * e * e + z * c * c, dz * c + 2 * y * p * e
        h[4, 4] = y * p * p
        h = h + np.tril(np.ones((5, 5)), -1)[:, :, None] * h.transpose(1, 0, 2)
        grad = np.einsum("kpn,kp->n", F, du)
        H = np.einsum("kpn,klp,lpm->nm", F, h, F)
        return U, grad, 0.5 * (H + H.T)

    def exact(self, inner: int = 8):
        """Tables of the exact kinematics (exact.py): the tangent rule on the pieces
        between both bending bases' interval ends and the section breaks, and the
        curvature energy on every link (twisting or not)."""
        beam = self.beam
        cuts = np.unique(np.round(np.concatenate(
            [self.bv.nodes, self.bw.nodes, beam.bend_v.breaks, beam.bend_w.breaks]), 14))
        nodes, wts, nfull, rows = tangent_rule(cuts, np.append(self.z, self.length), inner)
        self.rule = (nodes, wts, nfull, rows)
        self.ndv, self.ndw = self.bv.slope_matrix(nodes), self.bw.slope_matrix(nodes)
        self.C = dense_rule(wts, nfull, rows)
        if self.coupling is None:
            self._coupling(np.zeros((len(self.z), 0)), self._gj)

    def exact_points(self, fv, fw):
        """(r (points + tip, 3), dr/df_v, dr/df_w (points + tip, 3, nv)) in the beam frame
        (exact.py; analytic in f: complex steps pass)."""
        t, tb, ta = tangents(self.ndw @ fw, self.ndv @ fv)
        n, nv = self.C.shape[0], self.nv
        Jv = self.C @ (tb[:, :, None] * self.ndv[:, None, :]).reshape(len(tb), -1)
        Jw = self.C @ (ta[:, :, None] * self.ndw[:, None, :]).reshape(len(ta), -1)
        return self.C @ t, Jv.reshape(n, 3, nv), Jw.reshape(n, 3, nv)

    def second_order(self):
        """Sample the shortening matrices (basis.LinkBasis.shortening_matrix)."""
        zl = np.concatenate([self.z, [self.length]])
        Sv, Sw = self.bv.shortening_matrix(zl), self.bw.shortening_matrix(zl)
        self.Sv, self.SvL, self.Sw, self.SwL = Sv[:-1], Sv[-1], Sw[:-1], Sw[-1]

    def split(self, f):
        nv = self.nv
        return f[:nv], f[nv:2 * nv], f[2 * nv:]


class SpatialArmModel:
    """Equations of motion, kinematics and energy of a SpatialArm (parameters only)."""

    def __init__(self, arm: SpatialArm):
        self.arm = arm
        self.beams = [BeamData(lk.flexible) if lk.flexible is not None else None
                      for lk in arm.links]
        kin = getattr(arm, "kinematics", "small_deflection")
        if kin in ("second_order", "exact"):
            for b in self.beams:
                if b is not None:
                    b.second_order() if kin == "second_order" else b.exact()
        sizes = [1 + (b.n if b is not None else 0) for b in self.beams]
        self.off = np.concatenate([[0], np.cumsum(sizes)[:-1]]).astype(int)
        self.nq_arm = int(np.sum(sizes))
        self.n_links = arm.n_links
        self._joint_effects()
        nq = self.nq
        self.K = np.zeros((nq, nq))
        for i, b in enumerate(self.beams):
            if b is not None:
                s = self.flex_slice(i)
                self.K[s, s] = b.K
        self._fold_effects()
        self.gravity = np.asarray(arm.gravity, float)
        self._consts = []
        self._extra = []     # URDF-style data per link: origin, axis, end transform
        for lk in arm.links:
            j = lk.joint
            pre = (rot_z(j.theta), np.array([0.0, 0.0, j.d]))      # Trans_z(d) Rot_z(theta)
            dh_rest = (rot_x(j.alpha), np.array([j.a, 0.0, 0.0]))  # Trans_x(a) Rot_x(alpha)
            axis = np.asarray(j.axis, float)
            origin = None if lk.origin is None else (np.asarray(lk.origin[0], float),
                                                     np.asarray(lk.origin[1], float))
            end = None if lk.end_transform is None else (
                np.asarray(lk.end_transform[0], float), np.asarray(lk.end_transform[1], float))
            general = not np.array_equal(axis, [0.0, 0.0, 1.0])
            self._extra.append((origin, axis if general else None, end))
            bodies = []
            for body in (lk.root_body, lk.end_body):
                bodies.append(None if body.is_empty else
                              (body.mass, np.asarray(body.offset, float),
                               np.asarray(body.inertia, float)))
            pay = getattr(arm, "payload", None)
            if lk is arm.links[-1] and pay is not None and not pay.is_empty:
                bodies[1] = combine_bodies(bodies[1], (pay.mass, np.asarray(
                    pay.offset, float), np.asarray(pay.inertia, float)))
            self._consts.append((pre, dh_rest, bodies))
        self._structural_damping()
        #: (p0 (3), unit normal (3), k, c) of a contact_surface effect, or None
        ct = next((e for e in arm.effects if e.TYPE == "contact_surface" and not e.is_off),
                  None)
        self.contact = None if ct is None else ct.plane()
        #: end stops (description.JointStops): (joint coordinate, lower, upper, k, c,
        #: transition) per joint with a finite position limit that is not held
        js = arm.joint_stops
        self.stops = [] if js is None else [
            (int(self.off[i]), float(lk.joint.lower), float(lk.joint.upper), js.stiffness,
             js.damping, js.transition) for i, lk in enumerate(arm.links)
            if (np.isfinite(lk.joint.lower) or np.isfinite(lk.joint.upper))
            and self.off[i] not in self.held]

    # ------------------------------------------------------------ joint effects
    def _joint_effects(self):
        """Motor coordinates, actuator coordinate, rotors, held joints (see the module
        docstring)."""
        arm = self.arm
        n = self.n_links
        self.motor_index = np.full(n, -1, dtype=int)      # motor coordinate of joint i
        self.actuator_index = np.full(n, -1, dtype=int)   # where the joint torque acts
        nm = 0
        for i, lk in enumerate(arm.links):
            active = lk.joint.motor == "active"
            if lk.joint.gear == "elastic" and active:
                self.motor_index[i] = self.nq_arm + nm
                nm += 1
            if active:
                self.actuator_index[i] = self.motor_index[i] if self.motor_index[i] >= 0 \
                    else self.off[i]
        self.nq = self.nq_arm + nm
        self.held = np.array([self.off[i] for i, lk in enumerate(arm.links)
                              if lk.joint.motor == "locked" and lk.joint.gear == "rigid"],
                             dtype=int)
        # rotors: (J_r, n, spin coordinate or -1) per joint (J_r = 0: none)
        self.rotors = []
        self.friction = []          # (actuator coordinate, JointFriction effect)
        self.motors = []            # (joint, actuator coordinate, gear ratio, DCMotor)
        for i, lk in enumerate(arm.links):
            g = arm.effect("gear", lk.joint.name)
            self.rotors.append((0.0, 1.0, -1) if g is None else
                               (g["rotor_inertia"], g["ratio"], int(self.actuator_index[i])))
            f = arm.effect("joint_friction", lk.joint.name)
            if f is not None and not f.is_off and self.actuator_index[i] >= 0:
                self.friction.append((int(self.actuator_index[i]), f))
            dc = arm.effect("dc_motor", lk.joint.name)
            if dc is not None and self.actuator_index[i] >= 0:
                self.motors.append((i, int(self.actuator_index[i]),
                                    1.0 if g is None else g["ratio"], dc))

    def _fold_effects(self):
        """Springs and dampers of elastic gears into K and D, motor inertias into the
        constant M_const, the locked motors' spring preload into Q_const."""
        nq = self.nq
        self.D = np.zeros((nq, nq))
        self.M_const = np.zeros((nq, nq))
        self.Q_const = np.zeros(nq)
        #: gears with backlash: (q_i, motor coordinate or -1, k_t, b_t, half width,
        #: smoothing, locked_at)
        self.backlash = []
        for i, lk in enumerate(self.arm.links):
            e = self.arm.effect("joint_elasticity", lk.joint.name)
            if lk.joint.gear != "elastic" or e is None:
                continue
            k, b, jm = e["stiffness"], e["damping"], e["motor_inertia"]
            qi, m = self.off[i], self.motor_index[i]
            bl = self.arm.effect("backlash", lk.joint.name)
            if bl is not None and not bl.is_off:
                self.backlash.append((int(qi), int(m), k, b, bl["half_width"],
                                      bl["smoothing"], lk.joint.locked_at))
            if m >= 0:
                idx = np.array([qi, m])
                blk = np.array([[1.0, -1.0], [-1.0, 1.0]])
                self.K[np.ix_(idx, idx)] += k * blk
                self.D[np.ix_(idx, idx)] += b * blk
                self.M_const[m, m] += jm
            else:   # locked motor: the spring to ground at locked_at
                self.K[qi, qi] += k
                self.D[qi, qi] += b
                self.Q_const[qi] += k * lk.joint.locked_at

    def _structural_damping(self):
        """``structural_damping`` effects into D (see the module docstring)."""
        for i, lk in enumerate(self.arm.links):
            e = self.arm.effect("structural_damping", lk.name)
            if e is None or e.is_off or self.beams[i] is None:
                continue
            s = self.flex_slice(i)
            self.D[s, s] += self.structural_damping_block(i, *e.values)

    def structural_damping_block(self, i: int, k_a: float, a: float, b: float) -> np.ndarray:
        """k_a S1 per bending plane + a M_ff + b K_ff of flexible link i (module
        docstring; thesis Eqs. 35-36 and Rayleigh)."""
        import dataclasses

        from .description import SpatialArm
        bd = self.beams[i]
        nv = bd.nv
        blk = np.zeros((bd.n, bd.n))
        if k_a:
            blk[:nv, :nv] += k_a * bd.bv.S1
            blk[nv:2 * nv, nv:2 * nv] += k_a * bd.bw.S1
        if a:       # the link alone with its end body (not the payload), joint clamped
            lk = self.arm.links[i]
            alone = dataclasses.replace(lk, joint=dataclasses.replace(
                lk.joint, motor="active", gear="rigid"))
            sub = SpatialArmModel(SpatialArm(name="alone", links=(alone,),
                                             gravity=(0.0, 0.0, 0.0)))
            blk += a * sub.mass_matrix(np.zeros(sub.nq))[1:, 1:]
        if b:
            blk += b * bd.K
        return 0.5 * (blk + blk.T)

    def actuator_force(self, u, v, effort=None):
        """(Q, slope): the generalized force of the joint commands ``u`` (n_joints: torques
        or forces; a voltage on a ``dc_motor`` joint, through the motor model) on the
        actuator coordinates, clipped to ``effort`` (n_joints, default none), and
        d Q / dv (diagonal: the motors' back-EMF, 0 where a clip is active)."""
        u = np.asarray(u, float)
        effort = np.full(self.n_links, np.inf) if effort is None else np.asarray(effort, float)
        Q = np.zeros(self.nq)
        slope = np.zeros(self.nq)
        motor = {i: (n, e) for i, _, n, e in self.motors}
        for i, a in enumerate(self.actuator_index):
            if a < 0:
                continue
            if i not in motor:
                Q[a] += min(max(u[i], -effort[i]), effort[i])
                continue
            n, e = motor[i]
            R, kt, ke, imax, vmax = e.values
            cur = (min(max(u[i], -vmax), vmax) - ke * n * v[a]) / R
            ds = -n * kt * ke * n / R
            if abs(cur) > imax:
                cur, ds = float(np.clip(cur, -imax, imax)), 0.0
            tau = n * kt * cur
            if abs(tau) > effort[i]:
                tau, ds = float(np.clip(tau, -effort[i], effort[i])), 0.0
            Q[a] += tau
            slope[a] += ds
        return Q, slope

    def effect_force(self, v, q=None) -> np.ndarray:
        """Generalized force of the joint effects that is not in K and D: the locked
        motors' spring preload and the friction torques (N m or N); with ``q``, the
        backlash correction of the gear springs, the contact surface's J^T F and the
        second-order curvature load of twisting links (module docstring)."""
        Q = self.Q_const.copy()
        for a, f in self.friction:
            Q[a] += float(f.torque(v[a]))
        if q is not None and self.contact is not None:
            Q += self.contact_load(q, v)
        if q is not None and self.stops:
            Q += self.stop_load(q, v)
        if q is not None and self.coupled:
            Q += self.curvature_load(q)
        if q is not None:
            for qi, m, k, b, half, smooth, locked_at, x, xd in self._gaps(q, v):
                dz, sl = dead_zone(x, half, smooth)
                tau = k * (dz - x) + b * (sl - 1.0) * xd
                Q[qi] += tau
                if m >= 0:
                    Q[m] -= tau
        return Q

    def _contact(self, q, v=None):
        """(J (3 x nq), delta, normal force magnitude) of the contact surface at the tip
        (v None: at rest)."""
        p0, n, k, c = self.contact
        F = self.tip_frame(np.asarray(q, float))
        J = np.real(F.Jo)
        delta = float(-n @ (np.real(F.o) - p0))
        if delta <= 0.0:
            return J, delta, 0.0
        vn = 0.0 if v is None else float(n @ (J @ np.asarray(v, float)))
        return J, delta, max(0.0, k * delta - c * vn)

    def contact_force(self, q, v=None) -> np.ndarray:
        """Force (N, base frame, 3) of the contact surface on the tip (zero without one or
        out of contact; v None: at rest)."""
        if self.contact is None:
            return np.zeros(3)
        return self._contact(q, v)[2] * self.contact[1]

    def contact_load(self, q, v=None) -> np.ndarray:
        """J^T F (nq): the generalized force of the contact surface (zeros without one)."""
        if self.contact is None:
            return np.zeros(self.nq)
        J, _, fn = self._contact(q, v)
        return J.T @ (fn * self.contact[1])

    def contact_tangent(self, q, v=None):
        """(K_c, D_c): k g g^T and c g g^T, g = J^T n, while the contact force acts (the
        tangent of -J^T F for the Newton matrix, without the dJ/dq terms); zeros else."""
        Kc, Dc = np.zeros((self.nq, self.nq)), np.zeros((self.nq, self.nq))
        if self.contact is None:
            return Kc, Dc
        J, _, fn = self._contact(q, v)
        if fn > 0.0:
            _, n, k, c = self.contact
            g = J.T @ n
            gg = np.outer(g, g)
            Kc, Dc = k * gg, c * gg
        return Kc, Dc

    def _stop_forces(self, q, v=None):
        """Per end stop that acts: (coordinate, sigma, force f, tangent stiffness, tangent
        damping, potential) with the torque -sigma f (sigma +1 at the upper, -1 at the
        lower limit); v None: at rest (description.JointStops)."""
        for a, lo, hi, k, c, s in self.stops:
            x = float(q[a])
            w = 0.0 if v is None else float(v[a])
            sigma, d = (1.0, x - hi) if x > hi else (-1.0, lo - x)
            if d <= 0.0:
                continue
            dd = sigma * w
            if d < s:
                g, r, dr, e = d * d / (2 * s), d / s, 1.0 / s, k * d ** 3 / (6 * s)
            else:
                g, r, dr, e = d - s / 2, 1.0, 0.0, k * (d * d - s * d + s * s / 3) / 2
            yield a, sigma, k * g + c * r * dd, max(k * r + c * dr * dd, 0.0), c * r, e

    def stop_load(self, q, v=None) -> np.ndarray:
        """Generalized force of the end stops (nq; zeros inside the limits; the law of
        description.JointStops)."""
        Q = np.zeros(self.nq)
        for a, sigma, f, *_ in self._stop_forces(q, v):
            Q[a] -= sigma * f
        return Q

    def stop_tangent(self, q, v=None):
        """(K_s, D_s): the tangent of -stop_load for the Newton matrix on the diagonal,
        max(k r + c r' d', 0) and c r (description.JointStops; kept >= 0 so the matrix
        stays positive definite)."""
        Ks, Ds = np.zeros((self.nq, self.nq)), np.zeros((self.nq, self.nq))
        for a, _, _, kt, ct, _ in self._stop_forces(q, v):
            Ks[a, a] += kt
            Ds[a, a] += ct
        return Ks, Ds

    def _gaps(self, q, v):
        for qi, m, k, b, half, smooth, locked_at in self.backlash:
            x = (q[m] if m >= 0 else locked_at) - q[qi]
            xd = (v[m] if m >= 0 else 0.0) - v[qi]
            yield qi, m, k, b, half, smooth, locked_at, float(x), float(xd)

    def backlash_tangent(self, q, v):
        """(K_b, D_b): the tangent of the backlash corrections for the Newton matrix,
        on the gear's [[1, -1], [-1, 1]] block: max(k_t dz' + b_t dz'' x', 0) - k_t (the
        tangent stiffness, kept >= 0 so the matrix stays positive definite) and
        b_t (dz' - 1)."""
        Kb, Db = np.zeros((self.nq, self.nq)), np.zeros((self.nq, self.nq))
        for qi, m, k, b, half, smooth, _, x, xd in self._gaps(q, v):
            sl = dead_zone(x, half, smooth)[1]
            kt = max(k * sl + b * dead_zone_curvature(x, half, smooth) * xd, 0.0) - k
            idx = [qi] if m < 0 else [qi, m]
            blk = np.array([[1.0]]) if m < 0 else np.array([[1.0, -1.0], [-1.0, 1.0]])
            Kb[np.ix_(idx, idx)] += kt * blk
            Db[np.ix_(idx, idx)] += b * (sl - 1.0) * blk
        return Kb, Db

    @property
    def coupled(self) -> bool:
        """True with a twisting flexible link (BeamData.curvature_coupling)."""
        return any(b is not None and b.coupling is not None for b in self.beams)

    def curvature_load(self, q) -> np.ndarray:
        """-dU/dq of the second-order curvature energy (BeamData.curvature_coupling) of
        every twisting link (nq)."""
        Q = np.zeros(self.nq)
        for i, b in enumerate(self.beams):
            if b is not None and b.coupling is not None:
                s = self.flex_slice(i)
                Q[s] -= b.curvature_coupling(np.asarray(q, float)[s])[1]
        return Q

    def curvature_tangent(self, q) -> np.ndarray:
        """d^2U/dq^2 of that energy (nq x nq, the tangent of -curvature_load)."""
        Kc = np.zeros((self.nq, self.nq))
        for i, b in enumerate(self.beams):
            if b is not None and b.coupling is not None:
                s = self.flex_slice(i)
                Kc[s, s] = b.curvature_coupling(np.asarray(q, float)[s])[2]
        return Kc

    def effect_force_slope(self, v) -> np.ndarray:
        """d effect_force / dv (diagonal): the friction slopes (<= 0, but > 0 on the
        falling side of a Stribeck peak)."""
        d = np.zeros(self.nq)
        for a, f in self.friction:
            d[a] += float(friction_law(float(v[a]), *f.values)[1])
        return d

    @property
    def free_indices(self) -> np.ndarray:
        """Coordinates that move (all but the held joints of locked rigid motors)."""
        return np.setdiff1d(np.arange(self.nq), self.held)

    # ------------------------------------------------------------ indexing
    def flex_slice(self, i: int) -> slice:
        n = self.beams[i].n if self.beams[i] is not None else 0
        return slice(int(self.off[i]) + 1, int(self.off[i]) + 1 + n)

    def plane_indices(self, plane: str) -> np.ndarray:
        """Indices of the joint variables and the 'v', 'w' or 'phi' variables of every link
        (plane 'v' with the joints: the in-plane coordinates of a planar arm)."""
        idx = []
        for i, b in enumerate(self.beams):
            if plane == "joints" or plane == "v":
                idx.append(self.off[i])
            if b is None:
                continue
            s = self.flex_slice(i).start
            rng = {"v": range(0, b.nv), "w": range(b.nv, 2 * b.nv),
                   "phi": range(2 * b.nv, b.n)}.get(plane, range(0))
            idx += [s + k for k in rng]
        return np.array(sorted(idx), dtype=int)

    # ------------------------------------------------------------ kinematics
    def _chain(self, q, with_masses: bool, link_frames: list | None = None):
        """Propagate the frames; return the end frame of every link and, with
        ``with_masses``, the mass groups: points (m, p, Jp) and rotors (I, Jw).
        ``link_frames``: a list that receives (root, tip) per link: the frame after the
        joint motion where the beam starts, and the deflected tip section frame (Eq. 19;
        None for a rigid link)."""
        if not np.iscomplexobj(q):
            q = np.asarray(q, dtype=float)
        nq = self.nq
        F = Frame.base(nq, dtype=q.dtype)
        ends, points, rotors = [], [], []
        for i, (lk, b) in enumerate(zip(self.arm.links, self.beams)):
            k = self.off[i]
            (Rpre, tpre), (Rdh, tdh), (root_body, end_body) = self._consts[i]
            origin, axis, end = self._extra[i]
            if origin is not None:
                F = F.fixed(*origin)
            jr, ratio, spin = self.rotors[i]
            if with_masses and jr:
                e = F.R @ (np.asarray(lk.joint.axis, float) if axis is None else axis)
                Jr = F.Jw.copy()
                if spin >= 0:
                    Jr[:, spin] += ratio * e
                rotors.append(((jr * np.outer(e, e))[None], Jr[None]))
            if axis is not None:
                F = F.prismatic_axis(q[k], k, axis) if lk.joint.type == "prismatic" else \
                    F.revolute_axis(q[k], k, axis)
            else:
                F = F.prismatic(q[k], k) if lk.joint.type == "prismatic" else \
                    F.revolute(q[k], k)
            F = F.fixed(Rpre, tpre)
            if b is not None and b.beam.placement == "aux_z":
                F = F.fixed(Rdh, tdh)
            root = F
            if with_masses and root_body is not None:
                self._add_body(root, root_body, points, rotors)
            tip = None
            if b is not None:
                F = self._beam(F, q, i, b, with_masses, points, rotors)
                tip = F
                F = F.fixed(b.P.T, np.zeros(3))
                if b.beam.placement == "dh_x":
                    F = F.fixed(Rdh, np.zeros(3))
            else:
                F = F.fixed(Rdh, tdh)
            if end is not None:
                F = F.fixed(*end)
            if with_masses and end_body is not None:
                self._add_body(F, end_body, points, rotors)
            ends.append(F)
            if link_frames is not None:
                link_frames.append((root, tip))
        return ends, points, rotors

    @staticmethod
    def _add_body(F, body, points, rotors):
        m, c, I = body
        p, Jp = point_jacobians(F, c[None, :])
        if m:
            points.append((np.array([m]), p, Jp))
        if np.any(I):
            rotors.append(((F.R @ I @ F.R.T)[None], F.Jw[None]))

    def _beam(self, F, q, i, b: BeamData, with_masses, points, rotors) -> Frame:
        """Mass points of link i's beam and the frame at its deflected tip (Eq. 19)."""
        s = self.flex_slice(i)
        fv, fw, ft = b.split(q[s])
        Rb = F.R @ b.P
        Fb = Frame(Rb, F.o, F.Jo, F.Jw)
        cols = np.arange(s.start, s.stop)
        nv = b.nv
        if with_masses:
            n = len(b.z)
            v, w = b.Wv @ fv, b.Ww @ fw
            x = b.z + 0 * v
            if b.Sv is not None:      # second_order: x = z - u, u = 1/2 f^T S(z) f per plane
                Svf, Swf = b.Sv @ fv, b.Sw @ fw
                x = x - 0.5 * (Svf @ fv + Swf @ fw)
            r = np.stack([x, v, w], axis=1)
            if b.rule is not None:     # exact: r(s) = int t ds (exact.py)
                r, Jv, Jw = (a[:-1] for a in b.exact_points(fv, fw))
            p, Jp = point_jacobians(Fb, r)
            if b.rule is not None:
                Jp[:, :, cols[:nv]] += np.einsum("ab,pbj->paj", Rb, Jv)
                Jp[:, :, cols[nv:2 * nv]] += np.einsum("ab,pbj->paj", Rb, Jw)
            else:
                Jp[:, :, cols[:nv]] += Rb[None, :, 1, None] * b.Wv[:, None, :]
                Jp[:, :, cols[nv:2 * nv]] += Rb[None, :, 2, None] * b.Ww[:, None, :]
            if b.Sv is not None:
                Jp[:, :, cols[:nv]] -= Rb[None, :, 0, None] * Svf[:, None, :]
                Jp[:, :, cols[nv:2 * nv]] -= Rb[None, :, 0, None] * Swf[:, None, :]
            points.append((b.mass_w, p, Jp))
            if b.nt or b.rotary is not None:
                phi, dv, dw = b.Pt @ ft, b.dWv @ fv, b.dWw @ fw
                Ry = rot_y(-dw)
                Ryz = Ry @ rot_z(dv)
                ax_w = np.zeros((n, 3)) + np.array([0.0, -1.0, 0.0])   # d omega / d w'
                ax_v = Ry[:, :, 2]                                     # d omega / d v'
                ax_t = Ryz[:, :, 0]            # d omega / d phi: the centre line's tangent
                Rsec = Ryz @ rot_x(phi)
                Jw = np.broadcast_to(F.Jw, (n, 3, self.nq)).copy()
                Jw[:, :, cols[:nv]] += (ax_v @ Rb.T)[:, :, None] * b.dWv[:, None, :]
                Jw[:, :, cols[nv:2 * nv]] += (ax_w @ Rb.T)[:, :, None] * b.dWw[:, None, :]
                Jw[:, :, cols[2 * nv:]] += (ax_t @ Rb.T)[:, :, None] * b.Pt[:, None, :]
                Rs = Rb @ Rsec                             # section axes, base frame
                a = Rs[:, :, 0]
                I = b.polar_w[:, None, None] * a[:, :, None] * a[:, None, :]
                if b.rotary is not None:    # rho I_y y y^T + rho I_z z z^T
                    for k in (1, 2):
                        e = Rs[:, :, k]
                        I = I + b.rotary[:, k - 1, None, None] * e[:, :, None] * e[:, None, :]
                rotors.append((I, Jw))
        # tip frame
        L = b.length
        v, w, dv, dw = fv[nv - 2], fw[nv - 2], fv[nv - 1], fw[nv - 1]
        phi = ft[-2] if b.nt else 0.0 * v
        xl = L + 0 * v
        if b.Sv is not None:
            Svf, Swf = b.SvL @ fv, b.SwL @ fw
            xl = xl - 0.5 * (Svf @ fv + Swf @ fw)
        if b.rule is not None:         # exact: the tip at r(L) (exact.py)
            r, Jv, Jw = (a[-1] for a in b.exact_points(fv, fw))
            rl = Rb @ r
        else:
            rl = Rb @ np.array([xl, v, w])
        Jo = F.Jo - skew(rl) @ F.Jw
        if b.rule is not None:
            Jo[:, cols[:nv]] += Rb @ Jv
            Jo[:, cols[nv:2 * nv]] += Rb @ Jw
        else:
            Jo[:, cols[nv - 2]] += Rb[:, 1]
            Jo[:, cols[2 * nv - 2]] += Rb[:, 2]
        if b.Sv is not None:
            Jo[:, cols[:nv]] -= Rb[:, 0, None] * Svf[None, :]
            Jo[:, cols[nv:2 * nv]] -= Rb[:, 0, None] * Swf[None, :]
        Jw = F.Jw.copy()
        Ry = rot_y(-dw)
        Ryz = Ry @ rot_z(dv)
        Jw[:, cols[nv - 1]] += Rb @ Ry[:, 2]
        Jw[:, cols[2 * nv - 1]] += -Rb[:, 1]
        if b.nt:
            Jw[:, cols[-2]] += Rb @ Ryz[:, 0]
        return Frame(Rb @ Ryz @ rot_x(phi), F.o + rl, Jo, Jw)

    def frames(self, q) -> list[np.ndarray]:
        """4 x 4 pose of every link's end frame i (base frame), seed 000 Eqs. 20-22."""
        q = np.asarray(q)
        return [F.matrix() for F in self._chain(q, False)[0]]

    def tip_frame(self, q) -> Frame:
        q = np.asarray(q)
        return self._chain(q, False)[0][-1]

    def tip_position(self, q) -> np.ndarray:
        return np.real(self.tip_frame(np.asarray(q, float)).o)

    def tip_jacobian(self, q) -> np.ndarray:
        """(6, nq): linear and angular velocity of the end frame per q-dot."""
        F = self.tip_frame(np.asarray(q, float))
        return np.vstack([F.Jo, F.Jw])

    # ------------------------------------------------------------ dynamics
    def mass_matrix(self, q) -> np.ndarray:
        """M(q) = sum m Jp^T Jp + sum Jw^T I Jw (symmetric positive definite)."""
        _, points, rotors = self._chain(np.asarray(q, float), True)
        nq = self.nq
        M = np.zeros((nq, nq))
        for m, _, Jp in points:
            M += (Jp * m[:, None, None]).reshape(-1, nq).T @ Jp.reshape(-1, nq)
        for I, Jw in rotors:
            M += Jw.reshape(-1, nq).T @ (I @ Jw).reshape(-1, nq)
        return 0.5 * (M + M.T) + self.M_const

    def bias(self, q, v) -> np.ndarray:
        """c(q, v): velocity (Coriolis, centrifugal, gyroscopic) and gravity forces."""
        return self.terms(q, v)[1]

    def terms(self, q, v):
        """(M(q), c(q, v)) from one complex-step evaluation of the kinematics."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        _, points, rotors = self._chain(q + 1j * _H * v, True)
        nq = self.nq
        c = np.zeros(nq)
        M = np.zeros((nq, nq))
        g = self.gravity
        for m, _, Jp in points:
            J, Jd = Jp.real, Jp.imag / _H
            acc = (Jd @ v - g) * m[:, None]                  # m (dJ/dt v - g), (n, 3)
            J2 = J.reshape(-1, nq)
            c += acc.reshape(-1) @ J2
            M += (J * m[:, None, None]).reshape(-1, nq).T @ J2
        for I, Jw in rotors:
            J, Jd, Ir = Jw.real, Jw.imag / _H, I.real
            w = J @ v
            Iw = (Ir @ w[:, :, None])[:, :, 0]
            tau = (Ir @ (Jd @ v)[:, :, None])[:, :, 0] + cross(w, Iw)
            J2 = J.reshape(-1, nq)
            c += tau.reshape(-1) @ J2
            M += J2.T @ (Ir @ J).reshape(-1, nq)
        return 0.5 * (M + M.T) + self.M_const, c

    def gravity_force(self, q) -> np.ndarray:
        """dU_g/dq = -sum m Jp^T g."""
        return self.bias(q, np.zeros(self.nq))

    def gravity_stiffness(self, q) -> np.ndarray:
        """d(dU_g/dq)/dq by complex steps (exact to rounding), nq x nq."""
        q = np.asarray(q, float)
        out = np.zeros((self.nq, self.nq))
        for k in range(self.nq if np.any(self.gravity) else 0):
            dq = np.zeros(self.nq, dtype=complex)
            dq[k] = 1j * _H
            _, points, _ = self._chain(q + dq, True)
            col = np.zeros(self.nq)
            for m, _, Jp in points:
                col -= np.einsum("n,nik,i->k", m, Jp.imag / _H, self.gravity)
            out[:, k] = col
        return 0.5 * (out + out.T)

    def stiffness_matrix(self) -> np.ndarray:
        return self.K

    def acceleration(self, q, v, Q=None) -> np.ndarray:
        """q'' with the applied force Q, the joint effects (K, D, friction, preload) and
        the held joints (zero acceleration)."""
        v = np.asarray(v, float)
        M, c = self.terms(q, v)
        rhs = -c - self.K @ np.asarray(q, float) - self.D @ v + self.effect_force(v, q)
        if Q is not None:
            rhs = rhs + Q
        free = self.free_indices
        a = np.zeros(self.nq)
        a[free] = np.linalg.solve(M[np.ix_(free, free)], rhs[free])
        return a

    # ------------------------------------------------------------ energy
    def gravity_potential(self, q) -> float:
        _, points, _ = self._chain(np.asarray(q, float), True)
        return float(-sum(np.sum(m * (p @ self.gravity)) for m, p, _ in points))

    def energy(self, q, v) -> dict:
        """Kinetic, elastic and gravity energy (J); with a contact surface also its
        potential k delta^2 / 2 (delta > 0) as "contact", with end stops theirs as
        "stops"."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        out = {"kinetic": float(0.5 * v @ self.mass_matrix(q) @ v),
               "elastic": float(0.5 * q @ self.K @ q - self.Q_const @ q + sum(
                   k * (dead_zone_energy(x, half, smooth) - 0.5 * x * x)
                   for _, _, k, _, half, smooth, _, x, _ in self._gaps(q, v))),
               "gravity": self.gravity_potential(q)}
        out["elastic"] += sum(b.curvature_coupling(q[self.flex_slice(i)])[0]
                              for i, b in enumerate(self.beams)
                              if b is not None and b.coupling is not None)
        if self.contact is not None:
            delta = self._contact(q)[1]
            out["contact"] = 0.5 * self.contact[2] * max(delta, 0.0) ** 2
        if self.stops:
            out["stops"] = sum(e for *_, e in self._stop_forces(q))
        return out

    def total_energy(self, q, v) -> float:
        return float(sum(self.energy(q, v).values()))

    # ------------------------------------------------------------ deflections
    def tip_deflections(self, q) -> dict:
        """Per flexible link: tip v, w (m), tip slopes v', w' and tip twist phi (rad)
        (exact kinematics: v, w the tip's lateral displacements r_y(L), r_z(L), the slopes
        the section angles; exact.py)."""
        q = np.asarray(q, float)
        out = {}
        for i, (lk, b) in enumerate(zip(self.arm.links, self.beams)):
            if b is None:
                continue
            fv, fw, ft = b.split(q[self.flex_slice(i)])
            v, w = fv[-2], fw[-2]
            if b.rule is not None:
                v, w = b.exact_points(fv, fw)[0][-1, 1:]
            out[lk.name] = {"v": v, "w": w, "dv": fv[-1], "dw": fw[-1],
                            "phi": ft[-2] if b.nt else 0.0}
        return out
