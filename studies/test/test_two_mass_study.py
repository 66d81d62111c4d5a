"""The frequency-domain diagnosis of the two-mass bench's rigid nominal twin
(studies.two_mass_study, issue 22). Reads ../shared/data/real/two_mass_motor_bench_fditools
(skipped when absent)."""
import pytest

from flex_model.arm import arm_from_dict, load_arm
from studies.two_mass_data import TWO_MASS, period_frf, read_two_mass
from flex_twin.real_arms.two_mass_twin import arm_dict, parameters_from_arm
from studies.two_mass_study import fd_diagnosis


@pytest.fixture(scope="module")
def bench(shared_dir):
    root = shared_dir / "data" / "real"
    if not (root / TWO_MASS).is_dir():
        pytest.skip(f"real data not present ({root / TWO_MASS})")
    recs = {r: read_two_mass(r, root) for r in "AB"}
    return {"labs": {r: period_frf(x) for r, x in recs.items()},
            "p": parameters_from_arm(load_arm("two_mass_bench"))}


def test_diagnosis_names_the_coupling_elasticity(bench):
    """From the rigid nominal twin (inertias summed), fitted on A's motor FRF: the joint
    elasticity is named, its stiffness within 2 % of the two-inertia fit of both FRFs
    (539 N m/rad per N m/A of K_t), and it removes > 80 % of B's held-out gap."""
    nominal = arm_from_dict(arm_dict(bench["p"], elastic=False))
    d = fd_diagnosis(nominal, bench["labs"]["A"], bench["labs"]["B"])
    assert [h["hypothesis"] for h in d["named"]] == ["joint_elasticity@coupling"]
    best = d["named"][0]
    assert best["values"]["stiffness"] == pytest.approx(bench["p"].k, rel=0.02)
    assert 0.0 < best["values"]["damping"] < 0.2
    assert best["share"] > 0.8
    others = [h["share"] for h in d["hypotheses"][1:]]
    assert max(others) < 0.3
