"""The twin's own numerical and model-form floor on a run (issue 21, step 2).

Before any hypothesis, the replay at its setting (the nominal arm's variables per link and
kinematics, the replay step ``dt``) is compared with a refined twin R (two more variables
per link, ``second_order`` kinematics, a quarter of the step), both with the nominal
parameters, on the fit and the held-out recordings:

- the replay's own error d(S) = J(pred_S - pred_R): the twin-twin difference in the units
  of the noise power (the cost J of :mod:`.evaluation`), what the setting S misses of the
  refined twin;
- the model-form part of the data's residual: J(data - S) - J(data - R), what the
  refinement removes from the residual. A run made by the twin's own equations at its own
  setting has none (the refined twin is further from it: the difference is negative);
  a run of a better simulator has about d(S).

The replay's setting is refined only when the data are a finer model's run: on both
recordings, the refined twin is closer to the data by more than :data:`FLOOR_TARGET` and
:data:`FLOOR_SHARE` of the excess J - 1, and the data's residual along the twins'
difference u = (pred_R - pred_S) / sigma is about one u (:data:`FINER_RANGE`; on a
twin-made run with an effect that projection is the effect's, e.g. 7 u for a heavier
payload); it then takes the cheapest setting of the ladder (second_order; half the step;
two more variables) whose own error is at most
:data:`FLOOR_TARGET` on both recordings (well below the noise: an RMS error under 0.22 of
the noise level), else the one of the ladder with the least own error (R itself costs
too much per replay: it is the yardstick).

What remains of the floor at the chosen setting is model form, not a physical effect:

- the samples where the chosen twin and the refined twin disagree (the transients after a
  set-point step: a D term on a hub-less joint turns an unresolved joint rate into a
  torque spike, which no affordable step resolves) weigh less: the noise level of a
  channel becomes sigma_k = sigma sqrt(1 + (FLOOR_FACTOR e_k)^2), e_k the moving maximum
  over +-FLOOR_WINDOW samples of |pred_S - pred_R| / sigma (the refined twin is not exact
  either: the factor 2). Only on a run of a finer model (a twin-made run keeps its
  weights: bit-identical);
- the gate counts what is left, min(d(S), J(data - S) - J(data - R)) on the held-out
  recording (with those weights on a finer model's run), when the refined twin is closer
  to the data on both recordings and the projection is in range (else 0: on a twin-made
  run with an effect, that change is the effect's cross term with the refinement, not
  model form); the held-out excess
  must exceed gate + that, and the report states both parts: J(data - S) unweighted minus
  weighted (the transients) and the remainder.
"""
from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import numpy as np

from flex_model.dynamics import FlexArmModel
from . import spatial_loop
from .evaluation import cost, evaluate

#: "well below the noise": the replay's own error at most this (J units, noise power)
FLOOR_TARGET = 0.05
#: the refined twin must also explain this share of the excess J - 1 to refine the replay
FLOOR_SHARE = 0.1
#: variables added per link by the refinement
MORE_VARIABLES = 2
#: the refined twin's step: this fraction of the replay's
REFINED_STEP = 0.25
#: a finer model's run: its residual along the twins' difference, in units of it, in this
#: range on both recordings (1: the data are the refined twin's; see measure_floor)
FINER_RANGE = (0.5, 1.5)
#: the noise inflation where the chosen and the refined twin disagree (see above)
FLOOR_FACTOR = 2.0
FLOOR_WINDOW = 5


@dataclass(frozen=True)
class Setting:
    """A replay setting: variables per link, kinematics, integration step (s)."""

    variables: tuple
    kinematics: str
    dt: float

    def arm(self, nominal):
        if spatial_loop.is_spatial(nominal):
            return spatial_loop.with_variables(nominal, self.variables, self.kinematics)
        links = tuple(dataclasses.replace(lk, n_vars=n)
                      for lk, n in zip(nominal.links, self.variables))
        return dataclasses.replace(nominal, links=links, kinematics=self.kinematics)

    def as_dict(self) -> dict:
        return {"variables": list(self.variables), "kinematics": self.kinematics,
                "dt": self.dt}

    def label(self) -> str:
        return (f"{'/'.join(map(str, self.variables))} variables, {self.kinematics}, "
                f"dt {1e3 * self.dt:g} ms")


