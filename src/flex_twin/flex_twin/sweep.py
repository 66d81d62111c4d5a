"""``flex-twin sweep``: a scenario over a grid or a Monte-Carlo draw of its parameters.

    flex-twin sweep seed002_step --vary payload.mass=0:2:0.25 --out runs/sweep
    flex-twin sweep thesis_three_link_pd --vary control.pd.kp[0]=2000,5000,10000 \\
        --vary arm.links[0].material.E=normal:70e9:3.5e9 --samples 20 --seed 1

A ``--vary PATH=SPEC`` sets one field of the scenario YAML (``control.pd.kd[1]``,
``duration``) or of its arm (``arm.payload.mass``, ``arm.links[0].section.side``; the arm's
own top-level keys ``payload``, ``links``, ``joints``, ``effects`` and ``sensors`` may omit
``arm.``). SPEC is a grid ``start:stop:step`` (stop included), a list ``a,b,c``, a value, or
a random draw ``uniform:low:high`` / ``normal:mean:sd`` (``--samples`` draws per grid point,
``--seed`` for the generator). Every point is validated like a scenario file: a bad value
names the point, the field and what is allowed.

Each point is one task of the batch executor (:mod:`flex_twin.cluster`: local processes, or
a Dask cluster with ``--scheduler``). Per point: the tip's peak elastic deflection (the tip
against the rigid tip of the same joint angles), the residual vibration (max distance of the
tip from its final position after ``--after`` s, seed 002's radius of residual vibration
about the goal), the final tip error against the rigid tip at the PD set-points, and the
wall time. Writes ``sweep.csv``, ``sweep.json`` and ``sweep.png``.
"""
from __future__ import annotations

import argparse
import copy
import csv
import itertools
import json
import re
import sys
import time
from concurrent.futures import as_completed
from pathlib import Path

import numpy as np

from flex_model.arm import resolve_preset
from flex_model.config import ConfigError, read_yaml
from flex_model.scenario import SCENARIO_DIR, scenario_from_dict
from flex_model.simulate import SimulationDivergedError
from flex_model.statics import StaticConvergenceError

ARM_KEYS = ("payload", "links", "joints", "effects", "sensors")
METRICS = ("tip_peak_deflection_m", "residual_vibration_m", "tip_final_error_m")
_STEP = re.compile(r"^([A-Za-z_]\w*)((?:\[\d+\])*)$")
_NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"


def parse_path(path: str) -> list:
    """'arm.links[0].section.side' -> ['arm', 'links', 0, 'section', 'side']."""
    keys = []
    for part in path.split("."):
        m = _STEP.match(part)
        if not m:
            raise ValueError(f"--vary: bad field path {path!r} at {part!r}; expected names "
                             "and [index]es such as control.pd.kp[0] or arm.payload.mass")
        keys.append(m.group(1))
        keys += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    if keys[0] in ARM_KEYS:
        keys.insert(0, "arm")
    return keys


def parse_spec(text: str):
    """A grid/list/value -> ('grid', values); a draw -> ('uniform'|'normal', a, b)."""
    m = re.fullmatch(rf"(uniform|normal):({_NUMBER}):({_NUMBER})", text)
    if m:
        a, b = float(m.group(2)), float(m.group(3))
        if (m.group(1) == "uniform" and not b > a) or (m.group(1) == "normal" and not b > 0):
            raise ValueError(f"--vary: {text!r}: expected uniform:low:high with high > low "
                             "or normal:mean:sd with sd > 0")
        return (m.group(1), a, b)
    m = re.fullmatch(rf"({_NUMBER}):({_NUMBER}):({_NUMBER})", text)
    if m:
        a, b, step = (float(g) for g in m.groups())
        if not step > 0 or b < a:
            raise ValueError(f"--vary: {text!r}: expected start:stop:step with stop >= start "
                             "and step > 0")
        n = int(np.floor((b - a) / step + 1e-9)) + 1
        if n > 10000:
            raise ValueError(f"--vary: {text!r} gives {n} values; at most 10000")
        return ("grid", [a + k * step for k in range(n)])
    try:
        return ("grid", [float(v) for v in text.split(",")])
    except ValueError:
        raise ValueError(f"--vary: bad values {text!r}; expected start:stop:step, a,b,c, a "
                         "value, uniform:low:high or normal:mean:sd") from None


def parse_vary(items) -> list:
    """['PATH=SPEC', ...] -> [(path text, keys, spec)]."""
    out = []
    for item in items:
        path, sep, spec = item.partition("=")
        if not sep or not path or not spec:
            raise ValueError(f"--vary: got {item!r}; expected PATH=SPEC, e.g. "
                             "payload.mass=0:2:0.25")
        out.append((path, parse_path(path), parse_spec(spec)))
    return out


