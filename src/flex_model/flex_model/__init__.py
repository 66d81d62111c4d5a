"""flex_model: flexible-link arm models, simulation core and the model node.

Importing the package runs :func:`ros_environment`, so every process of the suite has
LOCALHOST discovery and a per-run domain before rclpy is imported.
"""
import os as _os
import random as _random


def ros_environment() -> None:
    """ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and a per-run ROS_DOMAIN_ID, unless the user
    chose otherwise: the default discovery multicasts on the network interface."""
    _os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    _os.environ.setdefault("ROS_DOMAIN_ID", str(_random.randint(1, 100)))


ros_environment()

__version__ = "0.1.0"
