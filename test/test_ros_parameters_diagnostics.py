"""The model node as ROS tools see it (issue 46 items 10c, 10d): parameter descriptors
through a real client's describe_parameters (read_only where the node is built from the
parameter, ranges where the code has bounds), and a steady 1 Hz status on /diagnostics
in every mode (realtime, lockstep, lockstep with the controller in the loop; the spatial
node's lockstep), so that a diagnostic aggregator does not mark the node stale."""
import time
import uuid

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rcl_interfaces.msg import Parameter as ParameterMsg, ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, SetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from flex_model.ros.model_node import ModelNode


@pytest.fixture
def ctx():
    context = rclpy.Context()
    rclpy.init(context=context)
    yield context
    rclpy.try_shutdown(context=context)


def _call(ex, client, request, timeout=30.0):
    assert client.wait_for_service(timeout_sec=timeout)
    future = client.call_async(request)
    end = time.monotonic() + timeout
    while not future.done():
        assert time.monotonic() < end, f"no answer from {client.srv_name}"
        ex.spin_once(timeout_sec=0.02)
    return future.result()


def test_descriptors_say_read_only_and_ranges(ctx):
    """A client node calls the model node's describe_parameters service (as ``ros2 param
    describe`` does): the parameters the node is built from are read_only (on main all
    were writable), the runtime ones writable; the bounded numbers carry their ranges;
    set_parameters on a read-only one is refused over the service."""
    ns = f"/d{uuid.uuid4().hex[:8]}"
    node = ModelNode(context=ctx, namespace=ns, parameter_overrides=[
        Parameter("mode", value="lockstep"), Parameter("lockstep_timeout", value=300.0)])
    client = rclpy.create_node("describe_client", context=ctx)
    ex = SingleThreadedExecutor(context=ctx)
    try:
        for n in (node, client):
            ex.add_node(n)
        names = ["arm", "mode", "rate", "max_step", "shape_points", "realtime_priority",
                 "vars_per_link", "publish_rate", "command_timeout", "max_torque",
                 "timeout_action"]
        srv = client.create_client(DescribeParameters, f"{ns}/flex_model/describe_parameters")
        got = {d.name: d for d in _call(ex, srv, DescribeParameters.Request(
            names=names)).descriptors}
        assert {n: got[n].read_only for n in names} == {
            "arm": True, "mode": True, "rate": True, "max_step": True, "shape_points": True,
            "realtime_priority": True, "vars_per_link": True, "publish_rate": False,
            "command_timeout": False, "max_torque": False, "timeout_action": False}

        def frange(name):
            (r,) = got[name].floating_point_range
            return r.from_value, r.to_value
        assert frange("max_step") == (0.0, 0.1)
        assert frange("rate")[0] == 0.0 and frange("rate")[1] > 1e300
        assert frange("command_timeout")[0] == 0.0
        (r,) = got["shape_points"].integer_range
        assert (r.from_value, r.to_value, r.step) == (2, 10000, 1)
        (r,) = got["realtime_priority"].integer_range
        assert (r.from_value, r.to_value, r.step) == (0, 99, 1)
        (r,) = got["vars_per_link"].integer_range
        assert (r.from_value, r.step) == (0, 2)
        assert not got["arm"].floating_point_range and not got["arm"].integer_range
        setter = client.create_client(SetParameters, f"{ns}/flex_model/set_parameters")
        value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=10.0)
        res = _call(ex, setter, SetParameters.Request(parameters=[
            ParameterMsg(name="rate", value=value),
            ParameterMsg(name="command_timeout", value=ParameterValue(
                type=ParameterType.PARAMETER_DOUBLE, double_value=-1.0)),
            ParameterMsg(name="publish_rate", value=value)])).results
        assert [r.successful for r in res] == [False, False, True]
        assert "read-only" in res[0].reason and "out of range" in res[1].reason
        assert node.get_parameter("rate").value == 1000.0 and node.p["publish_rate"] == 10.0
        ex.shutdown()
    finally:
        node.destroy_node()
        client.destroy_node()


MODES = {"realtime": [Parameter("rate", value=100.0), Parameter("max_step", value=0.01)],
         "lockstep": [Parameter("mode", value="lockstep"),
                      Parameter("lockstep_timeout", value=300.0)],
         "lockstep-in-loop": [Parameter("mode", value="lockstep"),
                              Parameter("controller", value="eq95"),
                              Parameter("controller_params.h", value=[25.0, 25.0]),
                              Parameter("controller_params.a", value=[5.0, 5.0]),
                              Parameter("publish_rate", value=50.0)],
         "spatial-lockstep": [Parameter("mode", value="lockstep"),
                              Parameter("lockstep_timeout", value=300.0)]}


@pytest.mark.parametrize("mode", list(MODES))
def test_diagnostics_status_every_second_in_every_mode(ctx, mode):
    """A subscriber to /diagnostics gets the node's OK status once a second of wall time
    (on main: nothing until a divergence), whether the model runs in realtime, waits in
    lockstep for commands that never come (simulation time stands still) or runs as
    fast as it computes with the controller in its loop."""
    ns = f"/g{uuid.uuid4().hex[:8]}"
    factory = ModelNode
    if mode.startswith("spatial"):  # the spatial arm's node (issue 25) too
        from flex_model.ros.model_node import SpatialModelNode as factory
    node = factory(context=ctx, namespace=ns, parameter_overrides=MODES[mode])
    probe = rclpy.create_node("diagnostics_probe", context=ctx)
    got = []
    probe.create_subscription(DiagnosticArray, "/diagnostics",
                              lambda m: got.extend((time.monotonic(), s) for s in m.status
                                                   if s.name == f"{ns}/flex_model"), 10)
    ex = SingleThreadedExecutor(context=ctx)
    try:
        for n in (node, probe):
            ex.add_node(n)
        end = time.monotonic() + 60.0
        while len(got) < 5:
            assert time.monotonic() < end, f"{len(got)} statuses in 60 s"
            ex.spin_once(timeout_sec=0.01)
        ex.shutdown()
    finally:
        node.destroy_node()
        probe.destroy_node()
    times = [t for t, _ in got]
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert all(0.8 < g < 1.2 for g in gaps), gaps
    word = "lockstep" if "lockstep" in mode else "realtime"
    assert all(s.level == DiagnosticStatus.OK and word in s.message for _, s in got)
    t = node.t if mode.startswith("spatial") else node.stepper.t
    if mode.endswith("lockstep"):
        assert t == 0.0  # no command: the clock stood still, the status came
    else:
        assert t > 0.0
