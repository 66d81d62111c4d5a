"""``flex-twin up``: start the suite's nodes from a ROS 2 parameter file in one process.

The file has the usual form ``<node name>: {ros__parameters: {...}}`` for the nodes
``flex_model``, ``flex_controller`` and ``flex_planner`` (the ones present are started),
as ``ros2 launch`` would pass it with ``--params-file``. One SingleThreadedExecutor runs
them all (``--processes`` starts one process per node with the same file instead, each
spinning its own). The run ends on Ctrl-C, or when the model's simulation time reaches
``--duration`` (one process).
"""
from __future__ import annotations

import signal
import subprocess
import sys
import time

from flex_model.config import ConfigError, read_yaml

NODES = {"flex_model": ("flex_model.model_node", "ModelNode"),
         "flex_controller": ("flex_control.controller_node", "ControllerNode"),
         "flex_planner": ("flex_planner.planner_node", "PlannerNode")}


def node_parameters(path) -> dict:
    """{node name: {parameter: value}} of a parameter file; unknown node names are errors."""
    data = read_yaml(path)
    out = {}
    for name, body in data.items():
        if name not in NODES:
            raise ConfigError(str(path), name, name, f"one of {', '.join(NODES)}")
        if not isinstance(body, dict) or not isinstance(body.get("ros__parameters", {}), dict):
            raise ConfigError(str(path), f"{name}.ros__parameters", body,
                              "a mapping of parameters")
        out[name] = dict(body.get("ros__parameters", {}))
    return out


def run_in_one_process(params: dict, duration: float | None = None, progress=None):
    """Create the nodes in one context and spin them with one SingleThreadedExecutor;
    returns the nodes (for callers that want to inspect them) after the duration
    (simulation time) or SIGINT/SIGTERM; then each node's ``stop()``, if it has one, runs
    while the context is valid (the controller commands zero torques)."""
    import importlib

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter

    from flex_model.ros_main import stop_on_signals

    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    nodes, ex = {}, None
    try:
        with stop_on_signals() as stop:
            for name, values in params.items():
                module, cls = NODES[name]
                node_cls = getattr(importlib.import_module(module), cls)
                nodes[name] = node_cls(context=ctx, parameter_overrides=[
                    Parameter(k, value=v) for k, v in values.items()])
            ex = SingleThreadedExecutor(context=ctx)
            for n in nodes.values():
                ex.add_node(n)
            model = nodes.get("flex_model")
            next_mark = 0.0
            while ctx.ok() and not stop:
                ex.spin_once(timeout_sec=0.01)
                if model is not None and duration is not None:
                    if progress is not None and model.stepper.t >= next_mark:
                        progress(model.stepper.t, duration)
                        next_mark += duration / 10
                    if model.stepper.t >= duration:
                        break
            for n in nodes.values():
                if hasattr(n, "stop") and ctx.ok():
                    n.stop()
    finally:
        if ex is not None:
            ex.shutdown()
        for n in nodes.values():
            n.destroy_node()
        rclpy.try_shutdown(context=ctx)
    return nodes


def _die_with_parent():
    """In a node's process (Linux): the default SIGINT disposition, and SIGTERM when the
    launching process dies, so a killed ``flex-twin up --processes`` leaves no node
    running on the domain."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)   # so the node's Python handles Ctrl-C
    try:
        import ctypes
        ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)   # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def run_in_processes(path, names) -> int:
    """One process per node (``python -m`` its module, which works in a pip and in a colcon
    install alike) with the same parameter file; the nodes end with this process. Ctrl-C
    (SIGINT) stops them even where it was inherited ignored (a background job of a
    non-interactive shell, as in CI)."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    procs = [subprocess.Popen([sys.executable, "-m", NODES[n][0], "--ros-args",
                               "--params-file", str(path)],
                              preexec_fn=_die_with_parent if sys.platform == "linux" else None)
             for n in names]
    try:
        while all(p.poll() is None for p in procs):
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass
    finally:
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        stop_by = time.monotonic() + 10.0   # one grace period for all nodes, then kill
        for p in procs:
            try:
                p.wait(timeout=max(0.1, stop_by - time.monotonic()))
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    return max((p.returncode or 0) for p in procs)


def cmd_up(args) -> int:
    params = node_parameters(args.config)
    if args.processes:
        return run_in_processes(args.config, list(params))
    run_in_one_process(params, args.duration)
    return 0


def add_up_parser(sub) -> None:
    sp = sub.add_parser("up", help="start the suite's nodes from a ROS 2 parameter file")
    sp.add_argument("config", help="parameter file (<node>: {ros__parameters: ...})")
    sp.add_argument("--processes", action="store_true", help="one process per node")
    sp.add_argument("--duration", type=float, default=None,
                    help="stop when the model's simulation time reaches this (s; one "
                    "process)")
    sp.set_defaults(func=cmd_up)

