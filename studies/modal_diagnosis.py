"""Single-effect diagnosis of measured natural frequencies (issue 9).

A candidate effect changes one parameter of the nominal arm (a stiffness or mass scale, a
tip mass or inertia, a compliant root, a hub inertia behind a PD joint). Each candidate is
fitted alone to the measured frequencies by bounded least squares on the relative
residuals ``ln(f_model / f_measured) / sigma``; candidates are ranked by chi^2. Candidates
whose predicted frequencies coincide are one *equivalence class*: the measured frequencies
cannot tell them apart (a uniform scale of EI and of the mass per length move every mode by
the same factor, sqrt(EI / m), thesis Eq. 31, so no number of frequencies separates them).
Parsimony: a second effect is kept only if an F-test on the extra chi^2 reduction says so.

The modal model is :func:`flex_model.modes.natural_modes` (clamped root, or the ``pd`` joint
for a root of finite stiffness ``kp``).
"""
from __future__ import annotations

import dataclasses
import sys
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.optimize import least_squares, minimize_scalar
from scipy.stats import f as f_dist

from flex_model.arm import ArmDescription
from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes


@dataclass(frozen=True)
class ModalSetup:
    """An arm and how its joint is held for the modal analysis (``clamped`` or ``pd``)."""

    arm: ArmDescription
    joints: str = "clamped"
    kp: float | None = None
    kd: float | None = None


class _MemoModel(FlexArmModel):
    """FlexArmModel with memoized link bases: the fits rebuild the model many times, and a
    candidate that changes only the payload, an end inertia or the joint keeps the nominal
    links (the bases depend on the section profile, the variables and the Timoshenko
    effect only)."""

    _memo: dict = {}

    def _link_basis(self, lk):
        key = (repr(lk.segments), lk.n_vars, repr(self.arm.effect("timoshenko", lk.name)))
        if key not in self._memo:
            if len(self._memo) > 64:
                self._memo.clear()
            self._memo[key] = super()._link_basis(lk)
        return self._memo[key]


def modal_frequencies(setup: ModalSetup, count: int) -> np.ndarray:
    """The ``count`` lowest vibration frequencies (Hz); rigid-body and overdamped modes
    (zeta >= 0.5, e.g. a hub on a strongly damped PD joint) are skipped, missing ones NaN."""
    res = natural_modes(_MemoModel(setup.arm), joints=setup.joints, kp=setup.kp,
                        kd=setup.kd)
    keep = (res.omega > 1e-6) & (res.damping_ratio < 0.5)
    f = res.frequencies_hz[keep][:count]
    return np.concatenate([f, np.full(count - len(f), np.nan)])


@dataclass(frozen=True)
class Candidate:
    """One effect with one parameter; ``apply(setup, value)`` gives the modified setup.

    ``tolerance``: relative manufacturing tolerance of the parameter about ``nominal``
    (None when the parameter is not a toleranced property, e.g. a root spring).
    ``log_scale``: fit ln(value) (scales, springs) instead of the value (added masses).
    """

    name: str
    parameter: str
    unit: str
    nominal: float
    bounds: tuple
    apply: Callable[[ModalSetup, float], ModalSetup]
    log_scale: bool = True
    tolerance: float | None = None
    note: str = ""


def _scaled_links(arm: ArmDescription, stiffness: float = 1.0, mass: float = 1.0):
    """Every link's EI times ``stiffness`` and mass per length times ``mass``."""
    links = tuple(dataclasses.replace(lk, segments=tuple(s.scaled(stiffness, mass)
                                                         for s in lk.segments))
                  for lk in arm.links)
    return dataclasses.replace(arm, links=links)


def link_totals(arm: ArmDescription) -> tuple[float, float, float]:
    """Total length (m), link mass (kg) and the mean EI (N m^2) of the chain."""
    length = sum(lk.length for lk in arm.links)
    z = np.linspace(0.0, 1.0, 201)
    mass = ei = 0.0
    for lk in arm.links:
        ei_z, m_z = lk.profile.properties(z * lk.length)[:2]
        mass += float(np.trapezoid(m_z, z * lk.length))
        ei += float(np.trapezoid(ei_z, z * lk.length))
    return length, mass, ei / length


