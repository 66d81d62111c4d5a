"""Arm description: a declarative YAML file, validated on load (thesis Ch. II notation).

Example (the thesis Example 1 arm)::

    name: thesis_example1
    gravity: [0.0, -9.81]            # m/s^2 in the base frame
    kinematics: small_deflection     # thesis Eq. 1; second_order (axial shortening); exact
    axial_vars: 0                    # exact only: axial strain variables per link (stretch)
    payload: {mass: 0.0, inertia: 0.0}
    links:
      - name: link1
        length: 2.0                  # m
        material: {E: 6.4e10, rho: 2700}
        section: {shape: square_hollow, side: 0.020, wall: 0.001}
        variables: 2                 # deformation variables (2 per interval)
        end_masses: {M_minus: 0, M_plus: 0, J_minus: 0, J_plus: 0}
        internal_friction: 0.0       # k_a of thesis Eq. (35), N s
        discretization: wavelet      # or assumed_modes, optimized_modes, ritz_polynomials,
                                     # lumped, fem (flex_model.discretizations)
      - ...
    joints:
      - {name: joint1, type: revolute}
    effects:                         # optional, see flex_model.effects
      - {type: gear, joint: joint1, ratio: 50, rotor_inertia: 0.002}
    tolerances: {E: 0.05}            # optional: relative tolerances of nominal parameters
    sensors:                         # optional, see flex_model.sensors
      - {kind: joint_encoder, joint: joint1, resolution: 0.0015, noise: 0.0}

A section dimension given as ``[root, tip]`` is linearly tapered; ``segments`` (a list of
``{length, section, material?}``) replaces ``section`` for piecewise sections. Shape
``explicit`` takes ``EI`` (N m^2) and ``m`` (kg/m) directly (no material needed).

``discretization`` (default ``wavelet``): ``variables`` is then the number of modes
(``assumed_modes``, ``optimized_modes``, with ``mode_type: clamped_free | hinged_free |
clamped_mass``; clamped_mass takes optional ``tip_mass``, ``tip_inertia``, default M+,
J+ and the payload), of polynomials (``ritz_polynomials``), of lumped masses (``lumped``,
seed 000: one variable, the first mode ``mode_type``, default clamped_mass, with
``variables`` masses) or twice the Hermite elements (``fem``, even). Every other variant
needs at least two variables (tip deflection and rotation); assumed and optimized modes
may have one (the first mode, the lumped link's limit for many masses).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from .config import MISSING, ConfigError, Fields, read_yaml
from .sections import SHAPE_DIMENSIONS, Segment, SectionProfile

PRESET_DIR = Path(__file__).resolve().parent / "presets"
#: link discretizations (flex_model.discretizations); wavelet is the thesis's Ch. II model
DISCRETIZATIONS = ("wavelet", "assumed_modes", "optimized_modes", "ritz_polynomials",
                   "lumped", "fem")
#: discretizations that may have one variable (the tip deflection of the first mode)
ONE_VARIABLE = ("lumped", "assumed_modes", "optimized_modes")
#: discretizations whose variables come in (deflection, rotation) pairs
PAIRED = ("wavelet", "fem")
#: small_deflection: the thesis model (Eq. 1); second_order: with the axial shortening of
#: bent links, u = 1/2 int d'^2 dz, which gives geometric stiffening (see kernels.py);
#: exact: the geometrically exact inextensible link (flex_model.exact_kinematics, its own
#: kernels: flex_model.simulate only)
KINEMATICS = ("small_deflection", "second_order", "exact")
#: most axial strain variables per link (Legendre polynomials of the strain, exact only)
AXIAL_VARS_MAX = 8


@dataclass(frozen=True)
class LinkDescription:
    """One flexible link: geometry, material, end bodies and discretization."""

    name: str
    length: float
    segments: tuple
    n_vars: int
    M_minus: float = 0.0
    M_plus: float = 0.0
    J_minus: float = 0.0
    J_plus: float = 0.0
    internal_friction: float = 0.0
    discretization: str = "wavelet"
    mode_type: str = "clamped_free"   # assumed/optimized modes and lumped (mode_shapes.py)
    tip_mass: float | None = None     # clamped_mass modes: M_p (default M+ and payload)
    tip_inertia: float | None = None  # clamped_mass modes: I_p (default J+ and payload)

    @property
    def profile(self) -> SectionProfile:
        return SectionProfile(list(self.segments))


@dataclass(frozen=True)
class JointDescription:
    """A joint between link i-1 (or the base) and link i; revolute and ideal for now."""

    name: str
    type: str = "revolute"


@dataclass(frozen=True)
class ArmDescription:
    """A planar serial chain of flexible links with a fixed base (thesis Fig. 1)."""

    name: str
    links: tuple
    joints: tuple
    gravity: tuple = (0.0, -9.81)
    payload_mass: float = 0.0
    payload_inertia: float = 0.0
    description: str = ""
    source: str = "<memory>"
    kinematics: str = "small_deflection"
    effects: tuple = ()
    sensors: tuple = ()
    tolerances: tuple = ()      # (name, relative tolerance) overriding NOMINAL_TOLERANCES
    axial_vars: int = 0         # axial strain variables per link (kinematics: exact only)

    def tolerance(self, name: str) -> float:
        """Relative manufacturing tolerance of a nominal parameter (E, rho, section, ...)."""
        from .effects import NOMINAL_TOLERANCES
        return dict(self.tolerances).get(name, NOMINAL_TOLERANCES[name])

    def effect(self, kind: str, target: str = ""):
        """The effect of a type on a target (joint/link name), or None."""
        for e in self.effects:
            if e.TYPE == kind and e.target == target:
                return e
        return None

    def with_effects(self, *effects) -> "ArmDescription":
        """The same arm with these effects added (replacing same type and target)."""
        keep = tuple(e for e in self.effects
                     if all((e.TYPE, e.target) != (n.TYPE, n.target) for n in effects))
        return dataclasses.replace(self, effects=keep + tuple(effects))

    @property
    def n_links(self) -> int:
        return len(self.links)

    @property
    def joint_names(self) -> list[str]:
        return [j.name for j in self.joints]

    def with_vars_per_link(self, n_vars: int) -> "ArmDescription":
        """The same arm with ``n_vars`` deformation variables on every link."""
        if n_vars < 2 or n_vars % 2:
            raise ConfigError(self.source, "vars_per_link", n_vars, "an even integer >= 2")
        links = tuple(dataclasses.replace(lk, n_vars=n_vars) for lk in self.links)
        return dataclasses.replace(self, links=links)

    def without_gravity(self) -> "ArmDescription":
        return dataclasses.replace(self, gravity=(0.0, 0.0))

    def with_kinematics(self, kinematics: str) -> "ArmDescription":
        if kinematics not in KINEMATICS:
            raise ConfigError(self.source, "kinematics", kinematics,
                              f"one of {', '.join(KINEMATICS)}")
        return dataclasses.replace(self, kinematics=kinematics)

    def with_axial_vars(self, n: int) -> "ArmDescription":
        """The same arm with ``n`` axial strain variables per link (extensible links;
        flex_model.exact_kinematics): validated by :meth:`check_axial`."""
        return dataclasses.replace(self, axial_vars=int(n))

    def check_axial(self) -> "ArmDescription":
        """Refuses (one line) axial variables outside kinematics: exact or their range."""
        n = self.axial_vars
        if not 0 <= n <= AXIAL_VARS_MAX:
            raise ConfigError(self.source, "axial_vars", n,
                              f"an integer 0..{AXIAL_VARS_MAX}")
        if n and self.kinematics != "exact":
            raise ConfigError(self.source, "axial_vars", n,
                              "0 unless kinematics: exact (the compiled kernels of "
                              f"{self.kinematics} keep the links inextensible)")
        return self


def _dims(f: Fields, shape: str) -> dict:
    dims = {}
    for name in SHAPE_DIMENSIONS[shape]:
        value = f.raw(name)
        if isinstance(value, (list, tuple)):
            if len(value) != 2:
                raise f.error(name, value, "a number or a [root, tip] pair of numbers > 0")
            pair = f.vector(name, 2)
        else:
            v = f.number(name, positive=True)
            pair = [v, v]
        if min(pair) <= 0:
            raise f.error(name, value, "a number or a [root, tip] pair of numbers > 0")
        dims[name] = tuple(pair)
    if shape == "explicit" and f.has("GA"):
        ga = f.number("GA", positive=True)
        dims["GA"] = (ga, ga)
    if "wall" in dims:
        for end, k in (("root", 0), ("tip", 1)):
            outer = min(dims[name][k] for name in dims if name != "wall")
            if 2 * dims["wall"][k] >= outer:
                raise f.error("wall", f.data["wall"],
                              f"less than half the outer dimension at the {end} ({outer} m)")
    f.done(["shape", *SHAPE_DIMENSIONS[shape]] + (["GA"] if shape == "explicit" else []))
    return dims


def _segment(sec: Fields, mat: dict, length: float) -> Segment:
    shape = sec.string("shape", choices=list(SHAPE_DIMENSIONS))
    dims = _dims(sec, shape)
    if shape != "explicit" and not mat:
        raise sec.error("shape", shape, "a 'material' {E, rho} for a geometric section")
    return Segment(length=length, shape=shape, dims=dims, **mat)


def _material(f: Fields) -> dict:
    mat = {"E": f.number("E", positive=True, unit="Pa"),
           "rho": f.number("rho", positive=True, unit="kg/m^3"),
           "G": f.number("G", 0.0, nonnegative=True, unit="Pa"),
           "shear_factor": f.number("shear_factor", 0.0, nonnegative=True)}
    f.done()
    return mat


def _link(f: Fields, index: int) -> LinkDescription:
    name = f.string("name", f"link{index + 1}")
    length = f.number("length", positive=True, unit="m")
    mat = _material(f.mapping("material")) if f.has("material") else {}
    if f.has("segments") == f.has("section"):
        raise f.error("section", f.data.get("section", MISSING),
                      "exactly one of 'section' or 'segments'")
    if f.has("section"):
        segments = (_segment(f.mapping("section"), mat, length),)
    else:
        segments = []
        for k, raw in enumerate(f.items("segments", min_len=1)):
            sf = Fields(raw, f.source, f"{f.sub('segments')}[{k}]")
            seg_len = sf.number("length", positive=True, unit="m")
            seg_mat = _material(sf.mapping("material")) if sf.has("material") else mat
            segments.append(_segment(sf.mapping("section"), seg_mat, seg_len))
            sf.done()
        total = sum(s.length for s in segments)
        if abs(total - length) > 1e-9 * length:
            raise f.error("segments", total, f"segment lengths summing to length = {length} m")
        segments = tuple(segments)
    disc = f.string("discretization", "wavelet", choices=list(DISCRETIZATIONS))
    n_vars = f.integer("variables", 2, min_value=1 if disc in ONE_VARIABLE else 2,
                       max_value=200, even=disc in PAIRED)
    options = _discretization_options(f, disc)
    ends = f.mapping("end_masses", {})
    end = {k: ends.number(k, 0.0, nonnegative=True, unit=u) for k, u in
           (("M_minus", "kg"), ("M_plus", "kg"), ("J_minus", "kg m^2"),
            ("J_plus", "kg m^2"))}
    ends.done()
    k_a = f.number("internal_friction", 0.0, nonnegative=True, unit="N s")
    f.done(["name", "length", "material", "section", "segments", "variables", "end_masses",
            "internal_friction", "discretization", *options])
    return LinkDescription(name=name, length=length, segments=segments, n_vars=n_vars,
                           internal_friction=k_a, discretization=disc, **options, **end)


def _discretization_options(f: Fields, disc: str) -> dict:
    """Options of the modal discretizations: mode_type and, for clamped_mass, tip_mass and
    tip_inertia (default: the link's M+, J+, plus the payload on the last link)."""
    if disc not in ("assumed_modes", "optimized_modes", "lumped"):
        return {}
    from .mode_shapes import MODE_TYPES
    default = "clamped_mass" if disc == "lumped" else "clamped_free"
    out = {"mode_type": f.string("mode_type", default, choices=list(MODE_TYPES))}
    if out["mode_type"] == "clamped_mass":
        for key, unit in (("tip_mass", "kg"), ("tip_inertia", "kg m^2")):
            if f.has(key):
                out[key] = f.number(key, nonnegative=True, unit=unit)
    return out


def arm_from_dict(data: dict, source: str = "<memory>") -> ArmDescription:
    """Validate a parsed arm description; errors name ``source`` and the field path."""
    f = Fields(data, source, "")
    name = f.string("name")
    description = f.string("description", "")
    gravity = tuple(f.vector("gravity", 2, [0.0, -9.81], unit="m/s^2"))
    kinematics = f.string("kinematics", "small_deflection", choices=list(KINEMATICS))
    axial_vars = f.integer("axial_vars", 0, min_value=0, max_value=AXIAL_VARS_MAX)
    pay = f.mapping("payload", {})
    payload_mass = pay.number("mass", 0.0, nonnegative=True, unit="kg")
    payload_inertia = pay.number("inertia", 0.0, nonnegative=True, unit="kg m^2")
    pay.done()
    raw_links = f.items("links", min_len=1)
    links = tuple(_link(Fields(r, source, f"links[{i}]"), i) for i, r in enumerate(raw_links))
    raw_joints = f.items("joints", [{} for _ in links])
    if len(raw_joints) != len(links):
        raise f.error("joints", len(raw_joints),
                      f"one joint per link ({len(links)} entries)")
    joints = []
    for i, r in enumerate(raw_joints):
        jf = Fields(r, source, f"joints[{i}]")
        joints.append(JointDescription(name=jf.string("name", f"joint{i + 1}"),
                                       type=jf.string("type", "revolute",
                                                      choices=["revolute"])))
        jf.done()
    names = [j.name for j in joints]
    if len(set(names)) != len(names):
        raise f.error("joints", names, "unique joint names")
    from .effects import parse_effects
    effects = parse_effects(f.items("effects", []), source, names, [lk.name for lk in links])
    from .effects import NOMINAL_TOLERANCES
    tf = f.mapping("tolerances", {})
    tolerances = tuple((k, tf.number(k, nonnegative=True, max_value=1.0))
                       for k in NOMINAL_TOLERANCES if tf.has(k))
    tf.done(list(NOMINAL_TOLERANCES))
    from .sensors import Sensor
    sensors = tuple(Sensor.parse(Fields(r, source, f"sensors[{k}]"), names,
                                 [lk.name for lk in links])
                    for k, r in enumerate(f.items("sensors", [])))
    f.done()
    return ArmDescription(name=name, links=links, joints=tuple(joints), gravity=gravity,
                          payload_mass=payload_mass, payload_inertia=payload_inertia,
                          description=description, source=source, kinematics=kinematics,
                          effects=effects, sensors=sensors, tolerances=tolerances,
                          axial_vars=axial_vars).check_axial()


def preset_names() -> list[str]:
    return sorted(p.stem for p in PRESET_DIR.glob("*.yaml"))


def resolve_preset(name_or_path: str | Path, directory: Path = PRESET_DIR) -> Path:
    """Path of a preset by name, or the given path if it is a file."""
    path = Path(name_or_path)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return path
    candidate = directory / f"{name_or_path}.yaml"
    if candidate.exists():
        return candidate
    known = ", ".join(sorted(p.stem for p in directory.glob("*.yaml")))
    raise ConfigError(str(name_or_path), "<preset>", str(name_or_path),
                      f"an existing YAML file or a preset name ({known})")


def load_arm(name_or_path: str | Path, vars_per_link: int | None = None) -> ArmDescription:
    """Load and validate an arm description by preset name or path."""
    path = resolve_preset(name_or_path)
    arm = arm_from_dict(read_yaml(path), str(path))
    return arm.with_vars_per_link(vars_per_link) if vars_per_link is not None else arm
