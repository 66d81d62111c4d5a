"""The extended Kalman filter of the flexible arm, gain-scheduled (docs/estimation.md).

State x = [q; v; p] (p: adapted parameters as random walks). Every ``relinearize_every``
samples the Jacobian A = df/dx is taken by central differences at the current estimate
(the spatial plant: a structured one) and held: the estimate moves by the two-stage
Rosenbrock method ROS2 (Verwer, Spee, Blom, Hundsdorfer 1999) with W = I - gamma T A,

    k1 = W^-1 f(x, u),  k2 = W^-1 (f(x + T k1, u) - 2 k1),  x+ = x + T (3/2 k1 + 1/2 k2),

second order whatever A is (a W-method: a stale Jacobian costs no order) and L-stable, so
the flexible modes far above the sample rate (the spatial links' torsion, kHz) are damped
instead of resolved. The covariance moves by P+ = F P F^T + Q_d with F the same step's
derivative for the held A. Process noise: a torque error per joint and a force at each link's
tip, each held over a sample (zero-order hold, as a digital command's error):
Q_d = Gamma W Gamma^T with Gamma the step's map of the generalized force through B(q)^-1,
plus the parameters' random walk (std^2 T per sample). Correction P - K H P (symmetrized)
with the readings present (NaN = missing); a delayed reading is compared with the estimate
of its time (a short buffer of past estimates), with the present H (delays short against
the arm's motion).
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.stats import chi2

from .measurements import check, outputs
from .plant import PARAMETER_FLOOR

#: ROS2's gamma = 1 + 1/sqrt(2): L-stable, second order for any Jacobian (a W-method)
GAMMA = 1.0 + 1.0 / np.sqrt(2.0)
#: default initial std and random-walk std (per sqrt(s)) of the adapted parameters
ADAPT_STD = {"coulomb_friction": 1.0, "viscous_friction": 2.0, "payload_mass": 0.3,
             "link_stiffness": 0.3}
ADAPT_WALK = {"coulomb_friction": 0.1, "viscous_friction": 0.2, "payload_mass": 0.02,
              "link_stiffness": 0.01}


@dataclass(frozen=True)
class EstimatorSettings:
    """Settings of the filter (SI units). ``torque_noise``: std (N m) of the input torque
    error per joint held over a sample (a scalar for every joint, or one per joint);
    ``modal_noise``: std (N) of a force at each link's tip normal to the link (what excites
    its modes: the model-form error of the link), held likewise, scalar or one per link
    (spatial arms: also one per link and bending plane, shape (n_links, 2): v, w);
    ``twist_noise``: std (N m) of a moment about each spatial link's axis at its tip
    (scalar or one per link; planar arms: must be 0);
    ``adapt``: names of the adapted parameters (flex_model.estimation.plant), with optional
    ``adapt_initial``, ``adapt_std`` (initial std) and ``adapt_walk`` (random-walk std per
    sqrt(s)) by name; ``relinearize_every``: samples between Jacobians (0: only at reset);
    ``adapt_reset_nis`` (0: off): covariance resetting, a change detector: when the NIS mean
    per reading over the last ``adapt_reset_window`` s exceeds it, the parameters'
    covariance goes back to their initial stds (their walk can then be small);
    ``adapt_horizon`` (s, 0: off): instead of their random walks, the joint frictions are
    fitted by least squares on the momentum balance of the last ``adapt_horizon`` s in
    blocks of ``adapt_block`` s (flex_model.estimation.horizon), and the filter considers
    them (Schmidt: their covariance is the fit's, no gain moves them); the payload and the
    stiffness stay random walks; ``adapt_spread`` (default 1, 0: off) scales the std of the
    process noise that carries the fit's moves over the window into the filter (the
    parameters' errors as torque noise: horizon.HorizonFit.spread)."""

    sample_period: float = 1e-3
    adapt: tuple = ()
    torque_noise: float | tuple = 0.1
    modal_noise: float | tuple = 0.0
    twist_noise: float | tuple = 0.0
    relinearize_every: int = 10
    initial_angle_std: float = 0.01
    initial_deflection_std: float = 0.02
    initial_rate_std: float = 0.1
    adapt_initial: dict = field(default_factory=dict)
    adapt_std: dict = field(default_factory=dict)
    adapt_walk: dict = field(default_factory=dict)
    friction_smoothing: float = 0.02
    adapt_reset_nis: float = 0.0
    adapt_reset_window: float = 0.2
    adapt_horizon: float = 0.0
    adapt_block: float = 0.05
    adapt_spread: float = 1.0

    def __post_init__(self):
        if not self.sample_period > 0:
            raise ValueError(f"sample_period: got {self.sample_period}; expected > 0 s")
        if int(self.relinearize_every) < 0:
            raise ValueError(f"relinearize_every: got {self.relinearize_every}; expected "
                             ">= 0 samples")
        if any(np.any(np.asarray(v, float) < 0) for v in
               (self.torque_noise, self.modal_noise, self.twist_noise)):
            raise ValueError("torque_noise, modal_noise and twist_noise must be >= 0")
        if self.adapt_reset_nis < 0 or not self.adapt_reset_window > 0:
            raise ValueError(f"adapt_reset_nis: got {self.adapt_reset_nis}, "
                             f"adapt_reset_window: got {self.adapt_reset_window}; "
                             "expected >= 0 and > 0 s")
        object.__setattr__(self, "adapt", tuple(self.adapt))
        self._check_horizon()

    def _check_horizon(self):
        """The horizon fit's settings, one-line errors naming the field."""
        h, b = self.adapt_horizon, self.adapt_block
        if not (h >= 0 and np.isfinite(h)):
            raise ValueError(f"adapt_horizon: got {h}; expected >= 0 s (0: off)")
        if not (b > 0 and np.isfinite(b) and (h == 0 or b <= h)):
            raise ValueError(f"adapt_block: got {b}; expected > 0 s and at most "
                             f"adapt_horizon ({h} s)")
        if not (self.adapt_spread >= 0 and np.isfinite(self.adapt_spread)):
            raise ValueError(f"adapt_spread: got {self.adapt_spread}; expected >= 0")
        if h and self.adapt_reset_nis:
            raise ValueError(f"adapt_horizon: got {h} with adapt_reset_nis "
                             f"{self.adapt_reset_nis}; expected no covariance resetting "
                             "with the horizon fit (adapt_reset_nis 0)")
        if h and not any(a.split(":")[0] in ("coulomb_friction", "viscous_friction")
                         for a in self.adapt):
            raise ValueError(f"adapt_horizon: got {h} with adapt {list(self.adapt)}; "
                             "expected a coulomb_friction:<joint> or viscous_friction:"
                             "<joint> in adapt (the frictions are what it fits)")


#: the fields of a Sample (and, stacked over time, of an EstimationResult)
FIELDS = ("t", "q", "v", "state_cov", "joint_angles", "joint_angles_std", "joint_rates",
          "joint_rates_std", "tip_deflections", "tip_deflections_std", "tip_position",
          "tip_position_cov", "tip_orientation", "tip_pose_cov", "innovation",
          "innovation_cov", "nis", "nis_dof", "nis_mean", "nis_95_fraction", "parameters",
          "parameter_std")


class Sample:
    """The estimate at one sample (after its correction): the fields of FIELDS, the
    derived ones (angles, deflections, tip, their stds) computed when first read (the live
    path reads what it publishes)."""

    def __init__(self, t, x, P, plant, maps, innovation, innovation_cov, nis, nis_dof,
                 nis_mean, nis_95_fraction):
        self.t, self._x, self.state_cov, self._plant, self._maps = t, x, P, plant, maps
        self.innovation, self.innovation_cov = innovation, innovation_cov
        self.nis, self.nis_dof, self.nis_mean = nis, nis_dof, nis_mean
        self.nis_95_fraction = nis_95_fraction
        nq = plant.nq
        self.q, self.v = x[:nq], x[nq:2 * nq]
        self._Pq, self._Pv = P[:nq, :nq], P[nq:2 * nq, nq:2 * nq]

    def __repr__(self):
        return f"Sample(t={self.t:.6g}, nis={self.nis:.3g}, parameters={self.parameters})"

    @cached_property
    def joint_angles(self):
        return self._plant.joint_angles(self.q)

    @cached_property
    def joint_angles_std(self):
        return _std(self._maps[0], self._Pq)

    @cached_property
    def joint_rates(self):
        return self._plant.joint_rates(self.v)

    @cached_property
    def joint_rates_std(self):
        return _std(self._maps[0], self._Pv)

    @cached_property
    def tip_deflections(self):
        return self._maps[1] @ self.q

    @cached_property
    def tip_deflections_std(self):
        return _std(self._maps[1], self._Pq)

    @cached_property
    def tip_position(self):
        return self._plant.tip_position(self.q)

    @cached_property
    def tip_position_cov(self):
        J = self._plant.tip_jacobian(self.q)
        return J @ self._Pq @ J.T

    @cached_property
    def tip_orientation(self):
        """(x, y, z, w) quaternion of the tip frame (planar: the tip tangent about z)."""
        return np.array(self._plant.tip_orientation(self.q))

    @cached_property
    def tip_pose_cov(self):
        """6 x 6 covariance of (x, y, z, rotation about x, y, z), base frame: the order of
        geometry_msgs/PoseWithCovariance."""
        J = self._plant.tip_pose_jacobian(self.q)
        return J @ self._Pq @ J.T

    @cached_property
    def parameters(self):
        return dict(zip(self._plant.param_names, self._x[2 * self._plant.nq:].tolist()))

    @cached_property
    def parameter_std(self):
        nq = self._plant.nq
        return dict(zip(self._plant.param_names,
                        np.sqrt(np.diag(self.state_cov)[2 * nq:]).tolist()))


def make_plant(model, settings):
    """PlanarPlant or SpatialPlant for a FlexArmModel or SpatialArmModel."""
    from ..spatial.dynamics import SpatialArmModel
    if isinstance(model, SpatialArmModel):
        from .spatial_plant import SpatialPlant
        return SpatialPlant(model, settings.adapt, settings.friction_smoothing)
    from .plant import PlanarPlant
    return PlanarPlant(model, settings.adapt, settings.friction_smoothing)


class Estimator:
    """The live path: ``reset`` then one ``step(u, y)`` per sample."""

    def __init__(self, model, measurements, settings: EstimatorSettings | None = None):
        self.settings = settings or EstimatorSettings()
        self.plant = make_plant(model, self.settings)
        self.measurements = list(measurements)
        check(self.measurements, self.plant)
        self.R = np.array([m.variance for m in self.measurements])
        T = self.settings.sample_period
        self.delays = np.array([int(round(m.delay / T)) for m in self.measurements])
        nq, npar = self.plant.nq, len(self.plant.params)
        self.n = 2 * nq + npar
        self._kinds = [k for k, _ in self.plant.params]
        self._angle = self.plant.angle_map()
        self._defl = self.plant.deflection_map()
        self.reset(np.zeros(nq), np.zeros(nq))
        self._noise_input()     # the noise settings' shapes checked on construction

    # ------------------------------------------------------------------ setup
    def reset(self, q0, v0=None, P0=None, t0: float = 0.0) -> None:
        """Start from (q0, v0) with the parameters' initial values; P0 default: the
        settings' initial stds."""
        s, nq = self.settings, self.plant.nq
        p0 = self.plant.nominal_parameters()
        for k, name in enumerate(self.plant.param_names):
            p0[k] = s.adapt_initial.get(name, p0[k])
        v0 = np.zeros(nq) if v0 is None else np.asarray(v0, float)
        self.x = np.concatenate([np.asarray(q0, float), v0, p0])
        self.P = self._initial_cov() if P0 is None else np.array(P0, float)
        if self.P.shape != (self.n, self.n):
            raise ValueError(f"P0: got shape {self.P.shape}; expected {(self.n, self.n)}")
        self.t = float(t0)
        self.k = 0
        self._since = None
        self._nis_sum, self._nis_in, self._nis_count = 0.0, 0, 0
        self._past = deque(maxlen=int(self.delays.max(initial=0)) + 1)
        self._window = deque(maxlen=max(int(round(s.adapt_reset_window / s.sample_period)), 1))
        self.resets = []   # times of the parameters' covariance resets
        self._fit = None
        if s.adapt_horizon:
            from .horizon import HorizonFit
            fit = HorizonFit(self.plant, s.adapt_horizon, s.adapt_block, s.sample_period,
                             p0, np.sqrt(np.diag(self.P)[2 * nq:]))
            self._fit = fit if fit.index.size else None

    def _initial_cov(self) -> np.ndarray:
        s, nq = self.settings, self.plant.nq
        sd = np.full(nq, s.initial_deflection_std)
        sd[self._angle.any(axis=0) & ~np.isin(np.arange(nq), self.plant.flex_indices())] = \
            s.initial_angle_std
        sp = [s.adapt_std.get(nm, ADAPT_STD[k]) for nm, k in
              zip(self.plant.param_names, self._kinds)]
        return np.diag(np.concatenate([sd, np.full(nq, s.initial_rate_std), sp]) ** 2)

    # ---------------------------------------------------------- linearization
    def _jacobian(self, f, x, n_out, cols=None) -> np.ndarray:
        """Central differences of f at x (n_out x len(cols); default all columns)."""
        cols = range(self.n) if cols is None else cols
        J = np.empty((n_out, len(cols)))
        for c, j in enumerate(cols):
            h = 1e-6 * max(1.0, abs(x[j]))
            xp, xm = x.copy(), x.copy()
            xp[j] += h
            xm[j] -= h
            J[:, c] = (f(xp) - f(xm)) / (2 * h)
        return J

    def _state_jacobian(self, u) -> np.ndarray:
        """df/dx by central differences."""
        return self._jacobian(lambda x: self.plant.derivative(x, u), self.x, self.n)

    def _noise_input(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, W): generalized-force directions of the process noise and their variances."""
        s, plant = self.settings, self.plant
        tn = np.broadcast_to(np.asarray(s.torque_noise, float), (plant.n_joints,))
        L = plant.link_force_map(self.x[:plant.nq])
        mn = _per_link(s.modal_noise, plant.n_links, L.shape[1] // plant.n_links,
                       "modal_noise")                 # spatial: v and w planes per link
        N, W = [plant.actuator_map(), L], [tn ** 2, mn ** 2]
        if np.any(np.asarray(s.twist_noise, float) > 0):
            if not plant.spatial:
                raise ValueError("twist_noise: planar links do not twist; leave it 0")
            N.append(plant.link_moment_map())
            W.append(_per_link(s.twist_noise, plant.n_links, 1, "twist_noise") ** 2)
        return np.hstack(N), np.concatenate(W)

    def relinearize(self, u) -> None:
        """A, F, S, Q_d and H at the current estimate (the gain schedule's update)."""
        s, plant, n, nq = self.settings, self.plant, self.n, self.plant.nq
        T = s.sample_period
        N, W = self._noise_input()
        B = np.zeros((n, N.shape[1]))
        B[nq:2 * nq] = plant.inverse_mass(self.x[:nq], self.x[2 * nq:]) @ N
        A = self._state_jacobian(u)
        self._Winv = np.linalg.inv(np.eye(n) - GAMMA * T * A)
        self.F = np.eye(n) + self._ros2_increment(A, A)
        Gam = self._ros2_increment(A, B)
        Qd = (Gam * W) @ Gam.T
        fitted = set() if self._fit is None else set(self._fit.index)
        walk = [0.0 if k in fitted else s.adapt_walk.get(nm, ADAPT_WALK[kind])
                for k, (nm, kind) in enumerate(zip(plant.param_names, self._kinds))]
        Qd[2 * nq:, 2 * nq:] += np.diag(np.square(walk) * T)
        if self._fit is not None and s.adapt_spread:   # the fit's moves as torque noise
            Gp = self._ros2_increment(A, A[:, 2 * nq + self._fit.index])
            Qd += (Gp * (s.adapt_spread ** 2 * self._fit.spread())) @ Gp.T
        self.Qd = 0.5 * (Qd + Qd.T)
        H = self._jacobian(lambda x: outputs(self.measurements, plant, x, u),
                           self.x, len(self.measurements))
        self.H = H
        self._since = 0

    # ------------------------------------------------------------------ step
    def step(self, u, y) -> Sample:
        """Correct with the readings y at the current time (NaN: missing), report, then
        predict to the next sample under the input u (held over the sample)."""
        u = np.asarray(u, float)
        every = int(self.settings.relinearize_every)
        if self._since is None or (every and self._since >= every):
            self.relinearize(u)
        nu, Sk, used, nis = self._correct(u, np.asarray(y, float))
        if self._fit is not None:
            self._refit(u)
        sample = self._report(nu, Sk, used, nis)
        self._watch(nis, used.size)
        self._predict(u)
        return sample

    def _correct(self, u, y):
        """(innovation, its covariance, indices of the readings used, NIS)."""
        m = len(self.measurements)
        used = np.flatnonzero(np.isfinite(y))
        if used.size == 0:
            self._remember()
            return np.full(m, np.nan), np.full((m, m), np.nan), used, np.nan
        h = outputs(self.measurements, self.plant, self.x, u)
        for r in used:
            d = self.delays[r]
            if d:
                past = self._past[-d] if len(self._past) >= d else self._past[0] \
                    if self._past else self.x
                h[r] = outputs([self.measurements[r]], self.plant, past, u)[0]
        H = self.H[used]
        v = y[used] - h[used]
        HP = H @ self.P
        S = HP @ H.T + np.diag(self.R[used])
        sol = np.linalg.solve(S, np.column_stack([HP, v]))
        K = sol[:, :-1].T
        if self._fit is None:
            self.x = self.x + K @ v
            self.P = self.P - K @ HP   # = (I - K H) P, symmetrized after the prediction
        else:                          # Schmidt: the parameters considered, not corrected
            K[2 * self.plant.nq + self._fit.index] = 0.0
            IKH = np.eye(self.n) - K @ H
            self.x = self.x + K @ v
            self.P = IKH @ self.P @ IKH.T + (K * self.R[used]) @ K.T    # Joseph
        self._project()
        if used.size == m:
            nu, Sk = v, S
        else:
            nu, Sk = np.full(m, np.nan), np.full((m, m), np.nan)
            nu[used] = v
            Sk[np.ix_(used, used)] = S
        self._remember()
        return nu, Sk, used, float(v @ sol[:, -1])

    def _watch(self, nis, dof) -> None:
        """Covariance resetting: the parameters' block of P back to the initial stds (cross
        terms zero) when the NIS mean per reading over the window passes adapt_reset_nis."""
        s, off = self.settings, 2 * self.plant.nq
        if not (s.adapt_reset_nis and self.plant.params and dof):
            return
        self._window.append(nis / dof)
        if len(self._window) == self._window.maxlen and \
                np.mean(self._window) > s.adapt_reset_nis:
            self.P[off:, :] = 0.0
            self.P[:, off:] = 0.0
            self.P[off:, off:] = self._initial_cov()[off:, off:]
            self._window.clear()
            self.resets.append(self.t)

    def _refit(self, u) -> None:
        """The horizon fit's new parameters and covariance at a block's end (cross terms
        with the state zero)."""
        fit = self._fit.add(self.x, u)
        if fit is not None:
            at = 2 * self.plant.nq + self._fit.index
            self.x[at] = fit[0]
            self.P[at, :] = 0.0
            self.P[:, at] = 0.0
            self.P[np.ix_(at, at)] = fit[1]

    def _remember(self) -> None:
        """The corrected estimate into the buffer of past ones (delayed readings)."""
        if self._past.maxlen > 1:
            self._past.append(self.x.copy())

    def _project(self) -> None:
        """Adapted parameters onto their physical range (friction, mass >= 0)."""
        off = 2 * self.plant.nq
        for k, kind in enumerate(self._kinds):
            self.x[off + k] = max(self.x[off + k], PARAMETER_FLOOR[kind])

    def _ros2_increment(self, A, G) -> np.ndarray:
        """The ROS2 step's increment for the linear right-hand side G (columns): with
        f = A x + G w, dx = T (3/2 k1 + 1/2 k2); F = I + increment(A), Gamma = increment(B)."""
        T = self.settings.sample_period
        k1 = self._Winv @ G
        k2 = self._Winv @ (G + T * (A @ k1) - 2.0 * k1)
        return T * (1.5 * k1 + 0.5 * k2)

    def _predict(self, u) -> None:
        """ROS2 (Verwer et al. 1999): k1 = W^-1 f(x), k2 = W^-1 (f(x + T k1) - 2 k1),
        x+ = x + T (3/2 k1 + 1/2 k2), W = I - gamma T A with the held Jacobian."""
        T, f = self.settings.sample_period, self.plant.derivative
        if hasattr(self.plant, "step"):  # the plant's own implicit step (spatial)
            self.x = self.plant.step(self.x, u, T)
        else:
            k1 = self._Winv @ f(self.x, u)
            k2 = self._Winv @ (f(self.x + T * k1, u) - 2.0 * k1)
            self.x = self.x + T * (1.5 * k1 + 0.5 * k2)
        self.P = self.F @ self.P @ self.F.T + self.Qd
        self.P = 0.5 * (self.P + self.P.T)
        self.t += self.settings.sample_period
        self.k += 1
        self._since += 1

    # ------------------------------------------------------------------ output
    def _report(self, nu, Sk, used, nis) -> Sample:
        dof = int(used.size)
        if dof:
            self._nis_sum += nis
            self._nis_count += 1
            self._nis_in += nis <= chi2_95(dof)
        count = max(self._nis_count, 1)
        return Sample(self.t, self.x.copy(), self.P.copy(), self.plant,
                      (self._angle, self._defl), nu, Sk, nis, dof,
                      self._nis_sum / count if self._nis_count else np.nan,
                      self._nis_in / count if self._nis_count else np.nan)


def _per_link(value, n_links, per, name) -> np.ndarray:
    """A noise std given as a scalar, one per link or (n_links, per): flat, link-major."""
    v = np.asarray(value, float)
    v = v[:, None] if v.ndim == 1 else v
    try:
        return np.broadcast_to(v, (n_links, per)).ravel()
    except ValueError:
        raise ValueError(f"{name}: got shape {np.shape(value)}; expected a scalar, "
                         f"{n_links} values or ({n_links}, {per})") from None


def _std(M, P) -> np.ndarray:
    return np.sqrt(np.maximum(((M @ P) * M).sum(axis=1), 0.0))


_CHI2 = {}


def chi2_95(dof: int) -> float:
    """The chi2 95 % bound of a NIS with dof degrees of freedom (cached)."""
    if dof not in _CHI2:
        _CHI2[dof] = float(chi2.ppf(0.95, dof))
    return _CHI2[dof]
