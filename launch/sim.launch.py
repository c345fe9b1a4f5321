"""Simulator (+ controller for controlled scenes) + recorder on a scene:

    ros2 launch rigid_body_sim sim.launch.py scene:=default

Arguments:
  scene       built-in scene name (config/<scene>.yaml) or a params-file path; an unknown
              name stops the launch at once with the list of scenes
  record      true/false: start the MCAP recorder (default true)
  output      recorder bag directory (default: rigid_body_sim_<scene name>)
  controller  auto/true/false: auto (default) starts the controller only for scenes that
              control the body, so a free-tumble scene receives no torque
  viewer      true/false: start the Foxglove viewer (default false; it opens a port)
  viewer_port its WebSocket port on 127.0.0.1 (default 8765)
  lockstep    true/false: the simulator holds each control instant until the controller's
              command for it (default false; docs/live-nodes.md, Lockstep)

A scene with several spacecraft (formation) gets one controller per spacecraft, in the
spacecraft's namespace (launch_plan.controllers).

The launch ends when the simulator exits (at the scene's ``duration``): every other node
is then stopped with SIGINT, and the recorder finalises its bag. What starts is decided by
``rigid_body_sim.launch_plan`` (plain Python, tested without ROS).
"""
from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, EmitEvent, LogInfo, OpaqueFunction,
                            RegisterEventHandler)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from rigid_body_sim.launch_plan import plan


def _nodes(context):
    def arg(name):
        return LaunchConfiguration(name).perform(context)
    # SceneError/ValueError here aborts the launch with its message (no node started)
    planned, summary = plan(arg('scene'), arg('record'), arg('output'), arg('controller'),
                            arg('viewer'), arg('viewer_port'), arg('lockstep'))
    actions = [LogInfo(msg=summary)]
    nodes = {}
    for p in planned:  # a formation's controllers: one per spacecraft, in its namespace
        nodes[p.executable] = Node(package='rigid_body_sim', executable=p.executable,
                                   name=p.name, namespace=p.namespace or None, output='screen',
                                   parameters=[*p.params_files, *([p.parameters]
                                                                 if p.parameters else [])])
        actions.append(nodes[p.executable])
    actions.append(RegisterEventHandler(OnProcessExit(
        target_action=nodes['simulator'],
        on_exit=[EmitEvent(event=Shutdown(reason='the simulation ended'))])))
    return actions


def generate_launch_description():
    return LaunchDescription([
        DeclareLaunchArgument('scene', default_value='default',
                              description='scene name or params file'),
        DeclareLaunchArgument('record', default_value='true',
                              description='start the MCAP recorder'),
        DeclareLaunchArgument('output', default_value='', description='recorder bag directory'),
        DeclareLaunchArgument('controller', default_value='auto',
                              description='auto: only for scenes that control the body'),
        DeclareLaunchArgument('viewer', default_value='false',
                              description='start the Foxglove viewer (ws://127.0.0.1:PORT)'),
        DeclareLaunchArgument('viewer_port', default_value='8765',
                              description='Foxglove viewer port'),
        DeclareLaunchArgument('lockstep', default_value='false',
                              description='hold each control instant until its command'),
        OpaqueFunction(function=_nodes),
    ])
