"""flex-twin up: the suite's parameter file, lockstep; by default the controller runs in the
model node's loop (one process, or a process per node), with ``--topic-loop`` the model
and controller nodes talk over topics (three processes); either way the loop settles at
the static equilibrium of the arm held by the PD of Eq. (95) (Kp = h a^2 per joint, seen
at the joints through the sampled loop); Ctrl-C leaves zero torques commanded by the
controller node."""
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from flex_model.arm import load_arm
from flex_model.config import ConfigError
from flex_model.dynamics import FlexArmModel
from flex_twin.ros_suite import in_loop_parameters, node_parameters
from flex_model.statics import static_equilibrium

PARAMS = Path(__file__).resolve().parents[1] / "ros2_ws" / "params" / "suite.yaml"


def pd_equilibrium_deg(params):
    arm = FlexArmModel(load_arm(params["flex_model"]["arm"]))
    h, a = np.array(params["flex_controller"]["h"]), np.array(params["flex_controller"]["a"])
    set_deg = params["flex_model"]["initial_joint_angles_deg"]
    eq = static_equilibrium(arm, np.radians(set_deg), joints="pd", kp=h * a * a)
    assert np.degrees(np.abs(eq.joint_angles - np.radians(set_deg))).max() > 0.1  # it sags
    return np.degrees(eq.joint_angles)


def test_in_loop_parameters_fold_the_controller_into_the_model():
    params = in_loop_parameters(node_parameters(PARAMS))
    assert list(params) == ["flex_model", "flex_planner"]
    m = params["flex_model"]
    assert (m["controller"], m["controller_rate"]) == ("eq95", 500.0)
    assert m["controller_params.h"] == [25.0, 25.0] and m["controller_params.a"] == [5.0, 5.0]
    assert not any(k.startswith("controller_params.") and k[18:] in (
        "rate_hz", "use_sim_time", "state_timeout", "parameter_services") for k in m)


@pytest.mark.parametrize("processes,topic_loop", [(True, True), (False, False), (True, False)],
                         ids=["three-topic-loop", "one-in-loop", "processes-in-loop"])
