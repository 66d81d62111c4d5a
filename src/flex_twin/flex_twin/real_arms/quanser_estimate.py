"""The live twin on the Quanser lab runs (issue 45): the tip deflection estimated from the
hub encoder and the voltage alone, compared with the lab's tip gauge.

The filter is flex_model.estimation's extended Kalman filter on the stored calibrated twin
(``quanser_cuboulder_calibrated``, fitted to the link-fit runs of CUBOULDER_SPLIT only); its
input is the logged voltage (the twin's ``dc_motor``), its one measurement the hub encoder
(4096 counts per turn: quantum 2 pi / 4096). The gauge never enters the filter: it is read
only to score the estimate, as :mod:`.replay` scores the open-loop twin, through the twin's
gauge (:func:`.replay.gauge_reading`: its sign, bias and lag, 37.4 ms in the stored twin).
The filter's noise levels (:data:`TUNED`) were chosen on the link-fit runs (:data:`TUNED_ON`)
and never on a held-out run. ``coverage_95``: the fraction of gauge samples within 1.96
sqrt(estimate variance + the log's 1 mm rounding variance, 1 mm^2 / 12).

The second structure, the driven link (:func:`estimate_run_driven`,
flex_model.estimation.driven_link: the link's mode driven by the hub's acceleration, the hub
pinned by the encoder alone), measures what the link, not the hub, leaves
(docs/estimation.md, "Against the link driven by the measured hub").
"""
from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.estimation import EstimatorSettings, Measurement, estimate_recording
from flex_model.estimation.driven_link import LinkMode, estimate_driven_link
from flex_model.estimation.filter import chi2_95
from flex_model.sensors import delayed
from ..estimate import Z95, coverage_95
from .calibration import CUBOULDER_SPLIT
from .quanser_data import CUBOULDER, cuboulder_files, read_cuboulder_file
from .quanser_twin import stored_calibrated_arm
from .replay import GAUGE_RESOLUTION, gauge_reading, rms, transient_share, twin_gauge, \
    TRANSIENT

#: the SRV02's output-shaft encoder: 4096 counts per turn
HUB_QUANTUM = 2 * np.pi / 4096
#: the log's 1 mm rounding as a std (m)
GAUGE_STD = GAUGE_RESOLUTION / np.sqrt(12)
#: the filter's settings, tuned on the link-fit runs TUNED_ON (docs/estimation.md)
#: initial_deflection_std: the link's ringing at rest before the first step of the fit runs
#: (gauge RMS 2.0-5.3 mm), not the 20 mm default, which let the filter swing the link by
#: 150 mm to explain the encoder's first counts
TUNED = {"torque_noise": 0.01, "modal_noise": 0.0, "relinearize_every": 20, "adapt": (),
         "initial_deflection_std": 0.005}
#: the encoder's noise std (rad) on top of its rounding: one count. At rest it flips by a
#: count; read as rounding alone (0.44 mrad) the filter took each flip for motion and
#: swung the link by it (fit runs' tip median 4.28 -> 3.89 mm with torque noise 0.01)
HUB_STD = 2 * np.pi / 4096
TUNED_ON = CUBOULDER_SPLIT["link_fit"]
#: the link's model error (m): added to the filter's variance in the band, chosen so that
#: the band holds 95 % of the TUNED_ON runs' gauge samples (bench/bench_quanser_estimate.py
#: --tune); the filter's own band (coverage_95_filter) is far narrower
TIP_MODEL_STD = 0.004215
#: the held-out flexible runs (CUBOULDER_SPLIT); those without a gauge are skipped
HELD_OUT = CUBOULDER_SPLIT["link_holdout"]
#: the driven link (flex_model.estimation.driven_link): the link's first clamped mode driven
#: by the hub's acceleration, the hub pinned by its encoder alone (white jerk), the gauge
#: read ``lag_s`` late. Tuned on link-fit runs only (bench/bench_quanser_estimate.py
#: --tune-link: a grid over frequency, damping and jerk noise, the gain and lag by least
#: squares): "hagenau" on Hagenau's two (flexarm_K1_6, flexarm_K1K2K3k4_6_-3_213_4), for
#: Hagenau's runs; "shared" on all three TUNED_ON, for the units without a fit run
#: (Covington, Unit7)
DRIVEN_LINK = {
    "hagenau": {"frequency_hz": 1.8, "damping_ratio": 0.03, "gain": 0.2311, "lag_s": 0.03,
                "jerk_noise": 1000.0},
    "shared": {"frequency_hz": 1.95, "damping_ratio": 0.03, "gain": 0.4029, "lag_s": 0.05,
               "jerk_noise": 100.0}}
