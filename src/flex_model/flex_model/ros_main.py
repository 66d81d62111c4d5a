"""The Jazzy ``main()`` idiom shared by the suite's nodes, with this workplace's ROS setup,
and the choice of executor.

Executors: ``single`` is rclpy's SingleThreadedExecutor (the realtime 1 kHz model loop);
``events`` is rclpy.experimental.EventsExecutor, which dispatches callbacks from C++
without rebuilding a wait set each time: about 30 instead of 200 us between two callbacks
here, which makes the lockstep model-controller loop 2.5 times faster (see
bench/bench_ros_suite.py). A node's console script takes ``--executor single|events``
before ``--ros-args``.
"""
from __future__ import annotations

import argparse
import signal

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

EXECUTORS = ("single", "events")


def make_executor(kind: str = "single", context=None):
    """A SingleThreadedExecutor (``single``) or an EventsExecutor (``events``)."""
    if kind == "events":
        from rclpy.experimental import EventsExecutor
        return EventsExecutor(context=context)
    if kind != "single":
        raise ValueError(f"executor: got {kind!r}; expected one of {', '.join(EXECUTORS)}")
    return SingleThreadedExecutor(context=context)


def executor_option(args=None) -> str:
    """The ``--executor`` option among a node's non-ROS command line arguments."""
    from rclpy.utilities import remove_ros_args
    ap = argparse.ArgumentParser(add_help=False)
    ap.add_argument("--executor", choices=EXECUTORS, default="single")
    return ap.parse_known_args(remove_ros_args(args)[1:])[0].executor


def run_node(factory, args=None, on_stop=None) -> None:
    """init, spin the node made by ``factory`` with the ``--executor`` of the command line
    until SIGINT or SIGTERM, call ``on_stop(node)`` while the context is still valid (the
    controller commands zero torques there), destroy, shut down.

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
        executor = make_executor(executor_option(args))
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
