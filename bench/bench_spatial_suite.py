"""Benchmark of the diagnosis on the spatial independent (Exudyn) suite (issue 44, item 4).

    python bench/independent_suite/generate_spatial.py --out runs/spatial_suite
    python bench/bench_spatial_suite.py [--suite runs/spatial_suite] [--subset all|PATTERNS]
        [--workers W] [--out bench/results/spatial_suite] [--resume] [--report-only]

Every case of the spatial suite (generate_spatial.py: a two-link L arm of geometrically
exact 3D beams under a continuous or sampled PD, healthy, one-effect and two-effect runs)
is diagnosed as a user would (:func:`flex_twin.diagnosis.batch.diagnose_run`: the planar
engine, the spatial arm through diagnosis/spatial_loop.py) and scored against its
truth.yaml as the planar suite is (bench_independent_suite.py: healthy clean, right effect,
wrong names, both effects of two-effect runs, parameter error). The truth's
``bending_stiffness`` (plane y or z: the section's EI_y or EI_z scaled) is the hypothesis
``bending_stiffness_<plane>``; its parameter error compares the stated section value.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_independent_suite as planar  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: the spatial suite's classes (a plane's stiffness is named per plane: no equivalence)
CLASSES = {"joint_friction": ("joint_friction",), "payload": ("payload",),
           "joint_elasticity": ("joint_elasticity",),
           "bending_stiffness_y": ("bending_stiffness_y",),
           "bending_stiffness_z": ("bending_stiffness_z",),
           "torsion_stiffness": ("torsion_stiffness",)}
KEY_PARAMETERS = {"joint_friction": ("viscous", "coulomb"), "payload": ("mass",),
                  "joint_elasticity": ("stiffness",), "bending_stiffness_y": ("EI_y",),
                  "bending_stiffness_z": ("EI_z",), "torsion_stiffness": ("GJ",)}
#: issue 44's acceptance for the spatial suite
TARGETS = {"healthy_none": 0.95, "right_all_effect_runs": 0.95, "wrong_name_runs": 0.03,
           "two_both_named": 0.90, "parameter_error_median": 0.05}


def _nominal_sections(case: Path) -> list:
    arm = yaml.safe_load((case / "arm.yaml").read_text())
    return [lk["flexible"]["section"] for lk in arm["links"]]


def spatial_truth(case: Path) -> dict:
    """truth.yaml in the hypotheses' vocabulary: a plane's stiffness as
    bending_stiffness_<plane> with the section value it states."""
    truth = yaml.safe_load((case / "truth.yaml").read_text())
    secs = _nominal_sections(case)
    hidden = []
    for h in truth.get("hidden") or []:
        h = dict(h)
        p = h["parameters"]
        if h["kind"] == "bending_stiffness":
            field = "EI_" + p["plane"]
            h["kind"] = "bending_stiffness_" + p["plane"]
            h["parameters"] = {field: secs[int(h["target"][-1]) - 1][field] * p["scale"]}
        elif h["kind"] == "torsion_stiffness":
            h["parameters"] = {"GJ": secs[int(h["target"][-1]) - 1]["GJ"] * p["scale"]}
        hidden.append(h)
    truth["hidden"] = hidden
    return truth


def run_case(case: Path, out: Path, executor, progress: bool = False) -> dict:
    from flex_twin.diagnosis.batch import RunSpec, diagnose_run
    truth = spatial_truth(case)
    row = {"case": case.name, "hidden": truth["hidden"], "expected": truth.get("expected")}
    t0, c0 = time.perf_counter(), planar._cpu_s(executor)
    try:
        s = diagnose_run(RunSpec.from_case_dir(case), str(out / case.name), plots=False,
                         executor=executor, progress=progress)
    except (ValueError, FileNotFoundError, ArithmeticError) as exc:
        row.update(error=f"{type(exc).__name__}: {exc}", wall_s=time.perf_counter() - t0,
                   cpu_s=planar._cpu_s(executor) - c0)
        return row
    import os
    row.update(wall_s=time.perf_counter() - t0, cpu_s=planar._cpu_s(executor) - c0,
               load=os.getloadavg()[0], score=planar.score(truth, s), stop=s.get("stop"),
               cost=s.get("cost"))
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default=str(ROOT / "runs" / "spatial_suite"))
    ap.add_argument("--subset", default="all", help="all, or case-id patterns a,b (fnmatch)")
    ap.add_argument("--workers", type=int, default=1, help="local processes of a diagnosis")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "spatial_suite"))
    ap.add_argument("--runs-dir", default=str(ROOT / "runs" / "bench_spatial_suite"))
    ap.add_argument("--resume", action="store_true")
    ap.add_argument("--progress", action="store_true")
    ap.add_argument("--report-only", action="store_true")
    args = ap.parse_args(argv)
    planar.CLASSES.clear()
    planar.CLASSES.update(CLASSES)
    planar.KEY_PARAMETERS.clear()
    planar.KEY_PARAMETERS.update(KEY_PARAMETERS)
    planar.TARGETS.update(TARGETS)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    res_path = out / "results.json"
    done = {}
    if (args.resume or args.report_only) and res_path.is_file():
        done = {r["case"]: r for r in json.loads(res_path.read_text())["runs"]}
    if not args.report_only:
        cases = planar.list_cases(Path(args.suite), args.subset)
        from flex_twin.cluster import local_executor
        ex = local_executor(args.workers)
        try:
            for k, name in enumerate(cases, 1):
                if name in done:
                    continue
                row = run_case(Path(args.suite) / name, Path(args.runs_dir), ex, args.progress)
                done[name] = row
                what = row.get("error") or (f"{row['score']['verdict']}; "
                                            f"{', '.join(row['score']['named']) or '-'}")
                print(f"[{k}/{len(cases)}] {name}: {what} ({row['wall_s']:.0f} s wall, "
                      f"{row.get('cpu_s') or 0:.0f} s CPU)", file=sys.stderr, flush=True)
                res_path.write_text(json.dumps({"runs": list(done.values())}, indent=1,
                                               default=float))
        finally:
            if hasattr(ex, "shutdown"):
                ex.shutdown()
    rows = sorted(done.values(), key=lambda r: r["case"])
    summary = planar.summarise(rows)
    text = planar.table(summary, rows).replace("Independent (Exudyn) suite",
                                               "Spatial independent (Exudyn) suite")
    (out / "summary.json").write_text(json.dumps(summary, indent=1, default=float))
    (out / "summary.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
