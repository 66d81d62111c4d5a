"""Benchmark: the ROS suite (issue 7). Prints figures; not a timed test.

(a) realtime: the model node alone at 1 kHz (SingleThreadedExecutor) on the Ch. V arm
    (thesis_example1_motors), without a controller and with Eq. 95 in its loop at 1 kHz,
    publishing at 250 Hz (/flex/shape at 50 Hz, only while subscribed): the share of
    missed 1 ms periods (ticks that came one period or more late; a tick is one period of
    the node's loop, ModelNode.realtime_period: a timer callback, or with realtime_priority
    one period of the callback's realtime slice; the node then integrates the owed steps,
    so simulation time keeps up), the distribution of tick periods and of the time spent
    in a tick, the CPU time of the node's process per period, the steps per tick, and the
    /joint_states
    latency in a subscriber in another process: from the tick that computed the state
    (its wall time is the state's instant) and from the publish call, to the arrival;
    with normal scheduling and with the node's realtime_priority 50 (SCHED_FIFO).
(b) lockstep: the suite of ros2_ws/params/suite.yaml (model + controller in a loop over
    ROS topics at 500 Hz, the planner idle) started by ``flex-twin up`` in one process and
    in three (``--processes``): the real-time factor (simulated / wall seconds), measured
    in this process from the stamps of /flex/tip_pose.

Every node spins in a SingleThreadedExecutor (flex_model.ros.main); suite.yaml makes the
nodes lean (no parameter services, type description service or QoS-event handlers: about
half the CPU time per control period in one process).

    python bench/bench_ros_suite.py [--seconds 5] [--json]

The machine is shared (2 cores): figures vary from run to run; run it twice.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

# a benchmark is isolated like a test: its own domain unless one is set
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 101))

ROOT = Path(__file__).resolve().parents[1]
SUITE = ROOT / "ros2_ws" / "params" / "suite.yaml"
PERIOD = 1e-3


def _stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def _spin_for(ex, seconds: float, pred=lambda: False) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end and not pred():
        ex.spin_once(timeout_sec=0.01)


def probe_main(topic: str, seconds: float, out: str) -> None:
    """Child process: record (stamp ns, arrival monotonic s) of ``topic`` for ``seconds``
    from the first arrival (giving up 90 s after the start)."""
    import rclpy
    from geometry_msgs.msg import PoseStamped
    from sensor_msgs.msg import JointState

    from rclpy.executors import SingleThreadedExecutor
    rclpy.init()
    node = rclpy.create_node("bench_probe")
    rows = []
    kind = JointState if topic == "/joint_states" else PoseStamped
    node.create_subscription(kind, topic, lambda m: rows.append(
        (_stamp_ns(m), time.monotonic())), 1000)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    _spin_for(ex, 90.0, lambda: rows)
    if rows:
        _spin_for(ex, seconds - (time.monotonic() - rows[0][1]))
    Path(out).write_text(json.dumps(rows))
    node.destroy_node()
    rclpy.try_shutdown()


def start_probe(topic: str, seconds: float, out: Path) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, __file__, "--probe", topic, "--seconds",
                             str(seconds), "--out", str(out)])


def _dist(values, scale=1e3) -> dict:
    v = scale * np.asarray(values)
    return {"median": float(np.median(v)), "p99": float(np.percentile(v, 99)),
            "max": float(v.max())}


def realtime(seconds: float, tmp: Path, priority: int = 0, controller: bool = False) -> dict:
    """(a): the model node at 1 kHz in this process (``priority``: its realtime_priority
    parameter; ``controller``: Eq. 95 (h = 25, a = 5) in its loop at 1 kHz, holding the
    initial pose), a probe in another."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from flex_model.ros.model_node import ModelNode

    probe = start_probe("/joint_states", seconds + 1.0, tmp / "rt.json")
    rclpy.init()
    try:
        node = ModelNode(parameter_overrides=[
            Parameter("arm", value="thesis_example1_motors"), Parameter("rate", value=1000.0),
            Parameter("publish_rate", value=250.0), Parameter("shape_rate", value=50.0),
            Parameter("initial_joint_angles_deg", value=[150.0, 130.0]),
            Parameter("start_paused", value=True),
            Parameter("realtime_priority", value=priority)] + ([
                Parameter("controller", value="eq95"),
                Parameter("controller_rate", value=1000.0),
                Parameter("controller_params.h", value=[25.0]),
                Parameter("controller_params.a", value=[5.0])] if controller else []))
        ex = SingleThreadedExecutor()
        ex.add_node(node)
        _spin_for(ex, 30.0, lambda: node.pub_js.get_subscription_count() > 0)
        _spin_for(ex, 1.0)  # the probe's subscription settles
        ticks, published = [], {}  # (start, duration, simulated), {stamp: (tick, publish)}
        period, publish = node.realtime_period, node.pub_js.publish

        def timed_period(elapsed):  # a tick: one period of the loop (the timer's callback,
            t0, sim0 = time.monotonic(), node.stepper.t  # or one of its realtime slice)
            ticks.append((t0, 0.0, 0.0))
            period(elapsed)
            ticks[-1] = (t0, time.monotonic() - t0, node.stepper.t - sim0)

        def timed_publish(raw):  # the serialized JointState (flex_model.ros.cdr_messages):
            sec, nsec = struct.unpack_from("<iI", raw, 4)  # its stamp leads, after CDR's 4
            published[sec * 1_000_000_000 + nsec] = (ticks[-1][0], time.monotonic())
            publish(raw)
        node.realtime_period = timed_period
        node.pub_js.publish = timed_publish
        node.paused = False  # (the paused ticks kept last_wall on the timer's grid)
        _spin_for(ex, 0.5)  # warm up (numba's cached code loads on the first step)
        del ticks[:]
        published.clear()
        load = os.getloadavg()[0]
        sim0, wall0, cpu0 = node.stepper.t, time.monotonic(), time.process_time()
        _spin_for(ex, seconds)
        wall, sim = time.monotonic() - wall0, node.stepper.t - sim0
        cpu = time.process_time() - cpu0  # this process: the node, its executor, DDS
        node.paused = True
        ex.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
        if priority:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    probe.wait(timeout=60)
    arrivals = json.loads((tmp / "rt.json").read_text())
    start = np.array([t[0] for t in ticks])
    gaps = np.diff(start)
    missed = np.maximum(np.rint(gaps / PERIOD) - 1, 0).sum()
    steps = np.rint(np.array([t[2] for t in ticks]) / PERIOD)
    lat_tick, lat_pub = [], []
    for stamp, arrival in arrivals:
        if stamp in published:
            t_tick, t_pub = published[stamp]
            lat_tick.append(arrival - t_tick)
            lat_pub.append(arrival - t_pub)
    return {"priority": priority, "controller": "eq95 in the loop" if controller else "none",
            "load_average": load,
            "seconds": wall, "ticks": len(ticks), "periods": wall / PERIOD,
            "missed_share": float(missed / (wall / PERIOD)),
            "cpu_per_period_ms": 1e3 * cpu / (wall / PERIOD),
            "tick_period_ms": _dist(gaps), "tick_time_ms": _dist([t[1] for t in ticks]),
            "ticks_with_catch_up_share": float(np.mean(steps > 1)),
            "max_steps_per_tick": int(steps.max()), "sim_over_wall": sim / wall,
            "published": len(published), "received": len(lat_tick),
            "latency_from_tick_ms": _dist(lat_tick), "latency_from_publish_ms": _dist(lat_pub)}


