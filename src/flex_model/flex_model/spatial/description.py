"""Spatial arm description: a YAML file placing joints by a Denavit-Hartenberg table (seed 000).

Convention: **standard DH** (seed 000 Eq. 17, Fu et al.), the transform from frame i-1 to
frame i is

    A_i = Trans_z(d_i) Rot_z(theta_i) Trans_x(a_i) Rot_x(alpha_i),

the joint variable q_i adds to ``theta`` (revolute) or to ``d`` (prismatic); both act
along/about z_{i-1}. ``convention: modified_dh`` (Craig) reads row i as (a_{i-1},
alpha_{i-1}, d_i, theta_i), A_i = Rot_x(alpha_{i-1}) Trans_x(a_{i-1}) Rot_z(theta_i)
Trans_z(d_i), the joint acting along/about z_i; it is regrouped exactly into the
standard form on load (:func:`modified_to_standard`: link i takes the next row's a,
alpha; Rot_x(alpha_0) Trans_x(a_0) becomes a fixed origin of link 1), so a link's end
frame (where ``end_body`` sits) is Craig's frame i carried to joint i+1, the last one
Craig's frame n, and a ``dh_x`` beam of link i runs to joint i+1.

Example (seed 000's real arm, vertical joint axis)::

    name: seed000_real_arm_3d
    gravity: [0.0, 0.0, -9.81]          # m/s^2, base frame
    links:
      - name: link1
        joint: {name: joint1, type: revolute, a: 0.28, alpha: 0.0, d: 0.0, theta: 0.0}
        flexible:
          placement: dh_x                # beam along x_i from the joint, length a (default)
          section: {EI_y: 248.0, EI_z: 0.70656, GJ: 1.0, rhoA: 0.1289, rhoJ: 1.0e-7}
          variables: 8                   # per bending plane, (deflection, rotation) pairs
          torsion_variables: 8           # even (+1: the root twist rate); 0: rigid
          rotary_inertia: false          # true: the sections' bending rotary inertia
        end_body: {mass: 0.025607, inertia: [0, 0, 0], offset: [0, 0, 0]}

A flexible link's beam frame has x along the beam, y in the plane normal to the joint
axis and z parallel to it; the deflection v (along y) bends about z (stiffness ``EI_z``),
w (along z) bends about y (``EI_y``), phi twists about x (``GJ``; ``rhoJ`` the polar mass
moment per length, kg m). Placements:

- ``dh_x``: the beam runs along x from the point Trans_z(d) Rot_z(theta) to the origin of
  frame i (length ``a``); its tip transform E (seed 000 Eq. 19) sits between
  Trans_x(a) and Rot_x(alpha) -- A_i = Trans_z(d) Rot_z(theta) Trans_x(a) E Rot_x(alpha).
- ``aux_z``: seed 000 Fig. 5 / Eq. 21: the beam runs along z_i from the origin of frame i
  (length ``length``), i.e. T = A_i A_aux E with A_aux = Trans_z(length).

``rigid`` links (no ``flexible`` key) are A_i. ``root_body`` (in the frame after
Trans_z(d) Rot_z(theta), or frame i for ``aux_z``) and ``end_body`` (in the link's
end frame i) are rigid bodies: ``mass`` (kg), ``inertia`` (kg m^2 about their centre,
3 diagonal values or a 3 x 3 matrix), ``offset`` (m, centre in that frame). A section
value may be a ``[root, tip]`` pair (linear taper).

A joint may carry the URDF limits ``lower``, ``upper`` (rad or m), ``effort`` (N m or N)
and ``velocity``; the top-level ``joint_stops: {stiffness, damping, transition}`` makes
the position limits end stops (:class:`JointStops`), else they are only reported
(spatial/limits.py).

``kinematics: second_order`` adds the axial shortening of the bent beams (the planar
arm's option, dynamics.py), ``kinematics: exact`` the geometrically exact (inextensible,
large rotation) centre line of exact.py; the default ``small_deflection`` is thesis Eq. 1.

Optional top-level keys: ``effects`` (flex_model.effects classes, SPATIAL_EFFECTS:
joint effects, ``structural_damping`` of flexible links and the arm's
``contact_surface`` at the tip, a plane in 3D: effects.contact; see dynamics.py),
``payload`` (a rigid body as ``end_body``, in the last link's end frame, lumped with
it by the model) and ``sensors`` (flex_model.sensors fields, the kinds of
spatial/sensors.py).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..arm import KINEMATICS as ARM_KINEMATICS
from ..config import ConfigError, Fields, read_yaml
from ..sections import Segment, SectionProfile

JOINT_TYPES = ("revolute", "prismatic")
#: seed 003's joint options (Sect. 2): motor active or locked, gear rigid or elastic
MOTOR_STATES = ("active", "locked")
GEAR_TYPES = ("rigid", "elastic")
#: effects of spatial joints (flex_model.effects classes, same YAML names and bounds)
SPATIAL_EFFECTS = ("gear", "joint_elasticity", "joint_friction", "dc_motor",
                   "structural_damping", "backlash", "contact_surface")
PLACEMENTS = ("dh_x", "aux_z")
SECTION_FIELDS = (("EI_y", "N m^2"), ("EI_z", "N m^2"), ("GJ", "N m^2"), ("rhoA", "kg/m"),
                  ("rhoJ", "kg m"))


@dataclass(frozen=True)
class RigidBody:
    """A rigid body fixed in a link frame: mass (kg), centre offset (m), inertia about its
    centre (kg m^2, 3 x 3 in that frame)."""

    mass: float = 0.0
    offset: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))

    @property
    def is_empty(self) -> bool:
        return self.mass == 0.0 and not np.any(np.asarray(self.inertia))


def lump_bodies(bodies) -> RigidBody:
    """One rigid body equal to the bodies (m, c, I_c) given in one frame (parallel axes:
    I = sum I_c + m (|d|^2 E - d d^T) about the common centre)."""
    m = sum(b[0] for b in bodies)
    if m <= 0.0:
        I = sum((np.asarray(b[2], float) for b in bodies), np.zeros((3, 3)))
        return RigidBody(inertia=tuple(map(tuple, I)))
    c = sum(b[0] * np.asarray(b[1], float) for b in bodies) / m
    I = np.zeros((3, 3))
    for mb, cb, Ib in bodies:
        d = np.asarray(cb, float) - c
        I += np.asarray(Ib, float) + mb * (d @ d * np.eye(3) - np.outer(d, d))
    return RigidBody(mass=float(m), offset=tuple(float(v) for v in c),
                     inertia=tuple(map(tuple, 0.5 * (I + I.T))))


@dataclass(frozen=True)
class SpatialJoint:
    """Joint i and its standard DH row (m, rad): the variable adds to theta or d.

    ``axis`` (unit, in the joint frame) is z for a DH joint, any direction for a URDF joint
    (the DH row is then zero and the link's ``origin`` places the joint). ``lower``,
    ``upper`` (rad or m), ``effort`` (N m or N) and ``velocity`` are the URDF limits
    (infinite when absent; see :func:`flex_model.spatial.limits`).

    Seed 003's joint options (its Sect. 2, Figs. 2-7): ``motor`` ``active`` | ``locked``
    (locked: the motor side clamped at ``locked_at``, rad or m, link side of the gear) and
    ``gear`` ``rigid`` | ``elastic`` (elastic: a ``joint_elasticity`` effect on the joint
    gives C_xi, B_xi and the motor inertia)."""

    name: str
    type: str = "revolute"
    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    axis: tuple = (0.0, 0.0, 1.0)
    lower: float = -np.inf
    upper: float = np.inf
    effort: float = np.inf
    velocity: float = np.inf
    motor: str = "active"
    gear: str = "rigid"
    locked_at: float = 0.0


@dataclass(frozen=True)
class JointStops:
    """End stops at the joints' position limits (``lower``, ``upper``): a spring-damper on
    the joint variable q beyond a limit, applied smoothly through a transition region
    (the third hard-stop model of MATLAB Simscape's Rotational Hard Stop: "stiffness and
    damping applied smoothly through transition region, damped rebound"). With the
    penetration d = q - upper (or lower - q) > 0, its rate d' and the width s:

        tau = -(k g(d) + c r(d) d'),   g = d^2 / (2 s) for d < s, d - s / 2 beyond;
                                       r = d / s for d < s, 1 beyond

    (sign: pushing back into the range; zero inside it). g is C1, so the implicit
    integrator's Newton iteration sees a continuous tangent k r(d) (a sharp on/off stop
    makes it cycle between the two sides); the damper may pull while the joint leaves
    the stop (damped rebound), with r -> 0 at the limit. Potential k (d^3 / (6 s)) for
    d < s, k (d^2 - s d + s^2 / 3) / 2 beyond. ``stiffness`` k (N m/rad; N/m on a
    prismatic joint), ``damping`` c (N m s/rad; N s/m), ``transition`` s (rad or m,
    default 1 mrad or 1 mm); one set for every joint with a finite limit."""

    stiffness: float
    damping: float = 0.0
    transition: float = 1.0e-3


@dataclass(frozen=True)
class FlexibleBeam:
    """The elastic part of a link: one profile per bending plane and one for torsion.

    ``bend_v``: EI_z and rhoA (deflection v along beam y); ``bend_w``: EI_y and rhoA
    (deflection w along beam z); ``torsion``: GJ (as "EI") and rhoJ (as "m"). Profiles are
    flex_model.sections.SectionProfile, so the planar wavelet basis (basis.py) applies.
    """

    length: float
    bend_v: SectionProfile
    bend_w: SectionProfile
    torsion: SectionProfile
    variables: int = 4
    torsion_variables: int = 4
    placement: str = "dh_x"
    #: bending rotary inertia (Rayleigh beam): the sections' inertia rho I_y, rho I_z about
    #: the bending axes, rho I = rhoJ EI / (EI_y + EI_z) per plane (a homogeneous section,
    #: rhoJ = rho (I_y + I_z): the planar timoshenko effect's rho I = (rho / E) EI)
    rotary_inertia: bool = False


@dataclass(frozen=True)
class SpatialLink:
    """One link: its joint, optional beam and bodies. ``origin`` (a (R, t) pair: 3 x 3
    rotation and 3 translation, m) is a fixed transform applied before the joint motion
    (URDF ``<joint><origin>``; None for DH). ``end_transform`` (R, t) is the fixed
    transform from the link frame (rigid) or the beam's tip section frame to the link's
    end frame (URDF: fixed joints after the last moving
    joint; None: identity)."""

    name: str
    joint: SpatialJoint
    flexible: FlexibleBeam | None = None
    root_body: RigidBody = RigidBody()
    end_body: RigidBody = RigidBody()
    origin: tuple | None = None
    end_transform: tuple | None = None


@dataclass(frozen=True)
class SpatialArm:
    """A serial chain of rigid and flexible links placed by a standard DH table."""

    name: str
    links: tuple
    gravity: tuple = (0.0, 0.0, -9.81)
    description: str = ""
    source: str = "<memory>"
    convention: str = "standard_dh"
    effects: tuple = ()
    #: a rigid body in the last link's end frame, lumped with its end body by the model
    payload: RigidBody = RigidBody()
    #: flex_model.sensors.Sensor objects (spatial/sensors.py: the kinds of spatial arms)
    sensors: tuple = ()
    #: end stops at the joints' position limits (None: the limits are only reported)
    joint_stops: JointStops | None = None
    #: small_deflection (thesis Eq. 1) or second_order (the axial shortening of the bent
    #: beams, u(s) = 1/2 int_0^s (v'^2 + w'^2): dynamics.py)
    kinematics: str = "small_deflection"

    @property
    def n_links(self) -> int:
        return len(self.links)

    def effect(self, kind: str, joint: str):
        """The effect of type ``kind`` on ``joint`` (None if absent)."""
        for e in self.effects:
            if e.TYPE == kind and e.target == joint:
                return e
        return None

    def joint_type_003(self, i: int) -> str:
        """Seed 003's name of joint i (Sect. 2): A|L (motor active or locked), E|R (an
        elastic element behind the motor or all rigid), with xi (elastic gear first) or
        theta (rigid gear, flexible link): 'AE_xi', 'LE_theta', 'AR', 'LR'."""
        lk = self.links[i]
        head = "A" if lk.joint.motor == "active" else "L"
        if lk.joint.gear == "elastic":
            return head + "E_xi"
        return head + ("E_theta" if lk.flexible is not None else "R")

    @property
    def joint_names(self) -> list[str]:
        return [lk.joint.name for lk in self.links]

    def without_gravity(self) -> "SpatialArm":
        return dataclasses.replace(self, gravity=(0.0, 0.0, 0.0))


# ---------------------------------------------------------------- parsing

def _pair(f: Fields, key: str, unit: str, nonnegative: bool = False):
    value = f.raw(key)
    allowed = f"a number {'>= 0' if nonnegative else '> 0'} or a [root, tip] pair ({unit})"
    vals = value if isinstance(value, (list, tuple)) else [value, value]
    if len(vals) != 2:
        raise f.error(key, value, allowed)
    try:
        out = tuple(float(v) for v in vals)
    except (TypeError, ValueError):
        raise f.error(key, value, allowed) from None
    if any(isinstance(v, bool) for v in vals) or not all(np.isfinite(out)) or \
            min(out) < 0 or (not nonnegative and min(out) <= 0):
        raise f.error(key, value, allowed)
    return out


def explicit_profile(length: float, stiffness, mass) -> SectionProfile:
    """A one-segment explicit profile: stiffness (N m^2) and mass (per length), each a
    number or a (root, tip) pair."""
    s = tuple(stiffness) if np.ndim(stiffness) else (float(stiffness),) * 2
    m = tuple(mass) if np.ndim(mass) else (float(mass),) * 2
    return SectionProfile([Segment(length=length, shape="explicit", dims={"EI": s, "m": m})])


def rigid_body(f: Fields) -> RigidBody:
    mass = f.number("mass", 0.0, nonnegative=True, unit="kg")
    offset = tuple(f.vector("offset", 3, [0.0, 0.0, 0.0], unit="m"))
    raw = f.raw("inertia", [0.0, 0.0, 0.0])
    allowed = "3 diagonal values >= 0 or a symmetric positive semi-definite 3 x 3 matrix (kg m^2)"
    try:
        arr = np.array(raw, dtype=float)
    except (TypeError, ValueError):
        raise f.error("inertia", raw, allowed) from None
    if arr.shape == (3,):
        arr = np.diag(arr)
    if arr.shape != (3, 3) or not np.all(np.isfinite(arr)):
        raise f.error("inertia", raw, allowed)
    scale = max(1e-30, float(np.max(np.abs(arr))))
    if np.max(np.abs(arr - arr.T)) > 1e-12 * scale or \
            np.min(np.linalg.eigvalsh(0.5 * (arr + arr.T))) < -1e-12 * scale:
        raise f.error("inertia", raw, allowed)
    f.done(["mass", "offset", "inertia"])
    return RigidBody(mass=mass, offset=offset, inertia=tuple(map(tuple, arr)))


def _joint(f: Fields, index: int) -> SpatialJoint:
    j = SpatialJoint(name=f.string("name", f"joint{index + 1}"),
                     type=f.string("type", "revolute", choices=list(JOINT_TYPES)),
                     a=f.number("a", 0.0, unit="m"), alpha=f.number("alpha", 0.0, unit="rad"),
                     d=f.number("d", 0.0, unit="m"), theta=f.number("theta", 0.0, unit="rad"),
                     motor=f.string("motor", "active", choices=list(MOTOR_STATES)),
                     gear=f.string("gear", "", choices=list(GEAR_TYPES)) if f.has("gear")
                     else "",
                     locked_at=f.number("locked_at", 0.0, unit="rad or m"))
    lim = {k: f.number(k, unit=u, nonnegative=k in ("effort", "velocity"))
           for k, u in (("lower", "rad or m"), ("upper", "rad or m"),
                        ("effort", "N m or N"), ("velocity", "rad/s or m/s")) if f.has(k)}
    if lim.get("lower", -np.inf) > lim.get("upper", np.inf):
        raise f.error("lower", lim["lower"], f"lower <= upper ({lim['upper']:g})")
    f.done(["name", "type", "a", "alpha", "d", "theta", "motor", "gear", "locked_at",
            "lower", "upper", "effort", "velocity"])
    return dataclasses.replace(j, **lim)


def parse_joint_stops(f: Fields, links, source: str) -> "JointStops | None":
    """The top-level ``joint_stops`` mapping (``stiffness``, ``damping``) of a DH arm file or
    a URDF side file; refused when no joint has a finite position limit."""
    if not f.has("joint_stops"):
        return None
    g = f.mapping("joint_stops")
    stops = JointStops(stiffness=g.number("stiffness", positive=True,
                                          unit="N m/rad, N/m on a prismatic joint"),
                       damping=g.number("damping", 0.0, nonnegative=True,
                                        unit="N m s/rad, N s/m on a prismatic joint"),
                       transition=g.number("transition", 1.0e-3, positive=True,
                                           max_value=0.1, unit="rad or m"))
    g.done(["stiffness", "damping", "transition"])
    if not any((np.isfinite(lk.joint.lower) or np.isfinite(lk.joint.upper)) and
               not (lk.joint.motor == "locked" and lk.joint.gear == "rigid") for lk in links):
        raise ConfigError(source, "joint_stops", "given",
                          "a moving joint with a finite lower or upper limit (joint fields "
                          "lower, upper; URDF <limit>; a locked rigid joint does not move): "
                          "the stops act at those limits")
    return stops


def joint_effects(f: Fields, links: list, source: str) -> tuple:
    """The ``effects:`` list of a spatial arm (the planar effect classes and YAML names,
    flex_model.effects; only SPATIAL_EFFECTS) and seed 003's ``motor``/``gear`` options
    of every joint checked against it. Returns (effects, links with ``gear`` resolved)."""
    from ..effects import parse_effects
    names = [lk.joint.name for lk in links]
    items = f.items("effects", []) if f.has("effects") else []
    for k, raw in enumerate(items):
        if isinstance(raw, dict) and raw.get("type") not in SPATIAL_EFFECTS and \
                isinstance(raw.get("type"), str):
            raise ConfigError(source, f"effects[{k}].type", raw.get("type"),
                              f"one of {', '.join(SPATIAL_EFFECTS)} (the effects of "
                              "spatial arms so far)")
    effects = parse_effects(items, source, names, [lk.name for lk in links])
    kinds = {(e.TYPE, e.target) for e in effects if not e.is_off}
    out = []
    for i, lk in enumerate(links):
        j = lk.joint
        elastic = ("joint_elasticity", j.name) in kinds
        path = f"links[{i}].joint"
        if j.gear == "elastic" and not elastic:
            raise ConfigError(source, path + ".gear", "elastic",
                              f"rigid, or a joint_elasticity effect on {j.name} (stiffness, "
                              "damping, motor_inertia: seed 003's C_xi, B_xi)")
        if j.gear == "rigid" and elastic:
            raise ConfigError(source, path + ".gear", "rigid",
                              f"elastic (the arm has a joint_elasticity effect on {j.name})")
        if j.motor == "locked" and ("joint_friction", j.name) in kinds:
            raise ConfigError(source, path + ".motor", "locked",
                              f"active, or no joint_friction effect on {j.name} (a locked "
                              "motor does not move: its friction does nothing)")
        if j.motor == "locked" and ("dc_motor", j.name) in kinds:
            raise ConfigError(source, path + ".motor", "locked",
                              f"active, or no dc_motor effect on {j.name} (a locked motor "
                              "takes no voltage)")
        if j.motor == "active" and j.locked_at != 0.0:
            raise ConfigError(source, path + ".locked_at", j.locked_at,
                              "no locked_at on an active motor (motor: locked)")
        out.append(dataclasses.replace(lk, joint=dataclasses.replace(
            j, gear="elastic" if elastic else "rigid")))
    for k, e in enumerate(effects):
        if e.TYPE == "backlash" and not e.is_off and ("joint_elasticity", e.target) not in kinds:
            raise ConfigError(source, f"effects[{k}].type", "backlash",
                              f"an elastic gear on {e.target} (a joint_elasticity effect with "
                              "a finite stiffness: backlash is a dead zone of its spring)")
        if e.TYPE == "structural_damping" and \
                next(lk for lk in links if lk.name == e.target).flexible is None:
            raise ConfigError(source, f"effects[{k}].link", e.target,
                              "a flexible link (structural_damping damps a link's "
                              "deformation)")
    return effects, out


def _flexible(f: Fields, joint: SpatialJoint) -> FlexibleBeam:
    placement = f.string("placement", "dh_x", choices=list(PLACEMENTS))
    if placement == "dh_x":
        if f.has("length"):
            raise f.error("length", f.data["length"],
                          "no 'length' with placement dh_x (the beam length is the DH a)")
        if joint.a <= 0:
            raise ConfigError(f.source, f.path.rsplit(".", 1)[0] + ".joint.a", joint.a,
                              "a > 0 (m): the length of a dh_x flexible beam")
        length = joint.a
    else:
        length = f.number("length", positive=True, unit="m")
    beam = flexible_beam(f, length, placement)
    f.done(["placement", "length", "section", "variables", "torsion_variables",
            "rotary_inertia"])
    return beam


def _section_values(sec: Fields) -> dict:
    vals = {k: _pair(sec, k, u, nonnegative=(k == "rhoJ")) for k, u in SECTION_FIELDS
            if k != "rhoJ" or sec.has(k)}
    vals.setdefault("rhoJ", (0.0, 0.0))
    return vals


def _profile(pieces, stiffness: str, mass: str) -> SectionProfile:
    return SectionProfile([Segment(length=ln, shape="explicit",
                                   dims={"EI": v[stiffness], "m": v[mass]})
                           for ln, v in pieces])


def flexible_beam(f: Fields, length: float, placement: str) -> FlexibleBeam:
    """The beam of a flexible link from its ``section`` (SECTION_FIELDS, each a number or
    [root, tip]; or a list of such sections, each with its ``length``, root first, the
    lengths adding up to the beam's), ``variables``, ``torsion_variables`` and
    ``rotary_inertia`` fields (the YAML arm file and the URDF side file share them)."""
    raw = f.raw("section")
    if isinstance(raw, list):
        pieces = []
        if not raw:
            raise f.error("section", raw, "a section mapping or a non-empty list of them")
        for k, item in enumerate(raw):
            sec = Fields(item, f.source, f"{f.sub('section')}[{k}]")
            ln = sec.number("length", positive=True, unit="m")
            pieces.append((ln, _section_values(sec)))
            sec.done([k for k, _ in SECTION_FIELDS] + ["length"])
        total = sum(ln for ln, _ in pieces)
        if abs(total - length) > 1e-9 * length:
            raise f.error("section", [ln for ln, _ in pieces],
                          f"segment lengths adding up to the beam length {length:g} m "
                          f"(got {total:g} m)")
        sec_err = Fields(raw[0], f.source, f"{f.sub('section')}[0]")
    else:
        sec = f.mapping("section")
        pieces = [(length, _section_values(sec))]
        sec.done([k for k, _ in SECTION_FIELDS])
        sec_err = sec
    nv = f.integer("variables", 4, min_value=2, max_value=200, even=True)
    nt = f.integer("torsion_variables", nv, min_value=0, max_value=200, even=True)
    rotary = f.boolean("rotary_inertia", False)
    if (nt or rotary) and min(max(v["rhoJ"]) for _, v in pieces) <= 0:
        raise sec_err.error("rhoJ", 0.0, "a polar mass moment per length > 0 (kg m) when "
                            "the link twists (torsion_variables > 0) or has rotary_inertia")
    return FlexibleBeam(length=length,
                        bend_v=_profile(pieces, "EI_z", "rhoA"),
                        bend_w=_profile(pieces, "EI_y", "rhoA"),
                        torsion=_profile(pieces, "GJ", "rhoJ"),
                        variables=nv, torsion_variables=nt, placement=placement,
                        rotary_inertia=rotary)


#: DH conventions of a YAML arm file
CONVENTIONS = ("standard_dh", "modified_dh")
#: kinematics of the flexible links: the planar arm's names (exact: spatial/exact.py)
KINEMATICS = ARM_KINEMATICS


def modified_to_standard(joints: list, fields: list) -> tuple:
    """Craig's modified DH rows -> the standard form used by the model (exact).

    Modified: A_i = Rot_x(alpha_{i-1}) Trans_x(a_{i-1}) Rot_z(theta_i) Trans_z(d_i), row i
    holding (a_{i-1}, alpha_{i-1}, d_i, theta_i). Regrouped, the product over the chain is
    Rot_x(alpha_0) Trans_x(a_0) * prod_i [Trans_z(d_i) Rot_z(theta_i) Trans_x(a_i)
    Rot_x(alpha_i)] with a_n = alpha_n = 0 (Rot_z and Trans_z commute, as Rot_x and
    Trans_x do): link i takes d_i, theta_i of its row and a_i, alpha_i of the next row,
    link 1 the fixed origin Rot_x(alpha_0) Trans_x(a_0). A ``dh_x`` beam of link i thus
    runs along x_i to joint i+1 (length: the next row's a); the last link has none (use
    ``placement: aux_z``). Returns (joints, origins)."""
    out, n = [], len(joints)
    for i, j in enumerate(joints):
        nxt = joints[i + 1] if i + 1 < n else None
        lf = fields[i]
        flex = lf.raw("flexible") if lf.has("flexible") else None
        if isinstance(flex, dict) and flex.get("placement", "dh_x") == "dh_x" and \
                (nxt is None or nxt.a <= 0):
            where = f"links[{i + 1}].joint.a" if nxt is not None else f"links[{i}].flexible"
            raise ConfigError(lf.source, where, nxt.a if nxt is not None else "dh_x",
                              "modified_dh: a dh_x beam of link i runs to joint i+1, its "
                              "length is the next row's a > 0 (m); the last link: "
                              "placement aux_z with a length")
        out.append(dataclasses.replace(j, a=nxt.a if nxt else 0.0,
                                       alpha=nxt.alpha if nxt else 0.0))
    a0, al0 = joints[0].a, joints[0].alpha
    origin0 = None if a0 == 0.0 and al0 == 0.0 else \
        (tuple(map(tuple, _rot_x(al0))), (float(a0), 0.0, 0.0))
    return out, [origin0] + [None] * (n - 1)


def _rot_x(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def dh_arm_from_dict(data: dict, source: str = "<memory>") -> SpatialArm:
    """Validate a parsed DH-table arm description; errors name ``source`` and the field.
    (:func:`flex_model.spatial.loader.spatial_arm_from_dict` reads URDF side files too.)"""
    f = Fields(data, source, "")
    name = f.string("name")
    description = f.string("description", "")
    convention = f.string("convention", "standard_dh", choices=list(CONVENTIONS))
    gravity = tuple(f.vector("gravity", 3, [0.0, 0.0, -9.81], unit="m/s^2"))
    items = f.items("links", min_len=1)
    fields = [Fields(raw, source, f"links[{i}]") for i, raw in enumerate(items)]
    joints = [_joint(lf.mapping("joint", {}), i) for i, lf in enumerate(fields)]
    origins = [None] * len(joints)
    if convention == "modified_dh":
        joints, origins = modified_to_standard(joints, fields)
    links = []
    for i, (lf, joint, origin) in enumerate(zip(fields, joints, origins)):
        lname = lf.string("name", f"link{i + 1}")
        flex = _flexible(lf.mapping("flexible"), joint) if lf.has("flexible") else None
        root = rigid_body(lf.mapping("root_body")) if lf.has("root_body") else RigidBody()
        end = rigid_body(lf.mapping("end_body")) if lf.has("end_body") else RigidBody()
        lf.done(["name", "joint", "flexible", "root_body", "end_body"])
        links.append(SpatialLink(name=lname, joint=joint, flexible=flex, root_body=root,
                                 end_body=end, origin=origin))
    names = [lk.joint.name for lk in links]
    if len(set(names)) != len(names):
        raise f.error("links", names, "unique joint names")
    effects, links = joint_effects(f, links, source)
    payload = rigid_body(f.mapping("payload")) if f.has("payload") else RigidBody()
    from .sensors import parse_sensors
    sensors = parse_sensors(f.items("sensors", []), source, names,
                            [lk.name for lk in links]) if f.has("sensors") else ()
    stops = parse_joint_stops(f, links, source)
    kinematics = f.string("kinematics", "small_deflection", choices=list(KINEMATICS))
    f.done(["name", "description", "convention", "gravity", "links", "effects", "payload",
            "sensors", "joint_stops", "kinematics"])
    return SpatialArm(name=name, links=tuple(links), gravity=gravity, description=description,
                      source=source, convention=convention, effects=effects, payload=payload,
                      sensors=sensors, joint_stops=stops, kinematics=kinematics)


# ---------------------------------------------------------------- planar embedding

def from_planar(arm, out_of_plane_stiffness: float = 1.0, torsion_stiffness: float | None = None,
                torsion_inertia: float | None = None) -> SpatialArm:
    """The spatial form of a planar ArmDescription (flex_model.arm), for the embedding test.

    Each planar link becomes a ``dh_x`` flexible link with a = L, alpha = 0, d = 0 (all
    joint axes parallel to the base z axis, the planar motion in the x-y plane); its
    in-plane profile is the planar one (any section, taper or segments); the data a planar
    file lacks are chosen: EI_y = ``out_of_plane_stiffness`` x EI_z, GJ =
    ``torsion_stiffness`` (default the mean EI / 1.3) and rhoJ = ``torsion_inertia``
    (default mean m (L/200)^2). M-, J- become the root body (J about z), M+, J+ the end
    body, the payload (J about z) the arm's ``payload`` (lumped with the last end body).
    Gravity (g_x, g_y) -> (g_x, g_y, 0); a ``contact_surface`` (x, y, normal_angle) is
    the plane through (x, y, 0) containing the z direction; the kinematics (small_deflection,
    second_order or exact) carries over, a link's ``internal_friction`` becomes (or adds to) its
    ``structural_damping``. Only ``wavelet`` links and the effects of
    SPATIAL_EFFECTS (same objects) are accepted."""
    if arm.kinematics not in KINEMATICS:
        raise ConfigError(arm.source, "kinematics", arm.kinematics,
                          f"one of {', '.join(KINEMATICS)}")
    bad = [e.TYPE for e in arm.effects if e.TYPE not in SPATIAL_EFFECTS]
    if bad:
        raise ConfigError(arm.source, "effects", bad,
                          f"only {', '.join(SPATIAL_EFFECTS)} (the effects of spatial arms "
                          "so far)")
    elastic = {e.target for e in arm.effects if e.TYPE == "joint_elasticity" and not e.is_off}
    links = []
    for i, (lk, jt) in enumerate(zip(arm.links, arm.joints)):
        if lk.discretization != "wavelet":
            raise ConfigError(arm.source, f"links[{i}].discretization", lk.discretization,
                              "wavelet (the spatial core uses the wavelet basis only)")
        prof = lk.profile
        zs = np.linspace(0.0, lk.length, 41)
        ei, m, _ = prof.properties(zs)
        ei_mean, m_mean = float(np.mean(ei)), float(np.mean(m))
        segs_w = [s.scaled(stiffness=out_of_plane_stiffness) for s in prof.segments]
        gj = ei_mean / 1.3 if torsion_stiffness is None else torsion_stiffness
        rj = m_mean * (lk.length / 200.0) ** 2 if torsion_inertia is None else torsion_inertia
        m_plus, j_plus = lk.M_plus, lk.J_plus
        beam = FlexibleBeam(length=lk.length, bend_v=prof, bend_w=SectionProfile(segs_w),
                            torsion=explicit_profile(lk.length, gj, rj), variables=lk.n_vars,
                            torsion_variables=lk.n_vars, placement="dh_x")
        links.append(SpatialLink(
            name=lk.name, joint=SpatialJoint(name=jt.name, a=lk.length, gear="elastic" if
                                             jt.name in elastic else "rigid"), flexible=beam,
            root_body=RigidBody(mass=lk.M_minus, inertia=tuple(map(tuple, np.diag(
                [0.0, 0.0, lk.J_minus])))),
            end_body=RigidBody(mass=m_plus, inertia=tuple(map(tuple, np.diag(
                [0.0, 0.0, j_plus]))))))
    g = tuple(arm.gravity) + (0.0,)
    payload = RigidBody(mass=arm.payload_mass, inertia=tuple(map(tuple, np.diag(
        [0.0, 0.0, arm.payload_inertia]))))
    return SpatialArm(name=arm.name + "_3d", links=tuple(links), gravity=g,
                      description=arm.description, source=arm.source,
                      effects=_with_internal_friction(arm), payload=payload,
                      kinematics=arm.kinematics)


def _with_internal_friction(arm) -> tuple:
    """The planar arm's effects with each link's own ``internal_friction`` k_a (thesis
    Eq. 35) added to its ``structural_damping`` effect (one made when it has none): the
    spatial model applies k_a per bending plane, so the in-plane block is the planar one."""
    from ..effects.structural_damping import StructuralDamping
    effects = list(arm.effects)
    for lk in arm.links:
        if lk.internal_friction <= 0.0:
            continue
        k = next((j for j, e in enumerate(effects) if e.TYPE == "structural_damping"
                  and e.target == lk.name), None)
        if k is None:
            effects.append(StructuralDamping(target=lk.name,
                                             values=(lk.internal_friction, 0.0, 0.0)))
        else:
            v = effects[k].values
            effects[k] = StructuralDamping(target=lk.name,
                                           values=(v[0] + lk.internal_friction,) + v[1:])
    return tuple(effects)


#: spatial presets live apart from the planar ones (the planar loader reads every
#: presets/*.yaml as a planar arm)
SPATIAL_PRESET_DIR = Path(__file__).resolve().parent.parent / "presets" / "spatial"


def is_spatial_arm(name_or_path) -> bool:
    """True for a spatial arm file (a ``convention`` key: a DH table, or a ``urdf`` key) or
    the name of a spatial preset that is not a planar one."""
    from ..arm import PRESET_DIR
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.is_file():
        if not path.is_file():
            return False
        data = read_yaml(path)
        return isinstance(data, dict) and ("convention" in data or "urdf" in data)
    return not (PRESET_DIR / f"{name_or_path}.yaml").exists() and \
        (SPATIAL_PRESET_DIR / f"{name_or_path}.yaml").exists()