def standard_candidates(setup: ModalSetup, *, pd_kp: float | None = None,
                        pd_kd: float | None = None) -> list[Candidate]:
    """The single-effect library for a (clamped) arm: stiffness scale, mass scale, tip
    mass, tip inertia, root compliance and, when ``pd_kp`` is given, a hub inertia behind a
    PD joint of that stiffness (and damping ``pd_kd``)."""
    arm = setup.arm
    length, mass, ei = link_totals(arm)
    tol_pay = arm.tolerance("payload")
    k_ref = ei / length          # the root spring that equals the beam's own stiffness scale
    cands = [
        Candidate("stiffness scale", "EI / EI_nominal", "-", 1.0, (0.2, 5.0),
                  lambda s, v: dataclasses.replace(s, arm=_scaled_links(s.arm, stiffness=v)),
                  tolerance=arm.tolerance("E"),
                  note="Young's modulus or section inertia (tolerance: that of E)"),
        Candidate("mass scale", "m / m_nominal", "-", 1.0, (0.2, 5.0),
                  lambda s, v: dataclasses.replace(s, arm=_scaled_links(s.arm, mass=v)),
                  tolerance=arm.tolerance("rho"),
                  note="density or distributed added mass (tolerance: that of rho)"),
        Candidate("tip mass", "payload mass", "kg", arm.payload_mass,
                  (0.0, arm.payload_mass + 2.0 * mass),
                  lambda s, v: dataclasses.replace(
                      s, arm=dataclasses.replace(s.arm, payload_mass=v)),
                  log_scale=False, tolerance=tol_pay if arm.payload_mass > 0 else None,
                  note="payload or sensor at the tip (tolerance: that of the payload)"),
        Candidate("tip inertia", "payload inertia", "kg m^2", arm.payload_inertia,
                  (0.0, arm.payload_inertia + mass * length ** 2),
                  lambda s, v: dataclasses.replace(
                      s, arm=dataclasses.replace(s.arm, payload_inertia=v)),
                  log_scale=False,
                  tolerance=tol_pay if arm.payload_inertia > 0 else None,
                  note="rotary inertia of the tip body"),
        Candidate("root compliance", "root spring kp", "N m/rad", float("inf"),
                  (1e-3 * k_ref, 1e4 * k_ref),
                  lambda s, v: dataclasses.replace(s, joints="pd", kp=v, kd=0.0),
                  note="a rotational spring at the clamp (pd joint of flex_model.modes)"),
    ]
    if pd_kp is not None:
        j_ref = mass * length ** 2 / 3.0

        def hub(s, v):
            first = dataclasses.replace(s.arm.links[0], J_minus=v)
            arm_h = dataclasses.replace(s.arm, links=(first,) + tuple(s.arm.links[1:]))
            return dataclasses.replace(s, arm=arm_h, joints="pd", kp=pd_kp, kd=pd_kd)

        cands.append(Candidate("hub inertia (PD joint)", "hub inertia J-", "kg m^2", 0.0,
                               (1e-6 * j_ref, 1e3 * j_ref), hub,
                               note=f"hub on a PD joint kp = {pd_kp:.4g} N m/rad, "
                                    f"kd = {pd_kd or 0.0:.4g} N m s/rad"))
    return cands