#: the link's model error (m) in the driven link's band: 95 % of the TUNED_ON runs' gauge
#: samples (bench_quanser_estimate.py --structure driven_link --tune)
DRIVEN_MODEL_STD = 0.003586
#: the structures of :func:`estimate_named`
STRUCTURES = ("full", "driven_link")


def link_unit(name: str) -> str:
    """The :data:`DRIVEN_LINK` entry of a CU Boulder run: Hagenau's own runs are its
    ``flexarm_*`` logs (studies.unit_calibration.UNITS), the others "shared"."""
    return "hagenau" if name.startswith("flexarm_") else "shared"


def estimate_run_driven(run, link: dict | None = None, model_std: float | None = None):
    """The driven link on a lab run's encoder alone (:data:`DRIVEN_LINK` of its unit, or
    ``link``), scored against its gauge like :func:`estimate_run`. The mode's gain is in
    the gauge's metres: it reads gauge_sign * d(t - lag_s) + gauge_bias."""
    p = link or DRIVEN_LINK[link_unit(run.name)]
    res = estimate_driven_link(run.theta, run.dt, LinkMode(
        p["frequency_hz"], p["damping_ratio"], p["gain"]), p["jerk_noise"], 0.0, 0.0,
        HUB_QUANTUM)
    d = delayed(run.t, res.deflection, p["lag_s"])
    sd = delayed(run.t, res.deflection_std, p["lag_s"])
    out = RunEstimate(run, res, run.gauge_sign() * d + run.gauge_bias(), sd, hub=res.theta,
                      label="estimate (driven link, hub alone)")
    out.model_std = DRIVEN_MODEL_STD if model_std is None else model_std
    summary = {"nis_mean": float(np.mean(res.nis)), "parameters": dict(p),
               "nis_95_fraction": float(np.mean(res.nis <= chi2_95(1)))}
    out.metrics = score(run, res.theta, summary, out.tip_reading, sd, out.model_std)
    return out


def hub_encoder() -> Measurement:
    """The hub encoder as the filter reads it: quantum 2 pi / 4096 and :data:`HUB_STD`."""
    return Measurement("theta", "joint_angle", 0, std=HUB_STD, quantum=HUB_QUANTUM)


def settings_for(run, **overrides) -> EstimatorSettings:
    """:data:`TUNED` at the run's sample period, with ``overrides``."""
    return EstimatorSettings(sample_period=run.dt, **{**TUNED, **overrides})


@dataclass
class RunEstimate:
    """One lab run's estimate: the tip as the gauge would read it (lab sign, bias, lag),
    its std, and the figures against the gauge."""

    run: object
    result: object
    tip_reading: np.ndarray
    tip_reading_std: np.ndarray
    metrics: dict = field(default_factory=dict)
    model_std: float = 0.0
    hub: np.ndarray | None = None
    label: str = "estimate (hub + voltage)"


def estimate_run(model: FlexArmModel, run, settings: EstimatorSettings | None = None,
                 model_std: float | None = None):
    """Estimate a lab run from its encoder and voltage; score against its gauge (the band
    with ``model_std``, default :data:`TIP_MODEL_STD`)."""
    settings = settings or settings_for(run)
    q0 = model.q_from_joint_angles([run.theta[0]])   # at rest, undeformed (no gravity)
    res = estimate_recording(model, run.t, run.voltage[:, None], run.theta[:, None],
                             [hub_encoder()], settings, q0=q0)
    gauge = twin_gauge(model)
    d = delayed(run.t, res.tip_deflections[:, 0], gauge.delay)
    sd = delayed(run.t, res.tip_deflections_std[:, 0], gauge.delay) * abs(gauge.gain)
    out = RunEstimate(run, res, gauge_reading(model, run, d), sd, hub=res.joint_angles[:, 0])
    out.model_std = TIP_MODEL_STD if model_std is None else model_std
    out.metrics = score(run, res.joint_angles[:, 0], res.summary, out.tip_reading, sd,
                        out.model_std)
    return out