def points(vary: list, samples: int, seed: int) -> list:
    """Every point: {path text: value}; the grid's product, with ``samples`` random draws
    of the random specs at each grid point."""
    grid = [(p, s[1]) for p, _, s in vary if s[0] == "grid"]
    draws = [(p, s) for p, _, s in vary if s[0] != "grid"]
    rng = np.random.default_rng(seed)
    out = []
    for combo in itertools.product(*[vals for _, vals in grid]) if grid else [()]:
        base = {p: v for (p, _), v in zip(grid, combo)}
        for _ in range(samples if draws else 1):
            pt = dict(base)
            for p, (kind, a, b) in draws:
                pt[p] = float(rng.uniform(a, b) if kind == "uniform" else rng.normal(a, b))
            out.append(pt)
    return out


def scenario_document(name_or_path) -> tuple:
    """(scenario mapping with its arm inlined, base directory, source) of a scenario."""
    path = resolve_preset(name_or_path, SCENARIO_DIR)
    data = read_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(str(path), "<file>", data, "a mapping")
    arm = data.get("arm")
    if isinstance(arm, str):
        local = path.parent / arm
        arm_path = local if local.suffix in (".yaml", ".yml") and local.exists() \
            else resolve_preset(arm)
        data = dict(data, arm=read_yaml(arm_path))
    return data, path.parent, str(path)


def _assign(doc: dict, keys: list, value, path: str) -> None:
    node = doc
    for k, nxt in zip(keys[:-1], keys[1:]):
        try:
            child = node[k]
        except (KeyError, IndexError, TypeError):
            if isinstance(k, str) and isinstance(node, dict) and not isinstance(nxt, int):
                child = node[k] = {}
            else:
                raise ValueError(f"--vary {path}: no field {k!r} in the scenario") from None
        node = child
    try:
        if isinstance(keys[-1], int) != isinstance(node, list):
            raise TypeError
        node[keys[-1]] = value
    except (IndexError, TypeError):
        raise ValueError(f"--vary {path}: no field {keys[-1]!r} in the scenario") from None


def point_scenario(doc: dict, base_dir, source: str, vary: list, point: dict):
    """The validated scenario of one point."""
    d = copy.deepcopy(doc)
    for path, keys, _ in vary:
        _assign(d, keys, point[path], path)
    label = ", ".join(f"{p} = {v:g}" for p, v in point.items())
    return scenario_from_dict(d, f"{source} [{label}]", base_dir)


def metrics(result, setpoints, after: float) -> dict:
    """Tip peak elastic deflection, residual vibration after ``after`` s, final tip error
    against the rigid tip at the set-points (m)."""
    model = result.model
    tip = result.tip_positions
    rigid = np.array([model.link_origins(model.q_from_joint_angles(th))[-1]
                      for th in result.joint_angles])
    late = result.t >= after - 1e-12
    out = {"tip_peak_deflection_m": float(np.max(np.linalg.norm(tip - rigid, axis=1))),
           "residual_vibration_m": float(np.max(np.linalg.norm(tip[late] - tip[-1], axis=1)))
           if np.any(late) else float("nan"),
           "tip_final_error_m": float("nan")}
    if setpoints is not None:
        goal = model.link_origins(model.q_from_joint_angles(setpoints))[-1]
        out["tip_final_error_m"] = float(np.linalg.norm(tip[-1] - goal))
    return out


def default_after(scenario) -> float:
    """The end of the last load (pulse or payload change), else 0."""
    ends = [p.end for p in scenario.pulses] + [c[0] for c in scenario.payload_changes]
    return max(ends, default=0.0)


#: the scenario fields that change the discretization: a sweep over one of them checks the
#: step advice at every point, otherwise once (run_sweep)
DISCRETIZATION = ("integrator", "vars_per_link", "kinematics")


def run_point(task) -> dict:
    """A sweep task: (doc, base_dir, source, vary, point, after, advise) -> the point's row
    (``advice``: the point's step-advice warning when ``advise``, else empty)."""
    doc, base_dir, source, vary, point, after, advise = task
    t0 = time.perf_counter()
    row = dict(point, advice="")
    try:
        sc = point_scenario(doc, base_dir, source, vary, point)
        row["advice"] = (sc.advice().warning or "") if advise else ""
        res = sc.run(advise=False)
        row.update(metrics(res, sc.pd.setpoints if sc.pd is not None else None,
                           default_after(sc) if after is None else after))
        row["error"] = ""
    except (ConfigError, ValueError, ArithmeticError, np.linalg.LinAlgError,
            SimulationDivergedError, StaticConvergenceError) as exc:
        row.update({m: float("nan") for m in METRICS})
        row["error"] = f"{type(exc).__name__}: {exc}"
    row["wall_s"] = time.perf_counter() - t0
    return row


