"""Spatial independent hidden-effect suite (issue 44, item 4), simulated by Exudyn.

The sibling of ``generate.py`` for spatial arms: the two-link L arm of
``bench/bench_spatial_exudyn.py`` (link 1 0.8 m along x, link 2 0.6 m along y from its
tip, both joint axes vertical, gravity -z; each link bends in two planes and twists),
built from Exudyn's geometrically exact 3D beams (``ObjectBeamGeometricallyExact``,
Simo-Reissner, 8 elements per link, the bench's section: axial and shear stiffness 1e8 N,
bending-axis section inertia rhoJ / 20), joints ``ObjectJointRevoluteZ``, closed loop under
a joint PD, set-point steps. Nothing of flex_model / flex_twin is imported: the suite
shares no equation with the twin. Benchmark-only: it re-executes itself in bench/.venv-peer.

    python bench/independent_suite/generate_spatial.py --list
    python bench/independent_suite/generate_spatial.py --out runs/spatial_suite      # all
    python bench/independent_suite/generate_spatial.py --out DIR --only S-cont-healthy-s1

Controllers: ``cont``: a continuous PD (the actuator connector's user function, inside
Exudyn's implicit integrator, on the true angle and rate); ``samp500``: a sampled PD at
500 Hz with a zero-order hold, reading the noisy encoder and tachometer. Gains kp (30, 8)
N m/rad, kd (6, 1.2) N m s/rad, no feed-forward (the joint axes are vertical: gravity
puts no torque on them).

Joint angle q_i: the actuator connector's rotation (stator to the driven body: the link
root, or the motor body of an elastic gear: a motor-side encoder). Deflections in the
link's root frame (x along the beam, z parallel to the joint axis): ``w<i>`` the tip's
y (in-plane, bending about z: EI_z), ``wz<i>`` its z (out of plane: EI_y), ``phi<i>`` the
tip's twist relative to the root (GJ).

Hidden effects (truth in the twin's vocabulary): ``joint_friction`` (viscous + Coulomb
tanh(w / 0.02 rad/s) on the actuator), ``payload`` (a point mass added to link 2's end
body), ``bending_stiffness`` (EI_y or EI_z of one link scaled: one plane), ``torsion_stiffness``
(GJ scaled), ``joint_elasticity`` (seed 003's elastic gear: a motor body with rotor
inertia J_m on the joint axis between the actuator and a torsional spring-damper to the
link root). Runs 4 s at h 5e-4 s, recorded at 200 Hz, a set-point step every 1 s.
"""
import argparse
import json
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
BENCH_DIR = os.path.dirname(HERE)
sys.path.insert(0, HERE)
sys.path.insert(0, BENCH_DIR)
from generate import _rng, _yaml, pd_body  # noqa: E402  (stdlib only at its top)

DURATION = 4.0                      # s
RATE = 200.0                        # Hz, recording
STEP_EVERY = 1.0                    # s, set-point steps
SAMPLED_PERIOD = 0.002              # s, 500 Hz zero-order hold
NEL, H = 8, 5e-4                    # elements per link, generalized-alpha step (s)
SPECTRAL_RADIUS = 0.9
FRICTION_EPS = 0.02                 # rad/s
KP, KD = [30.0, 8.0], [6.0, 1.2]
#: white noise (standard deviation) per channel kind
NOISE = {'q': 2e-5, 'v': 2e-3, 'tau': 0.01, 'w': 2e-5, 'wz': 2e-5, 'phi': 2e-5}
CONTROLLERS = {'cont': {'kind': 'continuous', 'kp': KP, 'kd': KD},
               'samp500': {'kind': 'sampled', 'period': SAMPLED_PERIOD, 'kp': KP, 'kd': KD}}
