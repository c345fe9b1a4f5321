"""Signals to real node processes: each exits quickly and cleanly, the recorder's bag is
finished whatever the signal sequence (SIGINT, SIGINT twice, SIGTERM), and nothing is
left behind. (The demo's own Ctrl-C handling is in test_demo.py.)
"""
import os
import signal
import subprocess
import sys
import time

import pytest

from ros_helpers import spin_until, venv_exe

SEQUENCES = {'sigint': (signal.SIGINT,), 'sigint_twice': (signal.SIGINT, signal.SIGINT),
             'sigterm': (signal.SIGTERM,)}


def _stop(proc, sequence):
    t0 = time.monotonic()
    for sig in sequence:
        proc.signal(sig)
        time.sleep(0.05)
    code = proc.wait(20)
    return code, time.monotonic() - t0


@pytest.mark.parametrize('sequence', list(SEQUENCES))
def test_nodes_stop_cleanly_and_the_bag_is_finished(ros_process, namespace, rclpy_node,
                                                    tmp_path, sequence):
    """Simulator, controller and recorder running together; every process gets the
    signal sequence (the recorder first, while it is busy recording 50 Hz topics): each
    exits with 0 within 2 s (wall, generous for a loaded machine: 5 s), no traceback, and
    `bag info` reads the bag without recover."""
    from geometry_msgs.msg import QuaternionStamped
    bag = tmp_path / 'bag'
    rec = ros_process(venv_exe('recorder'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', f'output:={bag}', '-p', 'flush_period:=10.0')
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'publish_rate:=50.0')
    ctl = ros_process(venv_exe('controller'), '--ros-args', '-r', f'__ns:={namespace}')
    seen = []
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude', seen.append, 100)
    assert spin_until(rclpy_node, lambda: len(seen) > 100, 60.0), sim.output()[-2000:]
    for proc in (rec, ctl, sim):
        code, took = _stop(proc, SEQUENCES[sequence])
        out = proc.output()
        assert code == 0 and 'Traceback' not in out, out[-3000:]
        assert took < 5.0, (proc.cmd[0], took)
    info = subprocess.run([os.path.join(os.path.dirname(sys.executable), 'rigid-body-sim'),
                           'bag', 'info', str(bag)], capture_output=True, text=True, timeout=60)
    assert info.returncode == 0, info.stdout + info.stderr
    assert 'attitude' in info.stdout and 'recover' not in info.stdout + info.stderr