def lockstep(seconds: float, processes: bool, tmp: Path) -> dict:
    """(b): ``flex-twin up`` the suite; the real-time factor from /flex/tip_pose stamps."""
    cmd = ["flex-twin", "up", str(SUITE)]
    if processes:
        cmd.append("--processes")
    out = tmp / f"ls_{processes}.json"
    probe = start_probe("/flex/tip_pose", seconds + 1.0, out)
    load = os.getloadavg()[0]
    suite = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        probe.wait(timeout=seconds + 100.0)
    finally:
        suite.send_signal(signal.SIGINT)
        try:
            suite.wait(timeout=20)
        except subprocess.TimeoutExpired:
            suite.kill()
    rows = np.array(json.loads(out.read_text()), dtype=float)
    if len(rows) < 10:
        return {"processes": 3 if processes else 1,
                "error": f"only {len(rows)} /flex/tip_pose messages received"}
    stamp, wall = 1e-9 * rows[:, 0], rows[:, 1]
    keep = (wall >= wall[0] + 1.0) & (wall <= wall[0] + 1.0 + seconds)  # skip the start
    stamp, wall = stamp[keep], wall[keep]
    return {"processes": 3 if processes else 1, "load_average": load,
            "simulated_s": float(stamp[-1] - stamp[0]), "wall_s": float(wall[-1] - wall[0]),
            "real_time_factor": float((stamp[-1] - stamp[0]) / (wall[-1] - wall[0]))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0, help="wall seconds per figure")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--only", choices=["realtime", "lockstep"], default=None,
                    help="one part of the benchmark")
    ap.add_argument("--probe", help=argparse.SUPPRESS)
    ap.add_argument("--out", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.probe:
        probe_main(args.probe, args.seconds, args.out)
        return 0
    os.chdir(ROOT)
    with tempfile.TemporaryDirectory() as tmp:
        rt = [] if args.only == "lockstep" else [
            realtime(args.seconds, Path(tmp), prio, ctl) for ctl in (False, True)
            for prio in (0, 50)]
        ls = [] if args.only == "realtime" else [
            lockstep(args.seconds, p, Path(tmp)) for p in (False, True)]
    if args.json:
        print(json.dumps({"realtime": rt, "lockstep": ls}, indent=1))
        return 0
    f = "{median:.3f} / {p99:.3f} / {max:.3f}".format
    for r in rt:
        how = f"SCHED_FIFO {r['priority']}" if r["priority"] else "normal scheduling"
        print(f"(a) realtime model node at 1 kHz, controller {r['controller']}, {how}, "
              f"{r['seconds']:.1f} s (load average "
              f"{r['load_average']:.1f}): {r['ticks']} ticks for {r['periods']:.0f} periods, "
              f"missed periods {100 * r['missed_share']:.2f} % (aim < 1 %), simulated/wall "
              f"{r['sim_over_wall']:.4f}")
        print(f"    CPU time of the node's process per 1 ms period: "
              f"{r['cpu_per_period_ms']:.3f} ms")
        print(f"    tick period ms (median / p99 / max): {f(**r['tick_period_ms'])}")
        print(f"    time in a tick ms:                   {f(**r['tick_time_ms'])}")
        print(f"    ticks that caught up missed steps: {100 * r['ticks_with_catch_up_share']:.2f}"
              f" % (at most {r['max_steps_per_tick']} steps)")
        print(f"    /joint_states at 250 Hz in another process ({r['received']} of "
              f"{r['published']}), latency ms from the tick: {f(**r['latency_from_tick_ms'])}")
        print(f"    {'':56s}from the publish: {f(**r['latency_from_publish_ms'])}")
    if ls:
        print("(b) lockstep suite (model + controller at 500 Hz, planner idle), flex-twin up:")
    for r in ls:
        where = f"{r['processes']} process{'es' if r['processes'] > 1 else ''}"
        if "error" in r:
            print(f"    {where:11s}: {r['error']}")
            continue
        print(f"    {where:11s}: {r['simulated_s']:.2f} s simulated in {r['wall_s']:.2f} s "
              f"wall, real-time factor {r['real_time_factor']:.2f} (aim >= 5; load average "
              f"{r['load_average']:.1f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