VARIABLES = 4                       # the twin's nominal: variables per direction
#: elastic gear (seed 003): motor-side rotor inertia J_m (kg m^2) and spring k (N m/rad)
#: per joint; damping 10 % of the locked-rotor mode
GEAR = [(0.05, 500.0), (0.01, 100.0)]
#: hub (motor rotor) inertia about each joint axis on the link root (kg m^2), transverse
#: 1e-6, mass 1e-4 kg: a sampled D term on the bare beam root (its section's rotary
#: inertia only) is unstable at any affordable period (Exudyn fails within 0.3 s), as on
#: the planar suite's hub-less arm A; kd T / J_hub = 0.6 on both joints
HUB = [0.05, 0.01]
HUB_BODY = {'mass': 1e-4, 'transverse': 1e-6}
#: link 1's end body carries joint 2's motor housing: its inertia about the (vertical)
#: joint axis 0.01 kg m^2 (the bench's 4e-4 under joint 2's sampled D term, whose reaction
#: acts on it: kd T / J = 15, unstable within 0.3 s; 0.6 with this)
END1_IZZ = 0.01


def effect(kind, target, **p):
    return {'kind': kind, 'target': target, 'parameters': p}


def _friction(j, level):
    fv, fc = ((0.5, 0.2), (1.0, 0.4))[level] if j == 0 else ((0.1, 0.04), (0.2, 0.08))[level]
    return effect('joint_friction', 'joint%d' % (j + 1), viscous=fv, coulomb=fc, static=fc,
                  regularization=FRICTION_EPS)


def _bending(link, plane, scale):
    return effect('bending_stiffness', 'link%d' % link, plane=plane, scale=scale)


def _torsion(link, scale):
    return effect('torsion_stiffness', 'link%d' % link, scale=scale)


def _elastic(j):
    jm, k = GEAR[j]
    return effect('joint_elasticity', 'joint%d' % (j + 1), stiffness=k,
                  damping=2 * 0.1 * math.sqrt(k * jm), motor_inertia=jm)


def _payload(m):
    return effect('payload', '', mass=m)


#: (tail, controller, hidden, seed)
SPECS = (
    ('healthy', 'cont', [], 1), ('healthy', 'cont', [], 2),
    ('healthy', 'samp500', [], 1), ('healthy', 'samp500', [], 2),
    ('joint_friction-joint1', 'cont', [_friction(0, 1)], 1),
    ('joint_friction-joint2', 'samp500', [_friction(1, 1)], 2),
    ('payload', 'cont', [_payload(0.2)], 2),
    ('payload', 'samp500', [_payload(0.1)], 1),
    ('bending-link1-y-0.8', 'cont', [_bending(1, 'y', 0.8)], 1),
    ('bending-link2-z-0.8', 'samp500', [_bending(2, 'z', 0.8)], 1),
    ('bending-link1-z-1.25', 'samp500', [_bending(1, 'z', 1.25)], 2),
    ('bending-link2-y-0.8', 'cont', [_bending(2, 'y', 0.8)], 2),
    ('torsion-link1-0.7', 'cont', [_torsion(1, 0.7)], 2),
    ('torsion-link1-0.75', 'samp500', [_torsion(1, 0.75)], 1),
    ('joint_elasticity-joint1', 'cont', [_elastic(0)], 1),
    ('joint_elasticity-joint2', 'samp500', [_elastic(1)], 2),
    ('two-joint_friction1+payload', 'cont', [_friction(0, 1), _payload(0.2)], 1),
    ('two-bending-link2-z+joint_friction2', 'samp500',
     [_bending(2, 'z', 0.8), _friction(1, 1)], 2),
    ('two-torsion-link1+payload', 'cont', [_torsion(1, 0.7), _payload(0.2)], 2),
    ('two-joint_elasticity1+bending-link2-y', 'samp500',
     [_elastic(0), _bending(2, 'y', 0.8)], 1),
    ('joint_friction-joint2', 'cont', [_friction(1, 1)], 1),
    ('payload', 'samp500', [_payload(0.2)], 2),
    # two-effect runs added for issue 44's both-named figure (one of each pairing)
    ('two-bending-link1-y+payload', 'samp500', [_bending(1, 'y', 0.8), _payload(0.2)], 1),
    ('two-torsion-link1+joint_friction1', 'cont', [_torsion(1, 0.7), _friction(0, 1)], 1),
    ('two-joint_elasticity2+joint_friction1', 'cont', [_elastic(1), _friction(0, 1)], 2),
    ('two-bending-link1-z+payload', 'cont', [_bending(1, 'z', 0.8), _payload(0.1)], 2),
    ('two-joint_friction2+payload', 'samp500', [_friction(1, 1), _payload(0.2)], 1),
    ('two-torsion-link1+bending-link2-z', 'samp500',
     [_torsion(1, 0.75), _bending(2, 'z', 0.8)], 2),
)
#: stored in test/data (the tests' cases)
CI_SUBSET = ('S-cont-healthy-s1', 'S-cont-bending-link1-y-0.8-s1', 'S-samp500-healthy-s1',
             'S-cont-joint_friction-joint2-s1')


