"""Arm descriptions and scenarios: validation messages and shipped presets."""
import copy
import re

import numpy as np
import pytest
import yaml

from flex_model import arm as arm_mod
from flex_model.arm import load_arm, preset_names
from flex_model.config import ConfigError
from flex_model.scenario import SCENARIO_DIR, load_scenario, scenario_names

EXAMPLE1 = arm_mod.PRESET_DIR / "thesis_example1.yaml"
BASE_ARM = yaml.safe_load(EXAMPLE1.read_text())
BASE_SCENARIO = yaml.safe_load((SCENARIO_DIR / "thesis_three_link_pd.yaml").read_text())
SHAPES = "square_hollow, rectangular_hollow, rectangular, circular, circular_hollow, explicit"


def _drop(d, key):
    del d[key]


def _segments(d):
    link = d["links"][0]
    section = link.pop("section")
    link["segments"] = [{"length": 1.0, "section": section},
                        {"length": 0.5, "section": section}]


# (id, change to the example 1 dict, field path, value as shown, what is allowed)
ARM_ERRORS = [
    ("negative_length", lambda d: d["links"][0].update(length=-2.0),
     "links[0].length", "-2.0", "a number > 0 (m)"),
    ("zero_stiffness", lambda d: d["links"][0].update(
        section={"shape": "explicit", "EI": 0, "m": 1.0}),
     "links[0].section.EI", "0.0", "a number > 0"),
    ("unknown_top_key", lambda d: d.update(colour="red"),
     "colour", "'red'",
     "no such field (known: axial_vars, description, effects, gravity, joints, kinematics, "
     "links, "),
    ("unknown_link_key", lambda d: d["links"][1].update(colour="red"),
     "links[1].colour", "'red'", "no such field (known: "),
    ("unknown_section_key", lambda d: d["links"][0]["section"].update(radius=0.1),
     "links[0].section.radius", "0.1", "no such field (known: shape, side, wall)"),
    ("string_for_number", lambda d: d["links"][0].update(length="two"),
     "links[0].length", "'two'", "a number > 0 (m)"),
    ("list_for_mapping", lambda d: d["links"][0].update(material=[6.4e10, 2700.0]),
     "links[0].material", "[64000000000.0, 2700.0]", "a mapping of fields"),
    ("missing_name", lambda d: _drop(d, "name"), "name", "<missing>", "this required field"),
    ("missing_links", lambda d: _drop(d, "links"), "links", "<missing>",
     "this required field"),
    ("missing_length", lambda d: _drop(d["links"][0], "length"), "links[0].length",
     "<missing>", "this required field"),
    ("missing_section", lambda d: _drop(d["links"][0], "section"), "links[0].section",
     "<missing>", "exactly one of 'section' or 'segments'"),
    ("thick_wall", lambda d: d["links"][0]["section"].update(wall=0.011),
     "links[0].section.wall", "0.011", "less than half the outer dimension at the root (0.02 m)"),
    ("segments_sum", _segments, "links[0].segments", "1.5",
     "segment lengths summing to length = 2.0 m"),
    ("odd_variables", lambda d: d["links"][0].update(variables=3),
     "links[0].variables", "3", "an even integer >= 2 <= 200"),
    ("unknown_shape", lambda d: d["links"][1]["section"].update(shape="triangle"),
     "links[1].section.shape", "'triangle'", f"one of {SHAPES}"),
    ("duplicate_joints", lambda d: d.update(joints=[{"name": "j"}, {"name": "j"}]),
     "joints", "['j', 'j']", "unique joint names"),
    ("joint_count", lambda d: d.update(joints=[{"name": "joint1"}]),
     "joints", "1", "one joint per link (2 entries)"),
]
ARM_ERRORS = [pytest.param(*c, id=c[0]) if type(c) is tuple else c for c in ARM_ERRORS]


def _message(path, field, shown, allowed):
    return re.escape(f"{path}: {field}: got {shown}; expected {allowed}")


@pytest.mark.parametrize("case, change, field, shown, allowed", ARM_ERRORS)
def test_arm_error_names_file_field_value_and_allowed(tmp_path, case, change, field, shown,
                                                      allowed):
    data = copy.deepcopy(BASE_ARM)
    change(data)
    path = tmp_path / f"{case}.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=_message(path, field, shown, allowed)) as info:
        load_arm(path)
    assert (info.value.source, info.value.path) == (str(path), field)


def test_unknown_preset_name_lists_the_presets():
    known = ", ".join(preset_names())
    with pytest.raises(ConfigError, match=_message("no_such_arm", "<preset>", "'no_such_arm'",
                                                   f"an existing YAML file or a preset "
                                                   f"name ({known})")):
        load_arm("no_such_arm")


