"""Fixed-step runs saved for a bit-for-bit comparison of two versions (issue 43, the one
loop): section E arm (4 variables per link, 1 ms, 0.4 s, 1 kN m pulse) with small-deflection,
second-order (full and simplified Newton) and exact kinematics, 300 direct steps of
solvers.loop.fixed_step, a stick-slip joint over 1 s; and the spatial arm's compiled
loop (issue 43, spatial.integrate.simulate_fixed_compiled): the two preset scenarios, the
seed 003 joint-type arm with friction, backlash, a held and a locked joint, DC motors, a
contact surface with a tip force, end stops, exact kinematics (curvature coupling), a
continued run and a restart, and failing steps (their substeps and the error). Prints the
CPU time.

    python bench/one_loop_runs.py out.npz [planar|spatial]   # on each version, then
                                                             # np.array_equal on every array
"""
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
from flex_model.arm import arm_from_dict, load_arm
from flex_model.dynamics import FlexArmModel
from flex_model.simulate import JointPD, Pulse, simulate
from flex_model.effects import StickSlipFriction, StructuralDamping
from flex_model.inputs import input_data
from flex_model.integrators import PlanarModel, consistent_acceleration
from flex_model.solvers.loop import fixed_step
from flex_model.solvers.status import newton_settings
TH0 = np.radians([-20.0, 20.0, -20.0])


def run(model, newton, t_final=0.4):
    return simulate(model, model.q_from_joint_angles(TH0), t_final=t_final,
                    sample_period=0.005, method="fixed", dt=1e-3, newton=newton,
                    pd=JointPD(np.full(3, 5e3), np.full(3, 250.0), TH0),
                    pulses=[Pulse(0.1, 0.2, (1000.0, 0.0, 0.0))])


def effect(cls, target="", **values):
    return cls(target=target, values=tuple(values.get(p.name, p.off) for p in cls.PARAMETERS))


def planar(out):
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
    X, st, t, xe, a1, ab1, it = fixed_step(PlanarModel(m.P, E), m.nq, 0.0, x, a, a.copy(),
                                           1e-3, 300, 1, newton_settings(0.9, 1e-10, 1e6),
                                           None)
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


def _save(out, key, run):
    out[f"{key}_q"], out[f"{key}_v"] = run.q, run.v
    out[f"{key}_it"] = np.array([run.newton_iterations])
    if run.acceleration is not None:
        out[f"{key}_acc"] = np.asarray(run.acceleration)


def _test_module(name):
    """A test module of flex_model by name (its arm builders)."""
    import importlib.util
    from flex_model.spatial.description import SPATIAL_PRESET_DIR
    path = Path(SPATIAL_PRESET_DIR).parent.parent.parent / "test" / f"{name}.py"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def spatial(out):
    from flex_model.errors import SimulationDivergedError
    from flex_model.scenario import load_scenario
    from flex_model.spatial.dynamics import SpatialArmModel
    from flex_model.spatial.integrate import simulate_fixed_compiled as run
    from flex_model.spatial.loader import spatial_arm_from_dict
    for name, duration in (("seed003_like_pd_step", 0.3), ("seed000_3d_pd_step", 0.2)):
        res = dataclasses.replace(load_scenario(name), duration=duration).run(advise=False)
        out[f"{name}_q"], out[f"{name}_v"] = res.q, res.v
        out[f"{name}_it"] = np.array([res.stats["newton_iterations"]])
    backlash, motor, contact = (_test_module(n) for n in (
        "test_spatial_effects_backlash", "test_spatial_effects_motor", "test_spatial_contact"))
    data, motors = backlash._backlash_arm(), motor._motor_arm()
    rng = np.random.default_rng(2)
    for key, d in (("effects", data), ("motors", motors)):
        m = SpatialArmModel(spatial_arm_from_dict(d))
        tau = rng.normal(scale=2.0, size=(200, m.n_links))
        q0 = rng.normal(scale=0.1, size=m.nq)
        v0 = rng.normal(scale=0.5, size=m.nq)
        q0[m.held], v0[m.held] = 0.3, 0.0
        a = run(m, q0, v0, 1e-3, 100, joint_torques=tau[:100])
        _save(out, key, a)
        _save(out, key + "_continued", run(m, a.q[-1], a.v[-1], 1e-3, 100,
                                           joint_torques=tau[100:], acceleration=a.acceleration))
        _save(out, key + "_restart", run(m, a.q[-1], a.v[-1], 1e-3, 100,
                                         joint_torques=-tau[100:], restart_from=a.acceleration))
        for max_iter in (12, 8, 2):     # failing steps: their substeps, or the error
            try:
                _save(out, f"{key}_fail{max_iter}", run(m, q0, v0, 1e-3, 50, max_iter=max_iter,
                                                        joint_torques=tau[:50]))
            except SimulationDivergedError as exc:
                out[f"{key}_fail{max_iter}_error"] = np.array([str(exc)])
    m, q0 = contact._seed003_with_contact()
    v0 = np.zeros(m.nq)
    v0[m.off] = [0.2, 0.3, -0.4]
    tipf = np.outer(np.sin(np.arange(100) * 0.05), [1.0, -2.0, 3.0])
    _save(out, "contact", run(m, q0, v0, 1e-3, 100, joint_torques=[1.0, 30.0, 8.0],
                              tip_force=tipf))
    stop = {"name": "stop_link", "gravity": [0.0, 0.0, -9.81],
            "joint_stops": {"stiffness": 1e3, "damping": 5.0, "transition": 1e-3},
            "links": [{"name": "link1", "end_body": {"mass": 1.0},
                       "joint": {"name": "joint1", "a": 0.5, "lower": -0.2, "upper": 0.2,
                                 "effort": 5.0},
                       "flexible": {"section": {"EI_y": 20.0, "EI_z": 20.0, "GJ": 15.0,
                                                "rhoA": 0.2, "rhoJ": 1e-5}, "variables": 4},
                       "root_body": {"mass": 0.5, "inertia": [0.01, 0.01, 0.05]}}]}
    m = SpatialArmModel(spatial_arm_from_dict(stop, "stop_link.yaml"))
    v0 = np.zeros(m.nq)
    v0[0] = 2.0
    _save(out, "stops", run(m, np.zeros(m.nq), v0, 1e-3, 400, joint_torques=[8.0]))
    exact = dict(stop, kinematics="exact", name="exact")
    exact.pop("joint_stops")
    exact["links"] = [dict(exact["links"][0], flexible=dict(
        exact["links"][0]["flexible"], torsion_variables=2))]
    m = SpatialArmModel(spatial_arm_from_dict(exact, "exact.yaml"))
    _save(out, "exact", run(m, np.zeros(m.nq), np.zeros(m.nq), 1e-3, 300,
                            joint_torques=[[3.0]] * 150 + [[-3.0]] * 150, rho_inf=0.5))


def main():
    t0 = time.process_time()
    out = {}
    which = sys.argv[2] if len(sys.argv) > 2 else "both"
    if which in ("planar", "both"):
        planar(out)
    if which in ("spatial", "both"):
        spatial(out)
    np.savez(sys.argv[1], **out)
    print("cpu", time.process_time() - t0)


if __name__ == "__main__":
    main()
