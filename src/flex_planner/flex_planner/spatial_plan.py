"""``flex-twin plan`` on a spatial arm (issue 25): the static-flexible inverse of every tip
waypoint (:mod:`flex_planner.spatial_inverse`) and a rest-to-rest joint trajectory through
them. The waypoint file (YAML)::

    coordinates: [x, y, z]          # optional: the task coordinates (default all three);
                                    # with roll, pitch, yaw (all three, rad, URDF fixed
                                    # axes) the tip frame's orientation too
    guess: [0.0, 0.3, -0.6]         # optional: joint values (rad or m) to start from
    waypoints:                      # tip positions (m, base frame) and times (s)
      - {t: 0.0, x: 0.9, y: 0.0, z: 0.4}
      - {t: 2.0, x: 0.8, y: 0.3, z: 0.5}

Each waypoint's inversion starts from the previous solution (the first from ``guess``).
Between waypoints each joint follows the quintic rest-to-rest polynomial
10 s^3 - 15 s^4 + 6 s^5 (zero rate and acceleration at the waypoints). Output: plan.csv
(t, <joint>_position, _velocity, _acceleration and, on arms with rigid driven joints, the
nominal torque _effort along the path: flex_planner.spatial_nominal) and a JSON/text
summary with the static tip error of every waypoint (forward statics at the inverse).
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from flex_model.config import Fields, read_yaml

from .spatial_inverse import (COORDINATES, ORIENTATION, check_joint_count, invert_tip_pose,
                              invert_tip_position)


def load_spatial_waypoints(path, n_joints: int):
    """(coordinates, guess or None, times, targets) of a spatial waypoint file; errors
    name the file and the field."""
    source = str(path)
    f = Fields(read_yaml(path), source, "")
    coords = f.raw("coordinates", list(COORDINATES))
    allowed = "a list of distinct x, y, z (at least one) and optionally roll, pitch, yaw " \
        "(all three)"
    if not isinstance(coords, list) or not coords or len(set(coords)) != len(coords) or \
            any(c not in COORDINATES + ORIENTATION for c in coords) or \
            not any(c in COORDINATES for c in coords) or \
            sum(c in ORIENTATION for c in coords) not in (0, 3):
        raise f.error("coordinates", coords, allowed)
    guess = np.array(f.vector("guess", n_joints, unit="rad or m")) if f.has("guess") else None
    rows = f.items("waypoints", min_len=1)
    f.done(["coordinates", "guess", "waypoints"])
    times, targets = [], []
    for i, raw in enumerate(rows):
        wf = Fields(raw, source, f"waypoints[{i}]")
        t = wf.number("t", nonnegative=True, unit="s")
        if times and t <= times[-1]:
            raise wf.error("t", t, f"a time > {times[-1]:g} s (increasing)")
        times.append(t)
        targets.append([wf.number(c, unit="rad" if c in ORIENTATION else "m")
                        for c in coords])
        wf.done(["t"] + list(coords))
    return tuple(coords), guess, np.array(times), np.array(targets)


def quintic_path(times, values, sample_period: float):
    """Rest-to-rest quintic between successive joint vectors: (t, pos, vel, acc)."""
    t = np.arange(0.0, times[-1] + 0.5 * sample_period, sample_period)
    pos = np.empty((len(t), values.shape[1]))
    vel, acc = np.zeros_like(pos), np.zeros_like(pos)
    pos[:] = values[0]
    for k in range(1, len(times)):
        T = times[k] - times[k - 1]
        sel = (t > times[k - 1]) & (t <= times[k])
        s = (t[sel] - times[k - 1]) / T
        d = values[k] - values[k - 1]
        pos[sel] = values[k - 1] + np.outer(10 * s**3 - 15 * s**4 + 6 * s**5, d)
        vel[sel] = np.outer((30 * s**2 - 60 * s**3 + 30 * s**4) / T, d)
        acc[sel] = np.outer((60 * s - 180 * s**2 + 120 * s**3) / T**2, d)
    return t, pos, vel, acc


def cmd_spatial_plan(args) -> int:
    from flex_model.spatial.analysis import static_equilibrium
    from flex_model.spatial.loader import load_spatial_arm
    from flex_model.spatial.dynamics import SpatialArmModel

    for attr, flag in (("task", "--task"), ("elbow", "--elbow"),
                       ("vars_per_link", "--vars-per-link")):
        if getattr(args, attr, None) is not None:
            raise ValueError(f"{flag}: not available for a spatial arm ({args.arm}); give a "
                             "spatial waypoint file (flex_planner.spatial_plan)")
    if args.waypoints is None:
        raise ValueError("waypoints: a spatial arm needs a waypoint YAML file (x, y, z)")
    model = SpatialArmModel(load_spatial_arm(args.arm))
    raw = read_yaml(Path(args.waypoints)).get("coordinates", list(COORDINATES))
    if isinstance(raw, list) and raw and all(c in COORDINATES + ORIENTATION for c in raw):
        check_joint_count(model, [c for c in raw if c in COORDINATES] or ["x"],
                          orientation=any(c in ORIENTATION for c in raw))  # refusal first
    coords, guess, times, targets = load_spatial_waypoints(Path(args.waypoints),
                                                           model.n_links)
    pos = [k for k, c in enumerate(coords) if c in COORDINATES]
    rot = [coords.index(c) for c in ORIENTATION if c in coords]
    coords_p = tuple(coords[k] for k in pos)
    t0 = time.perf_counter()
    sols, checks = [], []
    theta = guess
    idx = [COORDINATES.index(c) for c in coords_p]
    for k, (tk, p) in enumerate(zip(times, targets)):
        if rot:
            inv = invert_tip_pose(model, p[pos], p[rot], coords_p, theta)
        else:
            inv = invert_tip_position(model, p, coords, theta)
        theta = inv.joint_values
        fwd = static_equilibrium(model, theta).tip_position
        sols.append(theta.copy())
        checks.append({"index": k, "t_s": float(tk), "target_m": p[pos].tolist(),
                       "joint_values": theta.tolist(), "newton_iterations": inv.iterations,
                       "static_tip_m": fwd.tolist(),
                       "static_tip_error_m": float(np.linalg.norm(fwd[idx] - p[pos]))})
        if rot:
            checks[-1]["target_rpy_rad"] = p[rot].tolist()
            checks[-1]["static_tip_rpy_rad"] = inv.tip_rpy.tolist()
            checks[-1]["static_orientation_error_rad"] = inv.error_rad
    t, jpos, vel, acc = quintic_path(times, np.array(sols), args.sample_period)
    # the nominal joint torques along the path (thesis Ch. V.1 in 3D: the links' deformation
    # under the prescribed motion, flex_planner.spatial_nominal); rigid, driven joints only
    from .spatial_nominal import NotDrivenError, spatial_nominal_input
    from .trajectories import SampledTrajectory
    try:
        nominal = spatial_nominal_input(model, SampledTrajectory(t, jpos, vel, acc))
        effort, note = nominal.tau, None
    except NotDrivenError as exc:
        effort, note = None, str(exc)
    except (RuntimeError, np.linalg.LinAlgError) as exc:     # the path is still written
        effort, note = None, f"failed: {exc}"
    wall = time.perf_counter() - t0
    from flex_model.command import run_dir
    out = run_dir(args.out, f"plan-{Path(args.waypoints).stem}")
    csv = out / "plan.csv"
    fields = ("position", "velocity", "acceleration") + (("effort",) if note is None else ())
    names = ["t"] + [f"{j}_{f}" for f in fields for j in model.arm.joint_names]
    cols = [t, jpos, vel, acc] + ([effort] if note is None else [])
    np.savetxt(csv, np.column_stack(cols), delimiter=",", header=",".join(names),
               comments="", fmt="%.17g")
    summary = {"arm": model.arm.name, "spatial": True, "coordinates": list(coords),
               "samples": len(t), "wall_s": wall, "waypoints": checks, "csv": str(csv),
               "nominal_torque": "in plan.csv (<joint>_effort)" if note is None else
               f"none: {note}"}
    if args.json:
        print(json.dumps(summary))
        return 0
    print(f"plan on spatial arm {model.arm.name} (task coordinates {', '.join(coords)}): "
          f"{len(checks)} waypoints inverted in {wall:.3f} s, {len(t)} samples")
    for c in checks:
        print(f"  waypoint {c['index']} at t = {c['t_s']:g} s: joint values "
              + ", ".join(f"{a:.6f}" for a in c["joint_values"])
              + f", static tip error {c['static_tip_error_m']:.2e} m")
    print(f"  nominal torques: {summary['nominal_torque']}")
    print(f"  wrote {csv}")
    return 0