def score(run, hub, summary: dict, tip, tip_std, model_std: float) -> dict:
    """Hub and tip RMS, coverage, and where the tip error lies (before the first step:
    ringing the stuck hub cannot show; the TRANSIENT s after each step). ``hub``: the
    estimated hub angle; ``summary``: nis_mean, nis_95_fraction, parameters."""
    m = {"run": run.name, "duration_s": float(run.t[-1]),
         "hub_rms_rad": rms(hub - run.theta), "nis_mean": summary["nis_mean"],
         "nis_95_fraction": summary["nis_95_fraction"], "parameters": summary["parameters"]}
    if not run.has_gauge:
        return m
    err = tip - run.deflection
    steps = run.step_indices()
    k0 = int(steps[0]) if len(steps) else len(err)
    m.update(tip_rms_mm=1e3 * rms(err),
             tip_rms_from_first_step_mm=1e3 * rms(err[k0:]) if k0 < len(err) else None,
             before_first_step_share=float(np.sum(err[:k0] ** 2) / np.sum(err ** 2)),
             transient_share=transient_share(err, steps, int(round(TRANSIENT / run.dt))),
             gauge_rms_mm=1e3 * rms(run.deflection - run.gauge_bias()),
             tip_std_median_mm=1e3 * float(np.median(tip_std)),
             coverage_95_filter=coverage_95(err, tip_std, GAUGE_STD),
             coverage_95=coverage_95(err, np.hypot(tip_std, model_std), GAUGE_STD))
    return m


def estimate_named(root, name: str, settings: dict | None = None, out=None,
                   errors: bool = False, model_std: float | None = None,
                   structure: str = "full") -> dict:
    """The metrics of one CU Boulder run (by name): ``structure`` "driven_link"
    (:func:`estimate_run_driven`, ``settings`` replacing its link's) or "full" (the EKF on
    the stored calibrated twin, :func:`estimate_run`); with ``out``, its PNG there;
    ``errors``: also the tip error and the filter's std over time (``tip_error_m``,
    ``tip_std_m``). A module-level function: a worker process runs it."""
    run = read_cuboulder_file(next(p for p in cuboulder_files(Path(root) / CUBOULDER)
                                   if p.name == name))
    if structure == "driven_link":
        link = {**DRIVEN_LINK[link_unit(name)], **(settings or {})}
        est = estimate_run_driven(run, link, model_std)
    else:
        model = FlexArmModel(stored_calibrated_arm("flexible"))
        est = estimate_run(model, run, settings_for(run, **(settings or {})), model_std)
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        plot_run_estimate(est, Path(out) / f"estimate-{name.replace('.', '_')}.png")
    if errors:
        return {**est.metrics, "tip_error_m": est.tip_reading - run.deflection,
                "tip_std_m": est.tip_reading_std}
    return est.metrics


