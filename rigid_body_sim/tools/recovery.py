"""Recovery from crashed peers, timed (docs/bench beside the flood and the soak).

``python -m rigid_body_sim.tools.recovery [--out docs/bench]``

A simulator and a slewing controller (max torque 0.05 N·m, state_timeout 0.3 s; the
simulator's command_timeout 0.5 s). In turn: the controller is SIGKILLed and restarted,
then the simulator is SIGKILLed and restarted. Measured (wall time, this process's
receipt of the messages):
* controller killed → the simulator reports zero torque (its 1 Hz diagnostics: an upper
  bound; the hold itself is command_timeout);
* controller restarted → its first nonzero command (includes its start-up);
* simulator killed → the controller's first explicit zero command (stale state);
* simulator restarted → the controller's first nonzero command again;
* the largest command over the whole run against the controller's saturation.
Prints one JSON line; ``--out DIR`` writes DIR/recovery.json.
"""
from . import argument_parser
import os
import random
import signal
import subprocess
import sys
import time

import numpy as np

from ..bench.common import report
from .soak import _exe

MAX_TORQUE = 0.05


def run() -> dict:
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(101, 200)))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import Vector3Stamped
    ns = f'/recovery_{os.getpid()}'
    sim_cmd = _exe('simulator') + ['--ros-args', '-r', f'__ns:={ns}', '-p', 'publish_rate:=50.0',
                                   '-p', 'command_timeout:=0.5',
                                   '-p', 'initial_angular_velocity:=[0.0, 0.0, 0.0]']
    ctl_cmd = _exe('controller') + ['--ros-args', '-r', f'__ns:={ns}', '-p', 'mode:=slew',
                                    '-p', f'max_torque:={MAX_TORQUE}', '-p', 'state_timeout:=0.3',
                                    '-p', 'target_attitude:=[0.0, 0.0, 0.7071067811865476, '
                                    '0.7071067811865476]']

    def start(cmd):
        return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                start_new_session=True)

    rclpy.init()
    node = rclpy.create_node('recovery_probe')
    torques, diag = [], {}
    node.create_subscription(Vector3Stamped, f'{ns}/torque_command', lambda m: torques.append(
        (time.monotonic(), float(np.linalg.norm([m.vector.x, m.vector.y, m.vector.z])))), 1000)
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda a: [
        diag.update({kv.key: kv.value for kv in s.values}) for s in a.status
        if s.hardware_id == f'{ns}/attitude_simulator'], 100)

    def wait_for(done, timeout=60.0):
        end = time.monotonic() + timeout
        while not done() and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.02)
        if not done():
            raise RuntimeError('timed out waiting for the graph')
        return time.monotonic()

    def command_after(t0, nonzero):
        return lambda: any(t > t0 and ((v > 1e-9) == nonzero) for t, v in torques)

    def first(t0, nonzero):
        return next(t for t, v in torques if t > t0 and (v > 1e-9) == nonzero) - t0

    procs = {'simulator': start(sim_cmd), 'controller': start(ctl_cmd)}
    out = {}
    try:
        wait_for(command_after(0.0, True))
        wait_for(lambda: diag.get('torque_applied') == 'true')
        t_kill = time.monotonic()
        os.killpg(procs['controller'].pid, signal.SIGKILL)
        procs['controller'].wait(10)
        out['controller_killed_to_zero_torque_reported_s'] = round(
            wait_for(lambda: diag.get('torque_applied') == 'false', 30.0) - t_kill, 2)
        t_start = time.monotonic()
        procs['controller'] = start(ctl_cmd)
        wait_for(command_after(t_start, True))
        out['controller_restarted_to_control_s'] = round(first(t_start, True), 2)
        time.sleep(1.0)
        t_kill = time.monotonic()
        os.killpg(procs['simulator'].pid, signal.SIGKILL)
        procs['simulator'].wait(10)
        wait_for(command_after(t_kill, False))
        out['simulator_killed_to_zero_command_s'] = round(first(t_kill, False), 3)
        t_start = time.monotonic()
        procs['simulator'] = start(sim_cmd)
        wait_for(command_after(t_start, True))
        out['simulator_restarted_to_control_s'] = round(first(t_start, True), 2)
        out['largest_command_nm'] = max(v for _, v in torques)
        out['saturation_nm'] = MAX_TORQUE
        out['commands_received'] = len(torques)
    finally:
        for p in procs.values():
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGINT)
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
        node.destroy_node()
        rclpy.try_shutdown()
    return out


def main(argv=None) -> int:
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--out', help='directory for recovery.json (e.g. docs/bench)')
    args = parser.parse_args(argv)
    result = run()
    result['command'] = 'python -m rigid_body_sim.tools.recovery'
    report(result, args.out, 'recovery.json')
    return 0


if __name__ == '__main__':
    sys.exit(main())
