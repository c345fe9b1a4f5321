"""Peers that crash mid-run, on real processes: the simulator holds the last command for
command_timeout, then applies zero torque, and takes commands again when the controller
is back; a restarted simulator finds the controller waiting (zero torque while the state
is stale) and controlling again, its torque never above its saturation.
"""
import signal

import numpy as np

from ros_helpers import spin_until, venv_exe

MAX_TORQUE = 0.05


def _diag(rclpy_node, namespace):
    from diagnostic_msgs.msg import DiagnosticArray
    latest = {}

    def on(msg):
        for s in msg.status:
            if s.hardware_id == f'{namespace}/attitude_simulator':
                latest.clear()
                latest.update({kv.key: kv.value for kv in s.values})
    rclpy_node.create_subscription(DiagnosticArray, '/diagnostics', on, 100)
    return latest


def test_controller_and_simulator_restarts(ros_process, namespace, rclpy_node):
    from geometry_msgs.msg import Vector3Stamped
    ns = ['-r', f'__ns:={namespace}']
    sim_cmd = [venv_exe('simulator'), '--ros-args', *ns, '-p', 'publish_rate:=50.0',
               '-p', 'command_timeout:=0.5', '-p', 'initial_angular_velocity:=[0.0, 0.0, 0.0]']
    ctl_cmd = [venv_exe('controller'), '--ros-args', *ns, '-p', 'mode:=slew',
               '-p', f'max_torque:={MAX_TORQUE}', '-p', 'state_timeout:=0.3',
               '-p', 'target_attitude:=[0.0, 0.0, 0.7071067811865476, 0.7071067811865476]']
    sim = ros_process(*sim_cmd)
    ctl = ros_process(*ctl_cmd)
    torques = []
    rclpy_node.create_subscription(
        Vector3Stamped, f'{namespace}/torque_command',
        lambda m: torques.append(np.array([m.vector.x, m.vector.y, m.vector.z])), 1000)
    diag = _diag(rclpy_node, namespace)

    def commanding():
        return len(torques) > 5 and np.linalg.norm(torques[-1]) > 1e-6

    def diag_is(key, value):
        return lambda: diag.get(key) == value

    assert spin_until(rclpy_node, commanding, 60.0), ctl.output()[-2000:]
    assert spin_until(rclpy_node, diag_is('torque_applied', 'true'), 30.0)
    # the controller dies: held for command_timeout, then zero torque, counted
    ctl.signal(signal.SIGKILL)
    ctl.wait(10)
    assert spin_until(rclpy_node, diag_is('torque_applied', 'false'), 30.0), diag
    assert int(diag['commands_timed_out']) >= 1
    # it comes back: torque again
    n = len(torques)
    ctl = ros_process(*ctl_cmd)
    assert spin_until(rclpy_node, lambda: len(torques) > n + 5 and commanding(), 60.0)
    assert spin_until(rclpy_node, diag_is('torque_applied', 'true'), 30.0)
    # the simulator dies: the controller sees stale state and commands zero
    sim.signal(signal.SIGKILL)
    sim.wait(10)
    n = len(torques)
    assert spin_until(rclpy_node, lambda: len(torques) > n + 10 and
                      np.linalg.norm(torques[-1]) == 0.0, 30.0), ctl.output()[-2000:]
    # a new simulator: control resumes
    sim = ros_process(*sim_cmd)
    n = len(torques)
    assert spin_until(rclpy_node, lambda: len(torques) > n + 5 and commanding(), 60.0)
    # never a spike: every command within the controller's saturation
    assert max(np.linalg.norm(t) for t in torques) <= MAX_TORQUE * (1 + 1e-12)