def test_up_holds_the_equilibrium_and_ctrl_c_commands_zero(processes, topic_loop):
    """``flex-twin up`` as a process, with ``--processes`` (each node its own process,
    python -m) or without, the controller in the model's loop (default) or a node
    (``--topic-loop``): the equilibrium is the same (the loop over DDS between processes
    is not deterministic: a tick may see the previous state, which does not move a static
    equilibrium); SIGINT makes the controller node command zero torques and everything
    exit 0."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    params = node_parameters(PARAMS)
    proc = subprocess.Popen([sys.executable, "-m", "flex_twin.cli", "up", str(PARAMS)]
                            + ["--processes"] * processes + ["--topic-loop"] * topic_loop)
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        node = rclpy.create_node("probe_up", context=ctx)
        states, commands = [], []
        node.create_subscription(JointState, "/joint_states", states.append, 10)
        node.create_subscription(Float64MultiArray, "/effort_controller/commands",
                                 lambda m: commands.append(list(m.data)), 10)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        end = time.monotonic() + 60.0
        # 2 s of twin time and a command seen by the probe (its subscription may match the
        # controller's publisher after the model's, which steps with the held command)
        while not (states and states[-1].header.stamp.sec >= 2
                   and (commands or not topic_loop)):
            assert time.monotonic() < end and proc.poll() is None, "no lockstep progress"
            ex.spin_once(timeout_sec=0.05)
            del states[:-1], commands[:-1]
        theta = np.degrees(states[-1].position)
        # N m: holding the arm against gravity (in the loop: the applied torques)
        assert np.abs(commands[-1] if topic_loop else states[-1].effort).max() > 1.0
        assert commands == [] or topic_loop  # in the loop: no command topic
        proc.send_signal(signal.SIGINT)
        stop_by = time.monotonic() + 30.0   # its nodes get 10 s in all, then are killed
        while proc.poll() is None:
            assert time.monotonic() < stop_by, "flex-twin up did not stop"
            ex.spin_once(timeout_sec=0.05)
        ex.spin_once(timeout_sec=0.1)
        ex.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0
    if topic_loop:
        assert commands[-1] == [0.0, 0.0]
    np.testing.assert_allclose(theta, pd_equilibrium_deg(params), atol=0.02)


def test_parameter_file_errors_name_the_node(tmp_path):
    bad = tmp_path / "p.yaml"
    bad.write_text("flex_modle:\n  ros__parameters: {arm: x}\n")
    with pytest.raises(ConfigError, match=r"p.yaml: flex_modle: got 'flex_modle'; expected "
                                          r"one of flex_model, flex_controller, flex_planner"):
        node_parameters(bad)


def _children(pid: int) -> set:
    try:
        return {int(c) for t in Path(f"/proc/{pid}/task").iterdir()
                for c in (t / "children").read_text().split()}
    except OSError:
        return set()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux")
def test_a_killed_up_leaves_no_node_running():
    """SIGKILL of ``flex-twin up --processes`` (no chance to forward a signal) ends its node
    processes too: none is left publishing on the domain."""
    proc = subprocess.Popen([sys.executable, "-m", "flex_twin.cli", "up", str(PARAMS),
                             "--processes", "--topic-loop"])
    try:
        end = time.monotonic() + 60.0
        while len(_children(proc.pid)) < 3:
            assert time.monotonic() < end and proc.poll() is None, "no node processes"
            time.sleep(0.1)
        nodes = _children(proc.pid)
    finally:
        proc.kill()
        proc.wait()
    end = time.monotonic() + 20.0
    while any(Path(f"/proc/{p}").exists() and
              Path(f"/proc/{p}/stat").read_text().split()[2] != "Z" for p in nodes):
        assert time.monotonic() < end, f"node processes {nodes} outlived flex-twin up"
        time.sleep(0.1)


TWO_ARMS = Path(__file__).resolve().parents[1] / "docs" / "examples" / "two_arms.yaml"


def test_up_runs_the_docs_two_arm_file_in_its_namespaces():
    """Issue 46 item 10b: ``flex-twin up docs/examples/two_arms.yaml`` (fully qualified
    node names) was refused ("expected one of flex_model, ..."). Now each twin starts in
    its namespace with its controller in its model's loop; after 1 s of simulation time
    both arms hold their own set-points (30, 0 and -60, 20 deg) within the sag of the PD,
    and each ran on its own clock."""
    raw = node_parameters(TWO_ARMS)  # main: "expected one of flex_model, ..."
    from flex_twin.ros_suite import run_in_one_process, suite_nodes
    params, nodes = suite_nodes(raw)
    assert sorted(nodes) == [("flex_model", "model_node", "/robot1", "flex_model"),
                             ("flex_model", "model_node", "/robot2", "flex_model")]
    assert params["/robot1/flex_model"]["controller"] == "eq95"
    assert params["/robot2/flex_model"]["controller_params.h"] == [25.0, 25.0]
    running = run_in_one_process(params, duration=1.0)
    for key, set_deg in (("/robot1/flex_model", [30.0, 0.0]),
                         ("/robot2/flex_model", [-60.0, 20.0])):
        node = running[key]
        assert node.frames.base == key[1:7] + "/base_link"  # its frame_prefix
        assert node.stepper.t >= 1.0
        theta = np.degrees(node.model.joint_angles(node.stepper.q))
        np.testing.assert_allclose(theta, set_deg, atol=3.0)
    a, b = (np.degrees(running[k].model.joint_angles(running[k].stepper.q))
            for k in ("/robot1/flex_model", "/robot2/flex_model"))
    assert abs(a[0] - b[0]) > 80.0  # two different arms, not one twice


LAUNCH = Path(__file__).resolve().parents[1] / "ros2_ws" / "launch" / "suite.launch.py"


def _launch_with_stubs(monkeypatch, path):
    """The launch file's module, with stand-ins for the launch and launch_ros packages
    (not among the pip wheels): each records what the file gives it."""
    import importlib.util
    import types

    class Record:
        def __init__(self, *args, **kwargs):
            self.args, self.kwargs = args, kwargs

    class Config(Record):
        def perform(self, context):
            return context[self.args[0]]
    mods = {"launch": {"LaunchDescription": Record},
            "launch.actions": {"DeclareLaunchArgument": Record, "OpaqueFunction": Record},
            "launch.substitutions": {"LaunchConfiguration": Config},
            "launch_ros": {}, "launch_ros.actions": {"Node": Record}}
    for name, attrs in mods.items():
        mod = types.ModuleType(name)
        mod.__dict__.update(attrs)
        monkeypatch.setitem(sys.modules, name, mod)
    spec = importlib.util.spec_from_file_location("suite_launch", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _launched(module, **arguments):
    """(package, executable, namespace, name) and parameters of the launched nodes."""
    import yaml
    (entities,) = module.generate_launch_description().args
    context = {e.args[0]: e.kwargs["default_value"] for e in entities
               if "default_value" in e.kwargs}
    context.update(arguments)
    (opaque,) = [e for e in entities if "function" in e.kwargs]
    out = []
    for node in opaque.kwargs["function"](context):
        kw = node.kwargs
        params = yaml.safe_load(Path(kw["parameters"][0]).read_text())
        out.append(((kw["package"], kw["executable"], kw.get("namespace", ""), kw["name"]),
                    params))
    return out


@pytest.mark.parametrize("topic_loop", [False, True])
def test_launch_file_starts_the_nodes_of_up(monkeypatch, topic_loop):
    """Issue 46 item 10a: ros2_ws/launch/suite.launch.py (installed by flex_twin) starts
    up's nodes: by default the model with the controller in its loop and the planner (on
    main: the controller node over topics); topic_loop:=true the three nodes as ``up
    --topic-loop``; the two-arm file in its namespaces."""
    module = _launch_with_stubs(monkeypatch, LAUNCH)
    assert Path(module.PARAMS).resolve() == PARAMS.resolve()
    got = _launched(module, topic_loop=str(topic_loop).lower())
    from flex_twin.ros_suite import suite_nodes
    want_params, want_nodes = suite_nodes(node_parameters(PARAMS), topic_loop)
    assert [n for n, _ in got] == want_nodes
    assert [n[1] for n in want_nodes] == (
        ["model_node", "controller_node", "planner_node"] if topic_loop
        else ["model_node", "planner_node"])
    model = got[0][1]["flex_model"]["ros__parameters"]
    assert model == want_params["flex_model"]
    assert ("controller" in model) is not topic_loop
    got = _launched(module, params=str(TWO_ARMS), topic_loop="false")
    assert [n for n, _ in got] == [("flex_model", "model_node", "/robot1", "flex_model"),
                                   ("flex_model", "model_node", "/robot2", "flex_model")]


def test_launch_file_and_parameters_are_installed(monkeypatch):
    """flex_twin's setup.py installs the launch file and its default parameter file under
    share/flex_twin (where ``ros2 launch flex_twin suite.launch.py`` finds them)."""
    import os
    import runpy

    import setuptools
    captured = {}
    monkeypatch.setattr(setuptools, "setup", lambda **kw: captured.update(kw))
    setup_py = Path(__file__).resolve().parents[1] / "src" / "flex_twin" / "setup.py"
    cwd = os.getcwd()
    try:
        runpy.run_path(str(setup_py))
    finally:
        os.chdir(cwd)
    files = dict(captured["data_files"])
    assert files["share/flex_twin/launch"] == ["launch/suite.launch.py"]
    assert files["share/flex_twin/params"] == ["params/suite.yaml"]
    assert (setup_py.parent / "launch" / "suite.launch.py").resolve() == LAUNCH.resolve()
    assert (setup_py.parent / "params" / "suite.yaml").resolve() == PARAMS.resolve()


def test_record_during_up_is_complete_and_in_sim_time(tmp_path):
    """Issue 46 item 7, the README's flow: ``flex-twin record /joint_states
    /flex/deflections`` during ``flex-twin up`` (lockstep, the controller in the loop, many
    times faster than real time). On main the log times spanned the wall clock (5.1 s
    against 133.8 s of header stamps) and 6.5 % of the messages were lost. Now the
    recorder logs in simulation time because /clock is published, and takes every
    message: read back with the mcap reader, every header stamp of the run is there once
    (the first step's 0.002 s, then every 0.01 s to the end, publish_rate 100 Hz; the model
    starts paused until the recorder listens), and log times equal header stamps within
    one publication period (a /joint_states goes out just before the /clock of its
    step)."""
    import os
    import rclpy
    from mcap.reader import make_reader
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    from std_srvs.srv import SetBool
    import yaml

    params = node_parameters(PARAMS)
    params["flex_model"].update(start_paused=True, parameter_services=True)
    del params["flex_planner"]
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump({k: {"ros__parameters": v} for k, v in params.items()}))
    duration, period = 20.0, 1.0 / params["flex_model"]["publish_rate"]
    up = subprocess.Popen([sys.executable, "-m", "flex_twin.cli", "up", str(path),
                           "--duration", str(duration)])
    rec = subprocess.Popen([sys.executable, "-m", "flex_twin.cli", "record", "/joint_states",
                            "/flex/deflections", "-o", str(tmp_path / "bag"),
                            "--discovery-timeout", "120"], stderr=subprocess.PIPE, text=True)
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        node = rclpy.create_node("record_probe", context=ctx)
        pause = node.create_client(SetBool, "/flex_model/pause")
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        end = time.monotonic() + 180.0
        while not (pause.service_is_ready() and node.count_subscribers("/joint_states")
                   and node.count_subscribers("/flex/deflections")):
            assert time.monotonic() < end and up.poll() is None and rec.poll() is None
            ex.spin_once(timeout_sec=0.05)
        time.sleep(1.0)  # the recorder's subscriptions matched on its side too
        future = pause.call_async(SetBool.Request(data=False))
        while not future.done():
            assert time.monotonic() < end, "no answer from ~/pause"
            ex.spin_once(timeout_sec=0.05)
        assert up.wait(timeout=180) == 0
        time.sleep(1.0)
        rec.send_signal(signal.SIGINT)
        _, err = rec.communicate(timeout=60)
        assert rec.returncode == 0, err
        ex.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
        for p in (up, rec):
            if p.poll() is None:
                p.kill()
    (mcap,) = [os.path.join(tmp_path / "bag", f) for f in os.listdir(tmp_path / "bag")
               if f.endswith(".mcap")]
    got = {"/joint_states": [], "/flex/deflections": []}
    with open(mcap, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            stamp = deserialize_message(message.data, JointState).header.stamp
            got[channel.topic].append((message.log_time * 1e-9,
                                       stamp.sec + 1e-9 * stamp.nanosec))
    for topic, rows in got.items():
        log, stamps = np.array(rows).T
        n = len(stamps)
        assert n >= duration / period  # up ran to the end
        assert 0.0 < stamps[0] <= period  # the first step after the pause: none lost
        np.testing.assert_allclose(stamps, stamps[0] + period * np.arange(n), rtol=0,
                                   atol=1e-9)  # each publication once, none lost
        assert np.all(stamps - log >= -1e-9) and np.all(stamps - log <= period + 1e-9)
        assert abs((log[-1] - log[0]) - (stamps[-1] - stamps[0])) <= period + 1e-9
    assert "log time = sim time (/clock)" in err


def test_a_topic_loop_controller_holds_its_models_start_not_the_sagged_pose():
    """Issue 46 item 8: over topics, each controller node holds its own namespace's model
    start until a trajectory arrives (a restart then holds the same pose, no creep); a
    pose in the file is kept; in the loop there is no controller node to tell."""
    from flex_twin.ros_suite import suite_nodes
    raw = {"flex_model": {"initial_joint_angles_deg": [151.0, -20.0]},
           "flex_controller": {"rate_hz": 500.0},
           "/arm2/flex_model": {}, "/arm2/flex_controller": {},
           "/arm3/flex_model": {}, "/arm3/flex_controller": {"hold_joint_angles_deg": [5.0]}}
    params, _ = suite_nodes(raw, topic_loop=True)
    assert params["flex_controller"]["hold_joint_angles_deg"] == [151.0, -20.0]
    assert params["/arm2/flex_controller"]["hold_joint_angles_deg"] == [0.0]  # the default
    assert params["/arm3/flex_controller"]["hold_joint_angles_deg"] == [5.0]
    assert "hold_joint_angles_deg" not in raw["flex_controller"]   # the file is not changed
    in_loop, _ = suite_nodes(raw)
    assert not any("hold_joint_angles_deg" in body for body in in_loop.values())
