"""Launch the flex-twin suite (model, controller, planner) with ros2_ws/params/suite.yaml.

    ros2 launch ros2_ws/launch/suite.launch.py [params:=/path/to/params.yaml]

Every node spins in a SingleThreadedExecutor (flex_model.ros_main).
"""
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PARAMS = str(Path(__file__).resolve().parents[1] / "params" / "suite.yaml")
NODES = (("flex_model", "model_node", "flex_model"),
         ("flex_control", "controller_node", "flex_controller"),
         ("flex_planner", "planner_node", "flex_planner"))


def generate_launch_description():
    params = LaunchConfiguration("params")
    return LaunchDescription([
        DeclareLaunchArgument("params", default_value=PARAMS,
                              description="node parameter file (<node>: ros__parameters)"),
        *(Node(package=package, executable=executable, name=name, parameters=[params],
               output="screen")
          for package, executable, name in NODES),
    ])
