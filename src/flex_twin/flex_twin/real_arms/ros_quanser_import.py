"""Import a Quanser lab run into a rosbag2 (MCAP) bag with the suite's topics.

Topics (message conversions of the model node, flex_model.ros.conversions):

- ``/joint_states`` (sensor_msgs/JointState): hub angle (rad), rate (rad/s) and effort,
  the joint torque n K_t (V - K_e n theta_dot) / R of the arm's ``dc_motor`` and ``gear``
  (seed 003 Eq. 48: the lab measures the voltage, not the torque);
- ``/flex/deflections`` (JointState): ``link1/tip_deflection`` (m) and its rate in the
  twin's sign (``gauge_sign`` applied, ``gauge_bias`` removed), and ``link1/tip_rotation``
  estimated from the first clamped-hub mode shape (the gauge measures one quantity);
- ``/effort_controller/commands`` (std_msgs/Float64MultiArray): the voltage (V);
- ``/flex_planner/trajectory`` (trajectory_msgs/JointTrajectory): the reference, one
  hold-point message at t = 0 and at every change of the reference.

Stamps and bag times are the run's time from 0 (ns). A ros_* module (it builds messages);
ROS is imported lazily, inside the functions.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from flex_model.dynamics import FlexArmModel
from flex_model.modes import natural_modes
from .quanser_data import LabRun

TOPICS = ("/joint_states", "/flex/deflections", "/effort_controller/commands",
          "/flex_planner/trajectory")


def motor_torque(model: FlexArmModel, voltage, rate) -> np.ndarray:
    """Joint torque (N m) of the arm's DC motor for voltage V and joint rate (seed 003 Eq.
    48, inductance neglected, no current limit)."""
    jd = model.joint_data[0]
    col = {n: k for k, n in enumerate(model.JOINT_DATA)}
    if jd[col["motor"]] <= 0:
        raise ValueError(f"arm {model.arm.name}: no dc_motor effect on the joint")
    n, r, kt, ke = jd[col["ratio"]], jd[col["R"]], jd[col["Kt"]], jd[col["Ke"]]
    return n * kt * (np.asarray(voltage) - ke * n * np.asarray(rate)) / r


def tip_rotation_ratio(model: FlexArmModel) -> float:
    """Tip rotation per tip deflection (rad/m) of the first clamped-hub mode."""
    phi = natural_modes(model, joints="clamped").shapes_q[:, 0]
    return float(phi[model.tip_rotation_index(0)] / phi[model.tip_deflection_index(0)])


def import_run(run: LabRun, model: FlexArmModel, out) -> dict:
    """Write the run to a new bag directory ``out``; returns the message counts."""
    from builtin_interfaces.msg import Duration
    from std_msgs.msg import Float64MultiArray, Header
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    from flex_model.ros import conversions as conv
    from ..bags import BagWriter

    joint = model.arm.joint_names[0]
    link = model.arm.links[0].name
    effort = motor_torque(model, run.voltage, run.theta_rate)
    sign, bias = run.gauge_sign(), run.gauge_bias()
    defl = sign * (run.deflection - bias)
    defl_rate = sign * run.deflection_rate
    ratio = tip_rotation_ratio(model) if run.has_gauge else 0.0
    t_ns = [int(round(t * 1e9)) for t in run.t]
    with BagWriter(Path(out)) as bag:
        for k, t in enumerate(run.t):
            bag.write("/joint_states", conv.joint_state(t, [joint], [run.theta[k]],
                                                        [run.theta_rate[k]], [effort[k]]),
                      t_ns[k])
            if run.kind == "flexible":
                bag.write("/flex/deflections", conv.deflection_state(
                    t, [link], [defl[k]], [ratio * defl[k]], [defl_rate[k]],
                    [ratio * defl_rate[k]]), t_ns[k])
            bag.write("/effort_controller/commands",
                      Float64MultiArray(data=[float(run.voltage[k])]), t_ns[k])
        for k in np.concatenate([[0], run.reference_changes()]):
            msg = JointTrajectory(header=Header(stamp=conv.stamp(run.t[k])),
                                  joint_names=[joint])
            msg.points = [JointTrajectoryPoint(positions=[float(run.reference[k])],
                                               velocities=[0.0],
                                               time_from_start=Duration(sec=0, nanosec=0))]
            bag.write("/flex_planner/trajectory", msg, t_ns[k])
        counts = dict(bag.counts)
    return counts
