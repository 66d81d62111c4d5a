"""flex_model: flexible-link arm models, simulation core and the model node.

Importing the package changes no environment variable. Every process that starts ROS
calls :func:`ros_environment` just before ``rclpy.init`` (the nodes' ``run_node``, the
``flex-twin`` CLI, ``up``, ``twin-demo``, ``record``), so it has LOCALHOST discovery. The
ROS domain is the user's (ROS_DOMAIN_ID as set, else ROS's default 0): nodes started in
separate terminals and a system ``ros2`` CLI see each other. Only the tests and CI choose
a per-run domain (conftest.py, .ci/run).
"""
import os as _os


def ros_environment() -> None:
    """ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST unless the user chose otherwise: the default
    discovery multicasts on the network interface."""
    _os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")


__version__ = "0.1.0"
