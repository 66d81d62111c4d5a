"""FlexArmModel: the planar flexible-link arm of thesis Ch. II in manipulator-equation form.

    B(q) a + c(q, v) + K q + D v = H_c tau + H_d u_d                    (thesis Eq. 27)

with ``q = [alpha_1, q_f1, ..., alpha_nu, q_fnu]`` (absolute link angles and wavelet
deformation variables, Eq. 12), ``c`` the exact Coriolis, centrifugal and gravity terms of
the Lagrangian (``d/dt(B v) - 1/2 d/dq(v^T B v) - B a + dU_g/dq``), ``K`` the block
diagonal stiffness of Eqs. (24)-(25) and ``D`` the internal friction of Eqs. (35)-(36).
The joint angle an encoder sees is ``theta_i = alpha_i - alpha_{i-1} - gamma_{i-1,n}``
(root tangent of link i against the tip tangent of link i-1), so ``H_c = G^T`` with
``theta = G q``. The model holds parameters only, never state.
"""
from __future__ import annotations

import copy
import warnings
from collections import OrderedDict

import numpy as np

from . import kernels
from .arm import PAIRED, ArmDescription
from .basis import link_basis
from .effects.contact import CT_C, CT_K, CT_NX, CT_NY, CT_ON, CT_X, CT_Y
from .inputs import (JD_BACKLASH, JD_COG_A, JD_COG_N, JD_COG_PHASE, JD_K, JD_RATIO,
                     JD_SMOOTHING, JD_SS, JOINT_DATA)


#: memo of the Euler-Bernoulli wavelet bases, (repr of the link's segments, intervals) ->
#: LinkBasis: a replay, a fit or a diagnosis builds the model of the same links many times
#: (only effects, payload or the other link change); the basis depends on nothing else
#: and no model changes it (its arrays are copied into the model's).
_BASIS_MEMO: OrderedDict = OrderedDict()
_BASIS_MEMO_SIZE = 64
#: variables per link from which the fixed step of second-order kinematics solves its
#: iteration matrix as banded plus low rank (flex_model.iteration_matrix); below, the
#: dense factor is as cheap (section E, 16 per link: 70 us per step either way)
STRUCTURED_MIN_VARS = 24


def _memo_basis(lk, n_intervals):
    """``link_basis(lk.profile, n_intervals)``, memoized on the segments' values."""
    key = (repr(tuple(lk.segments)), int(n_intervals))
    b = _BASIS_MEMO.get(key)
    if b is None:
        b = link_basis(lk.profile, n_intervals)
        _BASIS_MEMO[key] = b
        if len(_BASIS_MEMO) > _BASIS_MEMO_SIZE:
            _BASIS_MEMO.popitem(last=False)
    else:
        _BASIS_MEMO.move_to_end(key)
    return b


