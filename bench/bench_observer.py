"""Benchmark: the model node in observer mode at 1 kHz (issue 45). Prints figures.

A bag (MCAP, flex_twin.bags.BagWriter) of ``--seconds`` (default 60) of 1 kHz
/joint_states of a simulated arm (default the Quanser flexible link,
quanser_cuboulder_calibrated: hub angle as position, the motor voltage as effort, a
+-``--amplitude`` V square wave smoothed over 20 ms) is written once (cached under
runs/bench_observer/), then fed as fast as the observer takes it: one process, one
SingleThreadedExecutor spinning a player node and the ObserverNode (its defaults: reliable
QoS, depth 1000). The player publishes the bag's CDR bytes in batches of ``--batch``
(< the depth, so nothing can be pushed out of the queue), waits until the observer has
stepped them, then sends the next batch. Reported: samples sent, received (steps of the
filter: a missed input shows here), wall time, real-time factor (bag seconds / wall
seconds; the aim: >= 2), us per sample in total, the CPU time of the process per sample
(every thread) and without the player's publishing (``observer_cpu_us``: what the node
costs; the real arm's driver is another process), split into the estimator's step, the
publication of the estimate (serialized templates) and the rest (taking and reading the
samples, the executor, DDS), and the estimator's step alone without ROS over the same
samples (wall and CPU time, and cProfile's top functions by own time). One core: the process pins
itself to CPU 0 (``--cpu``) with single-threaded BLAS (set before numpy is imported).

    python bench/bench_observer.py [--seconds 60] [--arm ARM] [--measure q1] [--json]

The machine is shared (2 cores, other jobs): figures vary; the load average is printed.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core: no BLAS thread pool
os.environ.setdefault("ROS_DOMAIN_ID", str(1 + os.getpid() % 101))  # isolated as a test

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CACHE = ROOT / "runs" / "bench_observer"  # (runs/: not in git)
TOPIC = "/joint_states"


def square_wave(t, amplitude: float, period: float = 2.0, smooth: float = 0.02):
    """+-amplitude, switching every period / 2, smoothed by tanh over ``smooth`` s."""
    width = smooth * 2 * np.pi / period
    return amplitude * np.tanh(np.sin(2 * np.pi * t / period) / width)


def write_bag(path: Path, arm: str, seconds: float, amplitude: float) -> None:
    """``seconds`` of the arm at 1 kHz as /joint_states (joint angles rounded to the arm's
    joint_encoder resolution, if it has one, rates, the input as effort), simulated by
    flex_model.simulate and written with BagWriter from the model node's CDR template."""
    from flex_model.ros import conversions as conv
    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_model.simulate import simulate
    from flex_twin.bags.writer import BagWriter

    model = FlexArmModel(load_arm(arm))
    n = model.n_links
    res = simulate(model, model.q_from_joint_angles(np.zeros(n)), t_final=seconds,
                   sample_period=1e-3, method="fixed",
                   policy=lambda t, x: np.full(n, square_wave(t, amplitude)))
    angles = res.joint_angles
    for sensor in model.arm.sensors:
        if sensor.kind == "joint_encoder" and sensor.resolution > 0:
            j = model.arm.joint_names.index(sensor.target)
            angles[:, j] = np.round(angles[:, j] / sensor.resolution) * sensor.resolution
    u = np.column_stack([square_wave(res.t, amplitude)] * n)
    cdr = conv.joint_state_cdr(model.arm.joint_names, n)
    with BagWriter(path) as bag:
        bag.add_topic(TOPIC, "sensor_msgs/msg/JointState")
        for k, tk in enumerate(res.t):
            values = np.concatenate([angles[k], res.joint_rates[k], u[k]])
            bag.write(TOPIC, cdr.fill(tk, values), int(round(tk * 1e9)))


def bag_path(arm: str, seconds: float, amplitude: float) -> Path:
    path = CACHE / f"{Path(arm).stem}_{seconds:g}s_{amplitude:g}"
    if not (path / "metadata.yaml").exists():
        t0 = time.monotonic()
        if path.exists():
            import shutil
            shutil.rmtree(path)
        write_bag(path, arm, seconds, amplitude)
        print(f"bag written: {path} ({time.monotonic() - t0:.1f} s)", file=sys.stderr)
    return path


class Timed:
    """Wall and CPU time (of this thread) spent in a callable (a bound method replaced in
    place)."""

    def __init__(self, owner, name: str):
        self.fn, self.wall, self.cpu, self.calls = getattr(owner, name), 0.0, 0.0, 0
        setattr(owner, name, self)

    def __call__(self, *args, **kwargs):
        w0, c0 = time.perf_counter(), time.thread_time()
        try:
            return self.fn(*args, **kwargs)
        finally:
            self.wall += time.perf_counter() - w0
            self.cpu += time.thread_time() - c0
            self.calls += 1


