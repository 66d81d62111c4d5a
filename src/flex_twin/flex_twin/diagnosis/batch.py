"""Many runs diagnosed at once: a folder, a glob or a manifest of runs -> one summary table.

A team with many arms records a run per arm per night; each run is diagnosed on its own
(:func:`diagnose_run`, the same workflow as ``flex-twin diagnose`` of one run, written to
``OUT/<run name>/``) and the verdicts are gathered in ``OUT/summary.csv``, ``summary.md``
and ``summary.json``. The runs are the tasks of the batch executor
(:mod:`flex_twin.cluster`: the local process pool, or a Dask cluster with ``--scheduler``);
inside a task a diagnosis runs serially. A run that fails is reported in the table with its
error and the others go on.

Manifest (paths relative to the manifest)::

    runs:
      - name: arm07_2026-12-01          # optional: default the data file's name
        data: arm07/fit.csv             # CSV or rosbag2 directory / .mcap
        holdout: arm07/holdout.csv      # optional (default: the last 40 % of data)
        arm: arm07/nominal_arm.yaml     # optional when --arm is given
        controller: arm07/controller.yaml   # optional when --controller is given
        link_topic: /arm07/link_encoders    # optional: the bag's link-side encoder topic
"""
from __future__ import annotations

import csv
import dataclasses
import glob
import json
import time
from concurrent.futures import as_completed
from dataclasses import dataclass
from pathlib import Path

from flex_model.config import ConfigError, Fields, read_yaml

SUMMARY_COLUMNS = ("run", "verdict", "named", "nominal_holdout_J", "final_holdout_J",
                   "holdout_error_reduction", "wall_s", "report", "error")


@dataclass(frozen=True)
class RunSpec:
    """One run to diagnose (paths as strings: a task crosses process boundaries).
    ``link_topic``: the sensor_msgs/JointState topic of a bag's link-side encoders (None:
    ``ros_recording.LINK_TOPIC``); it travels with the run to the worker that reads it."""

    name: str
    data: str
    arm: str
    controller: str
    holdout: str | None = None
    link_topic: str | None = None

    @classmethod
    def from_case_dir(cls, case) -> "RunSpec":
        """The run of a case directory (recording.csv, arm.yaml, controller.yaml: the
        independent suite's layout, bench/independent_suite/generate.py)."""
        case = Path(case)
        return cls(case.name, str(case / "recording.csv"), str(case / "arm.yaml"),
                   str(case / "controller.yaml"))

    def __post_init__(self):
        t = self.link_topic
        if t is not None and (not t.startswith("/") or any(c.isspace() for c in t)):
            raise ValueError(f"{self.name}: link_topic: got {t!r}; expected an absolute "
                             "topic name such as /flex/link_encoders")


def _is_run(path: Path) -> bool:
    return (path.is_file() and path.suffix in (".csv", ".mcap")) or \
        (path.is_dir() and (path / "metadata.yaml").is_file())


def _unique_names(runs: list) -> list:
    seen: dict = {}
    out = []
    for r in runs:
        k = seen.get(r.name, 0)
        seen[r.name] = k + 1
        out.append(r if k == 0 else dataclasses.replace(r, name=f"{r.name}_{k + 1}"))
    return out


