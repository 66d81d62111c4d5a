"""The realtime model node with realtime_priority, alone in its executor, runs its periods
in a slice of one timer callback on a wait set of its own (ModelNode._realtime_slice):
inputs still reach it (the slice returns to the executor on a message or a service
request), the model still steps in whole max_step steps on the wall clock, and most
periods run inside the slice (fewer executor wake-ups: what the slice is for)."""
import os
import threading
import time
import uuid

import numpy as np
import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import SetBool

from flex_model.ros.model_node import ModelNode


def test_realtime_slice_takes_inputs_and_steps_on_the_grid():
    ctx, probe_ctx = rclpy.Context(), rclpy.Context()
    rclpy.init(context=ctx)
    rclpy.init(context=probe_ctx)
    ns = f"/s{uuid.uuid4().hex[:8]}"
    node = ModelNode(context=ctx, namespace=ns, parameter_overrides=[
        Parameter("arm", value="thesis_example1_motors"), Parameter("rate", value=1000.0),
        Parameter("realtime_priority", value=1)])
    if os.sched_getscheduler(0) != os.SCHED_FIFO:  # the slice runs only under SCHED_FIFO
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        rclpy.try_shutdown(context=probe_ctx)
        pytest.skip("realtime_priority: SCHED_FIFO refused (needs CAP_SYS_NICE)")
    probe = rclpy.create_node("probe", context=probe_ctx, namespace=ns)
    payload = probe.create_publisher(Float64MultiArray, "flex/payload", 10)
    pause = probe.create_client(SetBool, f"{ns}/flex_model/pause")
    ex, probe_ex = SingleThreadedExecutor(context=ctx), SingleThreadedExecutor(context=probe_ctx)
    ex.add_node(node)
    probe_ex.add_node(probe)
    stop = threading.Event()
    worker = threading.Thread(target=lambda: [probe_ex.spin_once(timeout_sec=0.01)
                                              for _ in iter(stop.is_set, True)])
    ticks, periods = [0], [0]
    tick, period = node.on_tick, node.realtime_period
    node.timer.callback = lambda: (ticks.__setitem__(0, ticks[0] + 1), tick())
    node.realtime_period = lambda e: (periods.__setitem__(0, periods[0] + 1), period(e))
    try:
        worker.start()

        def spin_until(pred, timeout=20.0):
            end = time.monotonic() + timeout
            while not pred() and time.monotonic() < end:
                ex.spin_once(timeout_sec=0.01)
            return pred()
        assert spin_until(lambda: payload.get_subscription_count() > 0)
        assert spin_until(lambda: periods[0] >= 300)
        payload.publish(Float64MultiArray(data=[0.25, 0.002]))
        assert spin_until(lambda: tuple(node.stepper.model.payload) == (0.25, 0.002))
        future = pause.call_async(SetBool.Request(data=True))
        assert spin_until(future.done) and node.paused
        t = node.stepper.t
        spin_until(lambda: False, timeout=0.05)
        assert node.stepper.t == t  # paused: no period stepped inside a slice either
        assert abs(t / 1e-3 - round(t / 1e-3)) < 1e-6  # whole 1 ms steps
        assert periods[0] > 5 * ticks[0]  # most periods ran inside a slice
    finally:
        stop.set()
        worker.join()
        if os.sched_getscheduler(0) != os.SCHED_OTHER:  # (realtime_priority took effect)
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
        ex.shutdown()
        probe_ex.shutdown()
        node.destroy_node()
        probe.destroy_node()
        rclpy.try_shutdown(context=ctx)
        rclpy.try_shutdown(context=probe_ctx)
    assert np.isfinite(node.stepper.x).all()
