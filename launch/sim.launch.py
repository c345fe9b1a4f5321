"""Simulator + controller + recorder on a scene:

    ros2 launch rigid_body_sim sim.launch.py scene:=default

Arguments:
  scene       built-in scene name (config/<scene>.yaml) or an absolute params-file path
  record      true/false: start the MCAP recorder (default true)
  output      recorder bag directory (default: rigid_body_sim_<scene>)
  controller  true/false: start the controller (default true; scenes without a
              controller section simply leave it commanding zero torque in mode 'off')
"""
import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node


def _nodes(context):
    scene = LaunchConfiguration('scene').perform(context)
    params = scene if os.path.isabs(scene) else os.path.join(
        get_package_share_directory('rigid_body_sim'), 'config', f'{scene}.yaml')
    output = (LaunchConfiguration('output').perform(context)
              or f'rigid_body_sim_{os.path.basename(scene)}')
    return [
        Node(package='rigid_body_sim', executable='simulator', name='attitude_simulator',
             parameters=[params], output='screen'),
        Node(package='rigid_body_sim', executable='controller', name='attitude_controller',
             parameters=[params], output='screen',
             condition=IfCondition(LaunchConfiguration('controller'))),
        Node(package='rigid_body_sim', executable='recorder', name='mcap_recorder',
             parameters=[{'output': output, 'scene': os.path.basename(scene)}], output='screen',
             condition=IfCondition(LaunchConfiguration('record'))),
    ]


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('scene', default_value='default',
                              description='scene name or params file'),
        DeclareLaunchArgument('record', default_value='true',
                              description='start the MCAP recorder'),
        DeclareLaunchArgument('output', default_value='', description='recorder bag directory'),
        DeclareLaunchArgument('controller', default_value='true',
                              description='start the controller'),
        OpaqueFunction(function=_nodes),
    ])