def feed(bag: Path, arm: str, measure: str, batch: int) -> dict:
    """Feed the bag's /joint_states into an ObserverNode as fast as it takes them."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    from flex_model.ros import ros_environment
    from flex_model.ros.observer_node import ObserverNode
    from flex_twin.bags.reader import iter_raw

    raw = [data for _, _, _, data, _ in iter_raw(bag, [TOPIC])]
    ros_environment()
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        node = ObserverNode(context=ctx, parameter_overrides=[
            Parameter("arm", value=arm), Parameter("measure", value=measure),
            Parameter("parameter_services", value=False),
            Parameter("qos_event_warnings", value=False)])
        player = rclpy.create_node("bag_player", context=ctx)
        pub = player.create_publisher(JointState, TOPIC, QoSProfile(
            depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(player)
        while pub.get_subscription_count() == 0:
            ex.spin_once(timeout_sec=0.01)
        step = Timed(node.estimator, "step")
        publish = Timed(node, "publish")
        feeder = Timed(pub, "publish")  # the player's share (another process in a lab)
        # (first steps compile/warm the model's kernels: not in the figures)
        cpu0, wall0 = time.process_time(), time.perf_counter()
        sent = 0
        for start in range(0, len(raw), batch):
            for data in raw[start:start + batch]:
                pub.publish(data)
                sent += 1
            stall = time.monotonic() + 10.0
            while node.counts["samples"] + node.counts["dropped"] < sent and \
                    time.monotonic() < stall:
                ex.spin_once(timeout_sec=0.1)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        counts = dict(node.counts)
        level, message, _ = node.health()
    finally:
        rclpy.try_shutdown(context=ctx)
    n = max(counts["samples"], 1)
    return {"sent": sent, "received": counts["samples"], "dropped": counts["dropped"],
            "late": counts["late"], "missed": counts["missed"], "wall_s": wall,
            "bag_s": len(raw) * 1e-3, "real_time_factor": len(raw) * 1e-3 / wall,
            "us_per_sample": 1e6 * wall / n, "cpu_us_per_sample": 1e6 * cpu / n,
            "cpu_real_time_factor": len(raw) * 1e-3 / cpu,
            "estimator_step_us": 1e6 * step.wall / n, "estimator_step_cpu_us":
            1e6 * step.cpu / n, "publish_us": 1e6 * publish.wall / n,
            "publish_cpu_us": 1e6 * publish.cpu / n,
            "feeder_cpu_us": 1e6 * feeder.cpu / n,
            "observer_cpu_us": 1e6 * (cpu - feeder.cpu) / n,
            "observer_cpu_real_time_factor": len(raw) * 1e-3 / (cpu - feeder.cpu),
            "rest_cpu_us": 1e6 * (cpu - step.cpu - publish.cpu - feeder.cpu) / n,
            "health": f"{level}: {message}"}


def step_alone(bag: Path, arm: str, measure: str, count: int) -> dict:
    """The estimator's step without ROS over the bag's first ``count`` samples, and where
    its time goes (cProfile's top functions by own time)."""
    import cProfile
    import pstats

    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState

    from flex_model.arm import load_arm
    from flex_model.dynamics import FlexArmModel
    from flex_model.estimation import Estimator, EstimatorSettings
    from flex_model.ros.observer_node import measurements_named
    from flex_twin.bags.reader import iter_raw

    model = FlexArmModel(load_arm(arm))
    ms = measurements_named(model, measure.split(","))
    est = Estimator(model, ms, EstimatorSettings(sample_period=1e-3))
    est.reset(model.q_from_joint_angles(np.zeros(model.n_links)), np.zeros(model.nq))
    msgs = []
    for _, _, _, data, _ in iter_raw(bag, [TOPIC]):
        msgs.append(deserialize_message(data, JointState))
        if len(msgs) == count:
            break
    ys = [np.asarray(m.position, float)[[m_.index for m_ in ms]] for m in msgs]
    us = [np.asarray(m.effort, float) for m in msgs]
    t0, c0 = time.perf_counter(), time.thread_time()
    for u, y in zip(us, ys):
        est.step(u, y)
    alone = (time.perf_counter() - t0) / len(ys)
    alone_cpu = (time.thread_time() - c0) / len(ys)
    prof = cProfile.Profile()
    prof.enable()
    for u, y in zip(us, ys):
        est.step(u, y)
    prof.disable()
    stats = pstats.Stats(prof)
    top = sorted(stats.stats.items(), key=lambda kv: -kv[1][2])[:8]
    where = {f"{Path(f).name}:{fn}": round(1e6 * tt / len(ys), 1)
             for (f, _, fn), (_, _, tt, _, _) in top}
    return {"estimator_step_alone_us": 1e6 * alone,
            "estimator_step_alone_cpu_us": 1e6 * alone_cpu, "own_time_us_per_sample": where}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--arm", default="quanser_cuboulder_calibrated")
    ap.add_argument("--measure", default="q1")
    ap.add_argument("--amplitude", type=float, default=2.0, help="input amplitude (V or N m)")
    ap.add_argument("--batch", type=int, default=500)
    ap.add_argument("--cpu", type=int, default=0, help="pin to this CPU (-1: no pinning)")
    ap.add_argument("--profile-samples", type=int, default=2000)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if args.cpu >= 0 and hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {args.cpu})
    out = {"arm": args.arm, "measure": args.measure, "load_average": os.getloadavg()[0]}
    bag = bag_path(args.arm, args.seconds, args.amplitude)
    out.update(feed(bag, args.arm, args.measure, args.batch))
    out.update(step_alone(bag, args.arm, args.measure, args.profile_samples))
    if args.json:
        print(json.dumps(out, indent=1))
    else:
        for k, v in out.items():
            print(f"{k:26s} {v:.4g}" if isinstance(v, float) else f"{k:26s} {v}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