def estimate_held_out(root, names=HELD_OUT, settings: dict | None = None, progress=None,
                      out=None, workers: int = 1, errors: bool = False,
                      model_std: float | None = None, structure: str = "full") -> dict:
    """The estimate on the named CU Boulder runs with a gauge (default: the held-out
    flexible runs) by ``structure`` (:data:`STRUCTURES`, :func:`estimate_named`),
    ``workers`` processes; with ``out``, a PNG per run there; the band with ``model_std``
    (default :data:`DRIVEN_MODEL_STD` or :data:`TIP_MODEL_STD`). Returns
    {"runs": [per-run metrics], "summary": {...}, "settings": ..., "tuned_on": ...}."""
    if structure not in STRUCTURES:
        raise ValueError(f"structure: got {structure!r}; expected one of {STRUCTURES}")
    known = {p.name: p for p in cuboulder_files(Path(root) / CUBOULDER)}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ValueError(f"runs: unknown {', '.join(unknown)}; known: {', '.join(known)}")
    names = [n for n in names if read_cuboulder_file(known[n]).has_gauge]
    rows = []
    with ProcessPoolExecutor(workers) if workers > 1 else nullcontext() as pool:
        jobs = [(pool.submit if pool else _now)(estimate_named, root, n, settings, out,
                                                errors, model_std, structure) for n in names]
        for name, job in zip(names, jobs):
            rows.append(job.result())
            if progress:
                progress(f"  {name}: tip RMS {rows[-1]['tip_rms_mm']:.2f} mm, in the 95 % "
                         f"band {100 * rows[-1]['coverage_95']:.1f} %")
    driven = structure == "driven_link"
    default_std = DRIVEN_MODEL_STD if driven else TIP_MODEL_STD
    return {"structure": structure,
            "arm": "driven link" if driven else stored_calibrated_arm("flexible").name,
            "settings": ({u: {**v, **(settings or {})} for u, v in DRIVEN_LINK.items()}
                         if driven else {**TUNED, **(settings or {})}),
            "tuned_on": list(TUNED_ON),
            "tip_model_std_m": default_std if model_std is None else model_std,
            "runs": rows, "summary": summarize(rows)}


class _now:
    """A finished job (the serial path of :func:`estimate_held_out`)."""

    def __init__(self, fn, *args):
        self.value = fn(*args)

    def result(self):
        return self.value


def summarize(rows) -> dict:
    """tip_rms_median_mm, hub_rms_median_rad, coverage_95 (pooled over the samples),
    runs, and the medians of the error's location."""
    if not rows:
        return {"runs": 0}
    n = np.array([r["duration_s"] for r in rows])
    med = {k: float(np.median([r[k] for r in rows])) for k in (
        "tip_rms_mm", "tip_rms_from_first_step_mm", "before_first_step_share",
        "transient_share", "tip_std_median_mm")}
    return {"tip_rms_median_mm": med["tip_rms_mm"],
            "hub_rms_median_rad": float(np.median([r["hub_rms_rad"] for r in rows])),
            "coverage_95": float(np.sum(n * [r["coverage_95"] for r in rows]) / n.sum()),
            "coverage_95_filter": float(np.sum(n * [r["coverage_95_filter"] for r in rows])
                                        / n.sum()),
            "runs": len(rows),
            "tip_rms_from_first_step_median_mm": med["tip_rms_from_first_step_mm"],
            "before_first_step_share_median": med["before_first_step_share"],
            "transient_share_median": med["transient_share"],
            "tip_std_median_mm": med["tip_std_median_mm"]}


def plot_run_estimate(est: RunEstimate, path) -> None:
    """Tip: the gauge, the estimate as the gauge would read it and its 95 % band; hub:
    the encoder and the estimate."""
    from flex_model.plots import finish_figure, plt
    run, t = est.run, est.run.t
    fig, ax = plt.subplots(2, 1, figsize=(10, 5.2), sharex=True)
    band = Z95 * np.sqrt(est.tip_reading_std ** 2 + est.model_std ** 2 + GAUGE_STD ** 2)
    ax[0].fill_between(t, 1e3 * (est.tip_reading - band), 1e3 * (est.tip_reading + band),
                       alpha=0.3, color="C0", label="95 % band")
    ax[0].plot(t, 1e3 * est.tip_reading, "C0", lw=1.0, label=est.label)
    ax[0].plot(t, 1e3 * run.deflection, "k", lw=0.8, label="lab gauge (held out)")
    ax[0].set_ylabel("tip deflection (mm)")
    ax[1].plot(t, run.theta, "k", lw=0.8, label="encoder")
    ax[1].plot(t, est.hub, "C0", lw=0.8, label="estimate")
    ax[1].set_ylabel("hub angle (rad)")
    ax[1].set_xlabel("t (s)")
    m = est.metrics
    finish_figure(fig, ax, path, f"{run.name}: tip RMS {m.get('tip_rms_mm', 0):.2f} mm, "
                  f"in band {100 * m.get('coverage_95', 0):.0f} %")
