"""The twin demo over ROS: the thesis Ch. V task (VALIDATION.md section F).

The planner node inverts the four tip waypoints and publishes the joint trajectory with the
admissible nominal torque; Eq. (95) (h = 25, a = 5) with that feed-forward runs inside the
model node's loop (``controller:=eq95``, flex_model.control_loop: no DDS round trip per
control period, the ros2_control pattern), the model node integrates the arm in lockstep
and publishes at 50 Hz. With ``in_loop=False`` (``flex-twin twin-demo --topic-loop``) the
controller node applies the law instead, over ROS topics (the model publishes /joint_states
and /clock after every control period, the controller answers on
/effort_controller/commands). The nodes share one process (one SingleThreadedExecutor,
see flex_model.ros.main). Everything is
recorded into a rosbag2 (MCAP) bag under runs/<timestamp>/ with the simulation time as log
time (bag duration = simulated duration; ``flex-twin play --clock`` replays it in sim time);
then a summary table and PNG plots.

The arm is ``thesis_example1_motors``: the section F arm with geared motors at the joints
(a hub-less flexible arm makes the sampled Eq. 95 loop unstable, see the preset).
"""
from __future__ import annotations

import time
from datetime import datetime
from pathlib import Path

import numpy as np

from flex_model.ros import ros_environment
from flex_planner.planning import SECTION_F_TIMES, SECTION_F_WAYPOINTS

from .twin_demo_ahead import ARM, LAW, RATE

WAYPOINTS, TIMES = SECTION_F_WAYPOINTS, SECTION_F_TIMES   # thesis Ch. V task
RECORDED = {"/joint_states": "sensor_msgs/msg/JointState",
            "/flex/deflections": "sensor_msgs/msg/JointState",
            "/flex/tip_pose": "geometry_msgs/msg/PoseStamped",
            "/flex/shape": "visualization_msgs/msg/MarkerArray",
            "/effort_controller/commands": "std_msgs/msg/Float64MultiArray",
            "/flex_planner/waypoints": "nav_msgs/msg/Path",
            "/clock": "rosgraph_msgs/msg/Clock"}
#: the topics the summary reads (their messages kept serialized during the run)
KEPT = {name: RECORDED[name] for name in ("/flex/tip_pose", "/joint_states",
                                          "/flex/deflections")}
#: in the model's loop: wall time (s) between the executor's turns (timers, services; the
#: recorder takes the messages after every step itself); after the last step: the quiet
#: time (s) that ends taking the last messages
SPIN_PERIOD, QUIET = 0.05, 0.01
#: wall time (s) the demo waits for the planner: a fresh clone's planner compiles its loop
#: first (about 18 CPU-s, beside the in-loop kernels' 55), which took 12 min of wall time at
#: load average 30 on 2 cores (2026-12-07)
PLAN_TIMEOUT = 1800.0


def run(out_dir: Path | None = None, duration: float = 15.0, rate: float = RATE,
        progress=None, in_loop: bool = True, publish_rate: float = 50.0) -> dict:
    """Run the demo; returns the summary (also written as summary.json). ``in_loop``: the
    controller in the model's loop (default), else the controller node over topics."""
    import json

    import rclpy
    from rclpy.serialization import deserialize_message

    from flex_model.control_loop import compile_ahead_in_background, wait_for_shared_kernels
    from flex_model.urdf import plane_rotation
    from .bags.message_types import get_message

    out_dir = Path(out_dir or Path("runs") / f"{datetime.now():%Y%m%d-%H%M%S}-twin-demo")
    out_dir.mkdir(parents=True, exist_ok=True)
    ctx = rclpy.Context()
    ros_environment()   # LOCALHOST discovery before the participant exists
    rclpy.init(context=ctx)
    wall0 = time.perf_counter()
    phases = _Phases()
    # the model's in-loop kernels compile on the second core while the planner compiles its
    # own (a fresh clone: about half the demo's first run; docs/ros.md, the twin demo); under
    # make demo this process waits for the one the bootstrap started (twin_demo_ahead)
    ahead = compile_ahead_in_background(ARM, 1.0 / rate, LAW) if in_loop else None
    demo = _Demo(ctx, rate, in_loop)
    try:
        demo.start()
        if ahead is not None:   # the planner then loads the kernels it shares with the model
            wait_for_shared_kernels(ahead)
            phases.mark("wait for the shared kernels")
        plan = demo.plan()
        phases.mark("plan")
        if ahead is not None:
            import flex_model.plots  # noqa: F401  (matplotlib, for the summary: meanwhile)
            ahead.wait()
            phases.mark("wait for compile_ahead")
        model = demo.start_model(plan, publish_rate)
        phases.mark("model node")
        loop_wall, loop_cpu = demo.record(model, out_dir / "bag", duration, publish_rate,
                                          progress)
        phases.mark("loop and recording")
        wall = time.perf_counter() - wall0
    finally:
        if ahead is not None and ahead.poll() is None:   # the demo failed before the model
            ahead.kill()
            ahead.wait()
        if ahead is not None:
            ahead.stdout.close()
        demo.close()
        rclpy.try_shutdown(context=ctx)
    plane = plane_rotation(model.model.gravity)  # flex/tip_pose is in the base frame
    tips, states, defl = ([deserialize_message(data, get_message(KEPT[name]))
                           for data in demo.kept[name]] for name in KEPT)
    summary = _summarize(tips, states, defl, plan, wall, duration, out_dir, plane)
    summary.update(controller="in the model's loop (eq95)" if in_loop
                   else "controller node over topics",
                   loop_wall_s=loop_wall, loop_real_time_factor=duration / loop_wall,
                   loop_cpu_s=loop_cpu, loop_cpu_real_time_factor=duration / loop_cpu)
    phases.mark("summary and plot")
    summary["phases"] = phases.table()
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1))
    return summary


