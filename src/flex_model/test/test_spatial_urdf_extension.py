"""URDF ``<flex:flexible>`` link extension elements (issue 25: "links marked flexible in a
side file ... or in URDF <link> extension elements become flexible"): the element gives
the same arm as the side YAML, bad values are named by file, element path, value and what
is allowed, and a link made flexible twice is refused."""
from pathlib import Path

import numpy as np
import pytest

from flex_model.config import ConfigError
from flex_model.spatial import SpatialArmModel, load_spatial_arm
from flex_model.spatial.analysis import natural_modes, static_equilibrium
from flex_model.spatial.description import SPATIAL_PRESET_DIR
from flex_model.spatial.urdf import load_urdf_arm, spatial_arm_from_urdf

EXT = SPATIAL_PRESET_DIR / "ur5_like_arm_flexible_forearm.urdf"
PLAIN = SPATIAL_PRESET_DIR / "ur5_like_arm.urdf"


@pytest.fixture(scope="module")
def arms():
    side = load_spatial_arm("ur5_like_flexible_forearm")       # URDF + side YAML
    ext = load_spatial_arm("ur5_like_flexible_forearm_element")  # URDF with the element
    assert ext.name == "ur5_like_flexible_forearm_element"
    return SpatialArmModel(side), SpatialArmModel(ext)


def test_the_element_gives_the_side_yaml_arm(arms):
    side, ext = arms
    assert ext.nq == side.nq == 19
    assert [b is None for b in ext.beams] == [b is None for b in side.beams]
    rng = np.random.default_rng(25)
    for _ in range(3):   # frames of the deflected arm at random states (1e-12)
        q = rng.normal(0.0, 0.3, side.nq)
        q[side.flex_slice(2)] *= 0.01
        for Fa, Fb in zip(side.frames(q), ext.frames(q)):
            np.testing.assert_allclose(Fb, Fa, rtol=0, atol=1e-12)
        np.testing.assert_allclose(ext.mass_matrix(q), side.mass_matrix(q), rtol=0,
                                   atol=1e-12)
    np.testing.assert_array_equal(ext.K, side.K)
    theta = np.array([0.2, -0.6, 1.1, -0.4, 0.5, 0.3])
    fa = natural_modes(side, theta).frequencies_hz
    fb = natural_modes(ext, theta).frequencies_hz
    np.testing.assert_allclose(fb, fa, rtol=1e-12)
    assert 40.0 < fa[0] < 50.0                 # the forearm tube's first mode (docs: 43.5)
    sa, sb = static_equilibrium(side, theta), static_equilibrium(ext, theta)
    np.testing.assert_allclose(sb.tip_position, sa.tip_position, rtol=0, atol=1e-12)
    # the element really makes the forearm flexible: without it the arm is rigid
    plain = SpatialArmModel(load_urdf_arm(PLAIN))
    assert plain.nq == 6 and not any(b is not None for b in plain.beams)


