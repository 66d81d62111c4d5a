"""Launch the flex-twin suite as ``flex-twin up`` starts it (the same nodes:
flex_twin.ros_suite.suite_nodes): by default the model node with the controller in its
loop and the planner node; ``topic_loop:=true`` starts the controller node instead (model
and controller over topics, as ``up --topic-loop``). Fully qualified node names in the
file (``/robot1/flex_model``, docs/examples/two_arms.yaml) start in their namespaces.

    ros2 launch flex_twin suite.launch.py [params:=/path/to/params.yaml] [topic_loop:=true]

Installed with the flex_twin package (share/flex_twin/launch, its default parameter file
share/flex_twin/params/suite.yaml); ros2_ws/launch/suite.launch.py links here. Every node
spins in a SingleThreadedExecutor (flex_model.ros.main).
"""
import tempfile
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PARAMS = str(Path(__file__).resolve().parents[1] / "params" / "suite.yaml")


def suite(context):
    """The nodes of ``up`` for the file ``params``: the parameters (controller folded into
    the model unless topic_loop) go to each node in a file of their own."""
    from flex_twin.ros_suite import node_parameters, suite_nodes, write_parameter_file
    path = LaunchConfiguration("params").perform(context)
    topic_loop = LaunchConfiguration("topic_loop").perform(context).lower() in ("true", "1")
    params, nodes = suite_nodes(node_parameters(path), topic_loop)
    out = write_parameter_file(params, Path(tempfile.mkdtemp(prefix="flex-twin-launch-"))
                               / "params.yaml")
    return [Node(package=package, executable=executable, name=name, parameters=[str(out)],
                 output="screen", **({"namespace": ns} if ns else {}))
            for package, executable, ns, name in nodes]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument("params", default_value=PARAMS,
                              description="node parameter file (<node>: ros__parameters)"),
        DeclareLaunchArgument("topic_loop", default_value="false",
                              description="true: the controller node over topics instead "
                              "of the controller in the model's loop"),
        OpaqueFunction(function=suite),
    ])
