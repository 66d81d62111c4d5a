"""The Jazzy ``main()`` idiom shared by the suite's nodes, with this workplace's ROS setup."""
from __future__ import annotations

import rclpy
from rclpy.executors import ExternalShutdownException


def run_node(factory, args=None) -> None:
    """init, spin the node made by ``factory``, end cleanly on Ctrl-C, destroy, shut down.

    The ROS environment (LOCALHOST discovery, per-run domain) is set when flex_model is
    imported, before rclpy."""
    rclpy.init(args=args)
    node = None
    try:
        node = factory()
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:  # a callback that raced the shutdown by Ctrl-C is no error
        if rclpy.ok():
            raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
