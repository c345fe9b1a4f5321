"""The shipped rclpy example drives a real simulator: torque, ~/reset, a parameter."""
import ast
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
