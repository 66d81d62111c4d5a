"""Issue 44, item 3: an elastic joint behind a motor rotor. On a joint whose nominal arm
declares no rotor (a hub-less arm) the joint-elasticity hypothesis carries the motor-side
inertia, fitted with the spring's stiffness and damping (seed 002 Eqs. 11-14); behind a
gear the rotor is the gear's n^2 J_r (known within its tolerance) and the hypothesis keeps
the spring's two parameters."""
from pathlib import Path

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_twin.diagnosis.hypotheses import MOTOR_INERTIA, _elasticity

SUITE = Path(__file__).resolve().parents[3] / "test" / "data" / "independent_suite"


def _hypothesis(case, joint):
    """The elasticity hypothesis of ``joint`` on the nominal arm of a stored suite case
    (as library_hypotheses states it; k_ref 1e4 N m/rad, 50 N m at 5 mrad)."""
    arm = load_arm(SUITE / case / "arm.yaml")
    gear = arm.effect("gear", joint)
    return arm, _elasticity(joint, 1e4, bool(gear and gear["rotor_inertia"]))


def test_a_hub_less_joint_elasticity_fits_its_motor_inertia():
    arm, h = _hypothesis("A-cont-healthy-s1", "joint1")
    assert h.names == ("stiffness", "damping", "motor_inertia")
    # off: a rigid joint; the motor inertia's off value is the fixed one of before
    assert np.allclose(h.values(h.off())[1:], [0.0, MOTOR_INERTIA])
    # a probe moves the motor inertia alone (with a spring): its column is screened
    assert any(p[2] != h.off()[2] for p in h.probes)
    x = np.array([1.0, 1.0, 0.05 / MOTOR_INERTIA])      # a 0.05 kg m^2 rotor
    twin, _ = h.apply(arm, x)
    e = twin.effect("joint_elasticity", "joint1")
    assert e["motor_inertia"] == pytest.approx(0.05)
    assert e["stiffness"] == pytest.approx(h.scale[0])
    assert h.effect_dicts(arm, x)[0]["motor_inertia"] == pytest.approx(0.05)


def test_behind_a_gear_the_rotor_is_the_gears():
    arm, h = _hypothesis("B-samp500-healthy-s1", "joint2")
    assert h.names == ("stiffness", "damping")
    twin, _ = h.apply(arm, np.array([1.0, 1.0]))
    gear = arm.effect("gear", "joint2")
    assert twin.effect("joint_elasticity", "joint2")["motor_inertia"] == pytest.approx(
        gear["ratio"] ** 2 * gear["rotor_inertia"])


if not SUITE.is_dir():  # pragma: no cover - the suite is committed with the tests
    pytest.skip(f"{SUITE} missing", allow_module_level=True)