@dataclass
class EffectFit:
    """Least-squares fit of one or more candidates to measured frequencies."""

    candidates: list
    values: np.ndarray
    intervals: np.ndarray           # (n, 2): one-sigma interval of each value
    predicted_hz: np.ndarray        # all ``count`` modes at the fit
    residual: np.ndarray            # ln(f_model / f_measured) of the measured modes
    chi2: float
    dof: int
    at_bound: bool
    reachable: bool                 # the measured modes are matched within 3 sigma

    @property
    def name(self) -> str:
        return " + ".join(c.name for c in self.candidates)

    @property
    def rms_relative(self) -> float:
        return float(np.sqrt(np.mean(np.expm1(self.residual) ** 2)))

    def relative_change(self) -> np.ndarray:
        """value / nominal - 1 per candidate (NaN where the nominal is 0 or infinite)."""
        nom = np.array([c.nominal for c in self.candidates])
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(np.isfinite(nom) & (nom != 0), self.values / nom - 1.0, np.nan)

    def within_tolerance(self) -> list:
        """Per candidate: True/False against its tolerance, None if it has none."""
        return [None if c.tolerance is None or not np.isfinite(r) else bool(abs(r) <= c.tolerance)
                for c, r in zip(self.candidates, self.relative_change())]

    def as_dict(self) -> dict:
        return {"effects": [c.name for c in self.candidates],
                "parameters": [c.parameter for c in self.candidates],
                "units": [c.unit for c in self.candidates],
                "nominal": [c.nominal if np.isfinite(c.nominal) else None   # None: rigid
                            for c in self.candidates],
                "values": self.values.tolist(), "intervals": self.intervals.tolist(),
                "relative_change": [None if not np.isfinite(r) else float(r)
                                    for r in self.relative_change()],
                "tolerance": [c.tolerance for c in self.candidates],
                "within_tolerance": self.within_tolerance(),
                "predicted_hz": [None if not np.isfinite(f) else float(f)
                                 for f in self.predicted_hz],
                "residual_relative": np.expm1(self.residual).tolist(),
                "chi2": self.chi2, "dof": self.dof, "rms_relative": self.rms_relative,
                "at_bound": self.at_bound, "reachable": self.reachable}


def fit_effects(setup: ModalSetup, candidates, measured_hz, *, modes=None, sigma=0.005,
                count: int | None = None, grid: int = 7, start=None) -> EffectFit:
    """Fit the parameters of ``candidates`` (applied in turn) to ``measured_hz``.

    ``modes``: 1-based mode numbers of the measured frequencies (default 1..n);
    ``sigma``: relative uncertainty of each measured frequency; ``count``: modes predicted
    (default: the highest measured one). One parameter: the best point of a ``grid`` over
    its bounds, refined by Brent's bounded search; several: trust-region least squares
    from ``start`` (default: the nominal values), clipped to the bounds. The one-sigma
    intervals come from the Jacobian, inflated by the lack of fit when chi^2 / dof > 1.
    """
    measured = np.atleast_1d(np.asarray(measured_hz, float))
    modes = np.arange(1, len(measured) + 1) if modes is None else np.asarray(modes, int)
    count = int(max(modes)) if count is None else max(int(count), int(max(modes)))
    sig = np.broadcast_to(np.asarray(sigma, float), measured.shape)
    to_x = [np.log if c.log_scale else (lambda v: v) for c in candidates]
    from_x = [np.exp if c.log_scale else (lambda x: x) for c in candidates]
    lo = np.array([t(c.bounds[0]) for t, c in zip(to_x, candidates)], float)
    hi = np.array([t(c.bounds[1]) for t, c in zip(to_x, candidates)], float)
    cache = {}

    def predict(x):
        key = tuple(float(v) for v in x)
        if key not in cache:
            s = setup
            for c, back, xi in zip(candidates, from_x, x):
                s = c.apply(s, float(back(xi)))
            cache[key] = modal_frequencies(s, count)
        return cache[key]

    def resid(x):
        f = predict(x)[modes - 1]
        r = np.log(f / measured) / sig
        return np.where(np.isfinite(r), r, 1e6)

    steps = 1e-6 * (hi - lo)

    def jac(x):
        cols = []
        for j, h in enumerate(steps):     # central differences, one-sided at a bound
            xp, xm = x.copy(), x.copy()
            xp[j] = min(x[j] + h, hi[j])
            xm[j] = max(x[j] - h, lo[j])
            cols.append((resid(xp) - resid(xm)) / (xp[j] - xm[j]))
        return np.column_stack(cols)

    if len(candidates) == 1:      # grid, then Brent's bounded search in the best bracket
        xs = np.linspace(lo[0], hi[0], grid)
        k = int(np.argmin([np.sum(resid(xs[i:i + 1]) ** 2) for i in range(grid)]))
        best = minimize_scalar(lambda v: float(np.sum(resid(np.array([v])) ** 2)),
                               bounds=(xs[max(k - 1, 0)], xs[min(k + 1, grid - 1)]),
                               method="bounded", options={"xatol": 1e-6 * (hi[0] - lo[0])})
        x = np.array([best.x])
    else:
        nom = start if start is not None else [
            c.nominal if np.isfinite(c.nominal) else c.bounds[1] for c in candidates]
        x0 = np.clip([t(max(v, c.bounds[0])) for t, v, c in zip(to_x, nom, candidates)],
                     lo + 1e-9 * (hi - lo), hi - 1e-9 * (hi - lo))
        x = least_squares(resid, x0, jac=jac, bounds=(lo, hi), x_scale=(hi - lo) / 10,
                          xtol=1e-8, ftol=1e-8, gtol=1e-8).x
    r = resid(x)
    chi2 = float(np.sum(r ** 2))
    dof = len(measured) - len(candidates)
    inflate = max(1.0, chi2 / dof) if dof > 0 else 1.0
    J = jac(x)
    cov = np.linalg.pinv(J.T @ J) * inflate
    sx = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    values = np.array([b(xi) for b, xi in zip(from_x, x)])
    intervals = np.array([[b(max(xi - s, l)), b(min(xi + s, h))]
                          for b, xi, s, l, h in zip(from_x, x, sx, lo, hi)])
    span = hi - lo
    at_bound = bool(np.any((x - lo < 1e-6 * span) | (hi - x < 1e-6 * span)))
    res_log = r * sig
    return EffectFit(candidates=list(candidates), values=values, intervals=intervals,
                     predicted_hz=predict(x), residual=res_log, chi2=chi2, dof=dof,
                     at_bound=at_bound, reachable=bool(np.all(np.abs(r) < 3.0)))


