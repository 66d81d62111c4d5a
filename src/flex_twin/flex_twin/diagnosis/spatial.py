"""Diagnosis of spatial arms per joint and per bending plane (issue 25).

A recorded run of a spatial arm (the columns of the spatial scenario CSV: ``t``, joint
values ``q<i>``, joint torques ``tau<i>``, per flexible link
``<link>_tip_deflection_y|z`` and ``<link>_tip_twist``) is replayed through the twin
open loop: the recorded torques (linear between samples, at the loop's step times) from
the static equilibrium under gravity with the joints held at the recorded start
(spatial.analysis.static_equilibrium; zero rates), by the compiled generalized-alpha
loop. The residual of every channel is scaled by the channel's RMS in the recording,
so joint angles, in-plane and out-of-plane deflections and twists weigh alike.

Hypotheses (:func:`spatial_hypotheses`), one parameter each, per link and **per bending
plane** (v: bending about the beam's z, EI_z; w: about its y, EI_y) and per joint:

==================  ==========================================================  =========
kind                model change                                                parameter
==================  ==========================================================  =========
bending_stiffness   the plane's stiffness block of the link x s (EI of the       s (-)
                    plane scaled: thesis Eq. 14 is linear in EI)
torsion_stiffness   the link's torsion block x s (GJ scaled)                     s (-)
plane_damping       D += b K on the plane's (or the twist's) block: stiffness-  b (s)
                    proportional damping of that plane only (zeta = b w / 2)
joint_viscous       D += F_v on the joint coordinate                             N m s/rad
payload             a point mass at the last link's end frame                    kg
==================  ==========================================================  =========

Each is fitted alone (bounded scalar search, stiffness scales on a log scale) on every
other block of :data:`BLOCK` samples; the blocks between are held out (a single run's
transient is short: a split in time would leave the held-out part without the ringing
that tells the planes apart). The best fit is **named** when it
removes at least :data:`MIN_REDUCTION` of the cost both on the fitted part and on the
held-out part; then the search repeats with it in the twin (at most :data:`MAX_EFFECTS`
effects) while what remains is above :data:`GATE`; several named effects are refitted
together at the end (Nelder-Mead). A recording within the gate is
"no material discrepancy"; a residual no hypothesis explains is "unexplained".

Shares the planar diagnosis's ideas (hypotheses from an effects library, held-out
confirmation, a gate), not its engine: that one replays planar models in a compiled
closed loop (replay.py); the spatial replay is open loop, as the spatial recordings come
from experiments with recorded joint torques.
"""
from __future__ import annotations

import copy
import csv
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize_scalar

#: samples per block: the even blocks are fitted, the odd ones held out
BLOCK = 10
#: named when the cost falls by at least this share, fitted and held out
MIN_REDUCTION = 0.5
#: scaled mean-square residual below which nothing is material (5e-4: an RMS residual of
#: ~2 % of the channels' RMS, 2.5 x the healthy Exudyn recording's 1.9-2.1e-4, the twin's
#: model-form floor against that simulator; 1e-3 left a hidden 0.1 N m s/rad friction on
#: joint 1 unnamed beside a link's stiffness)
GATE = 5e-4
MAX_EFFECTS = 2
PLANES = {"v": "EI_z, bending in the beam's x-y plane", "w": "EI_y, bending in the beam's "
          "x-z plane", "phi": "GJ, twist"}


class SpatialRecordingError(ValueError):
    """A recording that does not fit the arm (names the file and the column)."""


@dataclass
class SpatialRecording:
    """Samples of a spatial run: t (n,), joint values q and torques tau (n, n_joints),
    ``channels`` name -> (n,) (the joints' ``q<i>`` and the links' tip deflections)."""

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray
    channels: dict
    source: str = "<memory>"


