"""flex_model: flexible-link arm models, simulation core and the model node.

Importing the package runs :func:`ros_environment`, so every process of the suite has
LOCALHOST discovery before rclpy is imported. The ROS domain is the user's (ROS_DOMAIN_ID as
set, else ROS's default 0): nodes started in separate terminals and a system ``ros2`` CLI see
each other. Only the tests and CI choose a per-run domain (conftest.py, .ci/run).
"""
import os as _os


def ros_environment() -> None:
    """ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST unless the user chose otherwise: the default
    discovery multicasts on the network interface."""
    _os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


ros_environment()

__version__ = "0.1.0"
