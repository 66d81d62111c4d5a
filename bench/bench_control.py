"""Controller benchmark: cost per control cycle and gain-schedule design time (Ch. V task).

Per cycle: ``torque(t, positions, velocities, deflections)`` of the Eq. (45) cascade, the
Eq. (95) PD with constant gains and with a 16-point schedule (inverse-distance
interpolation), and the node's whole core path (JointState -> arrays -> torque ->
Float64MultiArray, without DDS). Design: 16 design points along the thesis Ch. V
trajectory (VALIDATION.md section F) with the planner's admissible nominal input if
flex_planner is installed, else the quasi-static nominal; and the LTV check of the result.
Run: ``python bench/bench_control.py [--json]``.
"""
import json
import sys
import time

import numpy as np

from flex_model.arm import load_arm
from flex_model.dynamics import FlexArmModel

from flex_control.closed_loop import LinearizedTrajectory, NominalTrajectory
from flex_control.design import DesignSettings, design_schedule
from flex_control.laws import DecentralizedPD, PDLikeCascade, hold_reference
from flex_control.ltv import GainFunction, ltv_check

SECTION_F_TIP = np.array([[-1.0, -1.0], [-2.0, -1.0], [-2.0, -2.0], [-1.0, -2.0]])
SECTION_F_T = np.array([0.0, 5.0, 10.0, 15.0])


def nominal_trajectory(model):
    try:
        from flex_planner import plan_tip_path
        return "planner (admissible nominal input)", plan_tip_path(
            model, SECTION_F_TIP, SECTION_F_T, sample_period=0.01)
    except ImportError:
        from flex_control.nominal import quasi_static_trajectory
        # joint angles of the static deflected arm at the waypoints (elbow up)
        wp = np.radians([[154.735, 138.488], [149.220, 111.319], [178.560, 89.363],
                         [186.381, 111.961]])
        return "quasi-static", quasi_static_trajectory(model, SECTION_F_T, wp, 0.02)


def per_call_us(fn, n=20000):
    fn()
    t0 = time.perf_counter()
    for _ in range(n):
        fn()
    return 1e6 * (time.perf_counter() - t0) / n


def main(as_json=False):
    model = FlexArmModel(load_arm("thesis_example1"))
    source, plan = nominal_trajectory(model)
    names = model.arm.joint_names
    pos, vel, defl = plan.positions[700] + 0.01, plan.velocities[700], np.array([0.03, -0.004])

    t0 = time.perf_counter()
    design = design_schedule(model, plan, DesignSettings(n_points=16))
    design_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    lin = LinearizedTrajectory(model, NominalTrajectory.from_data(model, plan))
    linearize_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    rep = ltv_check(lin, GainFunction(schedule=design.schedule), keep_responses=False)
    ltv_s = time.perf_counter() - t0

    eq45 = PDLikeCascade(hold_reference(names, pos))
    eq95 = DecentralizedPD(plan, h=25.0, a=5.0, torque_limits=100.0)
    sched = DecentralizedPD(plan, schedule=design.schedule, torque_limits=100.0)
    cycle = {"eq45_us": per_call_us(lambda: eq45.torque(7.0, pos, vel)),
             "eq95_constant_us": per_call_us(lambda: eq95.torque(7.0, pos, vel)),
             "eq95_schedule_us": per_call_us(lambda: sched.torque(7.0, pos, vel, defl))}
    try:
        from sensor_msgs.msg import JointState

        from flex_control.ros_conversions import commands_msg, joint_state_arrays
        msg = JointState(name=list(names), position=pos.tolist(), velocity=vel.tolist())

        def node_path():
            p, v = joint_state_arrays(msg, names)
            return commands_msg(sched.torque(7.0, p, v, defl))

        cycle["node_core_path_schedule_us"] = per_call_us(node_path, 5000)
    except ImportError:
        pass
    out = {"nominal": source, "cycle": cycle,
           "design": {"points": 16, "seconds": design_s, "stabilizing": design.stabilizing,
                      "zeta_min": min(p.zeta_min for p in design.points),
                      "tau_max_s": max(p.tau_max for p in design.points),
                      "h_max": design.schedule.max_gains()[0].tolist(),
                      "a_max": design.schedule.max_gains()[1].tolist()},
           "ltv": {"linearize_seconds": linearize_s, "check_seconds": ltv_s,
                   "converged": rep.converged}}
    if as_json:
        print(json.dumps(out))
        return out
    print(f"thesis Ch. V task, nominal: {source}")
    for k, v in cycle.items():
        print(f"  {k[:-3]:28s} {v:8.2f} us per cycle")
    d = out["design"]
    print(f"  schedule design (16 points)  {d['seconds']:8.3f} s  stabilizing {d['stabilizing']},"
          f" zeta_min {d['zeta_min']:.4f}, tau_max {d['tau_max_s']:.3f} s")
    print(f"  linearization along 15 s     {linearize_s:8.3f} s; LTV check {ltv_s:.3f} s, "
          f"converged {rep.converged}")
    return out


if __name__ == "__main__":
    main("--json" in sys.argv[1:])