def expand_runs(inputs, arm: str | None, controller: str | None,
                link_topic: str | None = None) -> list:
    """RunSpecs from data paths, folders (every CSV, .mcap and rosbag2 directory in them),
    globs, or a manifest YAML (``runs:``); ``arm``, ``controller`` and ``link_topic``
    apply to every run that does not name its own."""
    runs = []
    for item in inputs:
        p = Path(item)
        if p.suffix in (".yaml", ".yml") and p.is_file():
            runs += _manifest_runs(p, arm, controller, link_topic)
            continue
        if p.is_dir() and not _is_run(p):
            found = sorted(q for q in p.iterdir() if _is_run(q))
            if not found:
                raise ValueError(f"{item}: no run in this folder (CSV, .mcap or rosbag2 "
                                 "directories)")
        elif any(ch in item for ch in "*?["):
            found = sorted(Path(q) for q in glob.glob(item) if _is_run(Path(q)))
            if not found:
                raise ValueError(f"{item}: the pattern matches no run (CSV, .mcap or rosbag2 "
                                 "directory)")
        elif _is_run(p):
            found = [p]
        else:
            raise FileNotFoundError(f"{item}: no such run (a CSV, .mcap, rosbag2 directory, "
                                    "folder of runs, glob or manifest YAML)")
        for q in found:
            if arm is None or controller is None:
                raise ValueError(f"{q}: --arm and --controller are needed for runs given "
                                 "by path (or name them per run in a manifest)")
            runs.append(RunSpec(q.stem if q.is_file() else q.name, str(q), arm, controller,
                                link_topic=link_topic))
    if not runs:
        raise ValueError("no run to diagnose")
    return _unique_names(runs)


def _manifest_runs(path: Path, arm, controller, link_topic=None) -> list:
    f = Fields(read_yaml(path), str(path), "")
    base = path.parent
    out = []
    raw_runs = f.items("runs", min_len=1)
    for k, raw in enumerate(raw_runs):
        rf = Fields(raw, str(path), f"runs[{k}]")

        def rel(key, default=None, rf=rf):
            if not rf.has(key):
                if default is None:
                    raise rf.error(key, None, "a path (relative to the manifest)")
                return default
            value = rf.string(key)
            q = Path(value)
            if q.is_absolute() or (key == "arm" and not (base / q).exists()):
                return value  # an absolute path, or the arm as a preset name
            return str(base / q)

        data = rel("data")
        topic = rf.string("link_topic") if rf.has("link_topic") else link_topic
        try:
            spec = RunSpec(rf.string("name", Path(data).stem), data,
                           rel("arm", arm or ""), rel("controller", controller or ""),
                           rel("holdout", "") or None, topic)
        except ValueError:
            raise rf.error("link_topic", topic, "an absolute topic name such as "
                           "/flex/link_encoders") from None
        if not spec.arm or not spec.controller:
            key = "arm" if not spec.arm else "controller"
            raise rf.error(key, None, f"a path, or --{key} for every run")
        rf.done()
        out.append(spec)
    f.done()
    return out


def load_any_arm(path):
    """A planar arm, or a spatial one (a DH table or URDF side file: the engine takes it
    through spatial_loop.py)."""
    from flex_model.arm import load_arm
    from flex_model.spatial.description import is_spatial_arm
    if is_spatial_arm(path):
        from flex_model.spatial.loader import load_spatial_arm
        return load_spatial_arm(path)
    return load_arm(path)


def diagnose_run(run: RunSpec, out_dir: str, gate: float | None = None,
                 segment: float | None = None, plots: bool = True, executor=None,
                 progress: bool = False, floor: bool = True) -> dict:
    """Diagnose one run (the workflow of ``flex-twin diagnose``) into ``out_dir``; returns
    the report's summary (diagnosis.json) with the wall time."""
    from flex_model.arm import resolve_preset

    from . import spatial_loop
    from .controller import check_integrable, load_controller
    from .engine import DEFAULT_GATE, diagnose
    from .sources import load_recording
    from .report import write_report

    t0 = time.perf_counter()
    arm_path = resolve_preset(run.arm)
    arm = load_any_arm(arm_path)
    controller = load_controller(run.controller)
    if controller.n_joints != arm.n_links:
        raise ValueError(f"{run.controller}: {controller.n_joints} joints in the controller, "
                         f"{arm.n_links} in the arm {arm_path}")
    check_integrable(controller, arm)
    fit = load_recording(run.data, arm.n_links, run.link_topic, arm.gravity)
    holdout = load_recording(run.holdout, arm.n_links, run.link_topic, arm.gravity) \
        if run.holdout else None
    for path, rec in ((run.data, fit), (run.holdout, holdout)):
        if rec is not None and controller.period > 0 and \
                rec.t[-1] - rec.t[0] < controller.period:
            raise ValueError(f"{path}: t: the run lasts {rec.t[-1] - rec.t[0]:.6g} s, shorter "
                             f"than one control step ({controller.period:g} s in "
                             f"{run.controller}): nothing to replay")
    if segment is not None and not segment > 0:
        raise ValueError(f"--segment: got {segment}; expected a time > 0 s")
    if executor is None:
        from ..cluster import SerialExecutor
        executor = SerialExecutor()
    step = {"dt": spatial_loop.MAX_STEP} if spatial_loop.is_spatial(arm) else {}
    d = diagnose(arm, controller, fit, holdout, executor=executor,
                 gate=DEFAULT_GATE if gate is None else gate, segment=segment,
                 progress=progress, floor=floor, **step)
    s = write_report(Path(out_dir), arm_path, d, plots=plots)
    s["wall_s"] = time.perf_counter() - t0
    return s