@dataclass
class Diagnosis:
    """Ranked single-effect fits, their equivalence classes and the parsimony check."""

    measured_hz: np.ndarray
    nominal_hz: np.ndarray
    fits: list                       # EffectFit, best (lowest chi^2) first
    classes: list                    # lists of fit indices with the same predicted modes
    indistinguishable: list          # pairs equal in *all* predicted modes (not just these)
    pair: EffectFit | None = None    # best two-effect fit (best class + the best other one)
    pair_p_value: float | None = None
    sigma: float = 0.005             # relative uncertainty of the measured frequencies

    def class_of(self, k: int) -> int:
        return next(i for i, c in enumerate(self.classes) if k in c)

    def as_dict(self) -> dict:
        return {"measured_hz": self.measured_hz.tolist(),
                "nominal_hz": [float(f) for f in self.nominal_hz],
                "fits": [dict(f.as_dict(), equivalence_class=self.class_of(k))
                         for k, f in enumerate(self.fits)],
                "classes": [[self.fits[k].name for k in c] for c in self.classes],
                "indistinguishable_by_any_frequency": [[self.fits[a].name, self.fits[b].name]
                                                       for a, b in self.indistinguishable],
                "two_effect_fit": None if self.pair is None else self.pair.as_dict(),
                "two_effect_p_value": self.pair_p_value, "sigma": self.sigma}