def read_spatial_recording(path, model) -> SpatialRecording:
    """Read a recording CSV (module docstring) for ``model``'s arm; a missing column or a
    non-uniform time grid is an error naming the file and the column."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    head = [h.strip() for h in rows[0]]
    data = np.array([[float(x) for x in r] for r in rows[1:] if r], float)
    col = {h: data[:, k] for k, h in enumerate(head)}
    nj = model.n_links

    def need(name, what):
        if name not in col:
            raise SpatialRecordingError(f"{path}: column {name!r} missing ({what}); "
                                        f"found {', '.join(head)}")
        return col[name]

    t = need("t", "time, s")
    dt = np.diff(t)
    if len(t) < 10 or np.any(dt <= 0) or np.max(np.abs(dt - dt[0])) > 1e-6 * dt[0]:
        raise SpatialRecordingError(f"{path}: column 't': expected >= 10 samples on a "
                                    "uniform increasing grid")
    q = np.column_stack([need(f"q{i + 1}", "joint value, rad or m") for i in range(nj)])
    tau = np.column_stack([need(f"tau{i + 1}", "joint torque, N m or N")
                           for i in range(nj)])
    ch = {f"q{i + 1}": q[:, i] for i in range(nj)}
    for i, lk in enumerate(model.arm.links):
        b = model.beams[i]
        if b is None:
            continue
        for suffix in ("tip_deflection_y", "tip_deflection_z") + \
                (("tip_twist",) if b.nt else ()):
            name = f"{lk.name}_{suffix}"
            if name in col:
                ch[name] = col[name]
    return SpatialRecording(t, q, tau, ch, str(path))


@dataclass(frozen=True)
class PlaneHypothesis:
    """One candidate effect of a spatial arm (module docstring's table)."""

    kind: str
    target: str          # link or joint name
    plane: str = ""      # v | w | phi for the link kinds
    bounds: tuple = (0.5, 2.0)
    off: float = 1.0
    log: bool = True
    unit: str = "-"

    @property
    def name(self) -> str:
        return f"{self.kind}@{self.target}" + (f"/{self.plane}" if self.plane else "")

    def describe(self, x: float) -> str:
        where = f"{self.target}" + (f", plane {self.plane} ({PLANES[self.plane]})"
                                    if self.plane else "")
        if self.kind in ("bending_stiffness", "torsion_stiffness"):
            return f"{self.kind.replace('_', ' ')} of {where} x {x:.3f}"
        return f"{self.kind.replace('_', ' ')} of {where}: {x:.4g} {self.unit}"


def spatial_hypotheses(model) -> list[PlaneHypothesis]:
    """Per flexible link: bending stiffness and damping per plane (v, w), torsion
    stiffness and damping (with twist variables); per moving joint: viscous friction; the
    payload."""
    out = []
    for i, lk in enumerate(model.arm.links):
        b = model.beams[i]
        if b is None:
            continue
        for p in ("v", "w"):
            out.append(PlaneHypothesis("bending_stiffness", lk.name, p))
        if b.nt:
            out.append(PlaneHypothesis("torsion_stiffness", lk.name, "phi"))
        for p in ("v", "w") + (("phi",) if b.nt else ()):
            out.append(PlaneHypothesis("plane_damping", lk.name, p, (0.0, 0.01), 0.0,
                                       False, "s"))
    for i, lk in enumerate(model.arm.links):
        if model.off[i] not in model.held:
            out.append(PlaneHypothesis("joint_viscous", lk.joint.name, "", (0.0, 2.0), 0.0,
                                       False, "N m s/rad"))
    out.append(PlaneHypothesis("payload", "", "", (0.0, 1.0), 0.0, False, "kg"))
    return out


def _block(model, link: str, plane: str) -> np.ndarray:
    i = [lk.name for lk in model.arm.links].index(link)
    b = model.beams[i]
    s = model.flex_slice(i).start
    rng = {"v": range(0, b.nv), "w": range(b.nv, 2 * b.nv), "phi": range(2 * b.nv, b.n)}
    return np.array([s + k for k in rng[plane]], dtype=int)


def apply(model, hyp: PlaneHypothesis, x: float):
    """A copy of ``model`` with the effect ``hyp`` at value ``x`` (module docstring)."""
    if hyp.kind == "payload":
        from flex_model.spatial.payload import model_with_payload
        return model_with_payload(model, model.arm, float(x)) if x > 0 else model
    m = copy.copy(model)
    m.K, m.D = model.K.copy(), model.D.copy()
    if hyp.kind == "joint_viscous":
        i = model.arm.joint_names.index(hyp.target)
        m.D[model.off[i], model.off[i]] += x
        return m
    idx = np.ix_(*(2 * (_block(model, hyp.target, hyp.plane),)))
    if hyp.kind in ("bending_stiffness", "torsion_stiffness"):
        m.K[idx] = model.K[idx] * x
    else:   # plane_damping
        m.D[idx] += x * model.K[idx]
    return m


def replay(model, rec: SpatialRecording, step: float = 1e-3) -> dict:
    """The twin's channels at the recording's samples (module docstring)."""
    from flex_model.spatial.analysis import static_equilibrium
    from flex_model.spatial.integrate import simulate_fixed_compiled
    period = float(rec.t[1] - rec.t[0])
    per = max(1, int(np.ceil(period / step - 1e-9)))
    h = period / per
    n = per * (len(rec.t) - 1)
    ts = rec.t[0] + h * np.arange(1, n + 1)
    tau = np.column_stack([np.interp(ts, rec.t, rec.tau[:, j]) for j in range(model.n_links)])
    q0 = static_equilibrium(model, rec.q[0]).q
    run = simulate_fixed_compiled(model, q0, np.zeros(model.nq), h, n, joint_torques=tau,
                                  rho_inf=0.9, tol=1e-8)
    Q = run.q[::per]
    out = {f"q{i + 1}": Q[:, model.off[i]] for i in range(model.n_links)}
    d = [model.tip_deflections(qq) for qq in Q]
    for lk in model.arm.links:
        if lk.name in d[0]:
            for suffix, key in (("tip_deflection_y", "v"), ("tip_deflection_z", "w"),
                                ("tip_twist", "phi")):
                out[f"{lk.name}_{suffix}"] = np.array([x[lk.name][key] for x in d])
    return out


def channel_scales(rec: SpatialRecording) -> dict:
    """Per channel its RMS in the recording, floored at 1 % of the largest RMS of its unit
    group (joint values, deflections, twists): a channel that hardly moves is at the
    resolution of the comparison and must not dominate (link 2's twist in the tests,
    1.5 urad against link 1's 6.6 mrad)."""
    rms = {k: float(np.sqrt(np.mean(v * v))) for k, v in rec.channels.items()}
    groups = {"q": [k for k in rms if k[0] == "q" and k[1:].isdigit()],
              "m": [k for k in rms if "deflection" in k], "r": [k for k in rms if "twist" in k]}
    out = {}
    for names in groups.values():
        top = max((rms[k] for k in names), default=0.0)
        for k in names:
            out[k] = max(rms[k], 1e-2 * top, 1e-15)
    return out


def cost(rec: SpatialRecording, pred: dict, scales: dict, mask) -> float:
    """Mean over channels of the mean square scaled residual on the samples ``mask``."""
    return float(np.mean([np.mean(((rec.channels[k] - pred[k])[mask] / s) ** 2)
                          for k, s in scales.items()]))


@dataclass
class Named:
    hypothesis: PlaneHypothesis
    value: float
    cost_fit: float
    cost_holdout: float

    @property
    def label(self) -> str:
        return self.hypothesis.describe(self.value)


@dataclass
class SpatialDiagnosis:
    verdict: str                      # no material discrepancy | named | unexplained
    named: list = field(default_factory=list)
    cost_fit: tuple = (0.0, 0.0)      # nominal, final
    cost_holdout: tuple = (0.0, 0.0)
    ranking: list = field(default_factory=list)   # first round: (name, value, J fit, J ho)
    channels: dict = field(default_factory=dict)  # name -> (RMS residual before, after)
    evaluations: int = 0
    #: the twin's channels before (nominal) and after (with the named effects)
    nominal: dict = field(default_factory=dict, repr=False)
    final: dict = field(default_factory=dict, repr=False)

    def summary(self) -> dict:
        """JSON-ready: verdict, named effects (kind, target, plane, value, unit), costs,
        the first round's ranking and the per-channel RMS residuals."""
        return {"verdict": self.verdict,
                "named": [{"kind": n.hypothesis.kind, "target": n.hypothesis.target,
                           "plane": n.hypothesis.plane, "value": n.value,
                           "unit": n.hypothesis.unit, "label": n.label} for n in self.named],
                "cost_fit": list(self.cost_fit), "cost_holdout": list(self.cost_holdout),
                "gate": GATE, "ranking": [list(r) for r in self.ranking],
                "channels_rms": {k: list(v) for k, v in self.channels.items()},
                "evaluations": self.evaluations}

    def report(self) -> str:
        lines = [f"verdict: {self.verdict}",
                 f"cost (scaled mean square) fitted part {self.cost_fit[0]:.4g} -> "
                 f"{self.cost_fit[1]:.4g}, held out {self.cost_holdout[0]:.4g} -> "
                 f"{self.cost_holdout[1]:.4g} (gate {GATE:g})"]
        lines += [f"named: {n.label} (cost fitted {n.cost_fit:.4g}, held out "
                  f"{n.cost_holdout:.4g})" for n in self.named]
        lines.append("first round, best five: " + "; ".join(
            f"{name} {x:.4g} ({jf:.3g} / {jh:.3g})" for name, x, jf, jh in self.ranking[:5]))
        lines.append("RMS residual per channel, before -> after: " + ", ".join(
            f"{k} {a:.3g} -> {b:.3g}" for k, (a, b) in self.channels.items()))
        return "\n".join(lines)


def _fit(model, hyp, rec, scales, fit, ho, step, counter):
    def f(y):
        x = float(np.exp(y)) if hyp.log else float(y)
        counter[0] += 1
        try:
            return cost(rec, replay(apply(model, hyp, x), rec, step), scales, fit)
        except RuntimeError:       # a Newton failure: this value is not a twin
            return 1e30
    lo, hi = hyp.bounds
    res = minimize_scalar(f, bounds=(np.log(lo), np.log(hi)) if hyp.log else (lo, hi),
                          method="bounded", options={"xatol": 1e-3 if hyp.log else
                                                     1e-3 * (hi - lo)})
    x = float(np.exp(res.x)) if hyp.log else float(res.x)
    pred = replay(apply(model, hyp, x), rec, step)
    return x, cost(rec, pred, scales, fit), cost(rec, pred, scales, ho)


def _refit_together(model, named, rec, scales, fit, ho, step, counter):
    """Refit the values of several named effects at once (each was fitted with the earlier
    ones held): Nelder-Mead on the fitted blocks' cost in the hypotheses' coordinates (log
    for the stiffness scales), within their bounds. Updates ``named`` in place; returns
    (twin, cost fitted, cost held out)."""
    from scipy.optimize import minimize
    hyps = [n.hypothesis for n in named]

    def to_x(y):
        x = [float(np.exp(v)) if h.log else float(v) for h, v in zip(hyps, y)]
        return [min(max(v, h.bounds[0]), h.bounds[1]) for h, v in zip(hyps, x)]

    def twin_of(x):
        m = model
        for h, v in zip(hyps, x):
            m = apply(m, h, v)
        return m

    def f(y):
        counter[0] += 1
        try:
            return cost(rec, replay(twin_of(to_x(y)), rec, step), scales, fit)
        except RuntimeError:
            return 1e30

    y0 = [np.log(n.value) if n.hypothesis.log else n.value for n in named]
    res = minimize(f, y0, method="Nelder-Mead",
                   options={"xatol": 1e-4, "fatol": 1e-12, "maxfev": 200})
    x = to_x(res.x)
    twin = twin_of(x)
    pred = replay(twin, rec, step)
    jf, jh = cost(rec, pred, scales, fit), cost(rec, pred, scales, ho)
    for n, v in zip(named, x):
        n.value = v
    named[-1].cost_fit, named[-1].cost_holdout = jf, jh
    return twin, jf, jh


def diagnose_spatial(model, rec: SpatialRecording, step: float = 1e-3,
                     hypotheses=None, progress=None) -> SpatialDiagnosis:
    """Name the effects (per joint and per bending plane) that explain where the
    recording and the twin ``model`` disagree (module docstring)."""
    scales = channel_scales(rec)
    n = len(rec.t)
    fit = (np.arange(n) // BLOCK) % 2 == 0
    ho = ~fit
    base = replay(model, rec, step)
    j0f, j0h = cost(rec, base, scales, fit), cost(rec, base, scales, ho)
    hyps = list(hypotheses if hypotheses is not None else spatial_hypotheses(model))
    diag = SpatialDiagnosis("no material discrepancy", cost_fit=(j0f, j0f),
                            cost_holdout=(j0h, j0h))
    counter = [0]
    twin, jf, jh = model, j0f, j0h
    while max(jf, jh) > GATE and len(diag.named) < MAX_EFFECTS:
        done = {(h.kind, h.target, h.plane) for h in (x.hypothesis for x in diag.named)}
        rows = []
        for hyp in hyps:
            if (hyp.kind, hyp.target, hyp.plane) in done:
                continue
            x, cf, ch = _fit(twin, hyp, rec, scales, fit, ho, step, counter)
            rows.append((hyp, x, cf, ch))
            if progress is not None:
                progress(f"{hyp.name}: {x:.4g}, cost {cf:.4g} / held out {ch:.4g}")
        rows.sort(key=lambda r: r[2])
        if not diag.named:
            diag.ranking = [(h.name, x, cf, ch) for h, x, cf, ch in rows]
        hyp, x, cf, ch = rows[0]
        if cf > (1 - MIN_REDUCTION) * jf or ch > (1 - MIN_REDUCTION) * jh:
            diag.verdict = "unexplained" if not diag.named else diag.verdict
            break
        diag.named.append(Named(hyp, x, cf, ch))
        diag.verdict = "named"
        twin, jf, jh = apply(twin, hyp, x), cf, ch
    if len(diag.named) > 1:         # the named effects' values refitted together
        twin, jf, jh = _refit_together(model, diag.named, rec, scales, fit, ho, step,
                                       counter)
    diag.cost_fit, diag.cost_holdout = (j0f, jf), (j0h, jh)
    final = replay(twin, rec, step)
    diag.channels = {k: (float(np.sqrt(np.mean((rec.channels[k] - base[k]) ** 2))),
                         float(np.sqrt(np.mean((rec.channels[k] - final[k]) ** 2))))
                     for k in scales}
    diag.evaluations = counter[0]
    diag.nominal, diag.final = base, final
    return diag


def write_outputs(diag: SpatialDiagnosis, rec: SpatialRecording, out_dir,
                  plots: bool = True) -> list:
    """report.md, diagnosis.json and (``plots``) overlay.png: every channel measured, the
    nominal twin and the diagnosed twin. Returns the paths written."""
    import json
    from pathlib import Path
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    lines = [f"# Spatial diagnosis of {rec.source}", "", f"**{diag.verdict}**", ""]
    lines += [f"- named: {n.label}" for n in diag.named] or ["- named: none"]
    lines += ["", "| | nominal twin | diagnosed twin |", "|---|---|---|",
              f"| cost, fitted blocks | {diag.cost_fit[0]:.4g} | {diag.cost_fit[1]:.4g} |",
              f"| cost, held-out blocks | {diag.cost_holdout[0]:.4g} | "
              f"{diag.cost_holdout[1]:.4g} |", "",
              f"Cost: mean over channels of the mean square residual scaled by the "
              f"channel's RMS; gate {GATE:g}.", "", "| channel | RMS residual, nominal | "
              "RMS residual, diagnosed |", "|---|---|---|"]
    lines += [f"| {k} | {a:.4g} | {b:.4g} |" for k, (a, b) in diag.channels.items()]
    lines += ["", "First round (each hypothesis fitted alone): name, value, cost fitted / "
              "held out", ""]
    lines += [f"- {name}: {x:.4g} ({jf:.4g} / {jh:.4g})" for name, x, jf, jh in
              diag.ranking]
    paths = [out / "report.md", out / "diagnosis.json"]
    paths[0].write_text("\n".join(lines) + "\n")
    paths[1].write_text(json.dumps(diag.summary(), indent=1, default=float))
    if plots and diag.nominal:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        names = list(diag.channels)
        fig, axes = plt.subplots(len(names), 1, figsize=(9, 1.8 * len(names)), sharex=True)
        for ax, k in zip(np.atleast_1d(axes), names):
            ax.plot(rec.t, rec.channels[k], "k", lw=1.2, label="measured")
            ax.plot(rec.t, diag.nominal[k], "C3--", lw=1, label="nominal twin")
            ax.plot(rec.t, diag.final[k], "C0", lw=1, label="diagnosed twin")
            ax.set_ylabel(k, fontsize=7)
        np.atleast_1d(axes)[0].legend(fontsize=7, loc="upper right")
        np.atleast_1d(axes)[-1].set_xlabel("t (s)")
        fig.suptitle(f"{diag.verdict}: " + ("; ".join(n.label for n in diag.named) or "-"),
                     fontsize=9)
        fig.tight_layout()
        paths.append(out / "overlay.png")
        fig.savefig(paths[-1], dpi=90)
        plt.close(fig)
    return paths
