"""The seed-000 link sagging under gravity, simulated by Exudyn (issue 24, item 3).

The geometrically exact reference of bench/bench_exact_kinematics.py: Exudyn's ANCF cable
elements (ObjectANCFCable2D: exact kinematics, large rotations; axially nearly rigid here)
integrated by Exudyn's generalized-alpha solver. Nothing of flex_model / flex_twin is
imported: the run shares no equation with the twin. Benchmark-only: stdlib at the top;
numpy and exudyn live in the peer virtualenv (bench/.venv-peer) and this script
re-executes itself there (as bench/independent_suite/generate.py does).

The case: one link of L = 0.28 m, m = 0.1289 kg/m, EI = 0.70656 N m^2 (seed 000, Table 1)
with a tip mass of 25.607 g (a point), clamped to a hub of 5 kg m^2 turning freely about
a fixed revolute joint (no torque), in the vertical plane (g = 9.81 m/s^2 along -y). At
t = 0 the link is straight along +x and at rest; it falls into its sag and oscillates
about it. Output (JSON on stdout): the tip deflection w(t) = (tip - root) . n(hub angle)
(normal to the root tangent) every ``--sample`` s, the hub angle, the period (mean spacing
of the maxima of w, each refined by a parabola through three samples) and CPU time.

    python bench/exact_kinematics_exudyn.py                      # nel 16, h 1e-4, 3 s
    python bench/exact_kinematics_exudyn.py --nel 32 --h 5e-5    # convergence
    python bench/exact_kinematics_exudyn.py --gscale 2           # twice the gravity
"""
import argparse
import json
import math
import os
import sys
import time

BENCH_DIR = os.path.dirname(os.path.abspath(__file__))

L, RHO_A, EI, TIP_MASS, HUB_J = 0.28, 0.1289, 0.70656, 0.025607, 5.0
GRAVITY = 9.81
EA = 1.0e6             # N: axial stiffness of the cable (strain ~ 1e-7 under these loads)
GLUE_INERTIA = 1e-10   # kg m^2: the tip body is a point mass (its rotation is glued)


def _reexec_in_peer_venv():
    """Run this script again with the peer venv's python (exudyn + numpy)."""
    try:
        import exudyn  # noqa: F401
        import numpy  # noqa: F401
        return
    except ImportError:
        pass
    sys.path.insert(0, BENCH_DIR)
    import peer_exudyn
    py = peer_exudyn._venv_python()
    if py is None:
        py = peer_exudyn.ensure_peer_venv()
        if py is None:
            sys.exit(1)
    if os.path.realpath(sys.prefix) == os.path.realpath(peer_exudyn.PEER_VENV):
        print('exact_kinematics_exudyn: exudyn/numpy missing in %s' % py, file=sys.stderr)
        sys.exit(1)
    os.execv(py, [py, os.path.abspath(__file__)] + sys.argv[1:])


def period_of_maxima(t, w):
    """Mean spacing of the local maxima of w (parabola through three samples each), by a
    least-squares line through their times; also the maxima's times and values."""
    import numpy as np
    t = np.asarray(t)
    w = np.asarray(w)
    k = np.flatnonzero((w[1:-1] > w[:-2]) & (w[1:-1] >= w[2:])) + 1
    tm, wm = [], []
    for i in k:
        y0, y1, y2 = w[i - 1], w[i], w[i + 1]
        den = y0 - 2 * y1 + y2
        s = 0.5 * (y0 - y2) / den if den != 0 else 0.0
        tm.append(t[i] + s * (t[i + 1] - t[i]))
        wm.append(y1 - 0.25 * (y0 - y2) * s)
    tm = np.array(tm)
    n = np.arange(len(tm))
    period = float(np.polyfit(n, tm, 1)[0]) if len(tm) > 1 else float('nan')
    return period, tm.tolist(), wm


