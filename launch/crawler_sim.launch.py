"""sim_node driven by gait_node, both on sim time (Jazzy Python launch format).

    ros2 launch crawler_sim crawler_sim.launch.py                    # the seed's two bodies
    ros2 launch crawler_sim crawler_sim.launch.py params:=chain_3body.yaml n_links:=2

``params`` names a file of the package's ``config/ros/`` (ROS parameter files; the scene files
of ``config/scenes/`` are for ``crawler-sim simulate``). sim_node publishes /clock; gait_node
uses it (use_sim_time) and plays its default stroke on ``linkage_cmd``.
"""
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    params = PathJoinSubstitution([FindPackageShare('crawler_sim'), 'config', 'ros',
                                   LaunchConfiguration('params')])
    return LaunchDescription([
        DeclareLaunchArgument('params', default_value='crawler_sim.yaml',
                              description='parameter file in share/crawler_sim/config/ros/'),
        DeclareLaunchArgument('n_links', default_value='1',
                              description='linkages the gait drives (bodies - 1)'),
        Node(package='crawler_sim', executable='sim_node', name='crawler_sim',
             parameters=[params], output='screen'),
        Node(package='crawler_sim', executable='gait_node', name='gait_node',
             parameters=[{'use_sim_time': True,
                          'n_links': ParameterValue(LaunchConfiguration('n_links'),
                                                    value_type=int)}],
             output='screen'),
    ])
