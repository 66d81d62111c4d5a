"""Independent hidden-effect suite for the diagnosis (issue 21, step 3), simulated by Exudyn.

The runs come from a *different* simulator than the twin: Exudyn's geometrically exact ANCF
cable elements (ObjectANCFCable2D: large rotations, axial extensibility, exact kinematics),
rigid bodies, constraints and connectors, integrated by Exudyn's generalized-alpha solver.
Nothing of flex_model / flex_twin is imported here: the suite shares no equation with the
twin. Benchmark-only: stdlib at the top; numpy and exudyn live in the peer virtualenv
(bench/.venv-peer, created by bench/peer_exudyn.py's ensure_peer_venv) and this script
re-executes itself there.

    python bench/independent_suite/generate.py --list
    python bench/independent_suite/generate.py --out runs/independent_suite          # all
    python bench/independent_suite/generate.py --out DIR --only A-cont-healthy-s1
    python bench/independent_suite/generate.py --out DIR --subset ci
    python bench/independent_suite/generate.py --convergence                       # nel, h
    python bench/independent_suite/generate.py --manifest test/data/independent_suite \
        --peaks runs/independent_suite     # saturation limits from the generated cases

Numerics: 8 ANCF elements per link, generalized-alpha at h = 2.5e-4 s (``--convergence``:
tip within ~0.15 mm max of a 16-element, 6.25e-5 s run). One 20 s run costs ~15-24 CPU s.

Per case DIR/<case>/ holds what a user hands ``flex-twin diagnose``: ``recording.csv``
(t, q<i>, v<i>, tau<i>, qset<i>, w<i>, tip_x, tip_y; SI, rad), ``controller.yaml`` and
``arm.yaml`` (the twin's nominal arm), plus ``truth.yaml`` (for scoring only).

Arms (two 2 m aluminium links, 20 x 1 mm square tube, E 64 GPa, rho 2700, vertical plane,
gravity 9.81 along -y, no gravity compensation, continuous PD kp 625 N m/rad, kd 176.8
N m s/rad on the joint angles of both joints):

- ``A``: no hub inertia (thesis Example 1). Its PD acts continuously (inside the implicit
  integrator: a sampled D term on a hub-less flexible link is unstable at any affordable
  period).
- ``C`` (issue 44): arm A with Kelvin-Voigt damping in the nominal description (ANCF
  bending damping b EI, b = 0.005 s on both links; a ``structural_damping`` effect per link
  in arm.yaml), continuous PD; its cases (``C_CASES``): healthy, link 2's E -15/-20/-25 %,
  joint-2 friction with a tip payload, a joint-1 spring with a 0.05 kg m^2 motor-side rotor.
- ``B``: geared motors at both joints (ratio 100, rotor 5e-5 kg m^2: 0.5 kg m^2 reflected),
  the rotor's kinetic energy 1/2 J_r (n theta_i' + Omega_stator)^2 exactly (a constant mass
  matrix on the stator and link root rotations). PD continuous, or sampled at 500 Hz with a
  zero-order hold (the controller reads the noisy encoders and tachometers) with kp (300,
  100), kd (60, 20): kp 625 / kd 176.8 sampled at 500 Hz is unstable on this arm (a ~100 /
  234 Hz flexible mode grows through the sampled D term).

Joint angle q_i: rotation of the root tangent of link i relative to the tip tangent of link
i-1 (the base for i = 1); of an elastic joint, the motor angle / n (the encoder sits on the
motor). w_i: tip of link i relative to its root, normal to its root tangent. tip: end of
link 2 in the base frame.

Hidden effects (truth in the twin's effect vocabulary, flex_model.effects):

- ``joint_friction``: tau_f = -F_v w - F_c tanh(w / eps) on the actuator coordinate
  (eps = 0.02 rad/s: smooth, no Stribeck);
- ``payload``: a point mass at the end of link 2 (a rigid body glued to the cable end);
- ``joint_elasticity`` (arm B): the rotor moves to a motor body coupled to the link root by
  a torsional spring-damper (k, b); the encoder reads the motor body;
- ``structural_damping``: ANCF bending damping d = b EI (virtual work int d kappa' dkappa:
  stiffness-proportional, Rayleigh b);
- ``stiffness``: E of one link changed;
- ``sensor_bias``: added to the encoder angle before the controller sees it (and recorded);
- ``torque_saturation``: the applied torque clipped at a limit (a fraction of the 99th
  percentile of |command| in the healthy run of the same seeds; corners rounded over 2 %
  of the limit); the recorded tau is the command;
- two-effect cases and healthy runs.
"""
import argparse
import json
import math
import os
import sys
import time
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
BENCH_DIR = os.path.dirname(HERE)
REPO_DIR = os.path.dirname(BENCH_DIR)


def _reexec_in_peer_venv():
    """Run this script again with the peer venv's python (exudyn + numpy), as
    bench/peer_exudyn.py does; create the venv when missing."""
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
        print('generate: creating the peer venv %s (exudyn, numpy)' % peer_exudyn.PEER_VENV,
              file=sys.stderr)
        py = peer_exudyn.ensure_peer_venv()
        if py is None:
            sys.exit(1)
    if os.path.realpath(sys.prefix) == os.path.realpath(peer_exudyn.PEER_VENV):
        print('generate: exudyn/numpy missing in %s' % py, file=sys.stderr)
        sys.exit(1)
    os.execv(py, [py, os.path.abspath(__file__)] + sys.argv[1:])


# ----------------------------------------------------------------------------- the suite
L_LINK = 2.0
E_NOM, RHO = 6.4e10, 2700.0
SIDE, WALL = 0.020, 0.001
GRAVITY = 9.81
KP, KD = 625.0, 176.8
GEAR_RATIO, ROTOR_J = 100.0, 5.0e-5            # arm B: 0.5 kg m^2 reflected per joint
DURATION = 20.0                                  # s
RATE = 500.0                                     # Hz, recording
STEP_EVERY = 2.0                                 # s, set-point steps
SAMPLED_PERIOD = 0.002                           # s, 500 Hz zero-order hold
FRICTION_EPS = 0.02                              # rad/s, tanh regularization
SATURATION_ROUNDING = 0.02                       # corners of the torque clip (x limit)
GLUE_MASS, GLUE_INERTIA = 1e-5, 1e-10            # bodies glued to cable ends (~ none)
#: white noise (standard deviation) added to each recorded channel; the sampled controller
#: reads q and v with this noise, the continuous one acts on the true (biased) angle
NOISE = {'q': 5e-5, 'v': 5e-3, 'tau': 0.05, 'w': 2e-4, 'tip': 1e-3}
#: numerics (chosen by --convergence, see PROVENANCE.md)
NEL = 8                                          # ANCF cable elements per link
H = 2.5e-4                                       # s, generalized-alpha step
SPECTRAL_RADIUS = 0.9

