"""flex_twin: the user-facing tools on top of flex_model, flex_control and flex_planner.

The ``flex-twin`` command, rosbag2 recording and playback, the suite launcher (``up``), the
demos, the diagnosis workflow, the real-arm tools and the comparison of discretizations.
Dependencies run one way: flex_twin -> flex_planner, flex_control -> flex_model.
Importing it imports flex_model, which sets LOCALHOST discovery before rclpy is loaded.
"""
import flex_model as _flex_model  # noqa: F401  (ROS environment first)

__version__ = "0.1.0"
