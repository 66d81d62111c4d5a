"""Torsion of a spatial yaw + pitch arm against Exudyn's geometrically exact beams (issue 47).

    python bench/bench_spatial_torsion.py [--duration 0.6] [--quick]
    BENCH_KINEMATICS=second_order ...   # ours with the axial shortening (the tip floor)
    BENCH_ROTARY=0 ...      # ours without the bending rotary inertia
    BENCH_TUBE=round30 ...  # a D 30 x 2 mm round tube instead of the 20 x 1 mm square one
    BENCH_PITCH_DEG=30 ...  # link 2 raised by 30 deg (default 0: in line with link 1)
    BENCH_HUB=rotor ...     # the joint inertias as rotors about the joint axis (ours only)

The arm (issue 47): joint 1 yaw (vertical axis z), link 1 (1 m) horizontal along x; at its
tip joint 2 pitch (axis horizontal, normal to link 1: standard DH alpha_1 = 90 deg), link 2
(1 m) in line with link 1 (DH theta_2 = BENCH_PITCH_DEG). Both links an aluminium tube,
20 x 1 mm square (E 70 GPa, G = E / 2.66, rho 2700 kg/m^3; EI 321 N m^2, GJ 180 N m^2 with
Bredt's J = 4 A_m^2 t / s_m = 0.75 I_p, rhoA 0.205 kg/m, rhoJ = rho I_p), a 0.2 kg tip
mass on each link, a 0.05 kg m^2 hub at each joint (a rigid body on the link root,
isotropic: joint 2's sits on link 1's tip), gravity -z, PD kp 200 N m/rad, kd 20 N m s/rad
on both joints about the start pose (its static equilibrium under gravity), then a 20 N m
sin^2 yaw torque pulse over 0.1 s. In line, link 1's twist is a second-order effect: the
yaw bends the links sideways while they droop under gravity.

- Ours: SpatialArmModel, the compiled generalized-alpha loop (rho_inf 0.9) with the PD
  inside (thesis Eq. 95), at several variables and steps.
- Exudyn (bench/.venv-peer only): every link a chain of ObjectBeamGeometricallyExact
  elements with the tube's own section values (EA, GA/chi (chi = 2), GJ, EI; inertia
  diag(rho I_p, rho I, rho I)), tip and hub bodies glued by GenericJoint,
  ObjectJointRevoluteZ joints, the PD as ObjectConnectorTorsionalSpringDamper,
  generalized-alpha rho_inf 0.9, at 16 and 32 elements per link.

Twist phi of link i: the roll angle atan2(R[2, 1], R[2, 2]) of its tip section frame
relative to its root frame, the same formula on both sides (ours from phi, v', w'). Tip:
the last tip point in the base frame. Prints the largest differences over the run.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, BENCH_DIR)
from peer_exudyn import peer_runs  # noqa: E402

E, G_MOD, RHO = 70e9, 70e9 / (2 * 1.33), 2700.0
D_OUT, WALL = 0.030, 0.002
L1 = L2 = 1.0
PITCH0 = np.radians(float(os.environ.get("BENCH_PITCH_DEG", "0")))   # link 2 raised
TIP_MASS, HUB_J = 0.2, 0.05
#: both sides: a small mass on the hubs and a small inertia on the tip masses (Exudyn's
#: glued rigid bodies need a regular mass matrix)
HUB_MASS, TIP_J = 1e-3, 1e-7
KP, KD = 200.0, 20.0
TAU1, T_PULSE = 20.0, 0.1
GRAV = 9.81
SAMPLE = 5e-3           # s, comparison grid (a whole number of every step)
ROTARY = os.environ.get("BENCH_ROTARY", "1") != "0"
HUB = os.environ.get("BENCH_HUB", "body")
TUBE = os.environ.get("BENCH_TUBE", "square20")
KINEMATICS = os.environ.get("BENCH_KINEMATICS", "small_deflection")


def tube():
    """Section: A, Ib (each bending axis), I_p (polar), J (torsion constant). Round tube
    D x t: J = I_p = 2 Ib; BENCH_TUBE=square20: the 20 x 1 mm square tube of issue 47's
    planar arm (J by Bredt, 4 A_m^2 t / s_m = 0.75 I_p)."""
    if TUBE == "square20":
        b, t = 0.020, 0.001
        A = b * b - (b - 2 * t) ** 2
        Ib = (b ** 4 - (b - 2 * t) ** 4) / 12
        bm = b - t
        return A, Ib, 2 * Ib, 4 * bm ** 4 * t / (4 * bm)
    ro, ri = D_OUT / 2, D_OUT / 2 - WALL
    A = np.pi * (ro ** 2 - ri ** 2)
    Ib = np.pi / 4 * (ro ** 4 - ri ** 4)
    return A, Ib, 2 * Ib, 2 * Ib


def section():
    A, Ib, Ip, J = tube()
    return {"EI_y": E * Ib, "EI_z": E * Ib, "GJ": G_MOD * J, "rhoA": RHO * A,
            "rhoJ": RHO * Ip}


def arm_dict(variables: int) -> dict:
    hub = {"mass": HUB_MASS, "inertia": [HUB_J] * 3}
    flex = {"section": section(), "variables": variables, "torsion_variables": variables}
    if ROTARY:
        flex["rotary_inertia"] = True
    tip = {"mass": TIP_MASS, "inertia": [TIP_J] * 3}
    links = [{"name": "link1", "joint": {"name": "yaw", "a": L1, "alpha": float(np.pi / 2)},
              "flexible": dict(flex), "end_body": tip},
             {"name": "link2", "joint": {"name": "pitch", "a": L2, "theta": float(PITCH0)},
              "flexible": dict(flex), "end_body": tip}]
    if HUB == "body":
        for lk in links:
            lk["root_body"] = hub
        return {"name": "yaw_pitch_tubes", "gravity": [0.0, 0.0, -GRAV], "links": links,
                "kinematics": KINEMATICS}
    return {"name": "yaw_pitch_tubes", "gravity": [0.0, 0.0, -GRAV], "links": links,
            "kinematics": KINEMATICS,
            "effects": [{"type": "gear", "joint": j, "ratio": 1.0, "rotor_inertia": HUB_J}
                        for j in ("yaw", "pitch")]}


def pulse(t):
    t = np.asarray(t, float)
    return np.where(t < T_PULSE, np.sin(np.pi * t / T_PULSE) ** 2, 0.0)


def roll(phi, dv, dw):
    """atan2(R[2, 1], R[2, 2]) of R = Ry(-w') Rz(v') Rx(phi) (the tip section frame)."""
    cp, sp, st = np.cos(dw), -np.sin(dw), np.sin(dv)
    return np.arctan2(np.cos(phi) * sp * st + np.sin(phi) * cp,
                      -np.sin(phi) * sp * st + np.cos(phi) * cp)


# ------------------------------------------------------------------ ours

def build_ours(variables: int):
    from flex_model.spatial import SpatialArmModel, spatial_arm_from_dict
    model = SpatialArmModel(spatial_arm_from_dict(arm_dict(variables)))
    K_pd = np.zeros((model.nq, model.nq))
    D_pd = np.zeros((model.nq, model.nq))
    for a in model.actuator_index:
        K_pd[a, a], D_pd[a, a] = KP, KD
    return model, K_pd, D_pd


def run_ours(variables: int, h: float, duration: float) -> dict:
    from flex_model.spatial.integrate import simulate_fixed_compiled
    from flex_model.spatial.scenario import pd_static_equilibrium
    model, K_pd, D_pd = build_ours(variables)
    q0 = pd_static_equilibrium(model, K_pd, np.zeros(2))
    K0 = model.K.copy()
    model.K = model.K + K_pd          # PD inside the loop (thesis Eq. 95)
    n = int(round(duration / h))
    t = h * np.arange(1, n + 1)
    tau = np.zeros((n, 2))
    tau[:, 0] = TAU1 * pulse(t)
    z = np.zeros(model.nq)
    simulate_fixed_compiled(model, q0, z, h, 2, damping=D_pd)     # compile / load
    t0 = time.process_time()
    run = simulate_fixed_compiled(model, q0, z, h, n, joint_torques=tau, damping=D_pd,
                                  rho_inf=0.9, tol=1e-9)
    cpu = time.process_time() - t0
    model.K = K0
    every = int(round(SAMPLE / h))
    q = run.q[::every]
    out = {"t": list(run.t[::every]), "cpu": cpu, "nq": model.nq,
           "q": np.degrees(q[:, model.off]).tolist()}
    d = [model.tip_deflections(qq) for qq in q]
    for lk in ("link1", "link2"):
        for k in ("v", "w"):
            out[f"{lk}_{k}"] = [x[lk][k] for x in d]
        out[f"{lk}_phi"] = [float(roll(x[lk]["phi"], x[lk]["dv"], x[lk]["dw"])) for x in d]
    out["tip"] = [model.tip_position(qq).tolist() for qq in q]
    return out


# ------------------------------------------------------------------ Exudyn (peer venv)

def _rot_x(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _rot_z(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _glued_body(mbs, exu, node, p, R, mass, inertia):
    from exudyn.utilities import (GenericJoint, LoadMassProportional, MarkerBodyMass,
                                  MarkerNodeRigid, NodeRigidBodyEP, ObjectRigidBody,
                                  RigidBodyInertia, RotationMatrix2EulerParameters)
    nb = mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(p) + list(
        RotationMatrix2EulerParameters(R))))
    ri = RigidBodyInertia(mass=mass, inertiaTensor=np.diag(inertia))
    body = mbs.AddObject(ObjectRigidBody(mass=mass, inertia=ri.GetInertia6D(),
                                         nodeNumber=nb))
    if mass:
        mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(
            MarkerBodyMass(bodyNumber=body)), loadVector=[0.0, 0.0, -GRAV]))
    glue = [mbs.AddMarker(MarkerNodeRigid(nodeNumber=node)),
            mbs.AddMarker(MarkerNodeRigid(nodeNumber=nb))]
    mbs.AddObject(GenericJoint(markerNumbers=glue, constrainedAxes=[1] * 6))


def run_exudyn(n_el: int, h: float, duration: float) -> dict:
    import exudyn as exu
    from exudyn.utilities import (LoadMassProportional, MarkerBodyMass, MarkerBodyRigid,
                                  MarkerNodeRigid, NodeRigidBodyEP,
                                  ObjectBeamGeometricallyExact,
                                  ObjectConnectorTorsionalSpringDamper, ObjectGround,
                                  ObjectJointRevoluteZ, RotationMatrix2EulerParameters,
                                  SensorNode, Torque)
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround())
    m_ground = mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground))
    A, Ib, Ip, J = tube()
    R1 = np.eye(3)
    R2 = _rot_x(np.pi / 2) @ _rot_z(PITCH0)
    links = [(np.zeros(3), R1), (np.array([L1, 0.0, 0.0]), R2)]
    roots, tips = [], []
    for p0, R in links:
        sd = exu.BeamSection()
        ga = G_MOD * A / 2.0          # thin round tube: shear factor chi = 2
        sd.stiffnessMatrix = np.diag([E * A, ga, ga, G_MOD * J, E * Ib, E * Ib])
        sd.inertia = np.diag([RHO * Ip, RHO * Ib, RHO * Ib])
        sd.massPerLength = RHO * A
        ep = list(RotationMatrix2EulerParameters(R))
        L = L1
        nodes = [mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(
            p0 + R[:, 0] * L * k / n_el) + ep)) for k in range(n_el + 1)]
        for a, b in zip(nodes[:-1], nodes[1:]):
            el = mbs.AddObject(ObjectBeamGeometricallyExact(nodeNumbers=[a, b],
                                                            length=L / n_el,
                                                            sectionData=sd))
            mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(
                MarkerBodyMass(bodyNumber=el)), loadVector=[0.0, 0.0, -GRAV]))
        _glued_body(mbs, exu, nodes[-1], p0 + R[:, 0] * L, R, TIP_MASS, [TIP_J] * 3)
        if HUB == "body":
            _glued_body(mbs, exu, nodes[0], p0, R, HUB_MASS, [HUB_J] * 3)
        roots.append(nodes[0])
        tips.append(nodes[-1])
    # joint frames: joint 1 z = base z; joint 2 z = link 1's tip y rotated: Rot_x(90) e_z
    parents = [m_ground, mbs.AddMarker(MarkerNodeRigid(nodeNumber=tips[0]))]
    rot0 = [np.eye(3), _rot_x(np.pi / 2)]
    rot1 = [np.eye(3), _rot_z(-PITCH0)]
    state = {"static": True}
    for i in range(2):
        m1 = mbs.AddMarker(MarkerNodeRigid(nodeNumber=roots[i]))
        mk = [parents[i], m1]
        mbs.AddObject(ObjectJointRevoluteZ(markerNumbers=mk, rotationMarker0=rot0[i],
                                           rotationMarker1=rot1[i]))
        mbs.AddObject(ObjectConnectorTorsionalSpringDamper(
            markerNumbers=mk, stiffness=KP, damping=KD, rotationMarker0=rot0[i],
            rotationMarker1=rot1[i]))
        if HUB == "rotor":
            raise SystemExit("BENCH_HUB=rotor: ours only")

    def f_child(mbs, t, load):
        s = np.sin(np.pi * t / T_PULSE) ** 2 if t < T_PULSE and not state["static"] else 0.0
        return [0.0, 0.0, TAU1 * s]

    mbs.AddLoad(Torque(markerNumber=mbs.AddMarker(MarkerNodeRigid(nodeNumber=roots[0])),
                       bodyFixed=True, loadVectorUserFunction=f_child))
    sens = {}
    for i, (r, tp) in enumerate(zip(roots, tips)):
        for name, node in (("root", r), ("tip", tp)):
            for kind, ovt in (("p", exu.OutputVariableType.Position),
                              ("R", exu.OutputVariableType.RotationMatrix)):
                sens[f"{name}{i}{kind}"] = mbs.AddSensor(SensorNode(
                    nodeNumber=node, storeInternal=True, writeToFile=False,
                    outputVariableType=ovt))
    mbs.Assemble()
    ss = exu.SimulationSettings()
    ti = ss.timeIntegration
    ti.endTime = duration
    ti.numberOfSteps = int(round(duration / h))
    ti.verboseMode = 0
    ti.generalizedAlpha.spectralRadius = 0.9
    ti.newton.useModifiedNewton = True
    ti.newton.absoluteTolerance = 1e-6
    ti.adaptiveStep = True
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = SAMPLE
    ss.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    ss.staticSolver.numberOfLoadSteps = 4
    ss.staticSolver.newton.absoluteTolerance = 1e-8
    mbs.SolveStatic(ss, updateInitialValues=True)
    state["static"] = False
    t0 = time.process_time()
    mbs.SolveDynamic(ss)
    cpu = time.process_time() - t0
    data = {k: mbs.GetSensorStoredData(s) for k, s in sens.items()}
    out = {"t": data["root0p"][:, 0].tolist(), "cpu": cpu,
           "n": int(mbs.systemData.ODE2Size())}
    Rs = {k: v[:, 1:].reshape(-1, 3, 3) for k, v in data.items() if k.endswith("R")}
    ps = {k: v[:, 1:4] for k, v in data.items() if k.endswith("p")}
    ang = []
    for i in range(2):
        par = np.broadcast_to(np.eye(3), Rs["root0R"].shape) if i == 0 else Rs["tip0R"]
        rel = np.einsum("nji,njk->nik", par @ rot0[i], Rs[f"root{i}R"] @ rot1[i])
        ang.append(np.degrees(np.unwrap(np.arctan2(rel[:, 1, 0], rel[:, 0, 0]))))
    out["q"] = np.array(ang).T.tolist()
    for i, lk in enumerate(("link1", "link2")):
        Rr = Rs[f"root{i}R"]
        d = np.einsum("nji,nj->ni", Rr, ps[f"tip{i}p"] - ps[f"root{i}p"])
        rel = np.einsum("nji,njk->nik", Rr, Rs[f"tip{i}R"])
        out[f"{lk}_v"] = d[:, 1].tolist()
        out[f"{lk}_w"] = d[:, 2].tolist()
        out[f"{lk}_phi"] = np.arctan2(rel[:, 2, 1], rel[:, 2, 2]).tolist()
    out["tip"] = ps["tip1p"].tolist()
    return out


# ------------------------------------------------------------------ comparison

def compare(a: dict, b: dict) -> dict:
    """Largest differences over the common samples (changes from the start state: both
    start at their own static equilibrium)."""
    n = min(len(a["t"]), len(b["t"]))
    qa, qb = np.array(a["q"])[:n], np.array(b["q"])[:n]
    res = {"dq_deg": float(np.max(np.abs((qa - qa[0]) - (qb - qb[0]))))}
    for lk in ("link1", "link2"):
        for k in ("v", "w", "phi"):
            x, y = np.array(a[f"{lk}_{k}"])[:n], np.array(b[f"{lk}_{k}"])[:n]
            res[f"{lk}_{k}"] = float(np.max(np.abs(x - y)) / max(np.max(np.abs(y)), 1e-30))
            res[f"{lk}_{k}_amp"] = float(np.max(np.abs(y)))
            peak = max(np.max(np.abs(y)), 1e-30)
            res[f"{lk}_{k}_peak_ratio"] = float(np.max(np.abs(x)) / peak)
    ta, tb = np.array(a["tip"])[:n], np.array(b["tip"])[:n]
    res["tip_mm"] = float(1e3 * np.max(np.linalg.norm(ta - tb, axis=1)))
    res["tip0_mm"] = float(1e3 * np.linalg.norm(ta[0] - tb[0]))
    return res


def _row(label, c):
    return (f"  {label}: joints {c['dq_deg']:.1e} deg, tip {c['tip_mm']:.3f} mm (start "
            f"{c['tip0_mm']:.3f}); twist peak ratio link1 {c['link1_phi_peak_ratio']:.3f}, "
            f"link2 {c['link2_phi_peak_ratio']:.3f}; max diff of the amplitude: " + ", ".join(
                f"{lk[-1]}{k} {100 * c[f'{lk}_{k}']:.2f} %" for lk in ("link1", "link2")
                for k in ("v", "w", "phi")))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=0.6)
    ap.add_argument("--quick", action="store_true", help="one resolution each")
    ap.add_argument("--peer", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--n-el", type=int, default=16, help=argparse.SUPPRESS)
    ap.add_argument("--h", type=float, default=1e-3, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.peer:
        print("JSON" + json.dumps(run_exudyn(args.n_el, args.h, args.duration)))
        return 0
    ours_res = [(8, 2.5e-4)] if args.quick else [(4, 1e-3), (8, 5e-4), (8, 2.5e-4),
                                                 (12, 1.25e-4)]
    peer_res = [(16, 2.5e-4)] if args.quick else [(16, 2.5e-4), (32, 1.25e-4)]
    ours = {r: run_ours(*r, args.duration) for r in ours_res}
    peer = peer_runs(__file__, peer_res, args.duration)
    if peer is None:
        return 1
    print(f"yaw + pitch tubes ({TUBE}, pitch {np.degrees(PITCH0):g} deg, rotary inertia "
          f"{'on' if ROTARY else 'off'}, hubs {HUB}), {TAU1:g} N m yaw pulse over "
          f"{T_PULSE:g} s, {args.duration:g} s; load {os.getloadavg()[0]:.1f}")
    for r, o in ours.items():
        print(f"  ours  {r[0]:2d} var., h {r[1]:.2e}: nq {o['nq']}, {o['cpu']:.2f} s CPU")
    for r, o in peer.items():
        print(f"  Exudyn {r[0]:2d} el., h {r[1]:.2e}: {o['n']} ODE2, {o['cpu']:.2f} s CPU")
    ref_o, ref_p = ours[ours_res[-1]], peer[peer_res[-1]]
    for r in ours_res[:-1]:
        print(_row(f"ours {r} vs ours finest", compare(ours[r], ref_o)))
    for r in peer_res[:-1]:
        print(_row(f"Exudyn {r} vs Exudyn finest", compare(peer[r], ref_p)))
    for r in ours_res:
        print(_row(f"ours {r} vs Exudyn finest", compare(ours[r], ref_p)))
    c = compare(ref_o, ref_p)
    print("  amplitudes (Exudyn finest): " + ", ".join(
        f"{lk}.{k} {c[f'{lk}_{k}_amp']:.3e}" for lk in ("link1", "link2")
        for k in ("v", "w", "phi")) + " (m, rad)")
    ok = abs(c["link1_phi_peak_ratio"] - 1.0) < 0.05 and c["link1_phi"] < 0.05
    print(f"  acceptance (link 1 twist within 5 %): {'met' if ok else 'NOT met'}; tip "
          f"floor {c['tip_mm']:.3f} mm")
    return 0


if __name__ == "__main__":
    sys.exit(main())
