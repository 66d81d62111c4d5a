"""ROS 2 planner node: tip waypoints in, joint trajectory with nominal torque out."""
from __future__ import annotations

from dataclasses import fields, replace

from flex_model.ros.main import (Managed, Param, ParameterError, clock_topic_param, follow_clock,
                                 lean_node, read_parameters, run_node)
from nav_msgs.msg import Path
from rclpy.lifecycle import LifecycleNode
from rclpy.serialization import deserialize_message
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from .config import DESCRIPTIONS, PlannerConfig
from .planning import INTEGRATION_STEP, plan
from .ros_messages import (deflections_msg, nominal_path_msg, path_request,
                           serialized_path_size, stamp_seconds, trajectory_msg)

#: parameters fixed for the node's life (the model is built from them)
READ_ONLY = ("arm", "vars_per_link")
#: default bound on the samples of a plan (200 s at the default 1 ms)
MAX_SAMPLES = 200_000
#: default bound on the waypoints of a request (planning and building the message cost
#: time in proportion: 1000 keep a request near a second on the dev machine)
MAX_WAYPOINTS = 1000
#: the planner's topics: relative names, not private ones (~/...), so that they do not
#: follow the node's name (a renamed planner still feeds the model and the controller,
#: which listen on flex_planner/trajectory) but do follow its namespace and remapping
TOPICS = {name: f"flex_planner/{name}" for name in
          ("waypoints", "trajectory", "nominal_path", "nominal_deflections")}


def _two_or_more(v):
    return None if v >= 2 else "an integer >= 2"


def parameter_specs() -> tuple:
    """PlannerConfig's fields (checked by PlannerConfig), ``max_samples``,
    ``max_waypoints`` and the node parameters."""
    specs = [Param(f.name, f.default, DESCRIPTIONS[f.name], runtime=f.name not in READ_ONLY)
             for f in fields(PlannerConfig)]
    specs.append(Param("max_samples", MAX_SAMPLES, "largest number of samples of a plan "
                       "(published, or computed at the nominal-input step if finer): a "
                       "request needing more is refused", True, _two_or_more))
    specs.append(Param("max_waypoints", MAX_WAYPOINTS, "largest number of waypoints of a "
                       "request: one with more is refused from its size alone, before it is "
                       "deserialized", True, _two_or_more))
    specs += [Param(name, True, "false: see flex_model.ros.main.lean_node")
              for name in ("parameter_services", "qos_event_warnings")]
    specs.append(clock_topic_param("the stamps of nominal_path"))
    return tuple(specs)


def samples_needed(times, sample_period: float) -> int:
    """Samples the plan of waypoint ``times`` computes: the published ones every
    ``sample_period`` or, if finer, the nominal-input solver's every INTEGRATION_STEP."""
    duration = float(times[-1] - times[0])
    return int(duration / min(sample_period, INTEGRATION_STEP) + 1e-6) + 2


class PlannerNode(Managed, LifecycleNode):
    """Plans a tip path (thesis Ch. IV-V.1) for every request; a lifecycle node
    (flex_model.ros.main.Managed): only an active node plans.

    Takes ``flex_planner/waypoints`` (nav_msgs/Path; each pose's stamp is its time from the
    start, positions in ``frame_id``, the tip orientation its yaw on arms of three or more
    links); publishes :data:`TOPICS` once per valid request. Parameters: the fields of
    :class:`flex_planner.config.PlannerConfig`, ``max_waypoints`` and ``max_samples``
    (larger requests are refused before any planning, in one line); a bad request is
    logged naming the point and nothing is published. docs/ros.md ("Nodes").
    """

    def __init__(self, **kwargs):
        super().__init__("flex_planner", **kwargs)
        self.specs = parameter_specs()
        self._start_lifecycle(self.specs, self.apply_parameters)

    def _configure(self) -> None:
        """Read and check the parameters, load the arm, make the topics."""
        values = read_parameters(self, self.specs)
        self.max_samples = values.pop("max_samples")
        self.max_waypoints = values.pop("max_waypoints")
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
        self.pub_trajectory = self.create_publisher(JointTrajectory, TOPICS["trajectory"],
                                                    reliable)
        self.pub_path = self.create_publisher(Path, TOPICS["nominal_path"], latched)
        self.pub_deflections = self.create_publisher(JointTrajectory,
                                                     TOPICS["nominal_deflections"], latched)
        # raw: a request's size is read from its bytes before rclpy builds its poses
        self.create_subscription(Path, TOPICS["waypoints"], self.on_waypoints, reliable,
                                 raw=True)
        follow_clock(self, clock_topic)
        lean_node(self, *lean)
        self.get_logger().info(f"planning for {self.model.arm.name} ({self.model.nq} "
                               f"coordinates) in frame {self.config.frame_id!r}")

    def apply_parameters(self, values: dict) -> None:
        """Run-time sample_period, elbow, frame_id, max_samples, max_waypoints (types
        checked; raises ValueError with the reason)."""
        max_samples = values.pop("max_samples", self.max_samples)
        max_waypoints = values.pop("max_waypoints", self.max_waypoints)
        self.config = replace(self.config, **values)
        self.max_samples, self.max_waypoints = max_samples, max_waypoints

    def bounded_request(self, data: bytes) -> Path:
        """The request of the serialized Path ``data``, refused (ValueError) before any
        work if it has more than max_waypoints poses or its first and last stamps span a
        plan of more than max_samples samples."""
        n = serialized_path_size(data)
        if n is not None and n > self.max_waypoints:
            raise ValueError(f"Path.poses: got {n} poses; expected at most max_waypoints = "
                             f"{self.max_waypoints} (thin the path, or raise max_waypoints)")
        msg = deserialize_message(data, Path)
        if len(msg.poses) > self.max_waypoints:  # not plain CDR: counted after all
            raise ValueError(f"Path.poses: got {len(msg.poses)} poses; expected at most "
                             f"max_waypoints = {self.max_waypoints}")
        if len(msg.poses) >= 2:
            times = [stamp_seconds(msg.poses[k].header.stamp) for k in (0, -1)]
            need = samples_needed(times, self.config.sample_period)
            if need > self.max_samples:
                raise ValueError(
                    f"Path.poses[{len(msg.poses) - 1}].header.stamp: got {times[-1]:.9g} s, "
                    f"a plan of {times[-1] - times[0]:.9g} s needing {need} samples (every "
                    f"{min(self.config.sample_period, INTEGRATION_STEP):g} s); expected at "
                    f"most max_samples = {self.max_samples} (shorten the motion, or raise "
                    "sample_period or max_samples)")
        return msg

    def on_waypoints(self, data: bytes) -> None:
        cfg = self.config
        try:
            if not self.active:
                raise ValueError("the node is inactive (lifecycle): activate it")
            msg = self.bounded_request(data)
            pts, times, phis = path_request(msg, cfg.frame_id, self.model.n_links >= 3)
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