class _Phases:
    """Wall and CPU seconds of the demo's phases (where a first run's time goes,
    docs/development.md): this process's, and the compile_ahead process's (a child)."""

    def __init__(self):
        self.t, self.c = time.perf_counter(), time.process_time()
        self.rows = [{"phase": "imports, rclpy.init", "wall_s": None, "cpu_s": self.c}]

    def mark(self, name: str) -> None:
        t, c = time.perf_counter(), time.process_time()
        self.rows.append({"phase": name, "wall_s": t - self.t, "cpu_s": c - self.c})
        self.t, self.c = t, c

    def table(self) -> dict:
        import resource
        kids = resource.getrusage(resource.RUSAGE_CHILDREN)
        return {"this_process": self.rows,
                "children_cpu_s": kids.ru_utime + kids.ru_stime}


def _lean():
    """Lean nodes (flex_model.ros.main.lean_node, as ros2_ws/params/suite.yaml): a faster
    loop."""
    from rclpy.parameter import Parameter
    return [Parameter(name, value=False) for name in (
        "parameter_services", "qos_event_warnings", "start_type_description_service")]


class _Demo:
    """The demo's nodes on one SingleThreadedExecutor: the planner, the controller node
    (over topics only), a probe that sends the waypoints and keeps the plan, and later the
    model."""

    def __init__(self, ctx, rate: float, in_loop: bool):
        from rclpy.executors import SingleThreadedExecutor
        self.ctx, self.rate, self.in_loop, self.nodes = ctx, rate, in_loop, []
        self.ex = SingleThreadedExecutor(context=ctx)
        self.kept = {name: [] for name in KEPT}

    def start(self) -> None:
        """The planner, the controller node (over topics) and the probe."""
        import rclpy
        from rclpy.parameter import Parameter as P
        from rclpy.qos import DurabilityPolicy, QoSProfile
        from trajectory_msgs.msg import JointTrajectory
        from nav_msgs.msg import Path as PathMsg

        from flex_control.controller_node import ControllerNode
        from flex_planner.planner_node import PlannerNode
        from .bags.message_types import get_message
        ctx, rate, in_loop = self.ctx, self.rate, self.in_loop
        self.planner = self._add(PlannerNode(context=ctx, parameter_overrides=[
            P("arm", value=ARM), P("sample_period", value=1.0 / rate), *_lean()]))
        if not in_loop:
            self._add(ControllerNode(context=ctx, parameter_overrides=[
                P("h", value=[25.0, 25.0]), P("a", value=[5.0, 5.0]), P("rate_hz", value=rate),
                P("use_sim_time", value=True), P("state_timeout", value=0.5), *_lean()]))
        self.probe = self._add(rclpy.create_node("demo_probe", context=ctx))
        self.plans = []
        self.probe.create_subscription(JointTrajectory, "flex_planner/trajectory",
                                       self.plans.append, 1)
        # the summary's topics as serialized messages (deserialized after the run): in
        # the model's loop the recorder keeps them (one reader per topic, taken in one
        # call per step); over topics the probe too (it has the state of t = 0, which the
        # model publishes when it starts, before the recorder subscribes)
        if not in_loop:
            for name, cls in KEPT.items():
                self.probe.create_subscription(get_message(cls), name,
                                               self.kept[name].append, 1000, raw=True)
        # latched (transient local): the recorder, started later, records the waypoints too
        self.pub = self.probe.create_publisher(PathMsg, "flex_planner/waypoints", QoSProfile(
            depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL))

    def _add(self, node):
        self.nodes.append(node)
        self.ex.add_node(node)
        return node

    def spin_until(self, pred, what: str, timeout: float = PLAN_TIMEOUT) -> None:
        end = time.monotonic() + timeout
        while not pred():
            if time.monotonic() > end:
                raise TimeoutError(f"twin demo: timed out waiting for {what}")
            self.ex.spin_once(timeout_sec=0.01)

    def plan(self):
        """Send the thesis Ch. V waypoints; the planner's joint trajectory."""
        from flex_planner.ros_messages import waypoints_msg
        self.spin_until(lambda: self.pub.get_subscription_count() > 0, "the planner")
        self.pub.publish(waypoints_msg([(x, y, t) for (x, y), t in zip(WAYPOINTS, TIMES)]))
        self.spin_until(lambda: self.plans, "the plan")
        if self.in_loop:
            # done with the planner: at load 30 (a first run planning for 12 min) it planned
            # again when the recorder subscribed to the latched waypoints, and the model
            # took that second plan on flex_planner/trajectory (tip 9-12 mm off)
            self.ex.remove_node(self.planner)
            self.nodes.remove(self.planner)
            self.planner.destroy_node()
        return self.plans[-1]

    def start_model(self, plan, publish_rate: float):
        """The model node in lockstep at the plan's start (static); in the loop: Eq. (95)
        inside it, the plan handed over in-process from t = 0 (on flex_planner/trajectory
        it would start when it arrives), paused (the demo steps it itself)."""
        from rclpy.parameter import Parameter as P

        from flex_model.ros import conversions as conv
        from flex_model.ros.model_node import ModelNode
        own = [P("controller", value="eq95"), P("controller_rate", value=self.rate),
               P("controller_params.h", value=[25.0]), P("controller_params.a", value=[5.0]),
               P("start_paused", value=True)] if self.in_loop else []
        model = self._add(ModelNode(context=self.ctx, parameter_overrides=[
            P("arm", value=ARM), P("mode", value="lockstep"), P("rate", value=self.rate),
            P("publish_rate", value=publish_rate),
            P("initial_joint_angles_deg", value=list(np.degrees(plan.points[0].positions))),
            P("start_static", value=True), P("lockstep_timeout", value=0.5), *_lean(), *own]))
        if self.in_loop:
            model.loop.set_trajectory(conv.trajectory_from_msg(plan, model.names), 0.0)
        return model

    def record(self, model, bag_dir: Path, duration: float, publish_rate: float,
               progress=None) -> tuple:
        """Run the model to ``duration`` while recording the bag; (loop wall s, loop CPU s).
        One time base, the simulation's: log time = the latest /clock (sim time from 0, as
        ``ros2 bag record --use-sim-time``), header stamps (the same sim time) for the
        stamped topics; bag duration = simulated duration."""
        from .bags import BagWriter, Recorder
        with BagWriter(bag_dir) as bag:
            recorder = Recorder(self.probe, bag, RECORDED, use_sim_time=True,
                                use_header_stamp=("/joint_states", "/flex/deflections",
                                                  "/flex/tip_pose"),
                                keep=KEPT if self.in_loop else ())
            if self.in_loop:  # the start (the node published it before the recorder was there)
                self.kept = recorder.kept
                model.publish_state(full=True)
                _load_compiled_loop(model.loop)
            w0, c0 = time.perf_counter(), time.process_time()
            self._advance(model, recorder, duration, publish_rate, progress)
            # the messages of the last step may still be queued: stop the model (no
            # further step) and take them until none has come for QUIET s, so that the
            # bag ends at the simulated duration
            self.ex.remove_node(model)
            _drain(self.ex, timeout_sec=QUIET)
            walls = time.perf_counter() - w0, time.process_time() - c0
            recorder.stop()
        return walls

    def _advance(self, model, recorder, duration: float, publish_rate: float, progress):
        """In the loop: up to the next publication in one compiled call (paused node: its
        own timer does not step), then the recorder takes the messages; over topics: spin."""
        from flex_model.errors import SimulationDivergedError
        period, per_publish = 1.0 / self.rate, max(1, int(round(self.rate / publish_rate)))
        n_periods, done, next_mark, next_spin = int(round(duration * self.rate)), 0, 0.0, 0.0
        while model.stepper.t < duration - 1e-9:
            if self.in_loop:
                k = min(per_publish, n_periods - done)
                model.step(k * period)
                done += k
                if model.diverged is not None:
                    raise SimulationDivergedError(
                        f"twin demo: the model diverged: {model.diverged.message}")
                recorder.drain()  # the step's messages, without waking the executor
                if time.monotonic() >= next_spin:  # timers, services (the recorder's
                    next_spin = time.monotonic() + SPIN_PERIOD  # 0.1 s poll)
                    _drain(self.ex)
            else:
                self.ex.spin_once(timeout_sec=0.01)
            if progress is not None and model.stepper.t >= next_mark:
                progress(model.stepper.t, duration)
                next_mark += duration / 20

    def close(self) -> None:
        self.ex.shutdown()
        for n in self.nodes:
            n.destroy_node()