class FlexArmModel:
    """Equations of motion, kinematics and energy of an arm description.

    With ``kinematics: exact`` the equations come from flex_model.exact_kinematics (its
    own compiled kernels, run by flex_model.simulate): ``P``, the data of kernels.py, then
    raises ExactKinematicsUnsupported with one line naming what to use instead.
    """

    _exact = None  # flex_model.exact_kinematics.ExactKinematics with kinematics: exact

    @property
    def P(self):
        """The compiled kernels' model data (kernels.py); refused with exact kinematics."""
        if self._exact is not None:
            from .exact_kinematics import REFUSAL, ExactKinematicsUnsupported
            raise ExactKinematicsUnsupported(f"{self.arm.source}: {REFUSAL}")
        return self._P

    @P.setter
    def P(self, value):
        self._P = value

    def __init__(self, arm: ArmDescription):
        self.arm = arm
        self.bases = [self._link_basis(lk) for lk in arm.links]
        self.nf = np.array([b.n_vars for b in self.bases], dtype=np.int64)
        self.off = np.concatenate([[0], np.cumsum(self.nf + 1)[:-1]]).astype(np.int64)
        self.n_links = len(self.bases)
        self.nq_arm = int(np.sum(self.nf + 1))
        # tip rotation per tip deflection of one-variable links (1: its own variable)
        self.tip_rotation_scale = np.array([getattr(b, "tip_rotation_scale", 1.0)
                                            for b in self.bases])
        if arm.kinematics in ("second_order", "exact") and np.any(self.nf == 1):
            raise ValueError(f"{arm.source}: kinematics: {arm.kinematics} needs links "
                             "with at least two variables (a lumped link has one)")
        # elastic joints add a motor coordinate each, after the arm's coordinates
        self.elastic_joints = [i for i, j in enumerate(arm.joint_names)
                               if (e := arm.effect("joint_elasticity", j)) and not e.is_off]
        # axial strain variables (kinematics: exact) after the motors: na per link
        self.axial_vars = int(arm.check_axial().axial_vars)
        first = self.nq_arm + len(self.elastic_joints)
        self.axial_off = first + self.axial_vars * np.arange(self.n_links, dtype=np.int64)
        self.nq = first + self.axial_vars * self.n_links
        nq = self.nq
        self.K = np.zeros((nq, nq))
        self.D = np.zeros((nq, nq))
        self._Bw = np.zeros((nq, nq))
        self._h = np.zeros(nq)
        self._k = np.zeros(nq)
        for i, (lk, b) in enumerate(zip(arm.links, self.bases)):
            s = self.flex_slice(i)
            self.K[s, s] = b.K
            self.D[s, s] = lk.internal_friction * b.S1
            self._Bw[s, s] = b.Bw
            self._h[s] = b.h
            self._k[s] = b.k
        if self.axial_vars:
            from .exact_kinematics import axial_stiffness
            for i, lk in enumerate(arm.links):
                a = slice(int(self.axial_off[i]), int(self.axial_off[i]) + self.axial_vars)
                self.K[a, a] = axial_stiffness(lk, self.bases[i].profile, self.axial_vars)
        self.G = np.zeros((self.n_links, nq))
        for i in range(self.n_links):
            self.G[i, self.off[i]] = 1.0
            if i > 0:
                self.G[i, self.off[i - 1]] = -1.0
                self.G[i, self.tip_rotation_index(i - 1)] = -self.tip_rotation_scale[i - 1]
        # the actuator's coordinate: the joint angle, or the motor angle of an elastic joint
        self.Ga = self.G.copy()
        for m, i in enumerate(self.elastic_joints):
            self.Ga[i] = 0.0
            self.Ga[i, self.nq_arm + m] = 1.0
        self.gravity = np.array(arm.gravity, dtype=float)
        self.B_const = np.zeros((nq, nq))
        self.torque_limit = np.full(self.n_links, np.inf)
        self.contact = np.zeros(7)
        self._apply_effects()
        if arm.kinematics == "exact":
            from .exact_kinematics import ExactKinematics
            self._exact = ExactKinematics(self)
        self.set_payload(arm.payload_mass, arm.payload_inertia)

    def _link_basis(self, lk):
        """The wavelet basis of a link: Euler-Bernoulli, or Timoshenko with its effect;
        another discretization (flex_model.discretizations) if the link asks for one."""
        from .effects import slenderness
        tim = self.arm.effect("timoshenko", lk.name)
        if lk.discretization != "wavelet":
            if tim is not None and not tim.is_off:
                raise ValueError(f"{self.arm.source}: effects: timoshenko on {lk.name}: "
                                 "only with discretization: wavelet")
            from .link_discretization import discretized_basis
            last = lk is self.arm.links[-1]
            return discretized_basis(lk, self.arm.payload_mass if last else 0.0,
                                     self.arm.payload_inertia if last else 0.0)
        if tim is None or tim.is_off:
            beta = slenderness(lk)
            if beta < 100:
                warnings.warn(f"{self.arm.source}: {lk.name}: beta = G A L^2 / (chi E I) = "
                              f"{beta:.3g} < 100: shear flexibility matters; add a "
                              "'timoshenko' effect (thesis Remark 6)", stacklevel=3)
            return _memo_basis(lk, lk.n_vars // 2)
        ga = tim["shear_stiffness"]
        seg = lk.segments[0]
        if np.isnan(ga) and not seg.G > 0:
            raise ValueError(f"{self.arm.source}: effects: timoshenko on {lk.name}: no "
                             "shear_stiffness and no material G to compute it from")
        rho_over_e = seg.rho / seg.E if seg.E > 0 else 0.0
        return link_basis(lk.profile, lk.n_vars // 2, shear=True,
                          shear_stiffness=None if np.isnan(ga) else ga,
                          rho_over_e=rho_over_e)

    #: columns of joint_data (inputs.JOINT_DATA, by name inputs.JD_K ...)
    JOINT_DATA = JOINT_DATA

    def _apply_effects(self) -> None:
        """Fold the arm's effects (flex_model.effects) into the model's constant data."""
        joints = self.arm.joint_names
        links = [lk.name for lk in self.arm.links]
        col = {name: k for k, name in enumerate(self.JOINT_DATA)}
        jd = np.zeros((self.n_links, len(self.JOINT_DATA)))
        jd[:, col["k"]] = np.inf
        jd[:, col["ws"]] = 1.0
        jd[:, col["eps"]] = 1.0
        jd[:, col["ratio"]] = 1.0
        jd[:, col["R"]] = 1.0
        jd[:, col["cog_N"]] = 1.0
        jd[:, col["imax"]] = jd[:, col["vmax"]] = np.inf
        jd[:, col["ss_ws"]] = jd[:, col["ss_k"]] = 1.0
        for e in self.arm.effects:
            i = joints.index(e.target) if e.TARGET == "joint" else None
            if e.TYPE == "gear":
                jd[i, col["ratio"]] = e["ratio"]
                self.B_const += e.inertia_matrix(self, i)
            elif e.TYPE == "joint_elasticity" and not e.is_off:
                jd[i, col["k"]], jd[i, col["b"]] = e["stiffness"], e["damping"]
                m = self.nq_arm + self.elastic_joints.index(i)
                self.B_const[m, m] += e["motor_inertia"]
            elif e.TYPE == "backlash":
                jd[i, col["backlash"]], jd[i, col["smoothing"]] = e.values
            elif e.TYPE == "joint_friction":
                jd[i, col["fv"]:col["eps"] + 1] = e.values
            elif e.TYPE == "dc_motor":
                jd[i, col["motor"]] = 1.0
                jd[i, col["R"]:col["vmax"] + 1] = e.values
            elif e.TYPE == "cogging":
                jd[i, col["cog_A"]:col["cog_phase"] + 1] = e.values
            elif e.TYPE == "stick_slip_friction" and not e.is_off:
                jd[i, col["ss_on"]:col["ss_frac"] + 1] = e.kernel_data()
            elif e.TYPE == "structural_damping":
                i = links.index(e.target)
                s = self.flex_slice(i)
                lk = self.arm.links[i]
                m_ff = self._Bw[s, s].copy()
                d, g = self.tip_deflection_index(i) - s.start, self.tip_rotation_index(i) - s.start
                m_ff[d, d] += lk.M_plus
                m_ff[g, g] += lk.J_plus * self.tip_rotation_scale[i] ** 2
                self.D[s, s] += e.damping_block(self.bases[i], m_ff)
            elif e.TYPE == "base_tilt":
                self.gravity = e.gravity(self.gravity)
            elif e.TYPE == "torque_saturation":
                self.torque_limit[i] = e["limit"]
            elif e.TYPE == "contact_surface":
                if e.normal and e.normal[2] != 0.0:
                    from .config import ConfigError
                    raise ConfigError(self.arm.source, "effects.contact_surface.normal",
                                      list(e.normal), "a normal in the arm's x-y plane "
                                      "(nz = 0) for a planar arm")
                self.contact = e.kernel_data()
        for i, b in enumerate(self.bases):  # rotary inertia of Timoshenko links (Remark 3)
            if b.rot_inertia:
                idx = np.concatenate([[self.alpha_index(i)],
                                      np.arange(self.nq)[self.flex_slice(i)]])
                blk = np.block([[np.array([[b.rot_inertia]]), b.rot_coupling[None, :]],
                                [b.rot_coupling[:, None], b.rot_matrix]])
                self.B_const[np.ix_(idx, idx)] += blk
        self.joint_data = jd
        # one bristle state z per stick-slip joint, in joint order, after q and v
        self.stick_slip_joints = [i for i in range(self.n_links) if jd[i, col["ss_on"]] > 0]

    # ----------------------------------------------------------------- indexing
    def alpha_index(self, i: int) -> int:
        return int(self.off[i])

    def flex_slice(self, i: int) -> slice:
        return slice(int(self.off[i]) + 1, int(self.off[i] + self.nf[i]) + 1)

    def tip_deflection_index(self, i: int) -> int:
        return int(self.off[i] + max(int(self.nf[i]) - 1, 1))

    def tip_rotation_index(self, i: int) -> int:
        """Index of the tip rotation; of a one-variable link, its variable (the tip
        deflection), the rotation being ``tip_rotation_scale[i]`` times it."""
        return int(self.off[i] + self.nf[i])

    def tip_rotation_matrix(self) -> np.ndarray:
        """R (n_links x nq): the tip rotations of the links relative to their root
        tangents are R q."""
        r = np.zeros((self.n_links, self.nq))
        for i in range(self.n_links):
            r[i, self.tip_rotation_index(i)] = self.tip_rotation_scale[i]
        return r

    def coordinate_names(self) -> list[str]:
        """Names of the entries of q: link<i>/alpha, link<i>/delta<k>, link<i>/gamma<k>,
        then <joint>/motor and link<i>/axial<k> (the strain's Legendre coefficients)."""
        names = []
        for lk, n in zip(self.arm.links, self.nf):
            names.append(f"{lk.name}/alpha")
            if n == 1:
                names.append(f"{lk.name}/delta")
                continue
            if n % 2 or lk.discretization not in PAIRED:
                names += [f"{lk.name}/eta{k + 1}" for k in range(n - 2)]
                names += [f"{lk.name}/delta", f"{lk.name}/gamma"]
                continue
            for k in range(n // 2):
                names += [f"{lk.name}/delta{k + 1}", f"{lk.name}/gamma{k + 1}"]
        names += [f"{self.arm.joint_names[i]}/motor" for i in self.elastic_joints]
        names += [f"{lk.name}/axial{k}" for lk in self.arm.links
                  for k in range(self.axial_vars)]
        return names

    @property
    def alpha_indices(self) -> np.ndarray:
        return self.off.copy()

    # ----------------------------------------------------------------- parameters
    def set_payload(self, mass: float, inertia: float) -> None:
        """Set the tip payload (kg, kg m^2): it adds to M+ and J+ of the last link."""
        if not (np.isfinite(mass) and np.isfinite(inertia)) or mass < 0 or inertia < 0:
            raise ValueError(f"payload: got mass={mass!r}, inertia={inertia!r}; "
                             "expected finite numbers >= 0 (kg, kg m^2)")
        self.payload = (float(mass), float(inertia))
        nl = self.n_links
        L = np.array([lk.length for lk in self.arm.links])
        m_plus = np.array([lk.M_plus for lk in self.arm.links])
        j_plus = np.array([lk.J_plus for lk in self.arm.links])
        m_plus[-1] += mass
        j_plus[-1] += inertia
        mtot = np.zeros(nl)
        ntot = np.zeros(nl)
        jrot = np.zeros(nl)
        Bp = self._Bw.copy()
        ht = self._h.copy()
        kt = self._k.copy()
        for i, (lk, b) in enumerate(zip(self.arm.links, self.bases)):
            mtot[i] = lk.M_minus + b.mass + m_plus[i]
            ntot[i] = b.first_moment + m_plus[i] * L[i]
            jrot[i] = lk.J_minus + b.second_moment + m_plus[i] * L[i] ** 2 + j_plus[i]
            d, g = self.tip_deflection_index(i), self.tip_rotation_index(i)
            Bp[d, d] += m_plus[i]
            ht[d] += m_plus[i]
            kt[d] += m_plus[i] * L[i]
            kt[g] += j_plus[i] * self.tip_rotation_scale[i]
        self.lengths = L
        mode = 1 if self.arm.kinematics == "second_order" else 0
        zq, mu, Wq, Sq, na, lo, wn, dS, Wl = (self._quadrature(m_plus) if mode
                                              else self._no_quadrature)
        jrig = np.array([lk.J_minus for lk in self.arm.links]) + j_plus
        jplus_tip = j_plus * self.tip_rotation_scale ** 2  # J+ on the tip rotation variable
        self.P = (mode, self.off, self.nf, L, mtot, ntot, jrot, jplus_tip, Bp, ht, kt,
                  zq, mu, Wq, Sq, jrig, self.B_const, na, lo, wn, dS, Wl,
                  *self._band_structure(Bp, mode))
        if self._exact is not None:  # a copy's payload must not change the original's
            self._exact = copy.copy(self._exact)
            self._exact.model = self
            self._exact.set_ends(m_plus, j_plus)

    _no_quadrature = (np.zeros((1, 1)), np.zeros((1, 1)), np.zeros((1, 1, 1)),
                      np.zeros((1, 1, 1, 1)), np.zeros((1, 1), dtype=np.int64),
                      np.zeros((1, 1), dtype=np.int64), np.zeros((1, 1), dtype=np.int64),
                      np.zeros((1, 1, 1, 1)), np.zeros((1, 1, 1)))

    def _quadrature(self, m_plus):
        """Run-time quadrature of the second-order kinematics (kernels.py, mode 1).

        Per link: the root point (M-), Gauss points of the distributed mass, padding,
        and the tip point (M+, with S(L)) last; ``na[i, k]``: the variables past it have
        W = 0 and S = 0 at that point (the wavelets' local support: the kernels skip
        them). Cached: only the end masses change.
        """
        if getattr(self, "_quad_cache", None) is None:
            per_link = []
            for b in self.bases:
                z, mw = b.runtime_quadrature()
                W = b.shape_matrix(z)
                S = b.shortening_matrix(np.concatenate([z, [b.length]]))
                per_link.append((z, mw, W, S))
            npt = max(len(p[0]) for p in per_link) + 2
            nfm = int(self.nf.max())
            nl = self.n_links
            zq = np.zeros((nl, npt))
            mu = np.zeros((nl, npt))
            Wq = np.zeros((nl, npt, nfm))
            Sq = np.zeros((nl, npt, nfm, nfm))
            for i, (z, mw, W, S) in enumerate(per_link):
                n, k = self.nf[i], len(z)
                zq[i, 1:1 + k] = z
                mu[i, 1:1 + k] = mw
                Wq[i, 1:1 + k, :n] = W
                Sq[i, 1:1 + k, :n, :n] = S[:-1]
                zq[i, -1] = self.bases[i].length
                Wq[i, -1, n - 2] = 1.0
                Sq[i, -1, :n, :n] = S[-1]
            nz = (Wq != 0.0) | np.any(Sq != 0.0, axis=3)          # (nl, npt, nfm)
            na = np.where(nz.any(axis=2), nfm - np.argmax(nz[:, :, ::-1], axis=2), 0)
            self._quad_cache = (zq, mu, Wq, Sq, na.astype(np.int64),
                                *self._increments(Wq, Sq))
        zq, mu, Wq, Sq, na, lo, wn, dS, Wl = self._quad_cache
        mu = mu.copy()
        for i, lk in enumerate(self.arm.links):
            mu[i, 0] = lk.M_minus
            mu[i, -1] = m_plus[i]
        return zq, mu, Wq, Sq, na, lo, wn, dS, Wl

    def _band_structure(self, Bp, mode, force=False):
        """(flags, V, lam) of the structured iteration matrix (flex_model.iteration_matrix):
        flags = [half bandwidth bw of the deformation inertia Bp, 1 if used]; the parts of
        B_const, D and K outside the band as eigenvectors V (nq x r) with eigenvalues lam
        (3 x r, one row per matrix). Used with second-order kinematics from
        STRUCTURED_MIN_VARS variables per link (below, the dense factor is as cheap; with
        ``force`` from any number), when the band is narrow and the rest of low rank;
        the D and K the integrators get (E) are those of the model (else the matrix is
        an approximation, which still converges or falls back to full Newton)."""
        nq = self.nq
        if mode != 1 or (int(self.nf.max()) < STRUCTURED_MIN_VARS and not force):
            return np.zeros(2, dtype=np.int64), np.zeros((nq, 0)), np.zeros((3, 0))
        cached = getattr(self, "_band_cache", None)
        if cached is not None and not force:
            return cached
        nzr, nzc = np.nonzero(Bp)
        bw = int(np.max(np.abs(nzr - nzc))) if len(nzr) else 0
        cols, lams = [], []
        far = np.abs(np.subtract.outer(np.arange(nq), np.arange(nq))) > bw
        for kind, M in enumerate((self.B_const, self.D, self.K)):
            R = np.where(far, M, 0.0)
            if not np.any(R):
                continue
            w, vec = np.linalg.eigh(0.5 * (R + R.T))
            keep = np.abs(w) > 1e-13 * max(np.max(np.abs(M)), 1e-300)
            for lam_k, v_k in zip(w[keep], vec[:, keep].T):
                lam = np.zeros(3)
                lam[kind] = lam_k
                cols.append(v_k)
                lams.append(lam)
        V = np.array(cols).T if cols else np.zeros((nq, 0))
        lam = np.array(lams).T if lams else np.zeros((3, 0))
        use = bw <= 8 and V.shape[1] <= 12
        out = (np.array([bw, int(use)], dtype=np.int64), np.ascontiguousarray(V),
               np.ascontiguousarray(lam))
        if not force:
            self._band_cache = out
        return out

    def _increments(self, Wq, Sq):
        """Local increments of the shortening matrix from point to point along a link,
        dS_k = S(z_k) - S(z_{k-1}) = int w' w'^T over [z_{k-1}, z_k] (padding points: 0),
        and the shape values, on the window of variables [lo, lo + wn) where they do not
        vanish (the wavelets' local support: at most 6 wide), so that the kernels
        accumulate S(z) q_f interval by interval at a cost linear in the variables."""
        nl, npt, nfm = Wq.shape
        lo = np.zeros((nl, npt), dtype=np.int64)
        wn = np.zeros((nl, npt), dtype=np.int64)
        incs = []
        for i in range(nl):
            prev = np.zeros((nfm, nfm))
            scale = max(float(np.max(np.abs(Sq[i]))), 1e-300)
            row = []
            for k in range(npt):
                real = k == 0 or k == npt - 1 or np.any(Sq[i, k] != 0.0) or \
                    np.any(Wq[i, k] != 0.0)
                d = Sq[i, k] - prev if real else np.zeros((nfm, nfm))
                d[np.abs(d) <= 1e-13 * scale] = 0.0  # rounding of the shared elements
                nzv = np.any(d != 0.0, axis=0) | (Wq[i, k] != 0.0)
                if nzv.any():
                    idx = np.flatnonzero(nzv)
                    lo[i, k], wn[i, k] = idx[0], idx[-1] - idx[0] + 1
                row.append(d)
                if real:
                    prev = Sq[i, k]
            incs.append(row)
        nw = max(int(wn.max()), 1)
        dS = np.zeros((nl, npt, nw, nw))
        Wl = np.zeros((nl, npt, nw))
        for i in range(nl):
            for k in range(npt):
                a, w = lo[i, k], wn[i, k]
                dS[i, k, :w, :w] = incs[i][k][a:a + w, a:a + w]
                Wl[i, k, :w] = Wq[i, k, a:a + w]
        return lo, wn, dS, Wl

    def with_gravity(self, gravity) -> "FlexArmModel":
        """A view of this model with another gravity vector (m/s^2); arrays are shared."""
        other = copy.copy(self)
        other.gravity = np.asarray(gravity, dtype=float).copy()
        return other

    @property
    def total_mass(self) -> float:
        return float(np.sum(self._P[kernels.P_MTOT]))

    # ----------------------------------------------------------------- dynamics
    def mass_matrix(self, q) -> np.ndarray:
        """B(q) (thesis Eqs. 18-23), symmetric positive definite."""
        if self._exact is not None:
            return self._exact.mass_matrix(q)
        return kernels.mass_matrix(np.asarray(q, dtype=float), self.P)

    def bias(self, q, v) -> np.ndarray:
        """c(q, v): Coriolis, centrifugal and gravity generalized forces (Eqs. 27, 26)."""
        q = np.asarray(q, dtype=float)
        if self._exact is not None:
            return self._exact.mass_and_bias(q, v, self.gravity[0], self.gravity[1])[1]
        return kernels.inverse_dynamics(q, np.asarray(v, dtype=float), np.zeros(self.nq),
                                        self.gravity[0], self.gravity[1], self.P)

    def gravity_force(self, q) -> np.ndarray:
        """dU_g/dq (thesis Eqs. 16, 26)."""
        return self.bias(q, np.zeros(self.nq))

    def inverse_dynamics(self, q, v, a) -> np.ndarray:
        """B(q) a + c(q, v) (without elastic, damping and applied forces)."""
        if self._exact is not None:
            return self._exact.inverse_dynamics(q, v, a, self.gravity[0], self.gravity[1])
        return kernels.inverse_dynamics(np.asarray(q, float), np.asarray(v, float),
                                        np.asarray(a, float), self.gravity[0],
                                        self.gravity[1], self.P)

    def stiffness_matrix(self) -> np.ndarray:
        """K = diag(0, K_1, 0, K_2, ...) (thesis Eqs. 24-25)."""
        return self.K

    def damping_matrix(self) -> np.ndarray:
        """D: internal friction k_a int w' w'^T dz per link (thesis Eqs. 35-36).

        Eq. (35)'s damping term -k_a d''_t is taken in weak (Galerkin) form, which gives the
        positive semi-definite matrix k_a int w'_i w'_j dz.
        """
        return self.D

    def input_matrix(self) -> np.ndarray:
        """H_c = Ga^T: actuator torques to generalized forces (thesis Eq. 29); Ga = G
        unless a joint is elastic, whose actuator drives its motor coordinate."""
        return self.Ga.T

    def tip_jacobian(self, q) -> np.ndarray:
        """d p_tip / d q (2 x nq): generalized force of a tip force F is J^T F (Eq. 30)."""
        if self._exact is not None:
            return self._exact.tip_jacobian(q)
        return kernels.tip_jacobian(np.asarray(q, float), self.P)

    def tip_torque_vector(self) -> np.ndarray:
        """Generalized force of a unit torque at the arm's end (acts on alpha_nu + gamma_nu)."""
        e = np.zeros(self.nq)
        e[self.alpha_index(self.n_links - 1)] = 1.0
        return e + self.tip_rotation_matrix()[-1]

    def joint_forces(self, q, v=None) -> np.ndarray:
        """Generalized forces of the joint effects: springs (with backlash), friction and
        cogging (flex_model.effects); not stick-slip friction, whose torque depends on its
        bristle state as well (:meth:`stick_slip_torques`)."""
        from .integrators import joint_passive_forces
        from .inputs import input_data
        q = np.asarray(q, float)
        v = np.zeros(self.nq) if v is None else np.asarray(v, float)
        if not hasattr(self, "_E0"):
            self._E0 = input_data(self, None, (), np.zeros(self.n_links))
        return joint_passive_forces(q, v, self._E0)

    @property
    def n_bristles(self) -> int:
        """Number of bristle states z (one per stick_slip_friction joint): the integrated
        state is x = [q; v; z]."""
        return len(self.stick_slip_joints)

    def stick_slip_torques(self, v, z) -> np.ndarray:
        """Torques (N m, n_links) of the stick-slip friction on the actuator coordinates
        at velocities v and bristle deflections z (zero at joints without the effect)."""
        from .effects.stick_slip import friction_magnitude
        tau = np.zeros(self.n_links)
        for k, i in enumerate(self.stick_slip_joints):
            tau[i] = -friction_magnitude(float(z[k]), float(self.Ga[i] @ v),
                                         self.joint_data[i, JD_SS:])
        return tau

    def bristle_energy(self, z) -> float:
        """Energy stored in the bristles of the stick-slip joints, sum sigma_0 z^2 / 2 (J)."""
        from .effects.stick_slip import SS_K
        return float(sum(0.5 * self.joint_data[i, JD_SS + SS_K] * float(z[k]) ** 2
                         for k, i in enumerate(self.stick_slip_joints)))

    def contact_force(self, q, v=None) -> np.ndarray:
        """Force (N, base frame) of the contact surface on the tip (zero without one)."""
        ct = self.contact
        if ct[CT_ON] <= 0:
            return np.zeros(2)
        q = np.asarray(q, float)
        tip = self.link_origins(q)[-1]
        n = ct[CT_NX:CT_NY + 1]
        pen = -n @ (tip - ct[CT_X:CT_Y + 1])
        vn = 0.0 if v is None else n @ (self.tip_jacobian(q) @ np.asarray(v, float))
        return max(0.0, ct[CT_K] * pen - ct[CT_C] * vn) * n if pen > 0 else np.zeros(2)

    def acceleration(self, q, v, Q) -> np.ndarray:
        """a = B^-1 (Q - c - K q - D v) for a generalized applied force Q."""
        q = np.asarray(q, float)
        v = np.asarray(v, float)
        rhs = np.asarray(Q, float) - self.bias(q, v) - self.K @ q - self.D @ v
        return np.linalg.solve(self.mass_matrix(q), rhs)

    # ----------------------------------------------------------------- kinematics
    def joint_angles(self, q) -> np.ndarray:
        """Encoder angles theta (rad): relative angle at each joint."""
        return self.G @ np.asarray(q, float)

    def joint_coordinate_matrix(self) -> np.ndarray:
        """T with q = T z, where z is q with every alpha_i replaced by the joint angle theta_i."""
        S = np.eye(self.nq)
        S[self.off] = self.G
        return np.linalg.inv(S)

    def q_from_joint_angles(self, theta, flex=None) -> np.ndarray:
        """q for joint angles theta (rad) and optional deformation variables; the motor
        coordinates of elastic joints equal their joint angles (unloaded springs)."""
        z = np.zeros(self.nq)
        if flex is not None:
            z[self.flex_indices] = flex
        z[self.off] = theta
        for m, i in enumerate(self.elastic_joints):
            z[self.nq_arm + m] = np.asarray(theta, float)[i]
        return self.joint_coordinate_matrix() @ z

    def v_from_joint_rates(self, rates) -> np.ndarray:
        """v for joint rates (rad/s) of the undeformed arm (motors turning with the joints)."""
        z = np.zeros(self.nq)
        z[self.off] = rates
        for m, i in enumerate(self.elastic_joints):
            z[self.nq_arm + m] = np.asarray(rates, float)[i]
        return self.joint_coordinate_matrix() @ z

    @property
    def flex_indices(self) -> np.ndarray:
        """Indices of the deformation variables in q."""
        return np.setdiff1d(np.arange(self.nq_arm), self.off)

    def actuator_angles(self, q) -> np.ndarray:
        """Angles the actuators see (rad, link side): joint angles, or motor angles / n of
        elastic joints (the motor encoders)."""
        return self.Ga @ np.asarray(q, float)

    def link_origins(self, q) -> np.ndarray:
        """Origins of the links and the arm's tip, (n_links + 1, 2), base frame (m)."""
        if self._exact is not None:
            return self._exact.link_origins(q)
        return kernels.link_origins(np.asarray(q, float), self.P)

    def tip_deflections(self, q) -> np.ndarray:
        """Tip deflection delta_n of every link (m), normal to the root tangent (with
        exact kinematics the tip's exact offset, not the variable delta_n)."""
        q = np.asarray(q, float)
        if self._exact is not None:
            return self._exact.tip_deflections(q)
        return np.array([q[self.tip_deflection_index(i)] for i in range(self.n_links)])

    def tip_rotations(self, q) -> np.ndarray:
        """Tip rotation gamma_n of every link (rad) relative to its root tangent."""
        return self.tip_rotation_matrix() @ np.asarray(q, float)

    def tip_pose(self, q) -> tuple[float, float, float]:
        """(x, y, phi) of the arm's end: position (m) and tangent angle (rad)."""
        q = np.asarray(q, float)
        x, y = self.link_origins(q)[-1]
        last = self.n_links - 1
        return float(x), float(y), float(q[self.alpha_index(last)]
                                         + self.tip_rotation_matrix()[last] @ q)

    def tip_specific_force(self, q, v, a) -> np.ndarray:
        """What an accelerometer at the arm's end measures: a_tip - g in the tip frame
        (x along the tip tangent), a_tip = J a + (dJ/dq v) v (m/s^2)."""
        q, v = np.asarray(q, float), np.asarray(v, float)
        h = 1e-6 / max(1.0, float(np.max(np.abs(v))))
        jdot_v = (self.tip_jacobian(q + h * v) - self.tip_jacobian(q - h * v)) @ v / (2 * h)
        acc = self.tip_jacobian(q) @ np.asarray(a, float) + jdot_v - self.gravity
        c, s = np.cos(self.tip_pose(q)[2]), np.sin(self.tip_pose(q)[2])
        return np.array([c * acc[0] + s * acc[1], -s * acc[0] + c * acc[1]])

    def shape(self, q, points_per_link: int = 21) -> list[np.ndarray]:
        """Deflected centre line of every link: list of (points, 2) arrays, base frame."""
        q = np.asarray(q, float)
        if self._exact is not None:
            return self._exact.shape(q, points_per_link)
        org = self.link_origins(q)
        out = []
        for i, (z, W) in enumerate(self._shape_sampling(points_per_link)):
            d = W @ q[self.flex_slice(i)]
            a = q[self.alpha_index(i)]
            c, s = np.cos(a), np.sin(a)
            out.append(np.column_stack([org[i, 0] + z * c - d * s, org[i, 1] + z * s + d * c]))
        return out

    def _shape_sampling(self, points_per_link: int) -> list:
        """(z, W) of every link at equally spaced points, computed once per count (the
        bases are fixed; sampling them costs about 1 ms, the model node draws at 50 Hz+)."""
        cache = self.__dict__.setdefault("_shape_cache", {})
        if points_per_link not in cache:
            zs = [np.linspace(0.0, b.length, points_per_link) for b in self.bases]
            cache[points_per_link] = [(z, b.shape_matrix(z)) for z, b in zip(zs, self.bases)]
        return cache[points_per_link]

    # ----------------------------------------------------------------- energy
    def joint_potential(self, q) -> float:
        """Energy stored in the joint springs (with backlash) and the cogging field (J)."""
        from .integrators import dead_zone_energy
        q = np.asarray(q, float)
        jd = self.joint_data
        u = 0.0
        for i in range(self.n_links):
            k, b, s = jd[i, JD_K], jd[i, JD_BACKLASH], jd[i, JD_SMOOTHING]
            if np.isfinite(k):
                x = (self.Ga[i] - self.G[i]) @ q
                u += k * (dead_zone_energy(x, b, s) if b > 0 else 0.5 * x * x)
            amp, n_per, phase = jd[i, JD_COG_A], jd[i, JD_COG_N], jd[i, JD_COG_PHASE]
            if amp:
                wn = n_per * jd[i, JD_RATIO]
                u += amp / wn * np.cos(wn * (self.Ga[i] @ q) + phase)
        return float(u)

    def energy(self, q, v) -> dict:
        """Kinetic, elastic and gravitational energy (J) of the arm (Eqs. 7, 13, 15)."""
        q = np.asarray(q, float)
        v = np.asarray(v, float)
        return {"kinetic": 0.5 * v @ self.mass_matrix(q) @ v,
                "elastic": 0.5 * q @ self.K @ q + self.joint_potential(q),
                "gravity": (self._exact.gravity_potential(q, *self.gravity)
                            if self._exact is not None else
                            kernels.gravity_potential(q, self.gravity[0], self.gravity[1],
                                                      self.P))}
