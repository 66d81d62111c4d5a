"""The only writer of the golden bags under test/data/bags (rosbag2, MCAP).

    python test/tools/make_golden_bags.py            # refuses to overwrite
    python test/tools/make_golden_bags.py --force    # regenerate on purpose

model_lockstep: the model of the arm below stepped by flex_model's core Stepper under a
fixed command sequence, recorded as the model node publishes it in lockstep mode: the
state at t = 0, then per 1 ms step the command (at t_k) and the state at t_k+1
(/joint_states, /flex/deflections). Replay test: test/test_replay_model_node.py.

controller_hold: a held reference (/flex_planner/trajectory, one point with feed-forward)
and model_lockstep's joint states, with the commands of the controller core
(flex_control DecentralizedPD, thesis Eq. 95) for each state. Replay test:
test/test_replay_controller_node.py.

planner_short: a two-waypoint request (/flex_planner/waypoints, nav_msgs/Path) on the
section F arm and the trajectory the planner core gives for it (/flex_planner/trajectory,
10 ms samples). Replay test: test/test_replay_planner_node.py.
"""
from __future__ import annotations

import argparse
import shutil
import sys
from pathlib import Path

import numpy as np
import yaml

from flex_model.ros import conversions as conv
from flex_model.arm import load_arm
from flex_twin.bags import BagWriter
from flex_model.dynamics import FlexArmModel
from flex_model.stepper import Stepper
from std_msgs.msg import Float64MultiArray

DATA = Path(__file__).resolve().parents[1] / "data" / "bags"
MODEL_LOCKSTEP = {"arm": "thesis_example1", "initial_joint_angles_deg": [10.0, -20.0],
                  "rate": 1000.0, "steps": 100}


def commands(n):
    """The recorded command sequence (N m): smooth, both signs, not constant."""
    return [np.array([2.0 * np.sin(0.3 * k), -0.5 + 0.01 * k]) for k in range(n)]


def make_model_lockstep(path: Path) -> None:
    p = MODEL_LOCKSTEP
    arm = load_arm(p["arm"])
    model = FlexArmModel(arm)
    st = Stepper(model, model.q_from_joint_angles(np.radians(p["initial_joint_angles_deg"])))
    dt = 1.0 / p["rate"]
    links = [lk.name for lk in arm.links]
    with BagWriter(path) as bag:
        bag.add_topic("/joint_states", "sensor_msgs/msg/JointState")
        bag.add_topic("/flex/deflections", "sensor_msgs/msg/JointState")
        bag.add_topic("/effort_controller/commands", "std_msgs/msg/Float64MultiArray")

        def record_state():
            t_ns = int(round(st.t * 1e9))
            bag.write("/joint_states", conv.joint_state(st.t, arm.joint_names,
                                                        *st.joint_state()), t_ns)
            bag.write("/flex/deflections", conv.deflection_state(st.t, links,
                                                                 *st.deflections()), t_ns)
        record_state()
        for k, u in enumerate(commands(p["steps"])):
            bag.write("/effort_controller/commands", Float64MultiArray(data=list(u)),
                      int(round(k * dt * 1e9)))
            st.set_command(u)
            st.advance(dt)
            record_state()
    (path / "provenance.yaml").write_text(yaml.safe_dump({
        "generator": "test/tools/make_golden_bags.py", "scenario": "model_lockstep",
        "parameters": p, "model": "flex_model.stepper.Stepper (generalized-alpha, 1 ms)"}))


CONTROLLER_HOLD = {"h": [2.0, 3.0], "a": [4.0, 5.0], "hold": [0.5, 0.25],
                   "feedforward": [1.5, -2.0], "torque_limits": [1000.0, 1000.0]}


def make_controller_hold(path: Path, states_bag: Path) -> None:
    from flex_control.laws import DecentralizedPD, hold_reference
    from flex_twin.bags import read_bag
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint
    p = CONTROLLER_HOLD
    names = ["joint1", "joint2"]
    ref = hold_reference(names, p["hold"])
    ref.efforts[:] = p["feedforward"]
    law = DecentralizedPD(ref, h=p["h"], a=p["a"])
    traj = JointTrajectory(joint_names=names, points=[JointTrajectoryPoint(
        positions=p["hold"], velocities=[0.0, 0.0], effort=p["feedforward"])])
    with BagWriter(path) as bag:
        bag.add_topic("/flex_planner/trajectory", "trajectory_msgs/msg/JointTrajectory")
        bag.add_topic("/joint_states", "sensor_msgs/msg/JointState")
        bag.add_topic("/effort_controller/commands", "std_msgs/msg/Float64MultiArray")
        bag.write("/flex_planner/trajectory", traj, 0)
        for topic, _, t_ns, msg in read_bag(states_bag, topics=["/joint_states"]):
            bag.write("/joint_states", msg, t_ns + 1)
            tau = law.torque(0.0, np.array(msg.position), np.array(msg.velocity))
            bag.write("/effort_controller/commands",
                      Float64MultiArray(data=[float(x) for x in tau]), t_ns + 2)
    (path / "provenance.yaml").write_text(yaml.safe_dump({
        "generator": "test/tools/make_golden_bags.py", "scenario": "controller_hold",
        "parameters": p, "states": "model_lockstep /joint_states",
        "controller": "flex_control.laws.DecentralizedPD (thesis Eq. 95)"}))


PLANNER_SHORT = {"arm": "thesis_example1", "sample_period": 0.01,
                 "waypoints": [[-1.0, -1.0], [-1.2, -1.1]], "times": [0.0, 1.0]}


def make_planner_short(path: Path) -> None:
    from flex_planner import plan_tip_path
    from flex_planner.ros_messages import trajectory_msg
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Path as PathMsg
    p = PLANNER_SHORT
    model = FlexArmModel(load_arm(p["arm"]))
    request = PathMsg()
    request.header.frame_id = "arm_plane"
    for (x, y), t in zip(p["waypoints"], p["times"]):
        pose = PoseStamped()
        pose.header.frame_id = "arm_plane"
        pose.header.stamp = conv.stamp(t)
        pose.pose.position.x, pose.pose.position.y = x, y
        pose.pose.orientation.w = 1.0
        request.poses.append(pose)
    traj = plan_tip_path(model, np.array(p["waypoints"]), np.array(p["times"]),
                         sample_period=p["sample_period"])
    with BagWriter(path) as bag:
        bag.add_topic("/flex_planner/waypoints", "nav_msgs/msg/Path")
        bag.add_topic("/flex_planner/trajectory", "trajectory_msgs/msg/JointTrajectory")
        bag.write("/flex_planner/waypoints", request, 0)
        bag.write("/flex_planner/trajectory", trajectory_msg(traj, "arm_plane"), 1)
    (path / "provenance.yaml").write_text(yaml.safe_dump({
        "generator": "test/tools/make_golden_bags.py", "scenario": "planner_short",
        "parameters": p, "planner": "flex_planner.plan_tip_path"}))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--force", action="store_true", help="overwrite existing golden bags")
    args = ap.parse_args(argv)
    makers = (("model_lockstep", make_model_lockstep),
              ("controller_hold",
               lambda path: make_controller_hold(path, DATA / "model_lockstep")),
              ("planner_short", make_planner_short))
    for name, make in makers:
        target = DATA / name
        if target.exists():
            if not args.force:
                print(f"{target} exists; use --force to regenerate it", file=sys.stderr)
                continue
            shutil.rmtree(target)
        make(target)
        print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
