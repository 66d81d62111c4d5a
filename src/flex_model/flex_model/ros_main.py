"""The Jazzy ``main()`` idiom shared by the suite's nodes, with this workplace's ROS setup.

Every node of the suite spins in rclpy's SingleThreadedExecutor (the stack's rule: the
experimental EventsExecutor cannot be stopped). That executor rebuilds its wait set in
Python on every wait, at a cost proportional to the number of entities of all its nodes,
so the nodes keep that number small (see :func:`lean_node` and bench/bench_ros_suite.py).
"""
from __future__ import annotations

import signal
from contextlib import contextmanager

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions


PARAMETER_SERVICES = ("describe_parameters", "get_parameter_types", "get_parameters",
                      "list_parameters", "set_parameters", "set_parameters_atomically")


def lean_node(node, parameter_services: bool, qos_event_warnings: bool) -> None:
    """Take entities the executor would wait on out of ``node`` (call it at the end of
    the node's ``__init__``).

    Without ``parameter_services`` the six parameter services rclpy made are destroyed
    (parameters can then not be listed or set from outside the process). Without
    ``qos_event_warnings`` the node's QoS-event handlers (rclpy gives every publisher and
    subscription one for incompatible QoS and one for incompatible types, which only log a
    warning) are destroyed, so no wait set gathers them."""
    if not parameter_services:
        for srv in list(node.services):
            if srv.srv_name.rsplit("/", 1)[-1] in PARAMETER_SERVICES:
                node.destroy_service(srv)
    if not qos_event_warnings:
        for entity in (*node.publishers, *node.subscriptions):
            for handler in entity.event_handlers:
                node.remove_waitable(handler)
                handler.destroy()
            entity.event_handlers = []


@contextmanager
def stop_on_signals():
    """A list that SIGINT and SIGTERM append to while inside (the previous handlers come
    back on exit): spin loops check it between callbacks, so nothing interrupts a
    callback and the context stays valid for a last command."""
    stop = []
    old = {sig: signal.signal(sig, lambda signum, frame: stop.append(signum))
           for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def run_node(factory, args=None, on_stop=None) -> None:
    """init, spin the node made by ``factory`` in a SingleThreadedExecutor until SIGINT or
    SIGTERM, call ``on_stop(node)`` while the context is still valid (the controller
    commands zero torques there), destroy, shut down.

    rclpy's signal handlers are replaced by :func:`stop_on_signals`, so no callback runs
    into a context that Ctrl-C has already shut down. The ROS environment
    (LOCALHOST discovery, per-run domain) is set when flex_model is imported, before
    rclpy."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = executor = None
    try:
        with stop_on_signals() as stop:
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
