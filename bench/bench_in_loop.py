"""Benchmark: controllers in the model's loop (issue 24). Prints figures; not a timed test.

The twin demo's task (thesis Ch. V, VALIDATION.md F): the planner's trajectory for the four
waypoints, Eq. (95) with h = 25, a = 5 and the nominal torque as feed-forward, on the arm
``thesis_example1_motors`` at a 500 Hz control rate with 1 ms model steps, 15 s. The
controller runs in the model's update loop (flex_model.control_loop.ControlLoop, what the
model node does with ``controller:=eq95``): the real-time factor is simulated / wall time
of the loop alone (no ROS), the tip error at the waypoints checks it is the demo's run.

    python bench/bench_in_loop.py [--rate 500] [--repeat 3] [--demo-seconds 3]
        [--publish-rates 250 50] [--no-topic-demo]

Prints, from one run: the core loop with the law compiled into it (one compiled call for
the whole task, flex_model.control_kernel) and with the law called from Python every
period (users' own controllers; ``compiled=False``), both as real-time factors of wall
and of CPU time (the CPU figure is what the loop costs on a machine shared with other
jobs); the model node in lockstep with ``controller:=eq95`` publishing at 250 and 50 Hz,
without a subscriber and with a raw subscriber of every topic in another process (as the
bag recorder's, /tf included where tf2_msgs imports; what it received is printed: a
lockstep model waits for nobody), real-time factors of wall and of the process's CPU
time; and the twin demo (nodes, bag recorder) with the controller in the model's loop and
over topics (the controller node), side by side, wall and CPU time of its loop.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

from flex_model.arm import load_arm
from flex_model.control_loop import ControlLoop
from flex_model.controller_interface import load_controller
from flex_model.dynamics import FlexArmModel
from flex_model.statics import static_equilibrium
from flex_model.stepper import Stepper
from flex_planner.planning import SECTION_F_TIMES, SECTION_F_WAYPOINTS, plan

WAYPOINTS, TIMES = SECTION_F_WAYPOINTS, SECTION_F_TIMES   # thesis Ch. V task


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=500.0, help="control rate (Hz)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--demo-seconds", type=float, default=3.0,
                    help="simulated seconds of each twin demo run (0: skip)")
    ap.add_argument("--publish-rates", type=float, nargs="*", default=[250.0, 50.0],
                    help="publication rates (Hz) of the model node runs")
    ap.add_argument("--no-topic-demo", action="store_true",
                    help="twin demo: only the controller in the model's loop")
    args = ap.parse_args()
    model = FlexArmModel(load_arm("thesis_example1_motors"))
    period = 1.0 / args.rate
    traj = plan(model, WAYPOINTS, TIMES, sample_period=period).trajectory
    theta0 = traj.positions[0]
    q0 = static_equilibrium(model, theta0, joints="clamped").q
    n = int(round(TIMES[-1] / period))
    marks = {int(round(t / period)): k for k, t in enumerate(TIMES)}
    # warm-up: numba loads (or compiles) both paths before anything is timed
    for compiled in (True, False):
        ctl = load_controller("eq95", model.arm.joint_names, {"h": [25.0], "a": [5.0]})
        ctl.set_trajectory(traj)
        ControlLoop(Stepper(model, q0), ctl, period, compiled=compiled).advance(3)
    final = {}
    for compiled in (True, False):
        best = best_cpu = None
        for _ in range(args.repeat):
            ctl = load_controller("eq95", model.arm.joint_names, {"h": [25.0], "a": [5.0]})
            ctl.set_trajectory(traj)
            loop = ControlLoop(Stepper(model, q0), ctl, period, compiled=compiled)
            errors = {}
            t0, c0 = time.perf_counter(), time.process_time()
            done = 0
            for k in sorted(marks):  # the whole task, in one call between the waypoints
                loop.advance(k - done)
                done = k
                errors[marks[k]] = float(np.linalg.norm(
                    model.link_origins(loop.stepper.q)[-1] - WAYPOINTS[marks[k]]))
            wall, cpu = time.perf_counter() - t0, time.process_time() - c0
            best = wall if best is None else min(best, wall)
            best_cpu = cpu if best_cpu is None else min(best_cpu, cpu)
        final[compiled] = loop.stepper.x
        what = "compiled law, one call per advance" if compiled else \
            "law called from Python every period"
        print(f"core loop, {what}: Eq. (95) at {args.rate:g} Hz, 1 ms model steps, "
              f"{TIMES[-1]:g} s task: wall {best:.3f} s (best of {args.repeat}), real-time "
              f"factor {TIMES[-1] / best:.1f} (CPU time: {TIMES[-1] / best_cpu:.1f}), "
              f"{1e6 * best_cpu / n:.0f} us CPU per control period")
        print("  tip error at the waypoints (mm): "
              + ", ".join(f"{1e3 * errors[k]:.2f}" for k in sorted(errors)))
    print(f"  compiled vs Python path, largest state difference after {TIMES[-1]:g} s: "
          f"{np.abs(final[True] - final[False]).max():.2e}")
    for publish_rate in args.publish_rates:
        for listen in (False, True):
            r = run_node(traj, theta0, args.rate, publish_rate, listen)
            print(f"model node, lockstep, controller:=eq95 (SingleThreadedExecutor, "
                  f"publishing at {publish_rate:g} Hz, one compiled call per publication), "
                  + ("a raw subscriber of every topic in another process"
                     if listen else "no subscriber")
                  + f": real-time factor {r['rtf']:.1f} (CPU time of the process: "
                  f"{r['rtf_cpu']:.1f}), {1e6 * r['cpu'] / r['publications']:.0f} us CPU "
                  f"per publication")
            if listen:
                print(f"  received of {r['publications']} publications: " + ", ".join(
                    f"{k} {v}" for k, v in sorted(r["received"].items())))
    if args.demo_seconds > 0:
        run_demos(args.demo_seconds, args.rate, topic_loop=not args.no_topic_demo)


def run_demos(seconds: float, rate: float, topic_loop: bool = True) -> None:
    """The twin demo (flex_twin.ros_twin_demo) for ``seconds``, the controller in the
    model's loop and over topics; the real-time factor of the stepping loop (nodes,
    recorder, bag), without the setup (planning, node creation)."""
    import tempfile

    from flex_twin.ros_twin_demo import run
    rows = []
    for in_loop in (True, False) if topic_loop else (True,):
        with tempfile.TemporaryDirectory() as tmp:
            s = run(tmp, duration=seconds, rate=rate, in_loop=in_loop)
        rows.append((s["controller"], s["loop_real_time_factor"],
                     s.get("loop_cpu_real_time_factor", float("nan"))))
    print(f"twin demo, {seconds:g} s recorded (real-time factor of the loop, wall; CPU "
          "time of the process): " + "; ".join(
              f"{what} {rtf:.1f} (CPU {cpu:.1f})" for what, rtf, cpu in rows)
          + (f"; ratio {rows[0][1] / rows[1][1]:.1f}" if len(rows) == 2 else ""))


TOPICS = ("/joint_states", "/clock", "/flex/deflections", "/flex/tip_pose", "/flex/shape",
          "/tf")


def listener_main(out: str) -> None:
    """Child process: raw subscriptions of the model node's topics (as the bag recorder's:
    reliable, depth 100, no deserialization), counting messages until SIGINT or SIGTERM;
    writes the counts to ``out`` (JSON)."""
    import json
    import signal

    import rclpy
    from geometry_msgs.msg import PoseStamped
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock
    from sensor_msgs.msg import JointState
    from visualization_msgs.msg import MarkerArray
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(1))
    rclpy.init(signal_handler_options=rclpy.signals.SignalHandlerOptions.NO)
    node = rclpy.create_node("bench_listener")
    counts = {t: 0 for t in TOPICS}  # /tf: 0 where tf2_msgs does not import
    from flex_model.ros.model_node import tf_message_type
    types = {"/joint_states": JointState, "/clock": Clock, "/flex/deflections": JointState,
             "/flex/tip_pose": PoseStamped, "/flex/shape": MarkerArray,
             "/tf": tf_message_type()[0]}
    for topic in [t for t in TOPICS if types[t] is not None]:
        def count(_raw, topic=topic):
            counts[topic] += 1
        node.create_subscription(types[topic], topic, count, 100, raw=True)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    while not stop:
        ex.spin_once(timeout_sec=0.05)
    with open(out, "w") as f:
        json.dump(counts, f)
    rclpy.try_shutdown()


def run_node(traj, theta0, rate: float, publish_rate: float, listen: bool = False) -> dict:
    """The same task in the model node (lockstep, in-loop eq95, publishing at
    ``publish_rate``: one compiled call per publication), spun by its executor; with
    ``listen`` a raw subscriber of every topic in another process (listener_main).
    Returns the real-time factors (wall, CPU time of this process: DDS threads
    included), the publications and what the listener received."""
    import json
    import os
    import signal
    import subprocess
    import sys
    import tempfile
    os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 101))
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from flex_model.ros.model_node import ModelNode
    child, out = None, tempfile.mktemp(suffix=".json")
    if listen:
        child = subprocess.Popen([sys.executable, __file__, "--listener", out])
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        node = ModelNode(context=ctx, parameter_overrides=[Parameter(k, value=v) for k, v in {
            "arm": "thesis_example1_motors", "mode": "lockstep", "controller": "eq95",
            "controller_rate": rate, "start_static": True, "start_paused": True,
            "publish_rate": publish_rate, "shape_rate": min(50.0, publish_rate),
            "initial_joint_angles_deg": list(np.degrees(theta0)),
            "controller_params.h": [25.0], "controller_params.a": [5.0],
            "parameter_services": False, "qos_event_warnings": False}.items()])
        node.loop.set_trajectory(traj, 0.0)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        pubs = [p for p in (node.pub_js, node.pub_clock, node.pub_defl, node.pub_tip,
                            node.pub_shape, node.pub_tf) if p is not None]
        end = time.monotonic() + 60.0
        while listen and not all(p.get_subscription_count() for p in pubs):
            if time.monotonic() > end or child.poll() is not None:
                raise RuntimeError("bench: the listener process did not subscribe")
            ex.spin_once(timeout_sec=0.01)
        published = [0]
        publish = node.pub_js.publish

        def counted(msg):
            published[0] += 1
            publish(msg)
        node.pub_js.publish = counted
        node.paused = False
        t0, c0 = time.perf_counter(), time.process_time()
        while node.stepper.t < TIMES[-1] - 1e-9:
            ex.spin_once(timeout_sec=0.01)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
        sim = node.stepper.t
    finally:
        rclpy.try_shutdown(context=ctx)
    received = {}
    if child is not None:
        time.sleep(1.0)  # the last messages in flight
        child.send_signal(signal.SIGINT)
        child.wait(timeout=30)
        with open(out) as f:
            received = json.load(f)
        os.unlink(out)
    return {"rtf": sim / wall, "rtf_cpu": sim / cpu, "cpu": cpu,
            "publications": published[0], "received": received}


if __name__ == "__main__":
    import sys
    if len(sys.argv) == 3 and sys.argv[1] == "--listener":
        listener_main(sys.argv[2])
    else:
        main()