CONTROLLERS = {'cont': {'kind': 'continuous', 'kp': [KP, KP], 'kd': [KD, KD]},
               # kp 625 / kd 176.8 sampled at 500 Hz is unstable on arm B (a 100 Hz / 234 Hz
               # flexible mode grows through the sampled D term, ~x2 every 2.5 s; the twin
               # refined to 8 variables per link diverges on it too): the sampled PD has the
               # gains of the twin's synthetic cases on this arm (diagnosis/synthetic.py)
               'samp500': {'kind': 'sampled', 'period': SAMPLED_PERIOD,
                           'kp': [300.0, 100.0], 'kd': [60.0, 20.0]}}
ARMS = {'A': {'rotor': False}, 'B': {'rotor': True},
        # issue 44: arm A with Kelvin-Voigt damping in its nominal description (ANCF
        # bending damping b EI, b = NOMINAL_KV s on both links, tolerance 0.5 in the twin)
        'C': {'rotor': False, 'kelvin_voigt': 0.005}}
CONFIGS = (('A', 'cont'), ('B', 'cont'), ('B', 'samp500'))
#: issue 44's cases on arm C (continuous PD): (id tail, [(kind, level, target index,
#: parameter overrides)]); the stiffness changes are 15-25 %, the elastic joint 1 has a
#: motor-side rotor of its own (no gear on the hub-less arm)
C_CASES = (('stiffness20-link2', [('stiffness', 1, 1, {'E': E_NOM * 0.80})]),
           ('stiffness15-link2', [('stiffness', 1, 1, {'E': E_NOM * 0.85})]),
           ('stiffness25-link2', [('stiffness', 1, 1, {'E': E_NOM * 0.75})]),
           ('two-joint_friction2+payload', [('joint_friction', 1, 1, {}),
                                            ('payload', 1, 0, {})]),
           ('joint_elasticity-rotor-joint1', [('joint_elasticity', 1, 0, {
               'stiffness': 1000.0, 'motor_inertia': 0.05,
               'damping': 2 * 0.1 * math.sqrt(1000.0 * 0.05)})]))
C_SEEDS = {'stiffness20-link2': (1, 2), 'stiffness15-link2': (3,), 'stiffness25-link2': (4,),
           'two-joint_friction2+payload': (1, 2), 'joint_elasticity-rotor-joint1': (1, 2)}


def _rng(*tags):
    import numpy as np
    return np.random.default_rng([zlib.crc32(str(t).encode()) for t in tags])


def effect_levels(kind, level, arm):
    """The hidden effect of a kind at magnitude level 0 (smaller) or 1 (larger): a dict
    with the twin's effect type, target and true parameter values."""
    if kind == 'joint_friction':
        fv, fc = ((3.0, 0.8), (8.0, 2.0))[level]
        return {'kind': kind, 'parameters': {'viscous': fv, 'coulomb': fc, 'static': fc,
                                             'regularization': FRICTION_EPS}}
    if kind == 'payload':
        return {'kind': kind, 'target': '', 'parameters': {'mass': (0.1, 0.3)[level]}}
    if kind == 'joint_elasticity':
        k = (1000.0, 300.0)[level]
        jm = GEAR_RATIO ** 2 * ROTOR_J
        return {'kind': kind, 'parameters': {'stiffness': k,
                                             'damping': 2 * 0.1 * math.sqrt(k * jm),
                                             'motor_inertia': jm}}
    if kind == 'structural_damping':
        return {'kind': kind, 'parameters': {'rayleigh_stiffness': (0.005, 0.02)[level]}}
    if kind == 'stiffness':
        return {'kind': kind, 'parameters': {'E': E_NOM * (1.25, 0.8)[level]}}
    if kind == 'sensor_bias':
        return {'kind': kind, 'parameters': {'bias': (0.005, -0.015)[level]}}
    if kind == 'torque_saturation':
        return {'kind': kind, 'parameters': {'fraction': (0.9, 0.6)[level]}}
    raise ValueError(kind)


TARGET_KIND = {'joint_friction': 'joint', 'joint_elasticity': 'joint', 'sensor_bias': 'joint',
               'torque_saturation': 'joint', 'structural_damping': 'link', 'stiffness': 'link',
               'payload': ''}
SINGLE_KINDS = ('joint_friction', 'payload', 'joint_elasticity', 'structural_damping',
                'stiffness', 'sensor_bias', 'torque_saturation')
#: two-effect cases: (kind, target index), (kind, target index)
PAIRS = ((('joint_friction', 0), ('payload', 0)),
         (('sensor_bias', 1), ('stiffness', 0)),
         (('torque_saturation', 0), ('structural_damping', 1)),
         (('joint_elasticity', 1), ('joint_friction', 0)))
SEEDS = (1, 2)
HEALTHY_SEEDS = (1, 2, 3, 4)


def _hidden(kind, level, target_index, arm):
    e = effect_levels(kind, level, arm)
    tk = TARGET_KIND[kind]
    e['target'] = '' if not tk else '%s%d' % (tk, target_index + 1)
    return e


