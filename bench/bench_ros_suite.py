"""Benchmark: the ROS suite (issue 7). Prints figures; not a timed test.

- realtime: the model node alone at 1 kHz on the Ch. V arm (thesis_example1_motors) for a
  few seconds: share of missed periods (timer gaps over 1.5 periods) and the publish
  latency of /joint_states above its best case (arrival wall time minus state time);
- lockstep: model + controller over ROS topics in one process (one executor), the
  real-time factor (simulated / wall seconds).

    python bench/bench_ros_suite.py [--seconds 5]
"""
from __future__ import annotations

import argparse
import time

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from flex_model.model_node import ModelNode
from flex_model.ros_suite import node_parameters, run_in_one_process


def realtime(seconds: float) -> dict:
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        node = ModelNode(context=ctx, parameter_overrides=[
            Parameter("arm", value="thesis_example1_motors"), Parameter("rate", value=1000.0),
            Parameter("publish_rate", value=250.0),
            Parameter("initial_joint_angles_deg", value=[150.0, 130.0])])
        probe = rclpy.create_node("bench_probe", context=ctx)
        arrivals = []
        probe.create_subscription(JointState, "/joint_states", lambda m: arrivals.append(
            (time.monotonic(), m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec)), 100)
        ticks = []
        tick = node.on_tick

        def timed_tick():
            ticks.append(time.monotonic())
            tick()
        node.timer.callback = timed_tick
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(probe)
        start = time.monotonic()
        sim0 = node.stepper.t
        while time.monotonic() - start < seconds:
            ex.spin_once(timeout_sec=0.001)
        wall = time.monotonic() - start
        gaps = np.diff(ticks)
        # arrival wall time minus state time: up to a constant offset (the clocks' origins),
        # so report it above its best case (the delivery delay beyond the fastest one)
        lat = np.array([a - s for a, s in arrivals[5:]])
        lat -= lat.min()
        out = {"ticks": len(ticks), "missed_share": float(np.mean(gaps > 1.5e-3)),
               "mean_period_ms": float(1e3 * gaps.mean()),
               "sim_over_wall": (node.stepper.t - sim0) / wall,
               "latency_ms_median": float(1e3 * np.median(lat)),
               "latency_ms_p99": float(1e3 * np.percentile(lat, 99))}
        node.destroy_node()
        probe.destroy_node()
        return out
    finally:
        rclpy.try_shutdown(context=ctx)


def lockstep(seconds: float) -> dict:
    params = node_parameters("ros2_ws/params/suite.yaml")
    params.pop("flex_planner")
    t0 = time.perf_counter()
    run_in_one_process(params, duration=seconds)
    wall = time.perf_counter() - t0
    return {"simulated_s": seconds, "wall_s": wall, "real_time_factor": seconds / wall}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=5.0)
    args = ap.parse_args(argv)
    rt = realtime(args.seconds)
    print(f"realtime model node at 1 kHz for {args.seconds:g} s: {rt['ticks']} ticks, mean "
          f"period {rt['mean_period_ms']:.3f} ms, missed periods {100 * rt['missed_share']:.2f} "
          f"%, simulated/wall {rt['sim_over_wall']:.3f}, /joint_states latency above best: median "
          f"{rt['latency_ms_median']:.2f} ms, p99 {rt['latency_ms_p99']:.2f} ms")
    ls = lockstep(args.seconds)
    print(f"lockstep model + controller (one process): {ls['simulated_s']:g} s simulated in "
          f"{ls['wall_s']:.2f} s: real-time factor {ls['real_time_factor']:.2f} (aim: 5)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