@dataclass
class Floor:
    """The measured floor (J units of the noise power; per recording "fit", "holdout")."""

    default: Setting
    reference: Setting
    chosen: Setting
    own_error_default: dict      # d(S0) = J(pred_S0 - pred_R)
    own_error: dict              # d(chosen)
    J_default: dict              # J(data - S0), nominal parameters
    J_reference: dict            # J(data - R)
    J_chosen: dict
    model_form: dict             # the remainder counted by the gate
    model_form_channels: dict    # held-out, per channel: mean((pred_S - pred_R) / sigma)^2
    refined: bool
    ladder: list = field(default_factory=list)
    wall_s: float = 0.0
    sigma: dict = None           # per recording: channel -> per-sample noise level (refined)
    J_weighted: dict = None      # J(data - chosen) with those noise levels
    along: dict = None           # the data's residual along the twins' difference (units)
    #: per recording: the nominal twin's residual vector at the chosen setting with the
    #: contexts' own noise levels (what the engine would replay again; it drops them)
    residuals: dict = None
    #: the floor measured again with the first named effect (:func:`model_form_with`):
    #: its labels, own error, gain, along and model form per recording; None if not
    remeasured: dict = None

    @property
    def changed(self) -> bool:
        return self.chosen != self.default

    def summary(self) -> dict:
        return {"default_setting": self.default.as_dict(),
                "reference_setting": self.reference.as_dict(),
                "chosen_setting": self.chosen.as_dict(), "refined": self.refined,
                "own_error_default": self.own_error_default,
                "own_error_chosen": self.own_error, "J_default": self.J_default,
                "J_reference": self.J_reference, "J_chosen": self.J_chosen,
                "model_form": self.model_form,
                "model_form_channels_holdout": self.model_form_channels,
                "ladder": self.ladder, "wall_s": self.wall_s,
                "J_chosen_floor_weighted": self.J_weighted,
                "transient_part": ({k: self.J_chosen[k] - self.J_weighted[k]
                                    for k in self.J_chosen} if self.J_weighted else None),
                "along": self.along, "target": FLOOR_TARGET,
                "remeasured_with_named": self.remeasured}


def _refinable(nominal, setting: Setting) -> bool:
    try:
        if spatial_loop.is_spatial(nominal):
            from flex_model.spatial.dynamics import SpatialArmModel
            SpatialArmModel(setting.arm(nominal))
            return True
        FlexArmModel(setting.arm(nominal))
        return True
    except ValueError:
        return False


def settings(nominal, dt: float) -> tuple[Setting, list, Setting]:
    """(the default setting, the ladder of finer ones cheapest first, the reference)."""
    n0 = spatial_loop.link_variables(nominal) if spatial_loop.is_spatial(nominal) else \
        tuple(lk.n_vars for lk in nominal.links)
    s0 = Setting(n0, nominal.kinematics, dt)
    more = tuple(n + MORE_VARIABLES for n in n0)
    cand = [Setting(n0, "second_order", dt), Setting(n0, "second_order", dt / 2),
            Setting(more, "second_order", dt / 2),
            Setting(more, "second_order", dt * REFINED_STEP)]
    ok = [s for s in cand if s != s0 and _refinable(nominal, s)]
    if not ok:   # no refinement of the variables or kinematics (a lumped link): the step
        ok = [Setting(n0, nominal.kinematics, dt * REFINED_STEP)]
    ladder = []
    for s in ok:
        if s not in ladder:
            ladder.append(s)
    return s0, ladder[:-1], ladder[-1]


def _floor_sigma(ctx, e):
    """(channel -> per-sample noise level over the whole recording, the weight vector of
    the scored samples): sigma sqrt(1 + (FLOOR_FACTOR env)^2), env the moving maximum of
    |e| (the weighted twin-twin difference of the scored samples, channels concatenated)."""
    from scipy.ndimage import maximum_filter1d
    names = ctx.rec.residual_channels
    n_rec = len(ctx.rec.t)
    m = len(e) // len(names)
    k0 = n_rec - m
    sig, w = {}, []
    for i, c in enumerate(names):
        env = maximum_filter1d(np.abs(e[i * m:(i + 1) * m]), 2 * FLOOR_WINDOW + 1)
        f = np.sqrt(1.0 + (FLOOR_FACTOR * env) ** 2)
        s = np.full(n_rec, float(ctx.sigma[c]))
        s[k0:] *= f
        sig[c] = s
        w.append(1.0 / f)
    return sig, np.concatenate(w)