def all_cases():
    """Every case of the suite: id, arm, controller, hidden effects, seeds."""
    out = []
    for arm, ctrl in CONFIGS:
        base = '%s-%s' % (arm, ctrl)
        for s in HEALTHY_SEEDS:
            out.append({'id': '%s-healthy-s%d' % (base, s), 'arm': arm, 'controller': ctrl,
                        'kind': 'healthy', 'hidden': [], 'reference_seed': s,
                        'noise_seed': 100 + s})
        for kind in SINGLE_KINDS:
            if kind == 'joint_elasticity' and not ARMS[arm]['rotor']:
                continue   # an elastic joint needs a rotor on its motor side
            if kind == 'torque_saturation' and not ARMS[arm]['rotor']:
                continue   # hub-less arm A under a clipped torque: Exudyn's Newton fails
            for level in (0, 1):
                for s in SEEDS:
                    j = (s + level) % 2  # alternate joints / links over the cases
                    h = _hidden(kind, level, j, arm)
                    out.append({'id': '%s-%s-m%d-s%d' % (base, kind, level, s), 'arm': arm,
                                'controller': ctrl, 'kind': kind, 'hidden': [h],
                                'reference_seed': s, 'noise_seed': 100 + s})
        for (k1, t1), (k2, t2) in PAIRS:
            if {'joint_elasticity', 'torque_saturation'} & {k1, k2} and not ARMS[arm]['rotor']:
                continue
            for s in SEEDS:
                hs = [_hidden(k1, 1, t1, arm), _hidden(k2, 1, t2, arm)]
                out.append({'id': '%s-two-%s+%s-s%d' % (base, k1, k2, s), 'arm': arm,
                            'controller': ctrl, 'kind': 'two:%s+%s' % (k1, k2),
                            'hidden': hs, 'reference_seed': s, 'noise_seed': 100 + s})
    return out + c_cases()


def c_cases():
    """Issue 44's cases on arm C (Kelvin-Voigt damping in the nominal arm, continuous PD):
    healthy runs, a link-2 stiffness change of 15-25 %, joint-2 friction with a tip payload,
    a joint-1 spring with a motor-side rotor inertia."""
    out = [{'id': 'C-cont-healthy-s%d' % s, 'arm': 'C', 'controller': 'cont',
            'kind': 'healthy', 'hidden': [], 'reference_seed': s, 'noise_seed': 100 + s}
           for s in (1, 2)]
    for tail, spec in C_CASES:
        for s in C_SEEDS[tail]:
            hs = []
            for kind, level, j, over in spec:
                h = _hidden(kind, level, j, 'C')
                h['parameters'].update(over)
                hs.append(h)
            kind = hs[0]['kind'] if len(hs) == 1 else \
                'two:%s+%s' % (hs[0]['kind'], hs[1]['kind'])
            out.append({'id': 'C-cont-%s-s%d' % (tail, s), 'arm': 'C', 'controller': 'cont',
                        'kind': kind, 'hidden': hs, 'reference_seed': s,
                        'noise_seed': 100 + s})
    return out


#: the subset stored in test/data for CI: a healthy run and a two-effect run
CI_SUBSET = ('B-samp500-healthy-s1', 'B-samp500-two-joint_friction+payload-s1',
             'A-cont-healthy-s1', 'C-cont-stiffness20-link2-s1')


def reference(seed, duration=DURATION, rate=RATE):
    """(t, qset): piecewise-constant set-points, a step every STEP_EVERY s, about the
    hanging pose (link 1 within +-0.6 rad of straight down, joint 2 within +-0.8 rad)."""
    import numpy as np
    rng = _rng('reference', seed)
    n = int(round(duration * rate)) + 1
    t = np.arange(n) / rate
    lo = np.array([-math.pi / 2 - 0.6, -0.8])
    hi = np.array([-math.pi / 2 + 0.6, 0.8])
    pose = lo + (hi - lo) * rng.uniform(0.3, 0.7, 2)
    n_seg = int(math.ceil(duration / STEP_EVERY)) + 1
    poses = [pose.copy()]
    for _ in range(n_seg):
        step = rng.uniform(0.05, 0.25, 2) * rng.choice([-1.0, 1.0], 2)
        pose = np.clip(pose + step, lo, hi)
        poses.append(pose.copy())
    poses = np.array(poses)
    k = np.floor(t / STEP_EVERY + 1e-9).astype(int)
    return t, poses[k], poses