def test_segments_and_taper_in_the_element_equal_the_yaml_list():
    """Two <flex:section length=..> segments, one tapered ("root tip"), = the YAML list."""
    text = EXT.read_text().replace(
        '<flex:section EI_y="6090.0" EI_z="6090.0" GJ="4520.0" rhoA="0.814" rhoJ="4.70e-4"/>',
        '<flex:section length="0.2" EI_y="6090.0" EI_z="5000 4000" GJ="4520.0" rhoA="0.814" '
        'rhoJ="4.70e-4"/>\n      <flex:section length="0.19225" EI_y="3000" EI_z="4000" '
        'GJ="2000" rhoA="0.5" rhoJ="3e-4"/>')
    ext = SpatialArmModel(spatial_arm_from_urdf(text, str(EXT)))
    yaml_flex = {"forearm_link": {
        "section": [{"length": 0.2, "EI_y": 6090.0, "EI_z": [5000.0, 4000.0], "GJ": 4520.0,
                     "rhoA": 0.814, "rhoJ": 4.70e-4},
                    {"length": 0.19225, "EI_y": 3000.0, "EI_z": 4000.0, "GJ": 2000.0,
                     "rhoA": 0.5, "rhoJ": 3e-4}],
        "variables": 4, "torsion_variables": 4,
        "root_body": {"mass": 1.2, "inertia": [0.0018, 0.00125, 0.0018]},
        "end_body": {"mass": 0.756, "inertia": [0.0008, 0.0008, 0.0008]}}}
    side = SpatialArmModel(spatial_arm_from_urdf(PLAIN.read_text(), str(PLAIN),
                                                 flexible_links=yaml_flex))
    theta = np.array([0.0, -0.5, 0.9, 0.0, 0.3, 0.0])
    fa = natural_modes(side, theta).frequencies_hz
    fb = natural_modes(ext, theta).frequencies_hz
    np.testing.assert_allclose(fb, fa, rtol=1e-12)
    uniform = natural_modes(SpatialArmModel(load_urdf_arm(EXT)), theta).frequencies_hz
    assert abs(fa[0] / uniform[0] - 1.0) > 0.05      # the segments changed the arm


WHERE = "robot/link[@name='forearm_link']/flex:flexible"


@pytest.mark.parametrize("old,new,path,words", [
    ('EI_y="6090.0"', 'EI_y="-1"', WHERE + "/flex:section[1]/@EI_y", "got -1.0; expected a "
     "number > 0"),
    ('EI_y="6090.0"', 'EI_y="stiff"', WHERE + "/flex:section[1]/@EI_y", "got 'stiff'"),
    ('variables="4" torsion', 'variables="3" torsion', WHERE + "/@variables",
     "an even integer"),
    ('<flex:root_body mass="1.2"', '<flex:root_body mass="-1.2"',
     WHERE + "/flex:root_body/@mass", "got -1.2; expected a number >= 0 (kg)"),
    ('rhoJ="4.70e-4"/>', 'rhoJ="4.70e-4" colour="red"/>', WHERE + "/flex:section[1]/@colour",
     "one of the attributes length, EI_y"),
    ('<flex:end_body', '<flex:tip_body', WHERE + "/flex:tip_body", "<flex:end_body> children"),
    ('<flex:section EI_y', '<flex:section length="0.3" EI_y', WHERE + "/flex:section",
     "adding up to the beam length 0.39225 m"),
    ('<flex:flexible variables="4" torsion_variables="4">', '<flexible variables="4">',
     "robot/link[@name='forearm_link']/flexible", 'xmlns:flex="urn:flex-arm-twin:urdf:1"'),
])
def test_bad_elements_name_file_path_value_and_what_is_allowed(old, new, path, words):
    text = EXT.read_text()
    assert text.count(old) == 1
    text = text.replace(old, new)
    if new.startswith("<flexible"):
        text = text.replace("</flex:flexible>", "</flexible>")
    with pytest.raises(ConfigError) as err:
        spatial_arm_from_urdf(text, str(EXT))
    msg = str(err.value)
    assert msg.startswith(f"{EXT}: {path}: "), msg
    assert words in msg, msg


def test_a_link_flexible_in_both_the_element_and_the_side_file_is_refused(tmp_path):
    side = tmp_path / "side.yaml"
    side.write_text(f"name: twice\nurdf: {EXT}\nflexible_links:\n  forearm_link:\n"
                    "    section: {EI_y: 1.0e3, EI_z: 1.0e3, GJ: 1.0e3, rhoA: 1.0, rhoJ: 1e-4}\n")
    with pytest.raises(ConfigError, match=r"side\.yaml: flexible_links\.forearm_link: .*"
                       r"conflicts are refused"):
        load_spatial_arm(side)
    # a side file with only the URDF reads the element
    only = tmp_path / "only.yaml"
    only.write_text(f"name: only_urdf\nurdf: {Path(EXT).name}\n")
    (tmp_path / Path(EXT).name).write_text(EXT.read_text())
    assert SpatialArmModel(load_spatial_arm(only)).nq == 19