def all_cases():
    out = []
    for tail, ctrl, hidden, s in SPECS:
        kind = 'healthy' if not hidden else hidden[0]['kind'] if len(hidden) == 1 else \
            'two:%s+%s' % (hidden[0]['kind'], hidden[1]['kind'])
        out.append({'id': 'S-%s-%s-s%d' % (ctrl, tail, s), 'arm': 'S', 'controller': ctrl,
                    'kind': kind, 'hidden': hidden, 'reference_seed': s,
                    'noise_seed': 100 + s})
    return out


def reference(seed, duration=DURATION, rate=RATE):
    """(t, qset, poses): set-points about the L pose, a step of 0.1-0.3 rad (joint 1) and
    0.1-0.4 rad (joint 2) every STEP_EVERY s, within +-0.8 rad."""
    import numpy as np
    rng = _rng('spatial-reference', seed)
    n = int(round(duration * rate)) + 1
    t = np.arange(n) / rate
    pose = rng.uniform(-0.2, 0.2, 2)
    poses = [pose.copy()]
    for _ in range(int(math.ceil(duration / STEP_EVERY)) + 1):
        step = rng.uniform([0.1, 0.1], [0.3, 0.4]) * rng.choice([-1.0, 1.0], 2)
        pose = np.clip(pose + step, -0.8, 0.8)
        poses.append(pose.copy())
    poses = np.array(poses)
    k = np.floor(t / STEP_EVERY + 1e-9).astype(int)
    return t, poses[k], poses


def _rot_z(a):
    import numpy as np
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _sections(hidden):
    import bench_spatial_exudyn as b
    secs = [dict(b.SEC1), dict(b.SEC2)]
    for e in hidden:
        i = int(e['target'][-1]) - 1 if e['target'] else None
        if e['kind'] == 'bending_stiffness':
            secs[i]['EI_' + e['parameters']['plane']] *= e['parameters']['scale']
        elif e['kind'] == 'torsion_stiffness':
            secs[i]['GJ'] *= e['parameters']['scale']
    return secs


