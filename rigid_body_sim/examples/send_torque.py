"""Drive a running simulator from rclpy: send a torque, call ~/reset, set a parameter.

The venv has no ``ros2`` command; this is its way to do what ``ros2 topic pub``,
``ros2 service call`` and ``ros2 param set`` do on a full install. Start a simulator
first (``.venv/bin/simulator``), then::

    .venv/bin/python -m rigid_body_sim.examples.send_torque [--torque 0.1] [--seconds 1]

ROS arguments go after ``--ros-args`` (``-r __ns:=/sat1`` for a namespaced simulator).
It prints the world-frame angular momentum L before and after the torque (L only changes
under torque), after the reset, and the parameter as read back.
"""
import argparse
import sys
import time

import rclpy
from geometry_msgs.msg import Vector3Stamped
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.node import Node
from std_srvs.srv import Trigger

SIMULATOR = 'attitude_simulator'


class Driver(Node):
    def __init__(self):
        super().__init__('send_torque_example')
        self.momentum = None  # latest world-frame angular momentum [kg*m^2/s]
        self.stamp = 0  # its header stamp [ns]
        self.samples = 0
        self.create_subscription(Vector3Stamped, 'angular_momentum', self._on_momentum, 10)
        self.torque = self.create_publisher(Vector3Stamped, 'torque_command', 10)

    def _on_momentum(self, msg):
        self.momentum = (msg.vector.x, msg.vector.y, msg.vector.z)
        self.stamp = msg.header.stamp.sec * 10 ** 9 + msg.header.stamp.nanosec
        self.samples += 1

    def spin_until(self, done, timeout, what):
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                raise TimeoutError(f'no {what} within {timeout:g} s: is the simulator running '
                                   '(in this namespace and ROS_DOMAIN_ID)?')
            rclpy.spin_once(self, timeout_sec=0.05)

    def next_sample(self, timeout, stamped_after=0):
        """The next sample, or the first stamped after ``stamped_after`` (ns): on a loaded
        machine a sample may be on its way that the simulator made before our command."""
        seen = self.samples
        if abs(self.stamp - stamped_after) > 3600 * 10 ** 9:
            stamped_after = 0  # sim-time stamps (publish_clock): not on this node's clock
        self.spin_until(lambda: self.samples > seen and self.stamp > stamped_after, timeout,
                        'angular_momentum sample')
        return self.momentum

    def drain(self, seconds):
        """Take whatever arrives during ``seconds``."""
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            rclpy.spin_once(self, timeout_sec=0.05)

    def send_torque(self, z, seconds):
        """Torque about the body z axis, re-sent at 20 Hz (the simulator drops a command
        older than its command_timeout), then zero."""
        msg = Vector3Stamped()
        msg.header.frame_id = 'base_link'  # the simulator's child_frame_id (or empty)
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            msg.vector.z = z
            self.torque.publish(msg)
            rclpy.spin_once(self, timeout_sec=0.05)
        msg.vector.z = 0.0
        self.torque.publish(msg)
        # the simulator stamps with its clock (this one unless it publishes /clock)
        return self.get_clock().now().nanoseconds

    def call(self, srv_type, name, request, timeout):
        client = self.create_client(srv_type, f'{SIMULATOR}/{name}')
        if not client.wait_for_service(timeout_sec=timeout):
            raise TimeoutError(f'service {client.srv_name} not available')
        future = client.call_async(request)
        self.spin_until(future.done, timeout, f'answer from {client.srv_name}')
        return future.result()


def main(argv=None):
    argv = sys.argv if argv is None else argv
    parser = argparse.ArgumentParser(prog='python -m rigid_body_sim.examples.send_torque',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--torque', type=float, default=0.1, help='N*m about body z')
    parser.add_argument('--seconds', type=float, default=1.0, help='how long (wall time)')
    parser.add_argument('--integrator', default='rk4', help='value to set')
    parser.add_argument('--timeout', type=float, default=30.0, help='per step, s')
    args = parser.parse_args(rclpy.utilities.remove_ros_args(argv)[1:])
    rclpy.init(args=argv)
    node = Driver()
    try:
        # a command sent before the simulator's subscription has matched ours is lost
        node.spin_until(lambda: node.torque.get_subscription_count() > 0, args.timeout,
                        'subscriber of torque_command')
        before = node.next_sample(args.timeout)
        print(f'L before: {before}')
        stopped = node.send_torque(args.torque, args.seconds)
        after = node.next_sample(args.timeout, stamped_after=stopped)
        print(f'L after {args.torque:g} N*m for {args.seconds:g} s: {after}')

        reply = node.call(Trigger, 'reset', Trigger.Request(), args.timeout)
        print(f'reset: {"ok" if reply.success else "refused"}: {reply.message}')
        node.drain(0.3)  # samples sent before the reset may still be on their way
        print(f'L after reset: {node.next_sample(args.timeout)}')

        value = ParameterValue(type=ParameterType.PARAMETER_STRING,
                               string_value=args.integrator)
        reply = node.call(SetParameters, 'set_parameters', SetParameters.Request(
            parameters=[Parameter(name='integrator', value=value)]), args.timeout)
        result = reply.results[0]
        print(f'set integrator = {args.integrator}: '
              f'{"ok" if result.successful else "refused: " + result.reason}')
        reply = node.call(GetParameters, 'get_parameters',
                          GetParameters.Request(names=['integrator']), args.timeout)
        print(f'integrator now: {reply.values[0].string_value}')
        return 0 if result.successful else 1
    except TimeoutError as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    sys.exit(main())
