"""Benchmark: lockstep soak of the model node (issue 23). Prints figures; not a timed test.

The model node (``thesis_example1_motors``, lockstep, 1 ms steps, started deflected at rest)
runs for ``--minutes`` of wall time; a probe in the same process re-sends the planner's
trajectory of the thesis Ch. V task (15 s, VALIDATION.md F) each time it has been run
through (the task, then its waypoints in reverse order, alternately: no jump of the
reference), and counts /joint_states. The clock starts after the first steps (numba may
compile the kernels first). Loops (``--loop``):

- ``in_loop`` (default): Eq. (95) (h = 25, a = 5, feed-forward) inside the model's loop at
  500 Hz (``controller:=eq95``), as fast as it computes;
- ``topic``: the controller node over topics, on the model's /clock (use_sim_time), model
  and controller at 500 Hz.

Printed: resident memory (RSS, MB, sampled every 5 s) after the warm-up (the first 20 %, at
least 30 s) and at the end, its growth, its trend after the warm-up (least-squares slope,
MB/min: single samples move by a few MB as the allocator takes and returns memory) and
peak; simulated time and real-time factor; missed steps: joint
states that did not arrive (publish_rate x simulated time - received), gaps in their
stamps (more than one publish period apart), and (topic loop) steps of the lockstep
watchdog (the loop stalled: no command within lockstep_timeout).

    nice -n 10 python bench/bench_soak.py [--minutes 10] [--loop in_loop|topic]

Acceptance of issue 23: over 10 minutes, growth < 10 MB and no missed step.
"""
from __future__ import annotations

import argparse
import gc
import os
import threading
import time
import uuid

import numpy as np
import psutil

os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 101))

import rclpy  # noqa: E402  (after the domain id)
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy  # noqa: E402
from sensor_msgs.msg import JointState  # noqa: E402
from trajectory_msgs.msg import JointTrajectory  # noqa: E402

from flex_model.arm import load_arm  # noqa: E402
from flex_model.dynamics import FlexArmModel  # noqa: E402
from flex_model.ros.model_node import ModelNode  # noqa: E402
from flex_planner.planning import SECTION_F_TIMES, SECTION_F_WAYPOINTS, plan  # noqa: E402
from flex_planner.ros_messages import trajectory_msg  # noqa: E402

WAYPOINTS, TIMES = SECTION_F_WAYPOINTS, SECTION_F_TIMES   # thesis Ch. V task
RATE = 500.0
PUBLISH_RATE = 100.0


