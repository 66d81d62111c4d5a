"""``flex-twin up``: start the suite's nodes from a ROS 2 parameter file in one process.

The file has the usual form ``<node name>: {ros__parameters: {...}}`` for the nodes
``flex_model``, ``flex_controller`` and ``flex_planner`` (the ones present are started),
as ``ros2 launch`` would pass it with ``--params-file``. One SingleThreadedExecutor runs
them all (``--processes`` starts one process per node with the same file instead, each
spinning its own). The run ends on Ctrl-C, or when the model's simulation time reaches
``--duration`` (one process).

By default the controller runs inside the model node's loop (:func:`in_loop_parameters`:
the ``flex_controller`` section becomes the model's ``controller``, ``controller_rate``
and ``controller_params.*``; no controller node, no DDS round trip per control period);
``--topic-loop`` starts the controller node instead, the model and controller then talk
over /joint_states and /effort_controller/commands as the file describes.
"""
from __future__ import annotations

import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from flex_model import ros_environment
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


#: controller node parameters that are not the law's (the node's own, or implied in the
#: model's loop)
CONTROLLER_NODE_ONLY = ("rate_hz", "state_timeout", "stale_action", "use_sim_time",
                        "parameter_services", "qos_event_warnings",
                        "start_type_description_service", "clock_topic", "joint_names",
                        "use_deflections", "law")


def in_loop_parameters(params: dict) -> dict:
    """The suite with its ``flex_controller`` run in the model's loop: the model gets
    ``controller`` (the law, default eq95), ``controller_rate`` (rate_hz, default 500 Hz)
    and ``controller_params.<name>`` for the law's parameters; the controller node is left
    out. Unchanged if there is no controller or no model, or the model has a controller."""
    if "flex_controller" not in params or "flex_model" not in params \
            or params["flex_model"].get("controller"):
        return params
    from flex_control.controller_node import NODE_DEFAULTS
    ctl = dict(NODE_DEFAULTS, **params["flex_controller"])
    model = dict(params["flex_model"], controller=str(ctl.get("law", "eq95")),
                 controller_rate=float(ctl.get("rate_hz", 500.0)))
    for name, value in ctl.items():
        if name not in CONTROLLER_NODE_ONLY:
            model[f"controller_params.{name}"] = value
    return {name: (model if name == "flex_model" else body)
            for name, body in params.items() if name != "flex_controller"}


def write_parameter_file(params: dict, path) -> Path:
    """``params`` as a ROS 2 parameter file (``<node>: {ros__parameters: ...}``)."""
    import yaml
    path = Path(path)
    path.write_text(yaml.safe_dump({name: {"ros__parameters": body}
                                    for name, body in params.items()}, sort_keys=False))
    return path


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
    ros_environment()   # LOCALHOST discovery before the participant exists
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
    if not args.topic_loop:
        params = in_loop_parameters(params)
    if args.processes:
        with tempfile.TemporaryDirectory(prefix="flex-twin-up-") as tmp:
            path = write_parameter_file(params, Path(tmp) / "params.yaml")
            return run_in_processes(path, list(params))
    run_in_one_process(params, args.duration)
    return 0


def add_up_parser(sub) -> None:
    sp = sub.add_parser("up", help="start the suite's nodes from a ROS 2 parameter file")
    sp.add_argument("config", help="parameter file (<node>: {ros__parameters: ...})")
    sp.add_argument("--processes", action="store_true", help="one process per node")
    sp.add_argument("--topic-loop", action="store_true",
                    help="start the controller node (model <-> controller over topics) "
                    "instead of running its law in the model's loop (the default)")
    sp.add_argument("--duration", type=float, default=None,
                    help="stop when the model's simulation time reaches this (s; one "
                    "process)")
    sp.set_defaults(func=cmd_up)