def test_missing_yaml_file_is_named(tmp_path):
    path = tmp_path / "absent.yaml"
    with pytest.raises(ConfigError, match=_message(path, "<file>", repr(str(path)),
                                                   "a readable file (No such file")):
        load_arm(path)


def test_yaml11_exponent_string_is_a_number(tmp_path):
    text = EXAMPLE1.read_text()
    assert "E: 6.4e10" in text and yaml.safe_load(text)["links"][0]["material"]["E"] == "6.4e10"
    path = tmp_path / "arm.yaml"
    path.write_text(text)
    arm = load_arm(path)
    assert [lk.segments[0].E for lk in arm.links] == [6.4e10, 6.4e10]
    ei = arm.links[0].profile.properties(0.0)[0][0]
    assert ei == pytest.approx(6.4e10 * (0.02**4 - 0.018**4) / 12, rel=1e-12)


def test_tapered_section_has_root_and_tip_stiffness(tmp_path):
    data = copy.deepcopy(BASE_ARM)
    data["links"][0]["section"]["side"] = [0.05, 0.03]
    path = tmp_path / "tapered.yaml"
    path.write_text(yaml.safe_dump(data))
    link = load_arm(path).links[0]
    ei, m, _ = link.profile.properties([0.0, 1.0, 2.0])
    for z, side in zip(ei, (0.05, 0.04, 0.03)):
        assert z == pytest.approx(6.4e10 * (side**4 - (side - 0.002)**4) / 12, rel=1e-12)
    assert ei[0] > 4 * ei[2]
    assert m[2] == pytest.approx(2700.0 * (0.03**2 - 0.028**2), rel=1e-12)


def test_with_vars_per_link():
    arm = load_arm("thesis_example1")
    assert [lk.n_vars for lk in arm.with_vars_per_link(6).links] == [6, 6]
    for bad in (3, 0):
        with pytest.raises(ConfigError, match=f"vars_per_link: got {bad}; expected an even "
                                              "integer >= 2"):
            arm.with_vars_per_link(bad)


@pytest.mark.parametrize("name", preset_names())
def test_every_arm_preset_loads(name):
    arm = load_arm(name)
    assert arm.name == name and arm.description
    assert len(arm.joints) == arm.n_links >= 1
    assert len(set(arm.joint_names)) == arm.n_links
    for lk in arm.links:
        assert lk.profile.length == pytest.approx(lk.length, rel=1e-12)
        ei, m, _ = lk.profile.properties(np.linspace(0.0, lk.length, 5))
        assert np.all(ei > 0) and np.all(m > 0)


@pytest.mark.parametrize("name", scenario_names())
def test_every_scenario_preset_loads(name):
    sc = load_scenario(name)
    assert sc.name == name and sc.duration > 0 and sc.sample_period <= sc.duration
    assert sc.joint_values.shape == sc.joint_rates.shape == (sc.arm.n_links,)


def test_three_link_pd_scenario_values():
    sc = load_scenario("thesis_three_link_pd")
    assert np.degrees(sc.joint_values) == pytest.approx([-20.0, 20.0, -20.0], abs=1e-12)
    assert list(sc.pd.kp) == [5000.0] * 3 and list(sc.pd.kd) == [250.0] * 3
    assert (sc.pulses[0].start, sc.pulses[0].end) == (3.0, 4.0)
    assert list(sc.pulses[0].joint_torques) == [1000.0, 0.0, 0.0]
    assert (sc.method, sc.rtol) == ("variable", 1e-7)


def _pulse(**kw):
    return lambda d: d["pulses"][0].update(**kw)


SCENARIO_ERRORS = [
    ("pulse_joint", _pulse(joint="joint9"), "pulses[0].joint", "'joint9'",
     "a joint name (joint1, joint2, joint3) or number 1..3"),
    ("pulse_end", _pulse(end=3.0), "pulses[0].end", "3.0", "a time after start (3.0 s)"),
    ("setpoints", lambda d: d["control"]["pd"].update(setpoints_deg=[-20.0, 20.0]),
     "control.pd.setpoints_deg", "[-20.0, 20.0]", "a list of 3 numbers (deg)"),
    ("integrator", lambda d: d["integrator"].update(method="euler"),
     "integrator.method", "'euler'", "one of variable, fixed"),
]
SCENARIO_ERRORS = [pytest.param(*c, id=c[0]) for c in SCENARIO_ERRORS]


@pytest.mark.parametrize("case, change, field, shown, allowed", SCENARIO_ERRORS)
def test_scenario_error_names_file_field_value_and_allowed(tmp_path, case, change, field,
                                                           shown, allowed):
    data = copy.deepcopy(BASE_SCENARIO)
    change(data)
    path = tmp_path / f"{case}.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=_message(path, field, shown, allowed)):
        load_scenario(path)