def _task(args) -> dict:
    """A batch task: one run, its row of the summary (errors become a row too)."""
    run, out_dir, gate, segment, plots, floor = args
    t0 = time.perf_counter()
    row = {"run": run.name, "report": str(Path(out_dir) / "report.md")}
    try:
        s = diagnose_run(run, out_dir, gate, segment, plots, floor=floor)
    except (ConfigError, ValueError, FileNotFoundError, ArithmeticError) as exc:
        row.update(verdict="error", error=f"{type(exc).__name__}: {exc}",
                   wall_s=time.perf_counter() - t0, report="")
        return row
    row.update(verdict=s["verdict"], named=named_text(s["named"]),
               nominal_holdout_J=s["cost"]["nominal_holdout"],
               final_holdout_J=s["cost"]["final_holdout"],
               holdout_error_reduction=s["holdout_error_reduction"], wall_s=s["wall_s"],
               error="")
    return row


def named_text(named: list) -> str:
    """'label (param value, ...)' of each named effect, '; '-separated ('' for none)."""
    return "; ".join(c["label"] + " (" + ", ".join(f"{k} {v:.4g}" for k, v in
                                                   c["parameters"].items()) + ")"
                     for c in named)


def diagnose_many(runs: list, out: Path, executor, gate=None, segment=None, plots=True,
                  log=print, floor: bool = True) -> list:
    """Diagnose every run (one task each) and write the summary table; returns its rows in
    the order of ``runs``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    futures = {executor.submit(_task, (r, str(out / r.name), gate, segment, plots, floor)): i
               for i, r in enumerate(runs)}
    rows = [None] * len(runs)
    for done, fut in enumerate(as_completed(futures), 1):
        i = futures[fut]
        rows[i] = fut.result()
        r = rows[i]
        what = r.get("named") or r["verdict"] if not r.get("error") else r["error"]
        log(f"[{done}/{len(runs)}] {r['run']}: {what} ({r['wall_s']:.0f} s)")
    write_summary(out, rows)
    return rows


def write_summary(out: Path, rows: list) -> None:
    """summary.csv (one row per run), summary.json and summary.md."""
    with open(out / "summary.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, SUMMARY_COLUMNS)
        w.writeheader()
        for r in rows:
            w.writerow({k: r.get(k, "") for k in SUMMARY_COLUMNS})
    (out / "summary.json").write_text(json.dumps({"runs": rows}, indent=1, default=float))
    lines = ["# Diagnosis of many runs", "",
             "| run | verdict | named | held-out J nominal -> final | reduction | wall (s) |",
             "|---|---|---|---|---|---|"]
    for r in rows:
        if r.get("error"):
            lines.append(f"| {r['run']} | error | {r['error']} | | | {r['wall_s']:.0f} |")
            continue
        lines.append(f"| [{r['run']}]({r['run']}/report.md) | {r['verdict']} | "
                     f"{r['named'] or '-'} | {r['nominal_holdout_J']:.3g} -> "
                     f"{r['final_holdout_J']:.3g} | {100 * r['holdout_error_reduction']:.1f} % "
                     f"| {r['wall_s']:.0f} |")
    (out / "summary.md").write_text("\n".join(lines) + "\n")
