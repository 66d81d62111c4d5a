"""``flex-twin modes``, ``static`` and ``simulate`` on spatial arms (issue 25).

An arm is spatial when its file is a spatial arm description (a ``convention`` key: a DH
table, or a ``urdf`` key: a URDF with a side file) or when its name is a preset of
``flex_model/presets/spatial``; the planar options that have no spatial meaning yet are
refused with one line naming the option. The numbers come from
:mod:`flex_model.spatial.analysis` (natural modes of M, K plus the gravity stiffness;
Newton equilibrium with the joints held). ``simulate`` runs every scenario through one
path (flex_twin.cli._simulate) and flex_model.plots.plot_simulation draws its run.
"""
from __future__ import annotations

import json

import numpy as np


def is_spatial(name_or_path) -> bool:
    """True for a spatial arm file or preset name, False for a planar one."""
    from flex_model.spatial.description import is_spatial_arm
    return is_spatial_arm(name_or_path)


def _refuse(args, unsupported: dict) -> None:
    """One line for the first planar-only option given: {attribute: (default, flag)}."""
    for attr, (default, flag) in unsupported.items():
        if getattr(args, attr, default) != default:
            raise ValueError(f"{flag}: not available for a spatial arm ({args.arm}); "
                             "use the planar arm files for it")


def _model_and_joints(args):
    from flex_model.spatial.loader import load_spatial_arm
    from flex_model.spatial.dynamics import SpatialArmModel
    arm = load_spatial_arm(args.arm)
    model = SpatialArmModel(arm)
    values = np.zeros(model.n_links)
    if args.joint_angles_deg is not None:
        if len(args.joint_angles_deg) != model.n_links:
            raise ValueError(f"--joint-angles-deg: got {len(args.joint_angles_deg)} values; "
                             f"expected {model.n_links} (one per joint of {arm.name})")
        for i, (link, x) in enumerate(zip(arm.links, args.joint_angles_deg)):
            # revolute joints in degrees, prismatic ones in metres
            values[i] = np.radians(x) if link.joint.type == "revolute" else x
    return arm, model, values


_COMMON = {"vars_per_link": (None, "--vars-per-link"), "kinematics": (None, "--kinematics"),
           "kp": (None, "--kp")}


def cmd_spatial_modes(args) -> int:
    from flex_model.spatial.analysis import natural_modes
    _refuse(args, {**_COMMON, "kd": (None, "--kd"), "state_space": (None, "--state-space"),
                   "plot": (None, "--plot")})
    if args.joints == "pd":
        raise ValueError(f"--joints pd: not available for a spatial arm ({args.arm}); "
                         "expected clamped or hinged")
    arm, model, values = _model_and_joints(args)
    md = natural_modes(model, values, joints=args.joints, gravity_preload=args.gravity_preload)
    count = len(md.omega) if args.count is None else min(args.count, len(md.omega))
    dominant = []
    for k in range(count):
        s = md.shapes_q[:, k]
        share = {pl: float(np.linalg.norm(s[model.plane_indices(pl)]) ** 2)
                 for pl in ("joints", "v", "w", "phi")}
        dominant.append(max(share, key=share.get))
    out = {"arm": arm.name, "coordinates": int(model.nq), "joints": args.joints,
           "frequencies_hz": [float(f) for f in md.frequencies_hz[:count]],
           "dominant": dominant}
    if args.json:
        print(json.dumps(out))
        return 0
    print(f"{arm.name}: spatial, {model.nq} coordinates, joints {args.joints} "
          "(dominant: v, w bending in the link's two principal planes, phi torsion)")
    print(f"{'mode':>4} {'f [Hz]':>12} {'dominant':>9}")
    for k, (f, d) in enumerate(zip(out["frequencies_hz"], dominant)):
        print(f"{k + 1:>4} {f:12.6g} {d:>9}")
    return 0


def cmd_spatial_static(args) -> int:
    from flex_model.spatial.analysis import static_equilibrium
    _refuse(args, {**_COMMON, "tip_torque": (0.0, "--tip-torque"),
                   "tip_force": (0.0, "--tip-force"), "no_gravity": (False, "--no-gravity")})
    if args.joints != "clamped":
        raise ValueError(f"--joints {args.joints}: not available for a spatial arm "
                         f"({args.arm}); the joints are held at their values")
    arm, model, values = _model_and_joints(args)
    st = static_equilibrium(model, values, linear=not args.nonlinear)
    R = st.tip_rotation
    # roll-pitch-yaw (x-y-z fixed axes, as URDF's rpy) of the tip frame
    rpy = [np.arctan2(R[2, 1], R[2, 2]), -np.arcsin(np.clip(R[2, 0], -1, 1)),
           np.arctan2(R[1, 0], R[0, 0])]
    out = {"arm": arm.name, "analysis": "nonlinear" if args.nonlinear else "linear",
           "tip_position_m": [float(x) for x in st.tip_position],
           "tip_rpy_deg": [float(np.degrees(a)) for a in rpy],
           "links": {k: {n: float(x) for n, x in d.items()} for k, d in st.deflections.items()}}
    if args.json:
        print(json.dumps(out))
        return 0
    x, y, z = out["tip_position_m"]
    print(f"{arm.name} (spatial, {out['analysis']} static, joints held):")
    print(f"  tip position   x {x:10.6f}  y {y:10.6f}  z {z:10.6f} m")
    print("  tip rpy        " + "  ".join(f"{a:9.4f}" for a in out["tip_rpy_deg"]) + " deg")
    for name, d in out["links"].items():
        print(f"  {name}: " + ", ".join(f"{n} {v:.6g}" for n, v in d.items()))
    return 0