def rss_mb() -> float:
    return psutil.Process().memory_info().rss / 2**20


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0, help="wall time (min)")
    ap.add_argument("--loop", choices=("in_loop", "topic"), default="in_loop")
    args = ap.parse_args()
    arm = "thesis_example1_motors"
    model = FlexArmModel(load_arm(arm))
    traj = plan(model, WAYPOINTS, TIMES, sample_period=1.0 / RATE).trajectory
    back = plan(model, WAYPOINTS[::-1], TIMES, sample_period=1.0 / RATE).trajectory
    angles = np.degrees(traj.positions[0]).tolist()
    lean = [Parameter("parameter_services", value=False),
            Parameter("qos_event_warnings", value=False)]
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    ns = f"/soak{uuid.uuid4().hex[:6]}"
    common = [Parameter("arm", value=arm), Parameter("mode", value="lockstep"),
              Parameter("rate", value=RATE), Parameter("publish_rate", value=PUBLISH_RATE),
              Parameter("initial_joint_angles_deg", value=angles),
              Parameter("start_static", value=True), Parameter("clock_topic", value="clock"),
              *lean]
    nodes = []
    if args.loop == "in_loop":
        model_node = ModelNode(context=ctx, namespace=ns, parameter_overrides=[
            *common, Parameter("controller", value="eq95"),
            Parameter("controller_rate", value=RATE),
            Parameter("controller_params.h", value=[25.0]),
            Parameter("controller_params.a", value=[5.0])])
        nodes.append(model_node)
    else:
        from flex_control.controller_node import ControllerNode
        model_node = ModelNode(context=ctx, namespace=ns, parameter_overrides=common)
        ctrl = ControllerNode(context=ctx, namespace=ns, parameter_overrides=[
            Parameter("h", value=[25.0, 25.0]), Parameter("a", value=[5.0, 5.0]),
            Parameter("rate_hz", value=RATE), Parameter("use_sim_time", value=True),
            Parameter("clock_topic", value="clock"), Parameter("state_timeout", value=0.5),
            *lean])
        nodes.append(ctrl)
        nodes.append(model_node)
    stalls = [0]
    original = model_node.apply_command_timeout

    def counting(stalled=False):
        stalls[0] += bool(stalled)
        original(stalled)
    model_node.apply_command_timeout = counting
    probe = rclpy.create_node(f"probe_{uuid.uuid4().hex[:6]}", context=ctx, namespace=ns)
    # the listener keeps counters only (a list of stamps would itself grow the RSS)
    # every step's state in the topic loop, publish_rate's with the in-loop controller
    state_rate = RATE if args.loop == "topic" else PUBLISH_RATE
    period_ns = int(round(1e9 / state_rate))
    seen = {"n": 0, "first": None, "last": None, "gaps": 0}

    def on_state(m):
        t = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
        if seen["first"] is None:
            seen["first"] = t
        elif t - seen["last"] > period_ns + 1000:
            seen["gaps"] += 1
        seen["n"] += 1
        seen["last"] = t
    probe.create_subscription(JointState, "joint_states", on_state,
                              QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    traj_pub = probe.create_publisher(
        JointTrajectory, "flex_planner/trajectory",
        QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
    published = [0]
    pub_js = model_node.pub_js
    publish = pub_js.publish

    def counted(msg):
        published[0] += 1
        publish(msg)
    pub_js.publish = counted
    ex = SingleThreadedExecutor(context=ctx)
    for node in nodes:
        ex.add_node(node)
    probe_ex = SingleThreadedExecutor(context=ctx)  # its own thread: a listener of its own
    probe_ex.add_node(probe)
    done = threading.Event()

    def spin_probe():
        while not done.is_set():
            probe_ex.spin_once(timeout_sec=0.05)
    thread = threading.Thread(target=spin_probe, daemon=True)
    thread.start()
    while traj_pub.get_subscription_count() < 1:
        ex.spin_once(timeout_sec=0.01)
    msgs = [trajectory_msg(traj, "base_link"), trajectory_msg(back, "base_link")]
    while model_node.stepper.t <= 0.0:  # the first step (a JIT compile of the kernels)
        ex.spin_once(timeout_sec=0.01)
    t0 = time.monotonic()
    t_sim0 = model_node.stepper.t
    duration = 60.0 * args.minutes
    warm = max(30.0, 0.2 * duration)
    rss_warm, t_warm = None, 0.0
    samples = []  # (wall s, RSS MB) after the warm-up
    peak = 0.0
    next_traj = 0.0     # simulated time of the next re-send
    next_sample = 0.0
    sends = 0
    while (now := time.monotonic() - t0) < duration:
        ex.spin_once(timeout_sec=0.01)
        t_sim = model_node.stepper.t
        if t_sim >= next_traj:
            traj_pub.publish(msgs[sends % 2])
            sends += 1
            next_traj = t_sim + TIMES[-1] + 1.0
        if now >= next_sample:
            next_sample = now + 5.0
            gc.collect()
            rss = rss_mb()
            peak = max(peak, rss)
            if rss_warm is None and now >= warm:
                rss_warm, t_warm = rss, now
            if rss_warm is not None:
                samples.append((now, rss))
    gc.collect()
    rss_end = rss_mb()
    peak = max(peak, rss_end)
    t_sim = model_node.stepper.t - t_sim0
    if rss_warm is None:
        rss_warm = rss_end
    samples.append((duration, rss_end))
    slope = 0.0
    if len(samples) >= 3:
        ts, ms = np.array(samples).T
        slope = float(np.polyfit(ts / 60.0, ms, 1)[0])
    received, gaps = seen["n"], seen["gaps"]
    expected = round((seen["last"] - seen["first"]) / period_ns) + 1 if received else 0
    steps = model_node.stepper.t * RATE
    time.sleep(0.5)  # the probe takes the last messages
    done.set()
    thread.join()
    ex.shutdown()
    probe_ex.shutdown()
    for node in (*nodes, probe):
        node.destroy_node()
    rclpy.try_shutdown(context=ctx)
    print(f"soak: {args.loop} loop, {arm}, lockstep at {RATE:g} Hz, {args.minutes:g} min wall")
    print(f"  RSS after warm-up ({t_warm:.0f} s) {rss_warm:.1f} MB, at the end "
          f"{rss_end:.1f} MB: growth {rss_end - rss_warm:+.2f} MB, trend {slope:+.2f} MB/min "
          f"over {len(samples)} samples (peak {peak:.1f} MB)")
    print(f"  simulated {t_sim:.1f} s in {duration:.0f} s: real-time factor "
          f"{t_sim / duration:.3f}; trajectory sent {sends} times")
    print(f"  steps: {steps:.6f} control periods of 1/{RATE:g} s (the time is a float sum: "
          f"{abs(steps - round(steps)) / RATE:.1e} s off the grid); watchdog steps (stalls) "
          f"{stalls[0]}; "
          f"diverged: {model_node.diverged is not None}")
    print(f"  joint_states: {published[0]} published, {received} received by a listener "
          f"(missed {published[0] - received}); stamps expected at {state_rate:g} Hz "
          f"{expected}, gaps {gaps}")


if __name__ == "__main__":
    main()