def _load_compiled_loop(loop) -> None:
    """Run two control periods of a copy of the in-loop controller on a copy of the state
    (the first on the Python path, flex_model.control_loop): numba loads the integrator
    and the compiled loop (from its cache, 0.3-0.4 s once per process) before the demo's
    loop is timed, which the node's first step did (setup, as planning is)."""
    import copy

    from flex_model.control_loop import ControlLoop
    from flex_model.stepper import Stepper
    st = loop.stepper
    scratch = Stepper(st.model, st.q.copy(), max_step=st.max_step)
    ControlLoop(scratch, copy.deepcopy(loop.controller), loop.period).advance(2)


def _drain(ex, limit: int = 100, timeout_sec: float = 0.0) -> None:
    """Run the executor's ready callbacks (what the last publications made ready) until
    none is left (none within ``timeout_sec``); one wait set serves all the callbacks
    ready at once."""
    from rclpy.executors import ShutdownException, TimeoutException
    for _ in range(limit):
        try:
            handler, _, _ = ex.wait_for_ready_callbacks(timeout_sec=timeout_sec)
        except (TimeoutException, ShutdownException):
            return
        handler()
        if handler.exception() is not None:
            raise handler.exception()


def _stamp_s(msg):
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _by_time(msgs):
    """Messages sorted by their header stamps, one per stamp."""
    seen = {}
    for m in msgs:
        seen.setdefault(_stamp_s(m), m)
    return [seen[t] for t in sorted(seen)]


