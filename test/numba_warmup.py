"""Compile the suite's numba kernels into the on-disk cache, in a background process.

conftest.py starts this script when a session collects most of the suite: on a fresh
clone every compiled loop is compiled once (tens of seconds each, single-threaded), and
the test process would do it serially while the second core idles. Here the loops that
later tests need are compiled first, on the other core; a test that gets there first
compiles for itself as before (numba writes its cache files atomically). It computes
nothing the tests check: tiny runs through the public functions, so that the argument
types are those of the tests. Errors are ignored (the tests report them).
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def replay_loops(tmp: Path) -> None:
    """The diagnosis replay: the sampled loop (synthetic cases) and the continuous one."""
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_twin.diagnosis.controller import load_controller
    from flex_twin.diagnosis.recording import load_csv
    from flex_twin.diagnosis.replay import replay
    from flex_twin.diagnosis.synthetic import generate_case
    case = generate_case("healthy", 1000, tmp / "case", duration=0.1, noise="none")
    replay(FlexArmModel(load_arm(case.nominal_arm)), load_controller(case.controller),
           load_csv(case.fit_csv, 2))
    suite = HERE / "data" / "independent_suite" / "A-cont-healthy-s1"
    rec = load_csv(suite / "recording.csv", 2)
    replay(FlexArmModel(load_arm(suite / "arm.yaml")), load_controller(suite / "controller.yaml"),
           rec.window(rec.t[0], rec.t[0] + 0.02))


def in_loop_control() -> None:
    """Eq. 95 in the model's loop (flex_model.control_kernel)."""
    from flex_model.arm import load_arm
    from flex_model.control_loop import ControlLoop
    from flex_model.controller_interface import load_controller
    from flex_model.dynamics import FlexArmModel
    from flex_model.stepper import Stepper
    model = FlexArmModel(load_arm("thesis_example1_motors"))
    ctl = load_controller("eq95", list(model.arm.joint_names), {"h": [25.0], "a": [5.0]})
    ControlLoop(Stepper(model), ctl, 2e-3).advance(2)


def variable_step() -> None:
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_model.simulate import simulate
    model = FlexArmModel(load_arm("thesis_three_link"))
    z = np.zeros(model.nq)
    simulate(model, z, z, t_final=1e-3, sample_period=1e-3, method="variable")


def structured_newton() -> None:
    """Simplified Newton on the banded-plus-low-rank iteration matrix (flex_model.
    iteration_matrix: from dynamics.STRUCTURED_MIN_VARS variables per link) and the full
    Newton of second order, as test_linear_cost.py runs them."""
    from flex_model.arm import load_arm
    from flex_model.dynamics import STRUCTURED_MIN_VARS, FlexArmModel
    from flex_model.simulate import simulate
    for nv, newton in ((STRUCTURED_MIN_VARS, "simplified"), (8, "full"), (8, "simplified")):
        model = FlexArmModel(load_arm("thesis_three_link", nv).with_kinematics("second_order"))
        z = np.zeros(model.nq)
        simulate(model, z, z, t_final=2e-3, sample_period=1e-3, method="fixed", dt=1e-3,
                 newton=newton)


def spatial() -> None:
    from flex_model.spatial.loader import load_spatial_arm
    from flex_model.spatial.dynamics import SpatialArmModel
    from flex_model.spatial.integrate import simulate_fixed_compiled
    model = SpatialArmModel(load_spatial_arm("seed000_real_arm_3d"))
    z = np.zeros(model.nq)
    simulate_fixed_compiled(model, z, z, 1e-3, 2)


def main() -> int:
    with tempfile.TemporaryDirectory() as tmp:
        for step in (lambda: replay_loops(Path(tmp)), in_loop_control, variable_step,
                     structured_newton, spatial):
            try:
                step()
            except Exception as exc:  # noqa: BLE001 - the tests report real failures
                print(f"numba warm-up: {exc!r}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