def build(mbs, exu, hidden):
    """The beams, end bodies and joints (no actuators): (roots, tips, stator markers,
    joint positions, end body 2's node)."""
    import numpy as np
    import bench_spatial_exudyn as b
    from exudyn.utilities import (GenericJoint, LoadMassProportional, MarkerBodyMass,
                                  MarkerBodyRigid, MarkerNodeRigid, NodeRigidBodyEP,
                                  ObjectBeamGeometricallyExact, ObjectGround,
                                  ObjectRigidBody, RigidBodyInertia,
                                  RotationMatrix2EulerParameters)
    payload = sum(e['parameters']['mass'] for e in hidden if e['kind'] == 'payload')
    secs = _sections(hidden)
    ground = mbs.AddObject(ObjectGround())
    m_ground = mbs.AddMarker(MarkerBodyRigid(bodyNumber=ground))
    ends = [dict(b.END1, inertia=b.END1['inertia'][:2] + [END1_IZZ]),
            dict(b.END2, mass=b.END2['mass'] + payload)]
    links = [(np.zeros(3), _rot_z(0.0), b.L1),
             (np.array([b.L1, 0.0, 0.0]), _rot_z(np.pi / 2), b.L2)]
    roots, tips = [], []
    for (p0, R, L), sec, end in zip(links, secs, ends):
        sd = exu.BeamSection()
        sd.stiffnessMatrix = np.diag([b.EX_EA, b.EX_GA, b.EX_GA, sec['GJ'], sec['EI_y'],
                                      sec['EI_z']])
        sd.inertia = np.diag([sec['rhoJ'], b.EX_ROT * sec['rhoJ'], b.EX_ROT * sec['rhoJ']])
        sd.massPerLength = sec['rhoA']
        ep = list(RotationMatrix2EulerParameters(R))
        nodes = [mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(
            p0 + R[:, 0] * L * k / NEL) + ep)) for k in range(NEL + 1)]
        for a, c in zip(nodes[:-1], nodes[1:]):
            el = mbs.AddObject(ObjectBeamGeometricallyExact(nodeNumbers=[a, c], length=L / NEL,
                                                            sectionData=sd))
            mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(
                MarkerBodyMass(bodyNumber=el)), loadVector=[0.0, 0.0, -b.G]))
        nb = mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(p0 + R[:, 0] * L) + ep))
        inertia = RigidBodyInertia(mass=end['mass'], inertiaTensor=np.diag(end['inertia']))
        body = mbs.AddObject(ObjectRigidBody(mass=end['mass'], inertia=inertia.GetInertia6D(),
                                             nodeNumber=nb))
        mbs.AddLoad(LoadMassProportional(markerNumber=mbs.AddMarker(
            MarkerBodyMass(bodyNumber=body)), loadVector=[0.0, 0.0, -b.G]))
        mbs.AddObject(GenericJoint(markerNumbers=[mbs.AddMarker(MarkerNodeRigid(
            nodeNumber=nodes[-1])), mbs.AddMarker(MarkerNodeRigid(nodeNumber=nb))],
            constrainedAxes=[1, 1, 1, 1, 1, 1]))
        roots.append(nodes[0])
        tips.append(nodes[-1])
    for i, (p0, R, _) in enumerate(links):     # the hubs, glued to the link roots
        ep = list(RotationMatrix2EulerParameters(R))
        nh = mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(p0) + ep))
        mbs.AddObject(ObjectRigidBody(nodeNumber=nh, mass=HUB_BODY['mass'], inertia=[
            HUB_BODY['transverse'], HUB_BODY['transverse'], HUB[i], 0, 0, 0]))
        mbs.AddObject(GenericJoint(markerNumbers=[mbs.AddMarker(MarkerNodeRigid(
            nodeNumber=roots[i])), mbs.AddMarker(MarkerNodeRigid(nodeNumber=nh))],
            constrainedAxes=[1, 1, 1, 1, 1, 1]))
    stators = [m_ground, mbs.AddMarker(MarkerNodeRigid(nodeNumber=tips[0]))]
    return roots, tips, stators, [p for p, _, _ in links], [R for _, R, _ in links]


