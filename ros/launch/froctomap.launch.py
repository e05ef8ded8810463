"""Runs the froctomap node next to octomap_server (ROS 2, Python launch).

froctomap is not an ament package (it is one Rust binary, `cargo install froctomap-cli
--features ros2`), so it is started with ExecuteProcess; its ROS arguments follow
`--ros-args` as for any node. Usage:

    ros2 launch froctomap.launch.py file:=/data/office.froct namespace:=/robot1

The node subscribes `octomap_binary` in the namespace (octomap_server's topic), records the
maps into `file`, and publishes `<ns>/froctomap/predicted` and `<ns>/froctomap/dynamic`.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess
from launch.substitutions import LaunchConfiguration


def generate_launch_description():
    file = LaunchConfiguration("file")
    namespace = LaunchConfiguration("namespace")
    use_sim_time = LaunchConfiguration("use_sim_time")
    return LaunchDescription([
        DeclareLaunchArgument("file", description="the living map (.froct), created if missing"),
        DeclareLaunchArgument("namespace", default_value="/"),
        DeclareLaunchArgument("use_sim_time", default_value="false"),
        DeclareLaunchArgument("horizon", default_value="0"),
        ExecuteProcess(
            cmd=[
                "froctomap", "ros2", file,
                "--network", "all",
                "--ros-args",
                "-r", ["__ns:=", namespace],
                "-p", ["use_sim_time:=", use_sim_time],
                "-p", ["horizon:=", LaunchConfiguration("horizon")],
                "-p", "commit_every:=1m",
            ],
            output="screen",
            # SIGINT on shutdown: the node commits what it gathered and exits 0.
            sigterm_timeout="30",
        ),
    ])
