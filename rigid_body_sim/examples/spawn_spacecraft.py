"""Spawn a spacecraft into a running simulator, list the entities, optionally delete one.

What ``ros2 service call .../spawn_entity`` does on a full install, from rclpy (the venv
has no ``ros2`` command). Start a simulator first (``.venv/bin/simulator --ros-args
--params-file config/formation.yaml``), then::

    .venv/bin/python -m rigid_body_sim.examples.spawn_spacecraft --name rescue --uri slew \
        --yaw 90 [--delete wingman]

It spawns ``--name`` with the body of the scene ``--uri`` (empty: the running scene's),
turned ``--yaw`` degrees about z. It waits for the new spacecraft's first attitude
sample on ``<name>/attitude``, then prints the entities. A refusal prints the reason and
exits 1.
"""
import argparse
import math
import sys
import time

import rclpy
from geometry_msgs.msg import QuaternionStamped
from rclpy.node import Node
from simulation_interfaces.msg import Result
from simulation_interfaces.srv import DeleteEntity, GetEntities, SpawnEntity

SIMULATOR = 'attitude_simulator'


def main(argv=None):
    args = rclpy.utilities.remove_ros_args(sys.argv if argv is None else argv)
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--name', default='rescue', help='the new spacecraft\'s name')
    parser.add_argument('--uri', default='', help='scene giving its body (name or path)')
    parser.add_argument('--yaw', type=float, default=0.0, help='its attitude about z [deg]')
    parser.add_argument('--delete', default='', help='a spacecraft to delete afterwards')
    parser.add_argument('--timeout', type=float, default=30.0, help='wait per step [s]')
    opts = parser.parse_args(args[1:])
    rclpy.init(args=argv)
    node = Node('spawn_spacecraft_example')
    try:
        return _run(node, opts)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


def _call(node, srv, name, request, timeout):
    client = node.create_client(srv, f'{SIMULATOR}/{name}')
    if not client.wait_for_service(timeout_sec=timeout):
        raise SystemExit(f'no {client.srv_name} after {timeout:g} s: is a simulator running?')
    future = client.call_async(request)
    rclpy.spin_until_future_complete(node, future, timeout_sec=timeout)
    if not future.done():
        raise SystemExit(f'{client.srv_name}: no answer after {timeout:g} s')
    return future.result()


def _run(node, opts) -> int:
    samples = []
    node.create_subscription(QuaternionStamped, f'{opts.name}/attitude', samples.append, 10)
    request = SpawnEntity.Request(name=opts.name, uri=opts.uri)
    half = math.radians(opts.yaw) / 2
    request.initial_pose.pose.orientation.z = math.sin(half)
    request.initial_pose.pose.orientation.w = math.cos(half)
    got = _call(node, SpawnEntity, 'spawn_entity', request, opts.timeout)
    if got.result.result != Result.RESULT_OK:
        print(f'spawn refused ({got.result.result}): {got.result.error_message}')
        return 1
    print(f'spawned {got.entity_name}')
    deadline = time.monotonic() + opts.timeout
    while not samples and time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.1)
    if not samples:
        print(f'no sample on {opts.name}/attitude after {opts.timeout:g} s')
        return 1
    q = samples[0].quaternion
    print(f'{opts.name}/attitude: ({q.x:.6f}, {q.y:.6f}, {q.z:.6f}, {q.w:.6f})')
    if opts.delete:
        gone = _call(node, DeleteEntity, 'delete_entity', DeleteEntity.Request(
            entity=opts.delete), opts.timeout)
        print(f'delete {opts.delete}: ' + ('ok' if gone.result.result == Result.RESULT_OK
                                           else gone.result.error_message))
    listed = _call(node, GetEntities, 'get_entities', GetEntities.Request(), opts.timeout)
    print('entities: ' + ', '.join(listed.entities))
    return 0


if __name__ == '__main__':
    sys.exit(main())
