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

import sys
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


def main(argv=None) -> int:
    """The planar suite's command line on the spatial suite, with its classes and truth."""
    planar.CLASSES.clear()
    planar.CLASSES.update(CLASSES)
    planar.KEY_PARAMETERS.clear()
    planar.KEY_PARAMETERS.update(KEY_PARAMETERS)
    return planar.main(argv, doc=__doc__, suite_name="spatial_suite", subset="all", workers=1,
                       truth_of=spatial_truth, title="Spatial independent (Exudyn) suite")


if __name__ == "__main__":
    sys.exit(main())
