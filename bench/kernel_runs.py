"""Kernel values and short runs saved for a bit-for-bit comparison of two versions (issue
43, functions that fit on a screen; one_loop_runs.py has the planar runs):

- spatial: on the arms of test_spatial_compiled (DH with dh_x and aux_z beams, a
  prismatic joint, torsion, bending rotary inertia, a URDF arm, the effects arm with
  rotors and motors), each with small-deflection, second-order and exact kinematics,
  compiled.spatial_eval (with M and the residual only) and tip_point at three random
  states and 60 compiled fixed steps of 0.1 ms under a constant joint torque;
- planar, second-order kinematics (section E arm, 8 variables per link): the inverse
  dynamics and the structured iteration matrix's factor (iteration_matrix) at random
  states, deflected and not;
- planar, exact kinematics: exact_kinematics.terms (B, c, J_tip) at random states.

    python bench/kernel_runs.py out.npz    # on each version, then np.array_equal
"""
import dataclasses
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "src", "flex_model", "test"))
from test_linear_cost import _model, _state, _structured  # noqa: E402  (written once there)
from test_spatial_compiled import _models  # noqa: E402

from flex_model.arm import load_arm  # noqa: E402
from flex_model.dynamics import FlexArmModel  # noqa: E402
from flex_model.exact_kinematics import terms  # noqa: E402
from flex_model.inputs import JointPD, input_data  # noqa: E402
from flex_model.iteration_matrix import structured_factor  # noqa: E402
from flex_model.spatial import SpatialArmModel  # noqa: E402
from flex_model.spatial.compiled import pack, spatial_eval, tip_point  # noqa: E402
from flex_model.spatial.integrate import joint_input_matrix, simulate_fixed_compiled  # noqa


def spatial(out):
    for name, base in _models().items():
        for kin in ("small_deflection", "second_order", "exact"):
            m = SpatialArmModel(dataclasses.replace(base.arm, kinematics=kin))
            data = pack(m)
            rng = np.random.default_rng(3)
            for s in range(3):
                q, v, a = (rng.normal(scale=x, size=m.nq) for x in (0.3, 2.0, 5.0))
                for want in (True, False):
                    M, f = spatial_eval(data, q, v, a, want)
                    out[f"{name}_{kin}_{s}_{int(want)}_M"] = M
                    out[f"{name}_{kin}_{s}_{int(want)}_f"] = f
                o, Jo = tip_point(data, q)
                out[f"{name}_{kin}_{s}_tip"] = np.concatenate([o, Jo.ravel()])
            nj = joint_input_matrix(m).shape[1]
            r = simulate_fixed_compiled(m, np.zeros(m.nq), np.zeros(m.nq), 1e-4, 60,
                                        joint_torques=np.full(nj, 0.5))
            out[f"{name}_{kin}_run_q"] = np.asarray(r.q)
            out[f"{name}_{kin}_run_v"] = np.asarray(r.v)
            out[f"{name}_{kin}_run_it"] = np.array([r.newton_iterations])


def planar(out):
    rng = np.random.default_rng(4)
    m = _structured(_model(8))
    E = input_data(m, JointPD(np.full(3, 5e3), np.full(3, 250.0), np.zeros(3)), (),
                   np.zeros(3))
    for scale in (0.0, 1e-3, 1e-2):
        q, v = _state(m, rng, scale)
        out[f"second_order_{scale}_f"] = m.inverse_dynamics(q, v, rng.normal(size=m.nq))
        for k, x in enumerate(structured_factor(q, v, 6e-4, 3e-7, m.P, E)):
            out[f"factor_{scale}_{k}"] = np.asarray(x)
    ex = FlexArmModel(load_arm("thesis_three_link", 4).with_kinematics("exact"))
    for s in range(3):
        q = ex.q_from_joint_angles(np.radians([-20.0, 20.0, -20.0]))
        q = q + 0.01 * rng.normal(size=ex.nq)
        for k, x in enumerate(terms(q, rng.normal(size=ex.nq), 0.3, -9.81, ex._exact.data)):
            out[f"exact_{s}_{k}"] = x


def main():
    t0 = time.process_time()
    out = {}
    planar(out)
    spatial(out)
    np.savez(sys.argv[1], **out)
    print("cpu", time.process_time() - t0, "arrays", len(out))


if __name__ == "__main__":
    main()