def measure_floor(executor, ctx, ctx_ho, progress=None) -> Floor:
    """The floor of the nominal twin on the two recordings and the chosen setting (see
    the module docstring). ``ctx``/``ctx_ho``: the contexts at the default setting."""
    t0 = time.perf_counter()
    nominal = ctx.nominal
    s0, ladder, ref = settings(nominal, ctx.dt)
    ones = np.ones(len(ctx.baseline_params))
    keys = (("fit", ctx), ("holdout", ctx_ho))

    def ctxs(s):
        arm = s.arm(nominal)
        return [dataclasses.replace(c, nominal=arm, dt=s.dt) for _, c in keys]

    r = {}

    def run(group):   # the residual vectors of these settings on both recordings
        outs = list(executor.map(evaluate, [(c, ones, []) for s in group for c in ctxs(s)]))
        for i, s in enumerate(group):
            r[s] = dict(zip([k for k, _ in keys], outs[2 * i:2 * i + 2]))
    run([s0, ref])
    if any(v is None for v in r[s0].values()) or any(v is None for v in r[ref].values()):
        # a twin that diverges: no floor measured (the engine refuses a diverging nominal)
        nan = {k: float("nan") for k, _ in keys}
        zero = {k: 0.0 for k, _ in keys}
        return Floor(s0, ref, s0, nan, nan, nan, nan, nan, zero, {}, False,
                     wall_s=time.perf_counter() - t0)

    def own(s):
        return {k: cost(r[s][k] - r[ref][k]) if r[s][k] is not None else np.inf
                for k, _ in keys}

    def costs(s):
        return {k: cost(v) if v is not None else np.inf for k, v in r[s].items()}
    gain = {k: costs(s0)[k] - costs(ref)[k] for k, _ in keys}
    # the data's residual along the twins' difference u = (pred_R - pred_S0) / sigma, in
    # units of u: about 1 on a finer model's run (r_S0 = u + noise); on a twin-made run the
    # projection of an effect, anything (a heavier payload: 7)
    d0 = own(s0)
    along = {k: (gain[k] + d0[k]) / (2.0 * d0[k]) if d0[k] > 0 else 0.0 for k, _ in keys}
    finer = all(FINER_RANGE[0] <= along[k] <= FINER_RANGE[1] for k, _ in keys)
    refine = finer and all(gain[k] > max(FLOOR_TARGET, FLOOR_SHARE * (costs(s0)[k] - 1.0))
                           for k, _ in keys)
    if refine:   # the ladder only where it is needed (a twin-made run: two replays each),
        # cheapest first, up to the first setting within the target (the one chosen)
        for s in ladder:
            run([s])
            if max(own(s).values()) <= FLOOR_TARGET:
                break
    tried = [s for s in ladder if s in r]
    J = {s: costs(s) for s in r}
    chosen = s0
    rows = [{"setting": s.as_dict(), "own_error": own(s), "J": J[s]}
            for s in [s0] + (tried if refine else [])]
    if refine:
        ok = [s for s in tried if max(own(s).values()) <= FLOOR_TARGET]
        chosen = ok[0] if ok else min(tried or [ref], key=lambda s: max(own(s).values()))
        if any(v is None for v in r[chosen].values()):   # every finer setting diverged
            chosen, refine = s0, False
    d = own(chosen)
    sig = Jw = None
    if refine and chosen != ref:   # the transients weigh less (module docstring)
        sig, w = {}, {}
        for k, c in keys:
            sig[k], w[k] = _floor_sigma(c, r[chosen][k] - r[ref][k])
        Jw = {k: cost(r[chosen][k] * w[k]) for k, _ in keys}
        dw = {k: cost((r[chosen][k] - r[ref][k]) * w[k]) for k, _ in keys}
        Jrw = {k: cost(r[ref][k] * w[k]) for k, _ in keys}
        model_form = {k: float(min(dw[k], max(0.0, Jw[k] - Jrw[k]))) for k, _ in keys}
    elif finer and all(gain[k] > 0.0 for k, _ in keys):
        model_form = {k: float(min(d[k], J[chosen][k] - J[ref][k])) for k, _ in keys}
    else:   # the refined twin is not closer to the data on both recordings: a twin-made
        # run, whose residual change under refinement is the cross term with an effect
        model_form = {k: 0.0 for k, _ in keys}
    names = ctx_ho.rec.residual_channels
    diff = r[chosen]["holdout"] - r[ref]["holdout"]
    per = np.split(diff, len(names))
    floor = Floor(s0, ref, chosen, own(s0), d, J[s0], J[ref], J[chosen], model_form,
                  {c: float(np.mean(p * p)) for c, p in zip(names, per)}, refine, rows,
                  time.perf_counter() - t0, sig, Jw, along, dict(r[chosen]))
    if progress:
        progress(f"floor: replay {s0.label()} against {ref.label()}: own error "
                 f"{floor.own_error_default['holdout']:.3g} (held out), residual "
                 f"{J[s0]['holdout']:.4g} -> {J[ref]['holdout']:.4g}; replay at "
                 f"{chosen.label()}, model form counted by the gate "
                 f"{model_form['holdout']:.3g}")
    return floor