def diagnose(setup: ModalSetup, candidates, measured_hz, *, sigma=0.005, count=None,
             same_tol: float = 1e-4, pair: bool = True) -> Diagnosis:
    """Fit every candidate alone, rank by chi^2, group equal predictions into classes.

    Two fits are in one class when their predicted measured modes agree within
    ``same_tol`` (relative); a pair is *indistinguishable by any frequency* when all
    ``count`` predicted modes agree (default: two more than measured). With ``pair`` and at
    least three measured modes, the best fit plus the best fit of another class are fitted
    together and an F-test says whether the second effect is justified.
    """
    measured = np.atleast_1d(np.asarray(measured_hz, float))
    n = len(measured)
    count = n + 2 if count is None else count
    nominal = modal_frequencies(setup, count)
    fits = [fit_effects(setup, [c], measured, sigma=sigma, count=count) for c in candidates]
    fits.sort(key=lambda f: (not f.reachable, f.chi2))

    def same(a, b, k):
        pa, pb = a.predicted_hz[:k], b.predicted_hz[:k]
        return bool(np.all(np.abs(pa / pb - 1.0) < same_tol))

    classes = []
    for k, f in enumerate(fits):
        for c in classes:
            if same(fits[c[0]], f, n):
                c.append(k)
                break
        else:
            classes.append([k])
    indist = [(a, b) for a in range(len(fits)) for b in range(a + 1, len(fits))
              if same(fits[a], fits[b], count)]
    diag = Diagnosis(measured, nominal, fits, classes, indist, sigma=float(sigma))
    if pair and n >= 3 and len(classes) > 1:
        second = fits[classes[1][0]]
        # start between the two single fits: each effect explains half of the gap
        first = fits[0].candidates[0]
        start = [0.5 * (f.candidates[0].nominal + f.values[0])
                 if np.isfinite(f.candidates[0].nominal) else 2.0 * f.values[0]
                 for f in (fits[0], second)]
        two = fit_effects(setup, [first, second.candidates[0]], measured, sigma=sigma,
                          count=count, start=start)
        diag.pair = two
        if two.dof > 0 and two.chi2 > 0:
            F = (fits[0].chi2 - two.chi2) / (two.chi2 / two.dof)
            diag.pair_p_value = float(f_dist.sf(max(F, 0.0), 1, two.dof))
    return diag


def shift_pattern(setup: ModalSetup, candidate: Candidate, target_hz: float, mode: int = 1,
                  count: int = 3) -> EffectFit:
    """The size of ``candidate`` that alone moves ``mode`` to ``target_hz``, with the
    shifts it then gives to all ``count`` modes (its signature)."""
    return fit_effects(setup, [candidate], [target_hz], modes=[mode], count=count)


def frequency_gap(setup: ModalSetup, candidates, measured_hz: float, *, mode: int = 1,
                  sigma: float = 0.002, count: int = 3) -> list[EffectFit]:
    """For one measured frequency: the size of each candidate that alone explains it
    (an exact solve when reachable: chi^2 = 0, one equation for one unknown), with the
    ``count`` modes it then predicts (the next modes are what would separate them)."""
    return [fit_effects(setup, [c], [measured_hz], modes=[mode], sigma=sigma, count=count)
            for c in candidates]


def reach_hz(setup: ModalSetup, candidate: Candidate, mode: int = 1) -> tuple[float, float]:
    """Frequency of ``mode`` (Hz) with the candidate at its lower and its upper bound."""
    return tuple(float(modal_frequencies(candidate.apply(setup, v), mode)[mode - 1])
                 for v in candidate.bounds)


# ----------------------------------------------------------------- what the reports print
def say_for(args):
    """Progress lines on stderr, ``[<command>] text`` (none with ``--json``)."""
    quiet = getattr(args, "json", False)
    return lambda text: None if quiet else print(f"[{args.command}] {text}", file=sys.stderr)


def fmt_value(v, unit="") -> str:
    """A fitted value with its unit for the reports (``rigid`` for inf, ``-`` for none)."""
    if v is None or not np.isfinite(v):
        return "rigid" if v is not None and v == np.inf else "-"
    return f"{v:.4g}{(' ' + unit) if unit and unit != '-' else ''}"


def change_text(fit) -> str:
    """The fit's relative change from nominal, in %."""
    r = fit.relative_change()[0]
    return "-" if not np.isfinite(r) else f"{100 * r:+.2f} %"


def tolerance_text(fit) -> str:
    """Whether the fit stays within its manufacturing tolerance."""
    c, ok = fit.candidates[0], fit.within_tolerance()[0]
    if ok is None:
        return "no tolerance"
    return f"{'yes' if ok else 'no'} (±{100 * c.tolerance:.0f} %)"