def simulate(case, noise_scale=1.0, duration=DURATION):
    """Run one case in Exudyn; returns (columns, data, info)."""
    import numpy as np
    import exudyn as exu
    from exudyn.utilities import (MarkerNodeRigid, NodeRigidBodyEP, ObjectJointRevoluteZ,
                                  ObjectConnectorTorsionalSpringDamper, ObjectRigidBody,
                                  RotationMatrix2EulerParameters)
    ctrl = CONTROLLERS[case['controller']]
    sampled = ctrl['kind'] == 'sampled'
    kp, kd = np.array(ctrl['kp']), np.array(ctrl['kd'])
    hidden = case['hidden']
    fric = np.zeros((2, 2))
    elastic = [None, None]
    for e in hidden:
        if e['kind'] == 'joint_friction':
            fric[int(e['target'][-1]) - 1] = (e['parameters']['viscous'],
                                              e['parameters']['coulomb'])
        if e['kind'] == 'joint_elasticity':
            elastic[int(e['target'][-1]) - 1] = e['parameters']
    t_rec, qset_rec, poses = reference(case['reference_seed'], duration)
    n_rec = len(t_rec)
    rec_stride = int(round(1.0 / RATE / H))
    ctrl_stride = int(round(ctrl.get('period', H) / H))
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    roots, tips, stators, P, Rs = build(mbs, exu, hidden)
    offsets = [0.0, math.pi / 2]
    state = {'cmd': np.zeros(2), 'static': True}
    rng_noise = _rng('spatial-noise', case['noise_seed'])
    nz = {k: noise_scale * s * rng_noise.standard_normal((n_rec, 2)) for k, s in NOISE.items()}

    def ref_at(t):
        return poses[min(int(math.floor(t / STEP_EVERY + 1e-9)), len(poses) - 1)]

    def ref_in_step(t):
        return poses[min(max(0, int(math.ceil(t / STEP_EVERY - 1e-9)) - 1), len(poses) - 1)]

    def make_uf(j):
        def uf(mbs_, t, item, rot, omega, k, d, off):
            q = rot - offsets[j]
            if sampled and not state['static']:
                cmd = state['cmd'][j]
            else:
                r = poses[0] if state['static'] else ref_in_step(t)
                cmd = kp[j] * (r[j] - q) - kd[j] * omega
            tau = cmd - fric[j, 0] * omega - fric[j, 1] * math.tanh(omega / FRICTION_EPS)
            return -tau
        return uf

    act = []
    for j in range(2):
        m0 = stators[j]
        m1 = mbs.AddMarker(MarkerNodeRigid(nodeNumber=roots[j]))
        mbs.AddObject(ObjectJointRevoluteZ(markerNumbers=[m0, m1]))
        driven = m1
        if elastic[j] is not None:    # motor body on the axis, spring-damper to the root
            e = elastic[j]
            ep = list(RotationMatrix2EulerParameters(Rs[j]))
            mn = mbs.AddNode(NodeRigidBodyEP(referenceCoordinates=list(P[j]) + ep))
            mbs.AddObject(ObjectRigidBody(nodeNumber=mn, mass=1e-4, inertia=[
                1e-6, 1e-6, e['motor_inertia'], 0, 0, 0]))
            driven = mbs.AddMarker(MarkerNodeRigid(nodeNumber=mn))
            mbs.AddObject(ObjectJointRevoluteZ(markerNumbers=[m0, driven]))
            mbs.AddObject(ObjectConnectorTorsionalSpringDamper(
                markerNumbers=[driven, m1], stiffness=e['stiffness'], damping=e['damping'],
                offset=0.0))
        act.append(mbs.AddObject(ObjectConnectorTorsionalSpringDamper(
            markerNumbers=[m0, driven], springTorqueUserFunction=make_uf(j))))
    OT = exu.OutputVariableType
    out = np.full((n_rec, 17), np.nan)
    out_cmd = np.zeros((n_rec, 2))

    def read_state():
        q = np.array([mbs.GetObjectOutput(a, OT.Rotation) for a in act]) - offsets
        v = np.array([mbs.GetObjectOutput(a, OT.AngularVelocityLocal) for a in act])
        d = np.zeros((2, 3))
        for i in range(2):
            Rr = np.array(mbs.GetNodeOutput(roots[i], OT.RotationMatrix)).reshape(3, 3)
            Rt = np.array(mbs.GetNodeOutput(tips[i], OT.RotationMatrix)).reshape(3, 3)
            dp = Rr.T @ (np.array(mbs.GetNodeOutput(tips[i], OT.Position))
                         - np.array(mbs.GetNodeOutput(roots[i], OT.Position)))
            rel = Rr.T @ Rt
            d[i] = dp[1], dp[2], math.atan2(rel[2, 1], rel[2, 2])
        return q, v, d

    def sample(s):
        if s % rec_stride == 0 or (sampled and s % ctrl_stride == 0):
            q, v, d = read_state()
            k = s // rec_stride
            if s % rec_stride == 0 and k < n_rec:
                out[k, 0] = k / RATE
                out[k, 1:3] = q + nz['q'][k]
                out[k, 3:5] = v + nz['v'][k]
                out[k, 7:9] = qset_rec[k]
                out[k, 9:11] = d[:, 0] + nz['w'][k]
                out[k, 11:13] = d[:, 1] + nz['wz'][k]
                out[k, 13:15] = d[:, 2] + nz['phi'][k]
            if sampled and s % ctrl_stride == 0:
                kk = min(k, n_rec - 1)
                state['cmd'] = kp * (ref_at(s * H) - (q + nz['q'][kk])) - kd * (v + nz['v'][kk])
            if s % rec_stride == 0 and k < n_rec:
                out_cmd[k] = state['cmd'] if sampled else kp * (ref_at(s * H) - q) - kd * v

    n_steps = int(round(duration / H))

    def pre_step(mbs_, t):
        state['t'] = t
        sample(int(round(t / H)) - 1)
        return True

    mbs.Assemble()
    ss = exu.SimulationSettings()
    ss.solution.file.write = False
    ss.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    ss.staticSolver.numberOfLoadSteps = 4
    ss.staticSolver.newton.absoluteTolerance = 1e-4
    t0, cpu0 = time.perf_counter(), time.process_time()
    mbs.SolveStatic(ss, updateInitialValues=True)
    state['static'] = False
    ti = ss.timeIntegration
    ti.startTime, ti.endTime = 0.0, duration
    ti.numberOfSteps = n_steps
    ti.verboseMode = 0
    ti.generalizedAlpha.spectralRadius = SPECTRAL_RADIUS
    ti.newton.useModifiedNewton = True
    ti.newton.absoluteTolerance = 1e-4
    ti.adaptiveStep = False
    mbs.SetPreStepUserFunction(pre_step)
    if sampled:
        sample(0)
    try:
        mbs.SolveDynamic(ss, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    except exu.SolverError as exc:
        raise RuntimeError('%s: Exudyn failed at t = %.4f s (%s)'
                           % (case['id'], state['t'], exc)) from None
    sample(n_steps)
    wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
    out[:, 5:7] = out_cmd + (0.0 if sampled else nz['tau'])
    out = out[:, :15]
    if np.isnan(out).any():
        k = int(np.argwhere(np.isnan(out))[0, 0])
        raise RuntimeError('%s: no sample at row %d' % (case['id'], k))
    cols = ['t', 'q1', 'q2', 'v1', 'v2', 'tau1', 'tau2', 'qset1', 'qset2', 'w1', 'w2',
            'wz1', 'wz2', 'phi1', 'phi2']
    info = {'wall_s': wall, 'cpu_s': cpu, 'nel': NEL, 'h': H,
            'rms': {c: float(np.sqrt(np.mean((out[:, k] - out[:, k].mean()) ** 2)))
                    for k, c in enumerate(cols) if k},
            'nODE2': len(mbs.systemData.GetODE2Coordinates())}
    return cols, out, info


def arm_yaml():
    """The twin's nominal spatial arm (flex_model.spatial schema, VARIABLES per
    direction): bench_spatial_exudyn.arm_dict."""
    import bench_spatial_exudyn as b
    d = b.arm_dict(VARIABLES)
    d['name'] = 'spatial_suite_l_arm'
    d['convention'] = 'standard_dh'
    d['links'][0]['end_body'] = dict(d['links'][0]['end_body'], inertia=b.END1['inertia'][:2]
                                     + [END1_IZZ])
    for lk, hub in zip(d['links'], HUB):
        lk['joint']['theta'] = float(lk['joint'].get('theta', 0.0))
        lk['root_body'] = {'mass': HUB_BODY['mass'], 'inertia': [
            HUB_BODY['transverse'], HUB_BODY['transverse'], hub]}
    return ('# the nominal arm of the spatial independent suite (bench_spatial_exudyn.py\'s L '
            'arm)\n' + _yaml(json.loads(json.dumps(d))) + '\n')


def controller_yaml(ctrl_id):
    return _yaml({'controller': pd_body(CONTROLLERS[ctrl_id])}) + '\n'


def write_case(case, out_dir, cols, data, info):
    import numpy as np
    d = os.path.join(out_dir, case['id'])
    os.makedirs(d, exist_ok=True)
    np.savetxt(os.path.join(d, 'recording.csv'), data, delimiter=',', header=','.join(cols),
               comments='', fmt=['%.4f'] + ['%.8g'] * (len(cols) - 1))
    with open(os.path.join(d, 'arm.yaml'), 'w') as f:
        f.write(arm_yaml())
    with open(os.path.join(d, 'controller.yaml'), 'w') as f:
        f.write(controller_yaml(case['controller']))
    ctrl = dict(CONTROLLERS[case['controller']], id=case['controller'])
    truth = {'id': case['id'], 'arm': 'S', 'controller': ctrl,
             'kind': case['kind'], 'hidden': case['hidden'],
             'reference_seed': case['reference_seed'], 'noise_seed': case['noise_seed'],
             'expected': 'none' if not case['hidden'] else 'named',
             'simulation': {k: info[k] for k in ('nel', 'h', 'wall_s', 'cpu_s', 'nODE2')}}
    with open(os.path.join(d, 'truth.yaml'), 'w') as f:
        f.write('# the hidden truth: for scoring only, never for the diagnosis\n')
        f.write(_yaml(truth) + '\n')
    return d


def _reexec_in_peer_venv():
    try:
        import exudyn  # noqa: F401
        import numpy  # noqa: F401
        return
    except ImportError:
        pass
    import peer_exudyn
    py = peer_exudyn._venv_python() or peer_exudyn.ensure_peer_venv()
    if py is None:
        sys.exit(1)
    os.execv(py, [py, os.path.abspath(__file__)] + sys.argv[1:])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--out', help='output directory (one folder per case)')
    ap.add_argument('--only', action='append', default=[], help='case id (a prefix* too)')
    ap.add_argument('--subset', choices=['ci'])
    ap.add_argument('--list', action='store_true')
    ap.add_argument('--skip-existing', action='store_true')
    ap.add_argument('--noise', type=float, default=1.0, help='factor on the noise levels')
    ap.add_argument('--step', type=float, default=H,
                    help='Exudyn step h (s; a divisor of the control and recording periods: '
                         'a convergence check, bench_spatial_sampled_replay.py)')
    a = ap.parse_args()
    globals()['H'] = a.step
    cases = all_cases()
    if a.list:
        for c in cases:
            print(c['id'])
        return 0
    if not a.out:
        ap.error('--out DIR is required (or --list)')
    sel = [c for c in cases if c['id'] in CI_SUBSET] if a.subset == 'ci' else cases
    if a.only:
        sel = [c for c in cases if any(c['id'].startswith(p[:-1]) if p.endswith('*')
                                       else c['id'] == p for p in a.only)]
    if a.skip_existing:
        sel = [c for c in sel if not os.path.exists(os.path.join(a.out, c['id'], 'truth.yaml'))]
    os.makedirs(a.out, exist_ok=True)
    for case in sel:
        cols, data, info = simulate(case, a.noise)
        write_case(case, a.out, cols, data, info)
        print('%-48s wall %5.1f s  cpu %5.1f s  rms %s' % (
            case['id'], info['wall_s'], info['cpu_s'],
            ' '.join('%s %.3g' % kv for kv in info['rms'].items())), flush=True)
    return 0


if __name__ == '__main__':
    _reexec_in_peer_venv()
    sys.exit(main())
