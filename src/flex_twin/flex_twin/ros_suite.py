"""``flex-twin up``: start the suite's nodes from a ROS 2 parameter file in one process.

The file has the usual form ``<node name>: {ros__parameters: {...}}`` for the nodes
``flex_model``, ``flex_controller`` and ``flex_planner`` (the ones present are started),
as ``ros2 launch`` would pass it with ``--params-file``; a fully qualified name
(``/robot1/flex_model``, as in docs/examples/two_arms.yaml) starts that node in its
namespace. One SingleThreadedExecutor runs them all (``--processes`` starts one process
per node with the same file instead, each spinning its own). The run ends on Ctrl-C, or
when every model's simulation time reaches ``--duration`` (one process).
ros2_ws/launch/suite.launch.py (installed as share/flex_twin/launch) starts the same
nodes (:func:`suite_nodes`).

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

from flex_model.ros import ros_environment
from flex_model.config import ConfigError, read_yaml

#: the model node in observer mode (``mode: observer`` in its section, issue 45)
OBSERVER = ("flex_model.ros.observer_node", "ObserverNode")
NODES = {"flex_model": ("flex_model.ros.model_node", "ModelNode"),
         "flex_controller": ("flex_control.controller_node", "ControllerNode"),
         "flex_planner": ("flex_planner.planner_node", "PlannerNode")}


def split_name(key: str) -> tuple[str, str]:
    """(namespace, node name) of a parameter file's node key: ``flex_model`` -> ("",
    "flex_model"), ``/robot1/flex_model`` -> ("/robot1", "flex_model")."""
    ns, _, name = str(key).rpartition("/")
    return ("/" + ns.strip("/") if ns.strip("/") else ""), name


def node_parameters(path) -> dict:
    """{node key: {parameter: value}} of a parameter file (keys as in the file: a node
    name, or a fully qualified one); unknown node names are errors."""
    data = read_yaml(path)
    out = {}
    for name, body in data.items():
        if split_name(name)[1] not in NODES:
            raise ConfigError(str(path), name, name, f"one of {', '.join(NODES)} (a "
                              "namespace may stand before: /robot1/flex_model)")
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
    """The suite with each ``flex_controller`` run in the loop of the ``flex_model`` of its
    namespace: the model gets ``controller`` (the law, default eq95), ``controller_rate``
    (rate_hz, default 500 Hz) and ``controller_params.<name>`` for the law's parameters;
    the controller node is left out. A namespace without a controller or a model, or
    whose model has a controller, is unchanged."""
    keys = {split_name(k): k for k in params}
    out = {}
    for key, body in params.items():
        ns, name = split_name(key)
        model, ctl = keys.get((ns, "flex_model")), keys.get((ns, "flex_controller"))
        if model is None or ctl is None or params[model].get("controller") or \
                params[model].get("mode") == "observer":
            out[key] = body
        elif name == "flex_model":
            out[key] = _with_controller(body, params[ctl])
        elif name != "flex_controller":
            out[key] = body
    return out


def held_at_the_model_start(params: dict) -> dict:
    """Each controller node (over topics) holds its model's initial joint angles until a
    trajectory arrives (``hold_joint_angles_deg``; issue 46 item 8: holding the first
    measured, sagged pose crept at every restart), unless its file gives a pose."""
    from flex_model.ros.model_node import PARAMETERS
    default = next(p.default for p in PARAMETERS if p.name == "initial_joint_angles_deg")
    keys = {split_name(k): k for k in params}
    out = dict(params)
    for key, body in params.items():
        ns, name = split_name(key)
        model = keys.get((ns, "flex_model"))
        if name == "flex_controller" and model is not None and \
                not body.get("hold_joint_angles_deg"):
            hold = params[model].get("initial_joint_angles_deg", default)
            out[key] = dict(body, hold_joint_angles_deg=[float(a) for a in hold])
    return out


def _with_controller(model: dict, controller: dict) -> dict:
    """A model's parameters with the controller's law in its loop."""
    from flex_control.controller_node import NODE_DEFAULTS
    ctl = dict(NODE_DEFAULTS, **controller)
    model = dict(model, controller=str(ctl.get("law", "eq95")),
                 controller_rate=float(ctl.get("rate_hz", 500.0)))
    for name, value in ctl.items():
        if name not in CONTROLLER_NODE_ONLY:
            model[f"controller_params.{name}"] = value
    return model


#: package and executable of each node (ament: ros2 run / launch)
EXECUTABLES = {"flex_model": ("flex_model", "model_node"),
               "flex_controller": ("flex_control", "controller_node"),
               "flex_planner": ("flex_planner", "planner_node")}


def suite_nodes(params: dict, topic_loop: bool = False) -> tuple[dict, list]:
    """What ``up`` (and the launch file) starts from a parameter file's ``params``: the
    parameters (the controller folded into the model unless ``topic_loop``) and per node
    (package, executable, namespace, name)."""
    params = in_loop_parameters(params) if not topic_loop else held_at_the_model_start(params)
    nodes = []
    for key in params:
        ns, name = split_name(key)
        nodes.append((*EXECUTABLES[name], ns, name))
    return params, nodes


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

    from flex_model.command import stop_on_signals

    ctx = rclpy.Context()
    ros_environment()   # LOCALHOST discovery before the participant exists
    rclpy.init(context=ctx)
    nodes, ex = {}, None
    try:
        with stop_on_signals() as stop:
            for key, values in params.items():
                ns, name = split_name(key)
                module, cls = node_class(name, values)
                node_cls = getattr(importlib.import_module(module), cls)
                nodes[key] = node_cls(context=ctx, namespace=ns or None, parameter_overrides=[
                    Parameter(k, value=v) for k, v in values.items()])
            ex = SingleThreadedExecutor(context=ctx)
            for n in nodes.values():
                ex.add_node(n)
            models = [n for k, n in nodes.items() if split_name(k)[1] == "flex_model"
                      and hasattr(n, "stepper")]  # (an observer follows its arm's time)
            next_mark = 0.0
            while ctx.ok() and not stop.is_set():
                ex.spin_once(timeout_sec=0.01)
                if models and duration is not None and all(m.configured for m in models):
                    t = min(m.stepper.t for m in models)
                    if progress is not None and t >= next_mark:
                        progress(t, duration)
                        next_mark += duration / 10
                    if t >= duration:
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


def node_class(name: str, values: dict) -> tuple[str, str]:
    """(module, class) of the node ``name`` with parameters ``values``: the model node in
    observer mode is flex_model.ros.observer_node's."""
    if name == "flex_model" and values.get("mode") == "observer":
        return OBSERVER
    return NODES[name]


