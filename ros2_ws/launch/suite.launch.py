"""Launch the flex-twin suite (model, controller, planner) with ros2_ws/params/suite.yaml.

    ros2 launch ros2_ws/launch/suite.launch.py [params:=/path/to/params.yaml]
"""
from pathlib import Path

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PARAMS = str(Path(__file__).resolve().parents[1] / "params" / "suite.yaml")


def generate_launch_description():
    params = LaunchConfiguration("params")
    return LaunchDescription([
        DeclareLaunchArgument("params", default_value=PARAMS),
        Node(package="flex_model", executable="model_node", name="flex_model",
             parameters=[params], output="screen"),
        Node(package="flex_control", executable="controller_node", name="flex_controller",
             parameters=[params], output="screen"),
        Node(package="flex_planner", executable="planner_node", name="flex_planner",
             parameters=[params], output="screen"),
    ])