def _summarize(tips, states, defl, plan, wall, duration, out_dir, plane) -> dict:
    from flex_model.plots import finish_figure, plt
    from flex_model.urdf import base_to_plane
    tips, states, defl = _by_time(tips), _by_time(states), _by_time(defl)
    t_tip = np.array([_stamp_s(m) for m in tips])
    xy = base_to_plane(plane, [[m.pose.position.x, m.pose.position.y, m.pose.position.z]
                               for m in tips])  # the plane, as the waypoints
    errors = []
    for (x, y), t in zip(WAYPOINTS, TIMES):
        if t > duration + 1e-9:
            continue
        k = int(np.argmin(np.abs(t_tip - t)))
        errors.append({"t_s": float(t), "tip_error_mm": float(1e3 * np.hypot(*(xy[k] - (x, y)))),
                       "sampled_at_s": float(t_tip[k])})
    t_js = np.array([_stamp_s(m) for m in states])
    q = np.array([m.position for m in states])
    tau = np.array([m.effort for m in states])
    d = np.array([m.position for m in defl])
    t_d = np.array([_stamp_s(m) for m in defl])
    summary = {"waypoints": errors,
               "max_abs_tip_deflection_mm": (1e3 * np.abs(d[:, 0::2]).max(axis=0)).tolist(),
               "peak_torque_nm": np.abs(tau).max(axis=0).tolist(),
               "simulated_s": duration, "wall_s": wall,
               "real_time_factor": duration / wall, "bag": str(out_dir / "bag")}
    fig, ax = plt.subplots(2, 2, figsize=(12, 8))
    ax[0, 0].plot(xy[:, 0], xy[:, 1], label="tip (model)")
    ax[0, 0].plot(WAYPOINTS[:, 0], WAYPOINTS[:, 1], "ro", label="waypoints")
    ax[0, 0].set(xlabel="x [m]", ylabel="y [m]", title="tip path vs waypoints")
    ax[0, 0].set_aspect("equal", adjustable="datalim")
    t_ref = np.array([p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec
                      for p in plan.points])
    q_ref = np.array([p.positions for p in plan.points])
    for j in range(q.shape[1]):
        ax[0, 1].plot(t_js, np.degrees(q[:, j]), label=f"joint{j + 1}")
        ax[0, 1].plot(t_ref, np.degrees(q_ref[:, j]), "k--", lw=0.7)
        ax[1, 1].plot(t_js, tau[:, j], label=f"joint{j + 1}")
    ax[0, 1].set(xlabel="t [s]", ylabel="joint angle [deg]", title="joints (dashed: plan)")
    for i in range(d.shape[1] // 2):
        ax[1, 0].plot(t_d, 1e3 * d[:, 2 * i], label=f"link{i + 1}")
    ax[1, 0].set(xlabel="t [s]", ylabel="tip deflection [mm]", title="link deflections")
    ax[1, 1].set(xlabel="t [s]", ylabel="torque [N m]", title="joint torques")
    finish_figure(fig, ax, out_dir / "twin_demo.png", "flex-twin: thesis Ch. V task over ROS")
    summary["png"] = str(out_dir / "twin_demo.png")
    return summary