def run_sweep(scenario, vary_items, out, executor, samples: int = 20, seed: int = 0,
              after: float | None = None, plot: bool = True, log=None) -> list:
    """Run every point on ``executor``; write sweep.csv/json/png to ``out``; rows in point
    order."""
    doc, base_dir, source = scenario_document(scenario)
    vary = parse_vary(vary_items)
    if not vary:
        raise ValueError("--vary: give at least one PATH=SPEC")
    if samples < 1:
        raise ValueError(f"--samples: got {samples}; expected >= 1")
    pts = points(vary, samples, seed)
    first = point_scenario(doc, base_dir, source, vary, pts[0])   # a bad path fails here
    # the step advice (Scenario.advice: the run's window about 10 times over) once, on the
    # first point, unless the sweep varies the discretization itself
    each = any(keys[0] in DISCRETIZATION for _, keys, _ in vary)
    try:
        advice = None if each else first.advice().warning
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, SimulationDivergedError,
            StaticConvergenceError) as exc:   # the first point's row reports it too
        advice = f"not checked: {type(exc).__name__}: {exc}"
    if advice and log:
        log(f"step advice (the discretization of every point): {advice}")
    futures = {executor.submit(run_point, (doc, base_dir, source, vary, p, after, each)): i
               for i, p in enumerate(pts)}
    rows = [None] * len(pts)
    for done, fut in enumerate(as_completed(futures), 1):
        rows[futures[fut]] = r = fut.result()
        if log:
            what = r["error"] or f"residual {1e3 * r['residual_vibration_m']:.3f} mm"
            log(f"[{done}/{len(pts)}] " + ", ".join(f"{p} = {r[p]:g}" for p in pts[0])
                + f": {what}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cols = list(pts[0]) + list(METRICS) + ["wall_s", "advice", "error"]
    with open(out / "sweep.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, cols)
        w.writeheader()
        w.writerows(rows)
    (out / "sweep.json").write_text(json.dumps(
        {"scenario": source, "vary": vary_items, "samples": samples, "seed": seed,
         "advice": advice, "points": rows}, indent=1, default=float))
    if plot:
        plot_sweep(rows, list(pts[0]), out / "sweep.png", Path(source).stem)
    return rows


def plot_sweep(rows, params, path, title) -> None:
    """Residual vibration and peak deflection against the first parameter (a line per value
    of the others, at most 8; points for random draws)."""
    from flex_model.plots import finish_figure, plt
    x = params[0]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    groups: dict = {}
    for r in rows:
        groups.setdefault(tuple(r[p] for p in params[1:]), []).append(r)
    for key, rs in list(groups.items())[:8]:
        rs = sorted(rs, key=lambda r: r[x])
        label = ", ".join(f"{p} = {v:g}" for p, v in zip(params[1:], key)) or None
        style = "o-" if len(rs) <= 200 and len(groups) < len(rows) else "o"
        for ax, m in zip(axes, ("residual_vibration_m", "tip_peak_deflection_m")):
            ax.plot([r[x] for r in rs], [1e3 * r[m] for r in rs], style, ms=3, label=label)
    for ax, m in zip(axes, ("residual vibration (mm)", "tip peak elastic deflection (mm)")):
        ax.set_xlabel(x)
        ax.set_ylabel(m)
    finish_figure(fig, axes, path, f"sweep of {title}")


def add_sweep_parser(sub) -> None:
    sp = sub.add_parser("sweep", help="a scenario over a grid or Monte-Carlo draw of its "
                        "parameters (locally or on a Dask cluster)", description=__doc__,
                        formatter_class=argparse.RawDescriptionHelpFormatter)
    sp.add_argument("scenario", help="scenario preset name or YAML path")
    sp.add_argument("--vary", action="append", default=[], metavar="PATH=SPEC",
                    help="field and values (repeatable)")
    sp.add_argument("--samples", type=int, default=20, help="random draws per grid point")
    sp.add_argument("--seed", type=int, default=0, help="seed of the random draws")
    sp.add_argument("--after", type=float, default=None,
                    help="residual vibration from this time (s; default: the last load's end)")
    sp.add_argument("--out", default=None, help="output directory (default runs/<time>-sweep)")
    sp.add_argument("--scheduler", default=None,
                    help="Dask scheduler address tcp://HOST:PORT or scheduler file")
    sp.add_argument("--workers", type=int, default=None, help="local processes")
    sp.add_argument("--no-plot", action="store_true")
    sp.add_argument("--json", action="store_true", help="print the rows as JSON")
    sp.set_defaults(func=cmd_sweep)


def cmd_sweep(args) -> int:
    from flex_model.command import run_dir
    from .cluster import batch_executor
    out = run_dir(args.out, "sweep")
    with batch_executor(args.scheduler, args.workers) as ex:
        rows = run_sweep(args.scenario, args.vary, out, ex, args.samples, args.seed,
                         args.after, plot=not args.no_plot,
                         log=lambda s: print(s, file=sys.stderr, flush=True))
    bad = sum(1 for r in rows if r["error"])
    if args.json:
        print(json.dumps(rows, indent=1, default=float))
    else:
        print(f"{len(rows)} points ({bad} failed): {out}/sweep.csv, {out}/sweep.png")
    return 1 if bad == len(rows) else 0
