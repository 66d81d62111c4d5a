"""Benchmark: CPU time of the model node's period (issue 43, one model node). Prints
figures; not a timed test.

The node in lockstep, stepped from this process without DDS traffic (no subscriber: the
shape and /tf are not computed, as in a run nobody draws): per period the command
timeout, the integration and the state publications (joint_states, /clock,
flex/deflections, flex/tip_pose at publish_rate). Planar: the default arm
(thesis_example1_motors) at 1 kHz, 1 ms steps, publishing at 250 Hz; spatial: the
seed003-like arm at 250 Hz, 1 ms steps (4 a period), publishing every period (the spatial
node's defaults). CPU time (process_time) per period and the real-time factor it allows
(period / CPU time); run it on main and on a branch to compare (the script speaks both
the former SpatialModelNode class and the one ModelNode).

    python bench/bench_one_node.py [--periods 2000] [--repeat 3]
"""
from __future__ import annotations

import argparse
import time


def _node(kind: str, ctx):
    from rclpy.parameter import Parameter
    params = {"mode": "lockstep", "lockstep_timeout": 600.0, "command_timeout": 0.0,
              "hold_until_command": False}
    if kind == "planar":
        from flex_model.ros.model_node import ModelNode as factory
    else:
        try:
            from flex_model.ros.model_node import SpatialModelNode as factory
        except ImportError:   # main before issue 43: the class of its own
            from flex_model.ros.spatial_node import SpatialModelNode as factory
        params.pop("hold_until_command")
    return factory(context=ctx, parameter_overrides=[Parameter(k, value=v)
                                                     for k, v in params.items()])


def cpu_per_period(kind: str, periods: int, repeat: int) -> tuple[float, float]:
    """(best CPU s per period, the model period s)."""
    import rclpy
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    node = _node(kind, ctx)
    try:
        period = 1.0 / node.p["rate"]
        if kind == "planar":
            node.stepper.set_command([1.0, -0.5])
            run = lambda: node.step(period)  # noqa: E731
        else:
            node.on_command(type("M", (), {"data": [1.0, -0.5, 0.2]})())
            legacy = hasattr(node, "publish")
            run = (lambda: (node.advance(), node.publish())) if legacy else node.advance
        for _ in range(50):   # warm: numba's cache, the templates
            run()
        best = float("inf")
        for _ in range(repeat):
            c0 = time.process_time()
            for _ in range(periods):
                run()
            best = min(best, (time.process_time() - c0) / periods)
        assert node.diverged is None
        return best, period
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--periods", type=int, default=2000)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args(argv)
    for kind in ("planar", "spatial"):
        cpu, period = cpu_per_period(kind, args.periods, args.repeat)
        print(f"{kind:8s} period {period * 1e3:.1f} ms: CPU {cpu * 1e6:8.1f} us a period, "
              f"real-time factor at most {period / cpu:6.1f}")


if __name__ == "__main__":
    main()
