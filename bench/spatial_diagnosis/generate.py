"""Recordings of a spatial arm made by an independent simulator, with effects hidden per
bending plane: the data of the spatial diagnosis tests (issue 25).

The arm and the experiment are those of ``bench/bench_spatial_exudyn.py`` (a two-link L arm
in the horizontal plane, both links bending in two planes and twisting; the static
equilibrium under gravity with the joints held, then a sin^2 torque pulse, joints free,
1 s), run by Exudyn's geometrically exact beams (16 elements per link, 0.5 ms: 0.35-0.7 %
from its 64-element reference). A case scales one section stiffness of the Exudyn arm
only, or adds viscous friction to a joint (a torsional damper across it; the geometrically
exact beam ignores Exudyn's section damping matrix, so no per-plane damping is hidden);
the twin keeps the nominal arm.

    python bench/spatial_diagnosis/generate.py --out test/data/spatial_independent

writes per case ``recording.csv`` (t, q1, q2 (rad), tau1, tau2 (N m),
link<i>_tip_deflection_y|z (m), link<i>_tip_twist (rad): the spatial scenario CSV's
columns) and ``truth.yaml``; the nominal arm is ``arm.yaml`` beside them. Exudyn runs in
bench/.venv-peer (``python3 bench/peer_exudyn.py --ensure-venv``); the product and the
tests never import it.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
BENCH = os.path.dirname(HERE)
PEER_PY = os.path.join(BENCH, ".venv-peer", "bin", "python")
#: case -> (link, section field, scale) of the Exudyn arm (None: healthy)
CASES = {
    "healthy": [],
    "link1-EI_y-0.8": [("link1", "EI_y", 0.8)],       # link 1 softer out of plane (w)
    "link2-EI_z-0.75": [("link2", "EI_z", 0.75)],     # link 2 softer in plane (v)
    "link1-GJ-0.7": [("link1", "GJ", 0.7)],           # link 1 softer in torsion
    "joint2-viscous-0.05": [("joint2", "viscous", 0.05)],   # N m s/rad in joint 2
    # two at once: link 2 softer in plane and joint 1 with viscous friction
    "two-link2-EI_z-0.8+joint1-viscous-0.1": [("link2", "EI_z", 0.8),
                                               ("joint1", "viscous", 0.1)],
}
N_EL, H, DURATION = 16, 5e-4, 1.0


def _peer(case: str) -> int:
    sys.path.insert(0, BENCH)
    import bench_spatial_exudyn as b
    arm = json.loads(json.dumps(b.arm_dict(4)))   # the nominal arm, before the change
    for link, field, value in CASES[case]:   # (link or joint, field, scale or value)
        sec = b.SEC1 if link == "link1" else b.SEC2
        if field == "viscous":
            b.JOINT_VISCOUS[int(link[-1]) - 1] = value
        else:
            sec[field] *= value
    out = b.run_exudyn(N_EL, H, DURATION)
    out["tau"] = (b.pulse(np.array(out["t"]))[:, None] * np.array(b.TAU)[None, :]).tolist()
    out["arm"] = arm
    print("JSON" + json.dumps(out))
    return 0


def _write(out_dir: str, case: str, res: dict) -> None:
    import yaml
    d = os.path.join(out_dir, case)
    os.makedirs(d, exist_ok=True)
    t = np.array(res["t"])
    cols = {"t": t}
    q = np.radians(np.array(res["q"]))
    tau = np.array(res["tau"])
    for i in range(2):
        cols[f"q{i + 1}"] = q[:, i]
    for i in range(2):
        cols[f"tau{i + 1}"] = tau[:, i]
    for lk in ("link1", "link2"):
        cols[f"{lk}_tip_deflection_y"] = np.array(res[f"{lk}_v"])
        cols[f"{lk}_tip_deflection_z"] = np.array(res[f"{lk}_w"])
        cols[f"{lk}_tip_twist"] = np.array(res[f"{lk}_phi"])
    data = np.column_stack(list(cols.values()))
    np.savetxt(os.path.join(d, "recording.csv"), data, delimiter=",", fmt="%.10e",
               header=",".join(cols), comments="")
    truth = {"case": case, "simulator": f"Exudyn ObjectBeamGeometricallyExact, {N_EL} "
             f"elements per link, h {H} s", "hidden": [
                 {"target": t, "field": fld, "value": v} for t, fld, v in CASES[case]]}
    with open(os.path.join(d, "truth.yaml"), "w") as f:
        yaml.safe_dump(truth, f, sort_keys=False)
    arm_path = os.path.join(out_dir, "arm.yaml")
    if not os.path.exists(arm_path):
        arm = res["arm"]
        arm["name"] = "exudyn_l_arm_nominal"
        arm["convention"] = "standard_dh"      # marks a spatial arm file
        with open(arm_path, "w") as f:
            f.write("# the nominal arm of bench/bench_spatial_exudyn.py (4 variables per "
                    "direction)\n")
            yaml.safe_dump(arm, f, sort_keys=False)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="test/data/spatial_independent")
    ap.add_argument("--only", nargs="*", choices=list(CASES))
    ap.add_argument("--peer", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.peer:
        return _peer(args.peer)
    if not os.path.exists(PEER_PY):
        print("bench/.venv-peer is missing: python3 bench/peer_exudyn.py --ensure-venv")
        return 1
    for case in args.only or CASES:
        r = subprocess.run([PEER_PY, os.path.abspath(__file__), "--peer", case],
                           capture_output=True, text=True)
        line = next((x for x in r.stdout.splitlines() if x.startswith("JSON")), None)
        if line is None:
            print(r.stdout[-2000:], r.stderr[-3000:])
            return 1
        res = json.loads(line[4:])
        _write(args.out, case, res)
        print(f"{case}: {len(res['t'])} samples, Exudyn {res['cpu']:.1f} s CPU")
    return 0


if __name__ == "__main__":
    sys.exit(main())
