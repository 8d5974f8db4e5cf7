"""Start sweep_node with a params file.

    ros2 launch sweep_ros sweep.launch.py
    ros2 launch sweep_ros sweep.launch.py params_file:=/path/to/my.yaml namespace:=crowd
"""
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from launch import LaunchDescription


def generate_launch_description():
    default_params = PathJoinSubstitution(
        [FindPackageShare("sweep_ros"), "config", "sweep_node.yaml"])
    return LaunchDescription([
        DeclareLaunchArgument(
            "params_file", default_value=default_params,
            description="sweep_node parameters (default: the package's config/sweep_node.yaml)"),
        DeclareLaunchArgument(
            "namespace", default_value="",
            description="namespace of the node and of its relative topics and services"),
        Node(
            package="sweep_ros",
            executable="sweep_node",
            name="sweep_node",
            namespace=LaunchConfiguration("namespace"),
            parameters=[LaunchConfiguration("params_file")],
            output="screen",
            emulate_tty=True,
        ),
    ])
