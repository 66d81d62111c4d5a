"""Bounded least-squares fits of the diagnosis: the tolerance-bounded baseline, and a
candidate effect jointly with the (linearized) baseline.

All residual evaluations go through an executor's ``map`` (finite-difference Jacobian
columns in parallel). The joint fit of a candidate uses variable projection: for each
trial of the effect's parameters x the correction d of the baseline scales and of the
effects accepted before is the bounded linear least-squares solution of r(x) + J d (J
their Jacobian, :class:`Linearization`), so the nonlinear search runs over the 1-3
effect parameters only (scipy.optimize.least_squares, 'trf',
one start per declared start point; the candidates' fits of smooth hypotheses update
their Jacobian by Broyden's secant between a difference Jacobian at each start and one at
the solution). A search whose evaluation budget ends mid-descent (its last step still
lowering the cost by more than :data:`LINE_GAIN`) goes on along that step
(:func:`line_search`) and restarts there.
Discrete parameters (actuator delay, whole control periods) are searched on integers.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares, lsq_linear
from scipy.stats import t as student_t

from .baseline import bounds as scale_bounds
from .evaluation import DIVERGED_COST, cost, evaluate

FD_STEP = 1e-2   # relative finite-difference step of the baseline scales (tolerance units)


@dataclass
class FitResult:
    """A fitted twin: scales, [(hyp, x)], weighted residuals, cost, Jacobian of the free
    parameters (for confidence intervals), evaluations used."""

    scales: np.ndarray
    effects: list
    r: np.ndarray
    J: float
    jac: np.ndarray | None = None
    x: np.ndarray | None = None
    evaluations: int = 0


def _map(executor, ctx, specs):
    return list(executor.map(evaluate, [(ctx, s, e) for s, e in specs]))


def baseline_jacobian(executor, ctx, scales, effects, r0):
    lo, hi = scale_bounds(ctx.baseline_params)
    steps = FD_STEP * (hi - lo) / 2
    specs = []
    for k in range(len(scales)):
        s = scales.copy()
        s[k] += steps[k]
        specs.append((s, effects))
    cols = _map(executor, ctx, specs)
    Jb = np.zeros((len(r0), len(scales)))
    for k, rk in enumerate(cols):
        if rk is not None:
            Jb[:, k] = (rk - r0) / steps[k]
    return Jb


def fit_baseline(executor, ctx, effects=(), iterations: int = 3,
                 start=None, r0=None) -> tuple[FitResult, np.ndarray]:
    """Gauss-Newton in the tolerance box (bounded linear step, re-linearized) from the
    nominal scales or ``start``; returns the fit and the baseline Jacobian at its
    solution. ``r0``: the residual vector at the start point when it is known (a replay
    saved)."""
    lo, hi = scale_bounds(ctx.baseline_params)
    s = np.ones(len(lo)) if start is None else np.clip(np.asarray(start, float), lo, hi)
    r = evaluate((ctx, s, list(effects))) if r0 is None else r0
    if r is None:
        raise ValueError("the nominal twin diverges on this recording")
    n_eval = 1
    Jb = None
    for _ in range(iterations):
        Jb = baseline_jacobian(executor, ctx, s, list(effects), r)
        n_eval += len(s)
        # the bounded linear step on the thin QR factors of Jb: ||r + Jb d|| =
        # ||Q^T r + R d|| + const, a problem of the size of the scales, not of the samples
        Q, R = np.linalg.qr(Jb)
        step = lsq_linear(R, -(Q.T @ r), bounds=(lo - s, hi - s)).x
        s_new = np.clip(s + step, lo, hi)
        r_new = evaluate((ctx, s_new, list(effects)))
        n_eval += 1
        if r_new is None or cost(r_new) >= cost(r) * (1 - 1e-4):
            break
        s, r = s_new, r_new
    return FitResult(s, list(effects), r, cost(r), evaluations=n_eval), Jb


@dataclass
class Linearization:
    """The linearized free parameters of a fitted twin, the columns of the variable
    projection: the baseline scales in their tolerance box, then the continuous parameters
    of the effects accepted so far within their bounds. A new candidate is so fitted
    jointly with the baseline and every effect before it (an effect fitted while a second
    one was missing has absorbed part of it). ``lo``/``hi`` bound the step d."""

    J: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    n_scales: int
    slots: tuple = ()        # (effect index, parameter index) of the columns after the scales

    def apply(self, scales, effects, d):
        """The scales and effects after the step d."""
        effects = [(h, np.array(x, float)) for h, x in effects]
        for (i, k), dk in zip(self.slots, d[self.n_scales:]):
            effects[i][1][k] = float(np.clip(effects[i][1][k] + dk, effects[i][0].lower[k],
                                             effects[i][0].upper[k]))
        return scales + d[:self.n_scales], effects


def linearize(executor, ctx, scales, effects, Jb) -> Linearization:
    """:class:`Linearization` at (scales, effects): the baseline Jacobian ``Jb`` and one
    finite-difference column per continuous parameter of the effects (from a fresh replay
    at that point, the residual of a fit being a linearized one)."""
    lo, hi = scale_bounds(ctx.baseline_params)
    slots, pts, steps = [], [], []
    for i, (h, x) in enumerate(effects):
        if h.discrete:
            continue
        for k in range(len(x)):
            step = 2e-2 * max(abs(x[k]), 0.5)
            if x[k] + step > h.upper[k]:
                step = -step
            p = np.array(x, float)
            p[k] += step
            slots.append((i, k))
            steps.append(step)
            pts.append(list(effects[:i]) + [(h, p)] + list(effects[i + 1:]))
    cols, elo, ehi = [], [], []
    if slots:
        outs = _map(executor, ctx, [(scales, e) for e in [list(effects)] + pts])
        r0 = outs[0]
        for (i, k), step, rk in zip(slots, steps, outs[1:]):
            ok = r0 is not None and rk is not None
            cols.append((rk - r0) / step if ok else np.zeros(Jb.shape[0]))
            h, x = effects[i]
            elo.append(h.lower[k] - x[k])
            ehi.append(h.upper[k] - x[k])
    J = np.column_stack([Jb] + cols) if cols else Jb
    return Linearization(J, np.concatenate([lo - scales, elo]) - 1e-12,
                         np.concatenate([hi - scales, ehi]) + 1e-12, len(scales),
                         tuple(slots))


class BaselineProjection:
    """r -> r + J d, d the bounded linear least-squares correction of the linearized free
    parameters (:class:`Linearization`). With the thin QR factors of J,
    ||r + J d|| = ||Q^T r + R d|| + const: each projection is a small bounded problem
    (n_free x n_free) instead of one on every sample."""

    def __init__(self, lin: Linearization):
        self.J = lin.J
        self.Q, self.R = np.linalg.qr(lin.J)
        self.bounds = (lin.lo, lin.hi)

    def __call__(self, r):
        d = lsq_linear(self.R, -(self.Q.T @ r), bounds=self.bounds).x
        return r + self.J @ d, d


def fit_candidate(executor, ctx, hyp, base: FitResult, lin, start=None,
                  max_nfev: int = 8, ftol: float = 1e-3, broyden: bool = False) -> FitResult:
    """Fit ``hyp`` jointly with the linearized baseline and accepted effects ``lin`` (a
    :class:`Linearization` at ``base``; variable projection), multi-start (the
    screening's linearized solution ``start`` first).

    The Jacobian is by forward differences (one replay per parameter); with ``broyden``
    only at each start and at the solution (the intervals' and identifiability's
    curvature), between them Broyden's rank-one secant update from the accepted steps
    (J+ = J + (df - J dx) dx^T / dx^T dx), which costs no replay."""
    s0 = base.scales
    project = BaselineProjection(lin)

    def fitted(d, x):
        s, effects = lin.apply(s0, base.effects, d)
        return s, effects + [(hyp, x)]
    n_eval = 0
    best = None

    def residual_of(x):
        nonlocal n_eval
        n_eval += 1
        r = evaluate((ctx, s0, base.effects + [(hyp, x)]))
        if r is None:
            return None
        return project(r)

    if hyp.discrete:
        tried = {}

        def try_int(k):
            if k not in tried and hyp.lower[0] <= k <= hyp.upper[0]:
                res = residual_of(np.array([float(k)]))
                tried[k] = (cost(res[0]) if res else DIVERGED_COST, res)
            return tried.get(k, (np.inf, None))[0]
        for k in (1, 2, 3, 5, 8, 12, 18, 25):
            try_int(k)
        k_best = min(tried, key=lambda k: tried[k][0])
        for k in range(k_best - 3, k_best + 4):
            try_int(k)
        k_best = min(tried, key=lambda k: tried[k][0])
        res = tried[k_best][1]
        x = np.array([float(k_best)])
        if res is None:
            return FitResult(s0, base.effects + [(hyp, x)], base.r, DIVERGED_COST,
                             evaluations=n_eval)
        r, d = res
        return FitResult(*fitted(d, x), r, cost(r), None, x, n_eval)

    xl, xu = np.array(hyp.lower, float), np.array(hyp.upper, float)
    cache = {}

    def fun(x):
        key = tuple(np.round(x, 12))
        if key not in cache:
            res = residual_of(x)
            cache[key] = (res[0], res[1]) if res else (None, None)
        r = cache[key][0]
        return np.full(len(base.r), 1e3) if r is None else r

    secant = {}   # the last Jacobian of this start and where: x, f, J, by differences

    def jac(x):
        f0 = fun(x)
        if broyden and secant:
            dx = x - secant["x"]
            if np.any(dx):
                J = secant["J"] + np.outer(f0 - secant["f"] - secant["J"] @ dx, dx / (dx @ dx))
                secant.update(x=np.array(x, float), f=f0, J=J, exact=False)
                return J
        J = fd_jac(x, f0)
        secant.update(x=np.array(x, float), f=f0, J=J, exact=True)
        return J

    def fd_jac(x, f0):
        # steps wide enough to see through regularized corners (tanh friction, dead zones)
        h = 2e-2 * np.maximum(np.abs(x), 0.5)
        h = np.where(x + h > xu, -h, h)
        pts = [x + h[k] * np.eye(len(x))[k] for k in range(len(x))]
        outs = _map(executor, ctx, [(s0, base.effects + [(hyp, p)]) for p in pts])
        nonlocal n_eval
        n_eval += len(pts)
        cols = []
        for p, rk in zip(pts, outs):
            if rk is None:
                cols.append(np.zeros(len(f0)))
                continue
            cols.append((project(rk)[0] - f0) / (p - x).sum())
        return np.column_stack(cols)

    # one start where the problem is convex enough (one declared start point), all of
    # them after the linearized one where it is not
    starts = list(hyp.starts)
    if start is not None and hyp.fit_from_probe:
        starts = [start] + (starts if len(starts) > 1 else [])
    exact = True
    for k, x_start in enumerate(starts):
        x0 = np.clip(np.array(x_start, float), xl + 1e-9, xu - 1e-9)
        budget = max_nfev if k == 0 else max(3, max_nfev // 2)
        secant.clear()
        trail = []   # (x, cost) of the trials, in order

        def traced(x):
            f = fun(x)
            trail.append((np.array(x, float), cost(f)))
            return f
        try:  # the further starts are a check for another basin: half the budget
            sol = least_squares(traced, x0, jac=jac, bounds=(xl, xu), method="trf",
                                max_nfev=budget, x_scale=1.0, ftol=ftol, xtol=1e-4)
            far = _descent_line(trail, ftol) if sol.status == 0 else None
            if far is not None:   # the budget ended mid-descent: along the last step
                x_line = line_search(lambda x: cost(fun(x)), *far, xl, xu)
                if cost(fun(x_line)) < cost(fun(sol.x)):
                    secant.clear()
                    sol = least_squares(fun, np.clip(x_line, xl + 1e-9, xu - 1e-9),
                                        jac=jac, bounds=(xl, xu), method="trf",
                                        max_nfev=max(3, budget // 2), x_scale=1.0,
                                        ftol=ftol, xtol=1e-4)
        except (ValueError, np.linalg.LinAlgError):
            continue
        r = fun(sol.x)
        if cache[tuple(np.round(sol.x, 12))][0] is None:
            continue   # the search ended where the twin diverges: no fit from this start
        if best is None or cost(r) < best[1]:
            best = (sol.x.copy(), cost(r), sol.jac.copy())
            exact = not broyden or (secant.get("exact", False)
                                    and np.array_equal(secant["x"], sol.x))
    if best is None:
        return FitResult(s0, base.effects, base.r, DIVERGED_COST, evaluations=n_eval)
    x, J, jacobian = best
    if not exact:   # the curvature at the solution by differences, not the secant's
        jacobian = fd_jac(x, fun(x))
    r, d = cache[tuple(np.round(x, 12))]
    return FitResult(*fitted(d, x), r, J, jacobian, x, n_eval)


#: a fit whose evaluation budget ends while its last accepted step still lowered the cost
#: by more than this fraction of it is continued by :func:`line_search`
LINE_GAIN = 0.02
#: :func:`line_search`: at most this many doublings of the step, then golden-section
#: reductions of the bracket
LINE_EXPANSIONS = 6
LINE_REDUCTIONS = 4


def _descent_line(trail, ftol):
    """(x_prev, x_last) of the last two accepted points of a trust-region search (the
    best-so-far sequence of its ``trail`` of (x, cost)) when its last step lowered the
    cost by more than :data:`LINE_GAIN` (and ``ftol``) of it, else None: Gauss-Newton
    steps that grow one after the other on a cost far from quadratic (a tip mass whose
    modal frequency sets the phase of 2 s of lightly damped oscillation: the cost falls
    from 1046 to 0.2 over 0 -> 0.3 kg in a valley +-8 % wide, the search made 8 steps of
    1.1-1.3 x the last one, Exudyn case A-cont-payload-m1-s1)."""
    best = []
    for x, c in trail:
        if np.isfinite(c) and (not best or c < best[-1][1]):
            best.append((x, c))
    if len(best) < 2:
        return None
    (x0, c0), (x1, c1) = best[-2], best[-1]
    if c0 - c1 <= max(LINE_GAIN, ftol) * c0 or not np.any(x1 != x0):
        return None
    return x0, x1


def line_search(f, x_prev, x_last, lo, hi):
    """The minimum of the scalar cost ``f`` along the line x_last + t (x_last - x_prev),
    t >= 0, within the box [lo, hi]: the step doubled while the cost falls (at most
    :data:`LINE_EXPANSIONS` times, to the box's edge), then golden-section reductions of
    the bracket (:data:`LINE_REDUCTIONS`). Returns the best x found (x_last if none is
    better)."""
    d = np.asarray(x_last, float) - np.asarray(x_prev, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        room = np.where(d > 0, (hi - x_last) / d, np.where(d < 0, (lo - x_last) / d, np.inf))
    t_max = float(np.min(room))
    if not t_max > 0:
        return np.asarray(x_last, float)

    def at(t):
        return np.clip(x_last + t * d, lo, hi)
    pts = [(0.0, f(at(0.0)))]
    t = 1.0
    for _ in range(LINE_EXPANSIONS):
        t = min(t, t_max)
        pts.append((t, f(at(t))))
        if pts[-1][1] >= pts[-2][1] or t >= t_max:
            break
        t *= 2.0
    i = min(range(len(pts)), key=lambda k: pts[k][1])
    if 0 < i < len(pts) - 1:   # bracketed: golden-section reductions
        a, b = pts[i - 1][0], pts[i + 1][0]
        g = (np.sqrt(5.0) - 1.0) / 2.0
        best = pts[i]
        for _ in range(LINE_REDUCTIONS):
            # the probe in the larger part of the bracket around the best point
            tb = best[0]
            tn = tb + (1.0 - g) * (b - tb) if b - tb > tb - a else tb - (1.0 - g) * (tb - a)
            fn = f(at(tn))
            if fn < best[1]:
                a, b = (tb, b) if tn > tb else (a, tb)
                best = (tn, fn)
            else:
                a, b = (a, tn) if tn > tb else (tn, b)
        return at(best[0])
    return at(pts[i][0])


def confidence_intervals(fit: FitResult, n_channels: int, block: int, n_eff: float,
                         level: float = 0.95):
    """Half-widths of two ``level`` intervals of the effect's x, and the condition number
    of the normalized information matrix.

    - resolution (noise only): Gauss-Newton covariance (A^T A)^-1 J n / n_eff, the sample
      count corrected to ``n_eff`` independent samples: is the effect resolved by the data
      at all (the identifiability check);
    - reported (noise and what the twin still misses): block sandwich covariance,
      cluster-robust in time. The residuals after a fit are coloured by the remaining model
      error, so the scores A_k r_k are summed over blocks of ``block`` samples (all
      channels of the same instants together), cov = (A^T A)^-1 (sum_b g_b g_b^T)
      (A^T A)^-1 G / (G - 1) with Student's t of G - 1 degrees of freedom (G blocks). With
      white residuals of unit variance it is (A^T A)^-1: wide where blocks of the run
      disagree on the value.
    Returns (reported, resolution, cond); (None, None, 1.0) without a Jacobian."""
    if fit.jac is None:
        return None, None, 1.0
    A = fit.jac
    info = A.T @ A
    d = np.sqrt(np.maximum(np.diag(info), 1e-300))
    cond = float(np.linalg.cond(info / np.outer(d, d)))
    try:
        bread = np.linalg.inv(info)
    except np.linalg.LinAlgError:
        inf = np.full(len(fit.x), np.inf)
        return inf, inf, np.inf
    z = student_t.ppf(0.5 + level / 2, np.inf)
    resolution = z * np.sqrt(np.maximum(np.diag(bread) * fit.J * len(fit.r)
                                        / max(n_eff, 1.0), 0.0))
    n_t = len(fit.r) // max(n_channels, 1)
    blocks = np.tile(np.arange(n_t) // max(block, 1), n_channels)[:len(fit.r)]
    G = int(blocks.max()) + 1
    if G < 3:
        return np.full(len(fit.x), np.inf), resolution, cond
    g = np.zeros((G, A.shape[1]))
    np.add.at(g, blocks, A * fit.r[:, None])
    cov = bread @ (g.T @ g) @ bread * G / (G - 1)
    reported = student_t.ppf(0.5 + level / 2, G - 1) * np.sqrt(np.maximum(np.diag(cov), 0.0))
    return reported, resolution, cond


def resolved_lower(r_a, r_b, n_channels: int, block: int, level: float = 0.95) -> bool:
    """Is the cost of the weighted residuals ``r_a`` lower than that of ``r_b`` (one
    recording, two twins) by a difference the data resolve? The test of equal predictive
    accuracy of Diebold and Mariano (1995): the loss differential r_a^2 - r_b^2 summed
    over time blocks of ``block`` samples (all channels: what the twins still miss colours
    the residuals, as for the block sandwich of :func:`confidence_intervals`), its mean
    over the G blocks against Student's t with G - 1 degrees of freedom; resolved when the
    two-sided ``level`` interval of that mean lies below zero."""
    return resolved_lower_on([(r_a, r_b, n_channels, block)], level)


def resolved_lower_on(recordings, level: float = 0.95) -> bool:
    """:func:`resolved_lower` over the blocks of several recordings together
    (``recordings``: [(r_a, r_b, n_channels, block), ...], one pair of twins)."""
    g = np.concatenate([_block_differences(*rec) for rec in recordings])
    G = len(g)
    if G < 3:
        return False
    sd = float(np.std(g, ddof=1))
    if sd == 0.0:
        return bool(np.mean(g) < 0.0)
    return bool(np.mean(g) + student_t.ppf(0.5 + level / 2, G - 1) * sd / np.sqrt(G) < 0.0)


def _block_differences(r_a, r_b, n_channels: int, block: int):
    """The loss differential r_a^2 - r_b^2 of one recording summed over its channels and
    over its whole time blocks of ``block`` samples."""
    r_a, r_b = np.asarray(r_a, float), np.asarray(r_b, float)
    n_t = len(r_a) // max(n_channels, 1)
    d = (r_a[:n_channels * n_t] ** 2 - r_b[:n_channels * n_t] ** 2)
    d = d.reshape(n_channels, n_t).sum(axis=0)
    G = n_t // max(block, 1)
    return d[:G * block].reshape(G, block).sum(axis=1)


def fit_task(task):
    """Worker function: fit one candidate (serially) and score it on the held-out data:
    (ctx, ctx_holdout, hyp, base, lin, start) -> (FitResult, J_holdout)."""
    from .evaluation import SerialExecutor
    ctx, ctx_ho, hyp, base, lin, start = task
    # the secant only for smooth hypotheses (every part screened by the linearized fit):
    # on a contact, a saturation, a gear or a dead zone it leaves the basin (contact seed
    # 1005 of the benchmark: its floor 24 % off instead of within 10 %)
    parts = (hyp.first, hyp.second) if hasattr(hyp, "second") else (hyp,)   # a pair
    smooth = all(p.linear for p in parts)
    fit = fit_candidate(SerialExecutor(), ctx, hyp, base, lin, start=start, broyden=smooth)
    r_ho = evaluate((ctx_ho, fit.scales, fit.effects))
    return fit, (cost(r_ho) if r_ho is not None else np.inf)