def run_in_processes(path, names, values=None) -> int:
    """One process per node (``python -m`` its module, which works in a pip and in a colcon
    install alike) with the same parameter file; the nodes end with this process. Ctrl-C
    (SIGINT) stops them even where it was inherited ignored (a background job of a
    non-interactive shell, as in CI). ``values``: the parameters per node name (a model
    in observer mode runs flex_model.ros.observer_node)."""
    signal.signal(signal.SIGINT, signal.default_int_handler)
    procs, values = [], values or {}
    for key in names:
        ns, name = split_name(key)
        procs.append(subprocess.Popen(
            [sys.executable, "-m", node_class(name, values.get(key, {}))[0], "--ros-args"]
            + (["-r", f"__ns:={ns}"] if ns else []) + ["--params-file", str(path)],
            preexec_fn=_die_with_parent if sys.platform == "linux" else None))
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
    params, _ = suite_nodes(node_parameters(args.config), args.topic_loop)
    if args.processes:
        with tempfile.TemporaryDirectory(prefix="flex-twin-up-") as tmp:
            path = write_parameter_file(params, Path(tmp) / "params.yaml")
            return run_in_processes(path, list(params), params)
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


def observer_arguments(args) -> list[str]:
    """The ROS arguments of ``flex-twin observe``: the model node's observer mode with
    the options as parameters."""
    params = {"mode": "observer", "arm": args.arm, "measure": args.measure,
              "input": args.input, "adapt": args.adapt, "adapt_horizon": args.adapt_horizon,
              "adapt_block": args.adapt_block, "sample_period": args.sample_period,
              "input_topic": args.input_topic}
    out = ["flex-twin-observe", "--ros-args"]
    if args.namespace:
        out += ["-r", f"__ns:={args.namespace}"]
    for name, value in params.items():
        out += ["-p", f"{name}:={value}" if value != "" else f"{name}:=''"]
    return out


def cmd_observe(args) -> int:
    from flex_model.ros.observer_node import main
    main(observer_arguments(args))
    return 0


def add_observe_parser(sub) -> None:
    sp = sub.add_parser("observe", help="the model node in observer mode: estimate a real "
                        "arm's state from its joint_states (issue 45; docs/ros.md)")
    sp.add_argument("--arm", default="quanser_cuboulder_calibrated",
                    help="arm preset or YAML: the model of the real arm")
    sp.add_argument("--measure", default="q", help="measurements, comma-separated: q<i>, "
                    "v<i> (joint_states position, velocity), w<i> (tip deflection), m<i>, "
                    "ax, ay, tip_x, tip_y, tip_z (flex/gauges, in this order); q: every "
                    "joint angle")
    sp.add_argument("--input", choices=("effort", "command"), default="effort",
                    help="the model's input: joint_states' effort, or the last "
                    "effort_controller/commands")
    sp.add_argument("--adapt", default="", help="parameters adapted online, comma-separated "
                    "(coulomb_friction:0, viscous_friction:0, payload_mass, link_stiffness:0)")
    sp.add_argument("--adapt-horizon", type=float, default=0.0, metavar="SECONDS",
                    help="fit the adapted joint frictions over the last SECONDS (the "
                    "horizon fit; default 0: random walks)")
    sp.add_argument("--adapt-block", type=float, default=0.05, metavar="SECONDS",
                    help="the horizon fit's block (default 0.05 s)")
    sp.add_argument("--sample-period", type=float, default=1e-3, help="s (the arm's)")
    sp.add_argument("--input-topic", default="joint_states")
    sp.add_argument("--namespace", default="", help="ROS namespace of the node")
    sp.set_defaults(func=cmd_observe)