def model_form_with(executor, ctx, ctx_ho, floor: Floor, scales, effects) -> dict:
    """The model-form part measured again with the named effects in both twins (the
    replay at its setting S and the refined twin R, both with ``scales`` and ``effects``).

    On a run whose hidden effect dominates the nominal twin's residual the first
    measurement cannot tell model form from the effect (the refined twin is "not closer":
    its change is the effect's cross term with the refinement, counted 0). Once the
    effect is named, what the data's residual r_S holds along the twins' difference
    u = (pred_R - pred_S) / sigma is the twin's own error: a = (r_S . u) / (u . u), the
    "along" of :func:`measure_floor` (0 on a run of the twin's own equations, 1 on one of
    the refined twin's), and the residual's power along u, a^2 d(S) with a clipped to
    [0, 1] (d(S) = J(u), the replay's own error), is model form: no further effect is
    needed for it. (Exudyn payload case B-samp500-payload-m1-s1 with the payload named:
    d 6.55 / 4.73, a 0.38 / 0.44: model form 1.0 / 0.92 of an excess of 1.3 / 1.6.)
    The model form counted is bounded by the twin's own error at the nominal parameters
    (:func:`bounded_model_form`). Returns {"own_error", "gain", "along", "model_form",
    "model_form_unbounded"} (per recording) and "finer"."""
    keys = (("fit", ctx), ("holdout", ctx_ho))
    ref_arm = floor.reference.arm(ctx.nominal)
    refs = [dataclasses.replace(c, nominal=ref_arm, dt=floor.reference.dt) for _, c in keys]
    specs = [(c, scales, list(effects)) for _, c in keys] + \
        [(c, scales, list(effects)) for c in refs]
    outs = list(executor.map(evaluate, specs))
    zero = {k: 0.0 for k, _ in keys}
    if any(o is None for o in outs):
        return {"own_error": None, "gain": None, "along": None, "model_form": zero,
                "model_form_unbounded": zero, "finer": False}
    rs = dict(zip([k for k, _ in keys], outs[:2]))
    rr = dict(zip([k for k, _ in keys], outs[2:]))
    d = {k: cost(rs[k] - rr[k]) for k, _ in keys}
    gain = {k: cost(rs[k]) - cost(rr[k]) for k, _ in keys}
    along = {k: (gain[k] + d[k]) / (2.0 * d[k]) if d[k] > 0 else 0.0 for k, _ in keys}
    finer = all(FINER_RANGE[0] <= along[k] <= FINER_RANGE[1] and gain[k] > 0.0
                for k, _ in keys)
    mf = {k: float(np.clip(along[k], 0.0, 1.0) ** 2 * d[k]) for k, _ in keys}
    return {"own_error": d, "gain": gain, "along": along, "finer": finer,
            "model_form_unbounded": mf, "model_form": bounded_model_form(floor, mf)}


def bounded_model_form(floor: Floor, mf: dict) -> dict:
    """The model form measured with the named effects, bounded by the twin's own error
    at the nominal parameters (d of :func:`measure_floor` at the chosen setting, per
    recording): the twin's numerical and model-form error is a property of its setting
    and of the run's excitation, which the named effects change a little, never a
    physical effect (issue 44). Where the twins' difference grows beyond that, what
    grows is a missing effect's cross term with the refinement (Exudyn case
    C-cont-two-joint_friction2+payload-s1: with the payload named the remeasured model
    form reached thousands of noise units, the gate rose to match and the joint-2
    friction was left unnamed)."""
    return {k: float(min(v, max(floor.own_error.get(k, 0.0), 0.0)))
            if np.isfinite(floor.own_error.get(k, np.nan)) else 0.0 for k, v in mf.items()}