def simulate(nel, h, t_end, sample, gscale, ea=EA):
    import numpy as np
    import exudyn as exu
    from exudyn.utilities import (ObjectGround, MarkerBodyRigid, MarkerBodyPosition,
                                  MarkerNodeRigid, MarkerNodePosition, NodeRigidBody2D,
                                  ObjectRigidBody2D, ObjectANCFCable2D, ObjectJointGeneric,
                                  ObjectJointRevolute2D, Force, VObjectJointGeneric)
    from exudyn.beams import GenerateBeamElementsAlongLine

    g = GRAVITY * gscale
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ObjectGround(referencePosition=[0, 0, 0]))
    m_ground = mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground, localPosition=[0, 0, 0]))
    hub = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[0, 0, 0]))
    hub_body = mbs.AddObject(ObjectRigidBody2D(nodeNumber=hub, mass=1.0, inertia=HUB_J))
    mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[
        m_ground, mbs.AddMarker(MarkerBodyPosition(bodyNumber=hub_body,
                                                   localPosition=[0, 0, 0]))]))
    tmpl = ObjectANCFCable2D(massPerLength=RHO_A, bendingStiffness=EI, axialStiffness=ea,
                             useReducedOrderIntegration=0)
    d = GenerateBeamElementsAlongLine(mbs, [0, 0, 0], [L, 0, 0], nel, tmpl,
                                      gravity=[0, -g, 0])
    elements = d['elements']
    # root clamped to the hub
    mbs.AddObject(ObjectJointGeneric(
        markerNumbers=[mbs.AddMarker(MarkerBodyRigid(bodyNumber=elements[0],
                                                     localPosition=[0, 0, 0])),
                       mbs.AddMarker(MarkerNodeRigid(nodeNumber=hub))],
        constrainedAxes=[1, 1, 0, 0, 0, 1], visualization=VObjectJointGeneric(show=False)))
    # tip mass: a body glued to the cable end (position and rotation)
    tip = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[L, 0, 0]))
    mbs.AddObject(ObjectRigidBody2D(nodeNumber=tip, mass=TIP_MASS, inertia=GLUE_INERTIA))
    mbs.AddLoad(Force(markerNumber=mbs.AddMarker(MarkerNodePosition(nodeNumber=tip)),
                      loadVector=[0, -g * TIP_MASS, 0]))
    mbs.AddObject(ObjectJointGeneric(
        markerNumbers=[mbs.AddMarker(MarkerBodyRigid(bodyNumber=elements[-1],
                                                     localPosition=[L / nel, 0, 0])),
                       mbs.AddMarker(MarkerNodeRigid(nodeNumber=tip))],
        constrainedAxes=[1, 1, 0, 0, 0, 1], visualization=VObjectJointGeneric(show=False)))

    OT = exu.OutputVariableType
    n_steps = int(round(t_end / h))
    stride = int(round(sample / h))
    assert abs(stride * h - sample) < 1e-12 * max(sample, 1.0), 'h must divide --sample'
    ts, ws, phis = [], [], []

    def record(s):
        pr = mbs.GetNodeOutput(hub, OT.Position)[:2]
        pt = mbs.GetNodeOutput(tip, OT.Position)[:2]
        phi = mbs.GetNodeOutput(hub, OT.Rotation)[2]
        ts.append(s * h)
        ws.append(float((pt - pr) @ np.array([-math.sin(phi), math.cos(phi)])))
        phis.append(float(phi))

    def pre_step(mbs_, t):
        s = int(round(t / h)) - 1     # the step ending at t starts from state s h
        if s % stride == 0:
            record(s)
        return True

    mbs.Assemble()
    ss = exu.SimulationSettings()
    ss.solution.file.write = False
    ss.linearSolver.solverType = exu.LinearSolverType.EXUdense
    ti = ss.timeIntegration
    ti.startTime, ti.endTime = 0.0, t_end
    ti.numberOfSteps = n_steps
    ti.verboseMode = 0
    ti.stepInformation = 0
    ti.generalizedAlpha.spectralRadius = 1.0
    ti.newton.relativeTolerance = 1e-8
    ti.newton.absoluteTolerance = 1e-6
    ti.adaptiveStep = False
    mbs.SetPreStepUserFunction(pre_step)
    cpu0 = time.process_time()
    mbs.SolveDynamic(ss, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    record(n_steps)
    cpu = time.process_time() - cpu0
    period, tmax, wmax = period_of_maxima(ts, ws)
    return {'simulator': 'Exudyn %s (numpy %s), ObjectANCFCable2D' % (exu.__version__,
                                                                     np.__version__),
            'nel': nel, 'h': h, 't_end': t_end, 'gscale': gscale, 'EA': ea,
            'cpu_s': cpu, 'period': period, 't_max': tmax, 'w_max': wmax,
            'sample': sample, 't': ts, 'w': ws, 'hub_angle': phis}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--nel', type=int, default=16)
    ap.add_argument('--h', type=float, default=1e-4)
    ap.add_argument('--t-end', type=float, default=3.0)
    ap.add_argument('--sample', type=float, default=1e-4)
    ap.add_argument('--gscale', type=float, default=1.0)
    ap.add_argument('--ea', type=float, default=EA, help='axial stiffness (N)')
    ap.add_argument('--summary', action='store_true', help='no time series in the JSON')
    a = ap.parse_args()
    out = simulate(a.nel, a.h, a.t_end, a.sample, a.gscale, a.ea)
    if a.summary:
        for k in ('t', 'w', 'hub_angle', 't_max', 'w_max'):
            out.pop(k)
    json.dump(out, sys.stdout)
    sys.stdout.write('\n')


if __name__ == '__main__':
    _reexec_in_peer_venv()
    main()
