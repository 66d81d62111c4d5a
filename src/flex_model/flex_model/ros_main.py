"""The Jazzy ``main()`` idiom shared by the suite's nodes, with this workplace's ROS setup.

Every node of the suite spins in rclpy's SingleThreadedExecutor (the stack's rule: the
experimental EventsExecutor cannot be stopped). That executor rebuilds its wait set in
Python on every wait, at a cost proportional to the number of entities of all its nodes,
so the nodes keep that number small (see :func:`lean_node`, :func:`event_callbacks` and
bench/bench_ros_suite.py).
"""
from __future__ import annotations

import signal

import rclpy
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions


def event_callbacks(warnings: bool) -> tuple[dict, dict]:
    """(``create_publisher``, ``create_subscription``) keyword arguments: with ``warnings``
    rclpy's defaults (a handler each for incompatible QoS and incompatible types, which
    only log), without them none. Each handler is a waitable that the
    SingleThreadedExecutor adds to every wait set."""
    if warnings:
        return {}, {}
    return ({"event_callbacks": PublisherEventCallbacks(use_default_callbacks=False)},
            {"event_callbacks": SubscriptionEventCallbacks(use_default_callbacks=False)})


def lean_node(node, parameter_services: bool) -> None:
    """Without ``parameter_services``, destroy the six parameter services rclpy created
    for ``node`` (call it right after ``Node.__init__``, before the node makes its own
    services): its parameters can then not be listed or set from outside."""
    if not parameter_services:
        for srv in list(node.services):
            node.destroy_service(srv)


def run_node(factory, args=None, on_stop=None) -> None:
    """init, spin the node made by ``factory`` in a SingleThreadedExecutor until SIGINT or
    SIGTERM, call ``on_stop(node)`` while the context is still valid (the controller
    commands zero torques there), destroy, shut down.

    rclpy's signal handlers are replaced by a flag checked between callbacks, so no
    callback runs into a context that Ctrl-C has already shut down. The ROS environment
    (LOCALHOST discovery, per-run domain) is set when flex_model is imported, before
    rclpy."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: stop.append(signum))
    node = executor = None
    try:
        executor = SingleThreadedExecutor()
        node = factory()
        executor.add_node(node)
        while rclpy.ok() and not stop:
            executor.spin_once(timeout_sec=0.05)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            if on_stop is not None and rclpy.ok():
                on_stop(node)
            if executor is not None:
                executor.shutdown()
            node.destroy_node()
        rclpy.try_shutdown()
