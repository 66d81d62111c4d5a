"""ROS 2 planner node: tip waypoints in, joint trajectory with nominal torque out."""
from __future__ import annotations

from dataclasses import fields, replace

from flex_model.ros_main import lean_node, run_node
from nav_msgs.msg import Path
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                SetParametersResult)
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from trajectory_msgs.msg import JointTrajectory

from .config import DESCRIPTIONS, PlannerConfig
from .planning import plan
from .ros_messages import deflections_msg, nominal_path_msg, path_request, trajectory_msg

#: parameters fixed for the node's life (the model is built from them)
READ_ONLY = ("arm", "vars_per_link")


class PlannerNode(Node):
    """Plans a tip path (thesis Ch. IV-V.1) for every request.

    Subscription: ``~/waypoints`` (nav_msgs/Path; each pose's stamp is its time from the
    start, positions in ``frame_id``; the tip orientation is the pose's yaw for arms with
    three or more links). Publications (once per valid request): ``~/trajectory``
    (trajectory_msgs/JointTrajectory: positions, velocities, accelerations and ``effort`` =
    the admissible nominal torque every ``sample_period``), ``~/nominal_path`` (nav_msgs/Path,
    the nominal tip path) and ``~/nominal_deflections`` (trajectory_msgs/JointTrajectory
    whose "joints" are the model's deformation variables, m and rad). With the node name
    ``flex_planner`` these are ``/flex_planner/...``. Parameters: the fields of
    :class:`flex_planner.config.PlannerConfig` (``arm``, ``vars_per_link`` read-only;
    ``sample_period``, ``elbow``, ``frame_id`` validated when set). A bad request
    (unreachable point, times not increasing, empty path, wrong frame) is logged as an error
    naming the point, nothing is published for it, and the node keeps serving. Node
    parameters ``parameter_services`` and ``qos_event_warnings`` (default true):
    flex_model.ros_main.lean_node.
    """

    def __init__(self, **kwargs):
        super().__init__("flex_planner", **kwargs)
        values = {}
        for f in fields(PlannerConfig):
            desc = ParameterDescriptor(description=DESCRIPTIONS[f.name],
                                       read_only=f.name in READ_ONLY)
            if f.name == "sample_period":
                desc.floating_point_range = [FloatingPointRange(from_value=1e-5, to_value=1.0)]
            if f.name == "vars_per_link":
                desc.integer_range = [IntegerRange(from_value=0, to_value=200, step=2)]
            values[f.name] = self.declare_parameter(f.name, f.default, desc).value
        self.config = PlannerConfig(**values)
        self.model = self.config.model()
        self.flex_indices = [i for i in range(self.model.nq) if i not in set(self.model.off)]
        reliable = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
        latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                             durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.pub_trajectory = self.create_publisher(JointTrajectory, "~/trajectory", reliable)
        self.pub_path = self.create_publisher(Path, "~/nominal_path", latched)
        self.pub_deflections = self.create_publisher(JointTrajectory, "~/nominal_deflections",
                                                     latched)
        self.create_subscription(Path, "~/waypoints", self.on_waypoints, reliable)
        lean = [self.declare_parameter(name, True).value
                for name in ("parameter_services", "qos_event_warnings")]
        self.add_on_set_parameters_callback(self.on_set_parameters)
        lean_node(self, *lean)
        self.get_logger().info(f"planning for {self.model.arm.name} ({self.model.nq} "
                               f"coordinates) in frame {self.config.frame_id!r}")

    def on_set_parameters(self, params) -> SetParametersResult:
        try:
            self.config = replace(self.config, **{p.name: p.value for p in params})
        except (TypeError, ValueError) as exc:
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def on_waypoints(self, msg: Path) -> None:
        cfg = self.config
        try:
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
