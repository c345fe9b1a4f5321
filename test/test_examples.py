"""The shipped rclpy example drives a real simulator: torque, ~/reset, a parameter."""
import ast
import os
import subprocess
import sys

from ros_helpers import venv_exe


def _vector(out, prefix):
    line = next(s for s in out.splitlines() if s.startswith(prefix))
    return ast.literal_eval(line[line.index('('):])


def test_send_torque_example_against_a_simulator(ros_process, namespace):
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}')
    res = subprocess.run([sys.executable, '-m', 'rigid_body_sim.examples.send_torque',
                          '--torque', '0.2', '--seconds', '1', '--timeout', '60',
                          '--ros-args', '-r', f'__ns:={namespace}'],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr + sim.output()[-3000:]
    out = res.stdout
    before, after = _vector(out, 'L before'), _vector(out, 'L after 0.2')
    reset = _vector(out, 'L after reset')
    # L (world) moves only under torque: about 0.2 N*m for about 1 s (held 0.5 s past)
    assert 0.05 < sum((a - b) ** 2 for a, b in zip(after, before)) ** 0.5 < 1.0, out
    # the default scene's initial L = I w0 = (0.05, 2, 0) in the world frame
    assert all(abs(a - b) < 1e-6 for a, b in zip(reset, (0.05, 2.0, 0.0))), out
    assert 'reset: ok' in out and 'set integrator = rk4: ok' in out
    assert 'integrator now: rk4' in out
    assert sim.poll() is None


def test_spawn_spacecraft_example_against_a_formation(ros_process, namespace):
    """The venv's way to spawn and delete: into the formation scene, while it runs."""
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '--params-file', os.path.join(os.path.dirname(os.path.dirname(
                          os.path.abspath(__file__))), 'config', 'formation.yaml'))
    cmd = [sys.executable, '-m', 'rigid_body_sim.examples.spawn_spacecraft', '--timeout', '60',
           '--ros-args', '-r', f'__ns:={namespace}']
    res = subprocess.run(cmd[:3] + ['--name', 'rescue', '--uri', 'slew', '--yaw', '90',
                                    '--delete', 'wingman'] + cmd[3:],
                         capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr + sim.output()[-3000:]
    out = res.stdout
    assert 'spawned rescue' in out and 'delete wingman: ok' in out
    q = _vector(out, 'rescue/attitude')  # 90° about z at its first sample
    assert abs(q[2] - 0.5 ** 0.5) < 0.05 and abs(q[3] - 0.5 ** 0.5) < 0.05, out
    assert 'entities: leader, leader/wheel_1, leader/wheel_2, leader/wheel_3, tumbler, ' \
        'rescue' in out
    again = subprocess.run(cmd[:3] + ['--name', 'rescue'] + cmd[3:], capture_output=True,
                           text=True, timeout=300)
    assert again.returncode == 1 and "'rescue' is running" in again.stdout, again.stdout
    assert sim.poll() is None
