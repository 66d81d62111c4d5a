"""Fixed-step runs saved for a bit-for-bit comparison of two versions (issue 43, the one
loop): section E arm (4 variables per link, 1 ms, 0.4 s, 1 kN m pulse) with small-deflection,
second-order (full and simplified Newton) and exact kinematics, 300 direct steps of
integrators.generalized_alpha, a stick-slip joint over 1 s. Prints the CPU time.

    python bench/one_loop_runs.py out.npz    # on each version, then np.array_equal
"""
import sys
import time

import numpy as np
from flex_model.arm import arm_from_dict, load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.simulate import JointPD, Pulse, simulate
from flex_model.effects import StickSlipFriction, StructuralDamping
from flex_model.inputs import input_data
from flex_model.integrators import consistent_acceleration, generalized_alpha
TH0 = np.radians([-20.0, 20.0, -20.0])


def run(model, newton, t_final=0.4):
    return simulate(model, model.q_from_joint_angles(TH0), t_final=t_final,
                    sample_period=0.005, method="fixed", dt=1e-3, newton=newton,
                    pd=JointPD(np.full(3, 5e3), np.full(3, 250.0), TH0),
                    pulses=[Pulse(0.1, 0.2, (1000.0, 0.0, 0.0))])


def effect(cls, target="", **values):
    return cls(target=target, values=tuple(values.get(p.name, p.off) for p in cls.PARAMETERS))


def main():
    t0 = time.process_time()
    out = {}
    arm = load_arm("thesis_three_link", 4)
    for kin, newtons in (("small_deflection", ("full",)),
                         ("second_order", ("full", "simplified")), ("exact", ("full",))):
        m = FlexArmModel(arm.with_kinematics(kin))
        for nw in newtons:
            r = run(m, nw)
            out[f"{kin}_{nw}_q"] = r.q
            out[f"{kin}_{nw}_v"] = r.v
            out[f"{kin}_{nw}_it"] = np.array([r.stats["newton_iterations"]])
    m = FlexArmModel(arm)
    x = np.concatenate([m.q_from_joint_angles(TH0), np.zeros(m.nq)])
    E = input_data(m, None, (), np.zeros(3))
    a = consistent_acceleration(0.0, x, m.P, E)
    X, st, t, xe, a1, ab1, it = generalized_alpha(0.0, x, a, a.copy(), 1e-3, 300, 1, 0.9,
                                                  1e-10, 1e6, m.P, E)
    out["direct_X"], out["direct_it"] = X, np.array([it, st])
    rot = arm_from_dict({"name": "rotor", "gravity": [0.0, 0.0], "links": [{
        "length": 1.0, "section": {"shape": "explicit", "EI": 1e3, "m": 0.01},
        "discretization": "assumed_modes", "variables": 1, "end_masses": {"J_minus": 0.1}}]})
    slip = effect(StickSlipFriction, "joint1", coulomb=1.0, static=1.5,
                  stribeck_velocity=0.05, stiffness=1e4,
                  damping=2.0 * np.sqrt(1e4 * 0.10333), elastic_fraction=0.5)
    mr = FlexArmModel(rot.with_effects(
        effect(StructuralDamping, "link1", rayleigh_stiffness=1e-4), slip))
    r = simulate(mr, np.zeros(mr.nq), t_final=1.0, sample_period=0.01,
                 pulses=[Pulse(0.0, 10.0, (1.6,))], method="fixed")
    out["ss_q"], out["ss_v"] = r.q, r.v
    np.savez(sys.argv[1], **out)
    print("cpu", time.process_time() - t0)


if __name__ == "__main__":
    main()
