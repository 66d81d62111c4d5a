"""ROS 2 planner node: tip waypoints in, joint trajectory with nominal torque out."""
from __future__ import annotations

from dataclasses import fields, replace

from flex_model.ros_main import (Param, ParameterError, clock_topic_param,
                                 declare_parameters, follow_clock, guard_parameters,
                                 lean_node, run_node)
from nav_msgs.msg import Path
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from .config import DESCRIPTIONS, PlannerConfig
from .planning import INTEGRATION_STEP, plan
from .ros_messages import deflections_msg, nominal_path_msg, path_request, trajectory_msg

#: parameters fixed for the node's life (the model is built from them)
READ_ONLY = ("arm", "vars_per_link")
#: default bound on the samples of a plan (200 s at the default 1 ms)
MAX_SAMPLES = 200_000


def _max_samples(v):
    return None if v >= 2 else "an integer >= 2"


def parameter_specs() -> tuple:
    """PlannerConfig's fields (checked by PlannerConfig), ``max_samples`` and the node
    parameters."""
    specs = [Param(f.name, f.default, DESCRIPTIONS[f.name], runtime=f.name not in READ_ONLY)
             for f in fields(PlannerConfig)]
    specs.append(Param("max_samples", MAX_SAMPLES, "largest number of samples of a plan "
                       "(published, or computed at the nominal-input step if finer): a "
                       "request needing more is refused", True, _max_samples))
    specs += [Param(name, True, "false: see flex_model.ros_main.lean_node")
              for name in ("parameter_services", "qos_event_warnings")]
    specs.append(clock_topic_param("the stamps of nominal_path"))
    return tuple(specs)


def samples_needed(times, sample_period: float) -> int:
    """Samples the plan of waypoint ``times`` computes: the published ones every
    ``sample_period`` or, if finer, the nominal-input solver's every INTEGRATION_STEP."""
    duration = float(times[-1] - times[0])
    return int(duration / min(sample_period, INTEGRATION_STEP) + 1e-6) + 2


class PlannerNode(Node):
    """Plans a tip path (thesis Ch. IV-V.1) for every request.

    Subscription: ``~/waypoints`` (nav_msgs/Path; each pose's stamp is its time from the
    start, positions in ``frame_id``; the tip orientation is the pose's yaw for arms with
    three or more links). Publications (once per valid request): ``~/trajectory``
    (trajectory_msgs/JointTrajectory: positions, velocities, accelerations and ``effort`` =
    the admissible nominal torque every ``sample_period``), ``~/nominal_path`` (nav_msgs/Path,
    the nominal tip path) and ``~/nominal_deflections`` (trajectory_msgs/JointTrajectory
    whose "joints" are the model's deformation variables, m and rad). With the node name
    ``flex_planner`` these are ``/flex_planner/...`` (``<ns>/flex_planner/...`` in a
    namespace). Parameters: the fields of :class:`flex_planner.config.PlannerConfig`
    (``arm``, ``vars_per_link`` read-only at run time; ``sample_period``, ``elbow``,
    ``frame_id`` validated when set; a float takes an integer), ``max_samples`` (default
    200000: a request whose plan needs more samples, e.g. a waypoint at t = 1e5 s, ~1e8
    samples, is refused in one line before any work). A bad request (unreachable point,
    times not increasing, empty path, wrong frame, too long) is logged as an error naming
    the point, nothing is published for it, and the node keeps serving. A bad parameter at
    start is one line naming it, its value and what is allowed. Node parameters
    ``parameter_services`` and ``qos_event_warnings`` (default true, read-only at run
    time): flex_model.ros_main.lean_node. With ``use_sim_time: true`` its stamps are the
    simulation time of ``clock_topic`` (default /clock; ``clock``: the namespace's).
    """

    def __init__(self, **kwargs):
        super().__init__("flex_planner", **kwargs)
        self.specs = parameter_specs()
        values = declare_parameters(self, self.specs)
        self.max_samples = values.pop("max_samples")
        lean = [values.pop(name) for name in ("parameter_services", "qos_event_warnings")]
        clock_topic = values.pop("clock_topic")
        try:
            self.config = PlannerConfig(**values)
            self.model = self.config.model()
        except (ValueError, OSError) as exc:
            raise ParameterError(f"parameter {exc}") from None
        self.flex_indices = [i for i in range(self.model.nq) if i not in set(self.model.off)]
        reliable = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_trajectory = self.create_publisher(JointTrajectory, "~/trajectory", reliable)
        self.pub_path = self.create_publisher(Path, "~/nominal_path", latched)
        self.pub_deflections = self.create_publisher(JointTrajectory, "~/nominal_deflections",
                                                     latched)
        self.create_subscription(Path, "~/waypoints", self.on_waypoints, reliable)
        guard_parameters(self, self.specs, self.apply_parameters)
        follow_clock(self, clock_topic)
        lean_node(self, *lean)
        self.get_logger().info(f"planning for {self.model.arm.name} ({self.model.nq} "
                               f"coordinates) in frame {self.config.frame_id!r}")

    def apply_parameters(self, values: dict) -> None:
        """Run-time sample_period, elbow, frame_id, max_samples (types checked; raises
        ValueError with the reason)."""
        max_samples = values.pop("max_samples", self.max_samples)
        self.config = replace(self.config, **values)
        self.max_samples = max_samples

    def on_waypoints(self, msg: Path) -> None:
        cfg = self.config
        try:
            pts, times, phis = path_request(msg, cfg.frame_id, self.model.n_links >= 3)
            n = samples_needed(times, cfg.sample_period)
            if n > self.max_samples:
                raise ValueError(
                    f"Path.poses[{len(times) - 1}].header.stamp: got {times[-1]:.9g} s, a plan "
                    f"of {times[-1] - times[0]:.9g} s needing {n} samples (every "
                    f"{min(cfg.sample_period, INTEGRATION_STEP):g} s); expected at most "
                    f"max_samples = {self.max_samples} (shorten the motion, or raise "
                    "sample_period or max_samples)")
            result = plan(self.model, pts, times, sample_period=cfg.sample_period,
                          elbow=cfg.elbow, orientations=phis)
        except (ValueError, RuntimeError) as exc:
            self.get_logger().error(f"waypoints rejected, nothing published: {exc}")
            return
        traj = result.trajectory
        self.pub_trajectory.publish(trajectory_msg(traj, cfg.frame_id))
        self.pub_path.publish(nominal_path_msg(traj, cfg.frame_id,
                                               self.get_clock().now().to_msg()))
        self.pub_deflections.publish(deflections_msg(traj, self.model.coordinate_names(),
                                                     self.flex_indices, cfg.frame_id))
        self.get_logger().info(f"planned {len(pts)} waypoints: {len(traj.t)} samples over "
                               f"{traj.duration:.3f} s")


def main(args=None) -> None:
    run_node(PlannerNode, args)


if __name__ == "__main__":
    main()
