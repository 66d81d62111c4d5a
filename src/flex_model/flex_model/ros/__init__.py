"""The ROS 2 adapters of flex_model (issue 43, the ament convention of a ``ros`` subpackage):
the model node (planar and spatial arms, observer mode), its lifecycle/parameter plumbing
(:mod:`.main`), message conversions and CDR templates. The numeric core (every other
flex_model module) imports nothing from here and no rclpy; importing flex_model changes no
environment variable. This ``__init__`` imports no ROS either.

Every process that starts ROS calls :func:`ros_environment` just before ``rclpy.init`` (the
nodes' ``run_node``, the ``flex-twin`` CLI, ``up``, ``twin-demo``, ``record``), so it has
LOCALHOST discovery. The ROS domain is the user's (ROS_DOMAIN_ID as set, else ROS's default
0); only the tests and CI choose a per-run domain (conftest.py, .ci/run).
"""
import os as _os


def ros_environment() -> None:
    """ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST unless the user chose otherwise: the default
    discovery multicasts on the network interface."""
    _os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