# ----------------------------------------------------------------------------- simulation
def simulate(case, nel=NEL, h=H, duration=DURATION, noise_scale=1.0, sat_limits=None,
             verbose=False):
    """Run one case in Exudyn; returns (columns, data, info)."""
    import numpy as np
    import exudyn as exu
    from exudyn.utilities import (ObjectGround, MarkerBodyRigid, MarkerBodyPosition,
                                  MarkerNodeRigid, MarkerNodePosition, NodeRigidBody2D,
                                  ObjectRigidBody2D, ObjectANCFCable2D, ObjectJointGeneric,
                                  ObjectJointRevolute2D, ObjectGenericODE2, Force,
                                  ObjectConnectorTorsionalSpringDamper, VObjectJointGeneric)
    from exudyn.beams import GenerateBeamElementsAlongLine

    arm = ARMS[case['arm']]
    ctrl = CONTROLLERS[case['controller']]
    sampled = ctrl['kind'] == 'sampled'
    kp, kd = np.array(ctrl['kp'], float), np.array(ctrl['kd'], float)
    hidden = {e['kind']: e for e in case['hidden']}
    t_rec, qset_rec, poses = reference(case['reference_seed'], duration)
    n_rec = len(t_rec)
    dt_rec = 1.0 / RATE
    rec_stride = int(round(dt_rec / h))
    assert abs(rec_stride * h - dt_rec) < 1e-12, 'h must divide the sample period'
    ctrl_stride = int(round(ctrl.get('period', h) / h)) if sampled else 1

    # effect parameters
    E = [E_NOM, E_NOM]
    if 'stiffness' in hidden:
        E[int(hidden['stiffness']['target'][-1]) - 1] = hidden['stiffness']['parameters']['E']
    bdamp = [arm.get('kelvin_voigt', 0.0)] * 2
    if 'structural_damping' in hidden:
        e = hidden['structural_damping']
        bdamp[int(e['target'][-1]) - 1] = e['parameters']['rayleigh_stiffness']
    fric = np.zeros((2, 2))
    if 'joint_friction' in hidden:
        e = hidden['joint_friction']
        fric[int(e['target'][-1]) - 1] = (e['parameters']['viscous'], e['parameters']['coulomb'])
    bias = np.zeros(2)
    if 'sensor_bias' in hidden:
        e = hidden['sensor_bias']
        bias[int(e['target'][-1]) - 1] = e['parameters']['bias']
    limit = np.full(2, np.inf)
    if 'torque_saturation' in hidden:
        e = hidden['torque_saturation']
        limit[int(e['target'][-1]) - 1] = e['parameters']['limit'] if sat_limits is None \
            else sat_limits[int(e['target'][-1]) - 1]
    payload = hidden['payload']['parameters']['mass'] if 'payload' in hidden else 0.0
    change_at = float(case.get('change_at', 0.0))
    if change_at > 0 and set(hidden) not in ({'joint_friction'}, {'payload'}):
        raise ValueError('%s: --change-at takes joint friction or payload cases only'
                         % case['id'])
    elastic = [None, None]
    if 'joint_elasticity' in hidden:
        e = hidden['joint_elasticity']
        elastic[int(e['target'][-1]) - 1] = (e['parameters']['stiffness'],
                                             e['parameters']['damping'],
                                             0.0 if arm['rotor'] else
                                             e['parameters']['motor_inertia'])

    A = SIDE ** 2 - (SIDE - 2 * WALL) ** 2
    I = (SIDE ** 4 - (SIDE - 2 * WALL) ** 4) / 12.0
    rhoA = RHO * A

    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    oGround = mbs.AddObject(ObjectGround(referencePosition=[0, 0, 0]))
    mGroundRigid = mbs.AddMarker(MarkerBodyRigid(bodyNumber=oGround, localPosition=[0, 0, 0]))
    mGroundPos = mbs.AddMarker(MarkerBodyPosition(bodyNumber=oGround, localPosition=[0, 0, 0]))

    q0 = poses[0]
    absang = [q0[0], q0[0] + q0[1]]
    P = [np.zeros(2)]
    for a in absang:
        P.append(P[-1] + L_LINK * np.array([math.cos(a), math.sin(a)]))

    picked = []   # a payload picked up mid-run (--change-at): (body, mass)

    def glue(pos, ang, element, local_x, mass=GLUE_MASS, inertia=GLUE_INERTIA):
        n = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[pos[0], pos[1], ang]))
        later = mass > GLUE_MASS and change_at > 0
        body = mbs.AddObject(ObjectRigidBody2D(nodeNumber=n, mass=GLUE_MASS if later else mass,
                                               inertia=inertia))
        if later:   # its mass is set and its weight acts from change_at on (pre_step)
            picked.append((body, mass))
            mbs.AddLoad(Force(markerNumber=mbs.AddMarker(MarkerNodePosition(nodeNumber=n)),
                              loadVector=[0, 0, 0], loadVectorUserFunction=lambda mbs_, t, f:
                              [0, -GRAVITY * mass, 0] if t >= change_at else [0, 0, 0]))
        elif mass > GLUE_MASS:
            mbs.AddLoad(Force(markerNumber=mbs.AddMarker(MarkerNodePosition(nodeNumber=n)),
                              loadVector=[0, -GRAVITY * mass, 0]))
        mC = mbs.AddMarker(MarkerBodyRigid(bodyNumber=element, localPosition=[local_x, 0, 0]))
        mN = mbs.AddMarker(MarkerNodeRigid(nodeNumber=n))
        mbs.AddObject(ObjectJointGeneric(markerNumbers=[mC, mN],
                                         constrainedAxes=[1, 1, 0, 0, 0, 1],
                                         visualization=VObjectJointGeneric(show=False)))
        return n

    root, tip = [], []
    for i in range(2):
        tmpl = ObjectANCFCable2D(massPerLength=rhoA, bendingStiffness=E[i] * I,
                                 axialStiffness=E[i] * A, bendingDamping=bdamp[i] * E[i] * I,
                                 useReducedOrderIntegration=0)
        d = GenerateBeamElementsAlongLine(mbs, [P[i][0], P[i][1], 0], [P[i + 1][0], P[i + 1][1], 0],
                                          nel, tmpl, gravity=[0, -GRAVITY, 0])
        Le = L_LINK / nel
        root.append(glue(P[i], absang[i], d['elements'][0], 0.0))
        if i == 1 and payload > 0:
            tip.append(glue(P[i + 1], absang[i], d['elements'][-1], Le, mass=payload))
        else:
            tip.append(glue(P[i + 1], absang[i], d['elements'][-1], Le))

    state = {'cmd': np.zeros(2), 'static': True}
    rng_noise = _rng('noise', case['noise_seed'])
    nz = {k: noise_scale * s * rng_noise.standard_normal((n_rec, 2)) for k, s in NOISE.items()}
    qset_ctrl = qset_rec

    def ref_at(t):
        """Set-point at a sample instant (right-continuous: the new one at a step)."""
        k = int(math.floor(t / STEP_EVERY + 1e-9))
        return poses[min(k, len(poses) - 1)]

    def ref_in_step(t):
        """Set-point over the integrator step ending at t (the new one on (2k, 2k+2])."""
        k = max(0, int(math.ceil(t / STEP_EVERY - 1e-9)) - 1)
        return poses[min(k, len(poses) - 1)]

    act = []
    sat_round = SATURATION_ROUNDING

    def clip(x, lim):
        """x clipped to [-lim, lim], corners rounded over sat_round * lim (C-infinity;
        a hard corner stalls Exudyn's Newton on the hub-less arm A)."""
        if not math.isfinite(lim):
            return x
        s2 = (sat_round * lim) ** 2
        return 0.5 * (math.sqrt((x + lim) ** 2 + s2) - math.sqrt((x - lim) ** 2 + s2))

    def make_uf(j):
        def uf(mbs_, t, item, rot, omega, k, d, off):
            if sampled and not state['static']:
                cmd = state['cmd'][j]
            else:
                r = poses[0] if state['static'] else ref_in_step(t)
                cmd = kp[j] * (r[j] - (rot + bias[j])) - kd[j] * omega
            tau = clip(cmd, limit[j])
            if t >= change_at:   # a hidden change mid-run (--change-at): friction from then on
                tau -= fric[j, 0] * omega + fric[j, 1] * math.tanh(omega / FRICTION_EPS)
            return -tau
        return uf

    for j in range(2):
        if j == 0:
            sPos, sRig, sNode = mGroundPos, mGroundRigid, None
        else:
            sPos = mbs.AddMarker(MarkerNodePosition(nodeNumber=tip[0]))
            sRig = mbs.AddMarker(MarkerNodeRigid(nodeNumber=tip[0]))
            sNode = tip[0]
        rPos = mbs.AddMarker(MarkerNodePosition(nodeNumber=root[j]))
        rRig = mbs.AddMarker(MarkerNodeRigid(nodeNumber=root[j]))
        mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[sPos, rPos]))
        driven = root[j]
        aRig = rRig
        if elastic[j] is not None:   # motor body on the joint axis, spring to the link root
            jpos = P[j]
            mNode = mbs.AddNode(NodeRigidBody2D(referenceCoordinates=[jpos[0], jpos[1], absang[j]]))
            k_t, b_t, j_m = elastic[j]   # j_m: the motor's own rotor (no gear, arm C)
            mbs.AddObject(ObjectRigidBody2D(nodeNumber=mNode, mass=GLUE_MASS,
                                            inertia=max(GLUE_INERTIA, j_m)))
            mbs.AddObject(ObjectJointRevolute2D(markerNumbers=[
                sPos, mbs.AddMarker(MarkerNodePosition(nodeNumber=mNode))]))
            aRig = mbs.AddMarker(MarkerNodeRigid(nodeNumber=mNode))
            mbs.AddObject(ObjectConnectorTorsionalSpringDamper(
                markerNumbers=[aRig, rRig], stiffness=k_t, damping=b_t, offset=0.0))
            driven = mNode
        if arm['rotor']:   # 1/2 J_r (n phi_driven' - (n - 1) phi_stator')^2
            nodes = [driven] if sNode is None else [sNode, driven]
            c = np.zeros(3 * len(nodes))
            c[-1] = GEAR_RATIO
            if sNode is not None:
                c[2] = 1.0 - GEAR_RATIO
            nn = len(c)
            mbs.AddObject(ObjectGenericODE2(nodeNumbers=nodes, massMatrix=ROTOR_J * np.outer(c, c),
                                            stiffnessMatrix=np.zeros((nn, nn)),
                                            dampingMatrix=np.zeros((nn, nn))))
        act.append(mbs.AddObject(ObjectConnectorTorsionalSpringDamper(
            markerNumbers=[sRig, aRig], springTorqueUserFunction=make_uf(j))))

    out = np.full((n_rec, 13), np.nan)
    out_cmd = np.zeros((n_rec, 2))
    OT = exu.OutputVariableType

    def read_state():
        q = np.array([mbs.GetObjectOutput(a, OT.Rotation) for a in act])
        v = np.array([mbs.GetObjectOutput(a, OT.AngularVelocityLocal) for a in act])
        w = np.zeros(2)
        for i in range(2):
            pr = mbs.GetNodeOutput(root[i], OT.Position)[:2]
            pt = mbs.GetNodeOutput(tip[i], OT.Position)[:2]
            phi = mbs.GetNodeOutput(root[i], OT.Rotation)[2]
            w[i] = (pt - pr) @ np.array([-math.sin(phi), math.cos(phi)])
        tipxy = mbs.GetNodeOutput(tip[1], OT.Position)[:2]
        return q, v, w, tipxy

    def sample(s):
        """State at step s (time s h): record every rec_stride steps, control updates."""
        if s % rec_stride == 0 or (sampled and s % ctrl_stride == 0):
            q, v, w, tipxy = read_state()
            k = s // rec_stride
            if s % rec_stride == 0 and k < n_rec:
                out[k, 0] = k * dt_rec
                out[k, 1:3] = q + bias + nz['q'][k]
                out[k, 3:5] = v + nz['v'][k]
                out[k, 9:11] = w + nz['w'][k]
                out[k, 11:13] = tipxy + nz['tip'][k]
                out[k, 7:9] = qset_ctrl[k]
            if sampled and s % ctrl_stride == 0:
                kk = min(k, n_rec - 1)
                qm = q + bias + nz['q'][kk]
                vm = v + nz['v'][kk]
                state['cmd'] = kp * (ref_at(s * h) - qm) - kd * vm
            if s % rec_stride == 0 and k < n_rec:
                if sampled:
                    out_cmd[k] = state['cmd']
                else:
                    out_cmd[k] = kp * (ref_at(s * h) - (q + bias)) - kd * v

    n_steps = int(round(duration / h))

    def pre_step(mbs_, t):
        s = int(round(t / h)) - 1          # the step ending at t starts from state s h
        sample(s)
        if picked and t >= change_at:      # the payload picked up (its mass from then on)
            for body, mass in picked:
                mbs.SetObjectParameter(body, 'physicsMass', mass)
            picked.clear()
        return True

    mbs.Assemble()
    ss = exu.SimulationSettings()
    ss.solution.file.write = False
    ss.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    st = ss.staticSolver
    st.verboseMode = 0
    st.newton.absoluteTolerance = 1e-6
    st.numberOfLoadSteps = 10
    t0 = time.perf_counter()
    cpu0 = time.process_time()
    mbs.SolveStatic(ss, updateInitialValues=True)
    state['static'] = False
    ti = ss.timeIntegration
    ti.startTime, ti.endTime = 0.0, duration
    ti.numberOfSteps = n_steps
    ti.verboseMode = 0
    ti.stepInformation = 0
    ti.generalizedAlpha.spectralRadius = SPECTRAL_RADIUS
    # full Newton with a torque limit (the Jacobian changes at the clip's corners)
    ti.newton.useModifiedNewton = not bool(np.isfinite(limit).any())
    ti.newton.absoluteTolerance = 1e-5
    ti.adaptiveStep = False
    ti.reuseConstantMassMatrix = not picked   # a mass set mid-run must enter the matrix
    mbs.SetPreStepUserFunction(pre_step)
    if sampled:
        sample(0)
    mbs.SolveDynamic(ss, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    sample(n_steps)
    wall = time.perf_counter() - t0
    cpu = time.process_time() - cpu0
    out[:, 5:7] = out_cmd + (0.0 if sampled else nz['tau'])
    if np.isnan(out).any():
        k = int(np.argwhere(np.isnan(out))[0, 0])
        raise RuntimeError('%s: no sample at row %d (t = %g s)' % (case['id'], k, k * dt_rec))
    cols = ['t', 'q1', 'q2', 'v1', 'v2', 'tau1', 'tau2', 'qset1', 'qset2', 'w1', 'w2',
            'tip_x', 'tip_y']
    info = {'wall_s': wall, 'cpu_s': cpu, 'nel': nel, 'h': h,
            'peak_command': np.max(np.abs(out_cmd), axis=0).tolist(),
            'p99_command': np.percentile(np.abs(out_cmd), 99, axis=0).tolist(),
            'nODE2': len(mbs.systemData.GetODE2Coordinates())}
    return cols, out, info


# ----------------------------------------------------------------------------- files
def _yaml(obj, indent=0):
    """A small block-style YAML emitter for dicts, lists, str, numbers, bool, None."""
    pad = '  ' * indent
    lines = []
    if isinstance(obj, dict):
        for k, v in obj.items():
            if isinstance(v, (dict, list)) and v and not _flow_ok(v):
                lines.append('%s%s:' % (pad, k))
                lines.append(_yaml(v, indent + 1))
            else:
                lines.append('%s%s: %s' % (pad, k, _scalar(v)))
    elif isinstance(obj, list):
        for v in obj:
            if isinstance(v, dict) and v:
                sub = _yaml(v, indent + 1).split('\n')
                lines.append('%s- %s' % (pad, sub[0].strip()))
                lines.extend(sub[1:])
            else:
                lines.append('%s- %s' % (pad, _scalar(v)))
    return '\n'.join(lines)


def _flow_ok(v):
    if isinstance(v, list):
        return all(isinstance(x, (int, float, str)) for x in v)
    if isinstance(v, dict):
        return len(v) <= 6 and all(isinstance(x, (int, float, str)) for x in v.values())
    return True


def _scalar(v):
    if isinstance(v, bool):
        return 'true' if v else 'false'
    if v is None:
        return 'null'
    if isinstance(v, float):
        if math.isinf(v):
            return '.inf' if v > 0 else '-.inf'
        return repr(float('%.10g' % v)) if abs(v) < 1e15 else '%.10e' % v
    if isinstance(v, int):
        return str(v)
    if isinstance(v, list):
        return '[' + ', '.join(_scalar(x) for x in v) + ']'
    if isinstance(v, dict):
        return '{' + ', '.join('%s: %s' % (k, _scalar(x)) for k, x in v.items()) + '}'
    s = str(v)
    if s == '' or any(c in s for c in ':#{}[],&*!|>\'"%@`') or s.strip() != s:
        return json.dumps(s)
    return s


def arm_yaml(arm_id):
    """The twin's nominal arm description (flex_model.arm schema)."""
    link = lambda i: {'name': 'link%d' % i, 'length': L_LINK,  # noqa: E731
                      'material': {'E': E_NOM, 'rho': RHO},
                      'section': {'shape': 'square_hollow', 'side': SIDE, 'wall': WALL},
                      'variables': 2}
    d = {'name': 'independent_suite_arm_%s' % arm_id,
         'description': ('Two 2 m aluminium links, 20 x 1 mm square tube, vertical plane' +
                         (', geared motors (ratio 100, rotor 5e-5 kg m^2)' if ARMS[arm_id]['rotor']
                          else ', no hub inertia')
                         + ' (Exudyn independent suite, arm %s)' % arm_id),
         'gravity': [0.0, -GRAVITY],
         'payload': {'mass': 0.0, 'inertia': 0.0},
         'links': [link(1), link(2)],
         'joints': [{'name': 'joint1'}, {'name': 'joint2'}]}
    if ARMS[arm_id]['rotor']:
        d['effects'] = [{'type': 'gear', 'joint': 'joint%d' % i, 'ratio': GEAR_RATIO,
                         'rotor_inertia': ROTOR_J} for i in (1, 2)]
    kv = ARMS[arm_id].get('kelvin_voigt')
    if kv:
        d['description'] += ', Kelvin-Voigt damping b = %g s' % kv
        d['effects'] = [{'type': 'structural_damping', 'link': 'link%d' % i,
                         'rayleigh_stiffness': kv} for i in (1, 2)]
    return _yaml(d) + '\n'


def pd_body(c) -> dict:
    """A controller entry ``c`` (kind, kp, kd, period) as the data's controller body
    (flex_twin.diagnosis.controller schema): a sampled PD (``period``), or a continuous one
    (``timing: continuous``, no period); both generators write it."""
    body = {'law': 'pd'}
    if c['kind'] != 'sampled':
        body['timing'] = 'continuous'
    body.update(kp=[float(x) for x in c['kp']], kd=[float(x) for x in c['kd']])
    if c['kind'] == 'sampled':
        body['period'] = c['period']
    body['feedforward'] = 'none'
    return body


def controller_yaml(ctrl_id):
    """The controller file of a case (:func:`pd_body`)."""
    c = CONTROLLERS[ctrl_id]
    body = pd_body(c)
    return ('# %s PD on the joint angles, no gravity compensation\n'
            % ('sampled (zero-order hold, %g Hz)' % (1 / c['period']) if c['kind'] == 'sampled'
               else 'continuous (evaluated inside the integrator)')
            + _yaml({'controller': body}) + '\n')


def case_truth(case, info=None):
    t = {'id': case['id'], 'arm': case['arm'],
         'controller': dict(CONTROLLERS[case['controller']], id=case['controller']),
         'kind': case['kind'], 'hidden': case['hidden'],
         'reference_seed': case['reference_seed'], 'noise_seed': case['noise_seed'],
         'expected': 'none' if not case['hidden'] else 'named'}
    if case.get('change_at'):
        t['change_at'] = case['change_at']
    if info:
        t['simulation'] = {k: info[k] for k in ('nel', 'h', 'wall_s', 'cpu_s', 'nODE2',
                                                'peak_command', 'p99_command')}
    return t


def write_case(case, out_dir, cols, data, info, keep=None, crop_from=0.0):
    """``keep``: the columns stored (default all), ``crop_from``: the rows from that time
    on (small test data)."""
    import numpy as np
    if keep:
        idx = [cols.index(c) for c in ['t'] + [c for c in keep if c != 't']]
        cols, data = [cols[i] for i in idx], data[:, idx]
    data = data[data[:, 0] >= crop_from - 1e-9]
    d = os.path.join(out_dir, case['id'])
    os.makedirs(d, exist_ok=True)
    fmt = ['%.4f'] + ['%.8g'] * (len(cols) - 1)
    np.savetxt(os.path.join(d, 'recording.csv'), data, delimiter=',', header=','.join(cols),
               comments='', fmt=fmt)
    with open(os.path.join(d, 'arm.yaml'), 'w') as f:
        f.write(arm_yaml(case['arm']))
    with open(os.path.join(d, 'controller.yaml'), 'w') as f:
        f.write(controller_yaml(case['controller']))
    with open(os.path.join(d, 'truth.yaml'), 'w') as f:
        f.write('# the hidden truth: for scoring only, never for the diagnosis\n')
        f.write(_yaml(case_truth(case, info)) + '\n')
    return d


_PEAKS = {}


def resolve_saturation(case, nel, h, duration, noise_scale, verbose):
    """Fill the saturation limit: a fraction of the 99th percentile of |command| on that
    joint in the healthy run of the same arm, controller and seeds (the peak command is a
    millisecond spike at a set-point step: a limit below it alone is not material)."""
    for e in case['hidden']:
        if e['kind'] != 'torque_saturation' or 'limit' in e['parameters']:
            continue
        key = _peak_key(case)
        if key not in _PEAKS:
            pilot = dict(case, id=case['id'] + '-pilot', hidden=[])
            _, _, info = simulate(pilot, nel, h, duration, noise_scale)
            _PEAKS[key] = info['p99_command']
            if verbose:
                print('  pilot %s: 99th percentile |command| %s N m (%.1f s)' % (
                    pilot['id'], ['%.2f' % p for p in info['p99_command']], info['wall_s']),
                    flush=True)
        j = int(e['target'][-1]) - 1
        e['parameters']['limit'] = float(e['parameters']['fraction'] * _PEAKS[key][j])


def _peak_key(case):
    return '%s-%s-r%d-n%d' % (case['arm'], case['controller'], case['reference_seed'],
                             case['noise_seed'])


def _load_peaks(out_dir):
    path = os.path.join(out_dir, PEAKS_FILE)
    if os.path.exists(path):
        with open(path) as f:
            return json.load(f)
    return {}


PEAKS_FILE = '_healthy_p99_command.json'


def run(cases, out_dir, nel=NEL, h=H, duration=DURATION, noise_scale=1.0, verbose=True,
        keep=None, crop_from=0.0):
    """Simulate and write the cases (healthy ones first: their peak commands set the
    saturation limits, kept in OUT/_healthy_peaks.json)."""
    times = {}
    default = (nel, h, duration, noise_scale) == (NEL, H, DURATION, 1.0)
    if default:
        _PEAKS.update({k: v for k, v in _load_peaks(out_dir).items()})
    cases = sorted(cases, key=lambda c: bool(c['hidden']))
    for case in cases:
        resolve_saturation(case, nel, h, duration, noise_scale, verbose)
        if default and any(e['kind'] == 'torque_saturation' for e in case['hidden']):
            merged = _load_peaks(out_dir)    # keep the pilot's percentiles too
            merged.update(_PEAKS)
            with open(os.path.join(out_dir, PEAKS_FILE), 'w') as f:
                json.dump(merged, f, indent=1)
        cols, data, info = simulate(case, nel, h, duration, noise_scale)
        write_case(case, out_dir, cols, data, info, keep, crop_from)
        times[case['id']] = info['wall_s']
        if not case['hidden'] and default:
            _PEAKS[_peak_key(case)] = info['p99_command']
            merged = _load_peaks(out_dir)    # other generator processes may share out_dir
            merged.update(_PEAKS)
            with open(os.path.join(out_dir, PEAKS_FILE), 'w') as f:
                json.dump(merged, f, indent=1)
        if verbose:
            print('%-50s wall %6.1f s  cpu %6.1f s  peak cmd %s' % (
                case['id'], info['wall_s'], info['cpu_s'],
                ['%.1f' % p for p in info['peak_command']]), flush=True)
    return times


# ----------------------------------------------------------------------------- convergence
CONV_REFERENCE = (16, 6.25e-5)
CONV_GRID = ((2, 1e-3), (4, 1e-3), (8, 1e-3), (4, 5e-4), (8, 5e-4), (2, 2.5e-4), (4, 2.5e-4),
             (8, 2.5e-4), (4, 1.25e-4), (8, 1.25e-4))


def convergence(duration=4.0, configs=(('A', 'cont'), ('B', 'samp500')), grid=CONV_GRID,
                reference_run=CONV_REFERENCE):
    """The first two set-point segments (a step at 2 s), noiseless, against a refined run
    (nel 16, h 6.25e-5 s): max and rms |tip error|, joint angle and tip deflection errors per
    element count and step."""
    import numpy as np
    results = {}
    for arm, ctrl in configs:
        case = {'id': '%s-%s-convergence' % (arm, ctrl), 'arm': arm, 'controller': ctrl,
                'hidden': [], 'reference_seed': 1, 'noise_seed': 101, 'kind': 'healthy'}
        runs = {}
        for nel, h in (reference_run,) + tuple(grid):
            cols, data, info = simulate(case, nel, h, duration, noise_scale=0.0)
            runs[(nel, h)] = (data, info)
            print('  %s nel %2d h %.2e: wall %.1f s' % (case['id'], nel, h, info['wall_s']),
                  flush=True)
        ref = runs[reference_run][0]
        for key, (data, info) in runs.items():
            if key == reference_run:
                continue
            d_tip = np.hypot(data[:, 11] - ref[:, 11], data[:, 12] - ref[:, 12])
            d_q = np.abs(data[:, 1:3] - ref[:, 1:3])
            d_w = np.abs(data[:, 9:11] - ref[:, 9:11])
            r = {'tip_max_mm': 1e3 * d_tip.max(), 'tip_rms_mm': 1e3 * np.sqrt(np.mean(d_tip ** 2)),
                 'q_max_mrad': 1e3 * d_q.max(), 'w_max_mm': 1e3 * d_w.max(),
                 'w_rms_mm': 1e3 * np.sqrt(np.mean(d_w ** 2)),
                 'wall_s_per_sim_s': info['wall_s'] / duration}
            results['%s nel=%d h=%g' % (case['id'], *key)] = r
            print('%-24s nel %2d h %.2e: tip max %.4f rms %.4f mm, q max %.4f mrad, '
                  'w max %.4f rms %.4f mm; wall %.2f s/sim s'
                  % (case['id'], key[0], key[1], r['tip_max_mm'], r['tip_rms_mm'],
                     r['q_max_mrad'], r['w_max_mm'], r['w_rms_mm'], r['wall_s_per_sim_s']),
                  flush=True)
    return results


# ----------------------------------------------------------------------------- manifest
def _generated_limit(runs_dir, case_id):
    """The saturation limit in a generated case's truth.yaml (None when not generated)."""
    import re
    path = os.path.join(runs_dir, case_id, 'truth.yaml') if runs_dir else ''
    if not path or not os.path.exists(path):
        return None
    with open(path) as f:
        m = re.search(r'parameters: \{fraction: [^,]+, limit: ([-+0-9.eE]+)\}', f.read())
    return float(m.group(1)) if m else None


def manifest_text(stored=(), peaks=None, runs_dir=None):
    import exudyn
    import numpy
    cases = all_cases()
    head = {'suite': 'independent hidden-effect suite (issue 21 step 3)',
            'generator': 'bench/independent_suite/generate.py',
            'simulator': 'Exudyn %s (numpy %s), ObjectANCFCable2D' % (exudyn.__version__,
                                                                   numpy.__version__),
            'numerics': {'elements_per_link': NEL, 'integrator': 'generalized-alpha',
                         'step': H, 'spectral_radius': SPECTRAL_RADIUS},
            'recording': {'rate': RATE, 'duration': DURATION, 'setpoint_step_every': STEP_EVERY},
            'noise_white_std': dict(NOISE),
            'files_per_case': ['recording.csv', 'controller.yaml', 'arm.yaml', 'truth.yaml'],
            'stored_here': list(stored),
            'regenerate': ('python bench/independent_suite/generate.py '
                           '--out runs/independent_suite [--only ID]')}
    counts = {}
    for c in cases:
        kind = 'two-effect' if c['kind'].startswith('two:') else c['kind']
        k = '%s-%s %s' % (c['arm'], c['controller'], kind)
        counts[k] = counts.get(k, 0) + 1
    head['counts'] = counts
    body = []
    for c in cases:
        t = case_truth(c)
        for e in t['hidden']:
            if e['kind'] == 'torque_saturation' and 'limit' not in e['parameters']:
                p = (peaks or {}).get(_peak_key(c))
                j = int(e['target'][-1]) - 1
                lim = _generated_limit(runs_dir, c['id'])
                if lim is None and p:
                    lim = float(e['parameters']['fraction'] * p[j])
                e['parameters']['limit'] = lim if lim is not None else \
                    'fraction x 99th percentile |tau| of the joint in the healthy run, same seeds'
        t['stored'] = c['id'] in stored
        body.append(t)
    head['cases'] = body
    return '# generated by bench/independent_suite/generate.py --manifest\n' + _yaml(head) + '\n'


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--out', help='output directory (one folder per case)')
    ap.add_argument('--only', action='append', default=[],
                    help='case id (repeatable; a prefix ending in * selects all that match)')
    ap.add_argument('--subset', choices=['ci'], help='the CI subset stored in test/data')
    ap.add_argument('--list', action='store_true', help='list the case ids')
    ap.add_argument('--skip-existing', action='store_true',
                    help='leave cases whose folder already has truth.yaml')
    ap.add_argument('--duration', type=float, default=DURATION, help='simulated s')
    ap.add_argument('--noise', type=float, default=1.0, help='factor on the noise levels')
    ap.add_argument('--nel', type=int, default=NEL)
    ap.add_argument('--h', type=float, default=H)
    ap.add_argument('--convergence', action='store_true')
    ap.add_argument('--manifest', metavar='DIR', help='write DIR/manifest.yaml')
    ap.add_argument('--peaks', metavar='RUNS',
                    help='a generated suite folder whose healthy peaks give the saturation '
                    'limits in the manifest (default: the manifest folder)')
    ap.add_argument('--stored', nargs='*', default=None,
                    help='case ids stored with the manifest (default: the folders in DIR)')
    ap.add_argument('--change-at', type=float, default=0.0, metavar='T',
                    help='joint friction cases: the friction acts from T s on only (a change '
                    'hidden mid-run; the case id gets -at<T>)')
    ap.add_argument('--seeds', metavar='S1,S2',
                    help='set-point seeds of the effect cases (default 1,2; noise seed 100 + s)')
    ap.add_argument('--columns', help='comma-separated columns to store (default all)')
    ap.add_argument('--crop-from', type=float, default=0.0, metavar='T0',
                    help='store the rows from T0 s on only')
    a = ap.parse_args()
    if a.seeds:
        global SEEDS
        SEEDS = tuple(int(x) for x in a.seeds.split(','))
    cases = all_cases()
    if a.change_at > 0:
        cases = [dict(c, id='%s-at%g' % (c['id'], a.change_at), change_at=a.change_at,
                      kind=c['kind'] + ' from %g s' % a.change_at)
                 for c in cases if c['kind'] in ('joint_friction', 'payload')]
    if a.list:
        for c in cases:
            print(c['id'])
        return 0
    if a.convergence:
        print(json.dumps(convergence(), indent=1))
        return 0
    if a.manifest:
        stored = a.stored if a.stored is not None else sorted(
            d for d in os.listdir(a.manifest) if os.path.isdir(os.path.join(a.manifest, d)))
        peaks = _load_peaks(a.peaks) if a.peaks else _load_peaks(a.manifest)
        with open(os.path.join(a.manifest, 'manifest.yaml'), 'w') as f:
            f.write(manifest_text(stored, peaks, a.peaks))
        return 0
    if not a.out:
        ap.error('--out DIR is required (or --list, --convergence, --manifest)')
    sel = cases
    if a.subset == 'ci':
        sel = [c for c in cases if c['id'] in CI_SUBSET]
    if a.only:
        want = []
        for pat in a.only:
            m = [c for c in cases if (c['id'].startswith(pat[:-1]) if pat.endswith('*')
                                      else c['id'] == pat)]
            if not m:
                ap.error('--only %s: no such case (see --list)' % pat)
            want += [c for c in m if c not in want]
        sel = want
    os.makedirs(a.out, exist_ok=True)
    if a.skip_existing:
        sel = [c for c in sel if not os.path.exists(os.path.join(a.out, c['id'], 'truth.yaml'))]
    run(sel, a.out, a.nel, a.h, a.duration, a.noise,
        keep=a.columns.split(',') if a.columns else None, crop_from=a.crop_from)
    return 0


if __name__ == '__main__':
    _reexec_in_peer_venv()
    sys.exit(main())
