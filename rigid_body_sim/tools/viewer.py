"""Benchmark of the ``attitude_viewer`` node beside a real-time simulator at 50 Hz.

``python -m rigid_body_sim.tools.viewer [--seconds 10] [--no-client]``

One run, three phases of ``--seconds`` each, the same simulator process throughout:
1. the simulator alone;
2. with the viewer, no Foxglove client connected;
3. with the viewer and one Foxglove client (test/foxglove_client, the npm client the tests
   use, if node and its modules are installed) subscribed to every channel.

Prints per phase: the simulator's achieved real-time factor (mean and minimum of its 1 s
diagnostics), its missed deadlines, its CPU and the viewer's CPU in % of one core
(/proc utime+stime over the phase); then a summary line (JSON) and the verdict. Target:
viewer ≤ 5 % of a core, simulator RTF unchanged (within 1 % of its RTF alone).
"""
from . import argument_parser
import json
import os
import random
import shutil
import subprocess
import sys
import time

from .live_simulator import _cpu_seconds

RATE = 50.0
CLIENT = os.path.join(os.path.dirname(__file__), '..', '..', 'test', 'foxglove_client')


def _exe(name):
    path = os.path.join(sys.prefix, 'lib', 'rigid_body_sim', name)
    return [path] if os.path.exists(path) else [sys.executable, '-m',
                                                f'rigid_body_sim.nodes.{name}']


def _free_port():
    import socket
    with socket.socket() as s:
        s.bind(('127.0.0.1', 0))
        return s.getsockname()[1]


def run(seconds=10.0, client=True, log=print) -> dict:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.node import Node
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(101, 200)))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    ns = f'/bench_viewer_{os.getpid()}'
    port = _free_port()
    client_js = os.path.abspath(os.path.join(CLIENT, 'client.js'))
    client = client and shutil.which('node') is not None and \
        os.path.isdir(os.path.join(CLIENT, 'node_modules', '@foxglove'))
    quiet = {'stdout': subprocess.DEVNULL, 'stderr': subprocess.DEVNULL,
             'start_new_session': True}
    sim = subprocess.Popen(_exe('simulator') + ['--ros-args', '-r', f'__ns:={ns}', '-p',
                                                f'publish_rate:={RATE}'], **quiet)
    viewer = node = None
    diag = []  # (wall, rtf, missed total) of the simulator

    def on_diag(msg):
        for s in msg.status:
            if s.name.startswith('attitude_simulator'):
                v = {kv.key: kv.value for kv in s.values}
                diag.append((time.monotonic(), float(v['real_time_factor_achieved']),
                             int(v['missed_deadlines'])))

    def spin(t):
        end = time.monotonic() + t
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)

    def phase(name, extra=None):
        p = extra
        t0, c_sim = time.monotonic(), _cpu_seconds(sim.pid)
        c_view = _cpu_seconds(viewer.pid) if viewer else None
        spin(seconds)
        if p is not None:
            p.wait(timeout=30)
        wall = time.monotonic() - t0
        rows = [d for d in diag if t0 + 1.5 < d[0] <= t0 + wall]
        rtf = [r for _, r, _ in rows]
        out = {'phase': name, 'seconds': round(wall, 2),
               'simulator_rtf_mean': sum(rtf) / len(rtf) if rtf else float('nan'),
               'simulator_rtf_min': min(rtf) if rtf else float('nan'),
               'simulator_missed_deadlines': rows[-1][2] - rows[0][2] if rows else None,
               'simulator_cpu_percent': 100.0 * (_cpu_seconds(sim.pid) - c_sim) / wall,
               'viewer_cpu_percent': (100.0 * (_cpu_seconds(viewer.pid) - c_view) / wall
                                      if viewer else None)}
        log(json.dumps(out))
        return out

    try:
        rclpy.init()
        node = Node('bench_viewer_probe', namespace=ns)
        node.create_subscription(DiagnosticArray, '/diagnostics', on_diag, 100)
        spin(5.0)  # start-up (kernel cache load) and discovery
        results = [phase('simulator alone')]
        viewer = subprocess.Popen(_exe('viewer') + ['--ros-args', '-r', f'__ns:={ns}',
                                                    '-p', f'port:={port}'], **quiet)
        spin(5.0)  # the viewer's start-up is not part of its steady cost
        results.append(phase('with viewer, no client'))
        if client:
            proc = subprocess.Popen(['node', client_js, '--url', f'ws://127.0.0.1:{port}',
                                     '--seconds', str(seconds), '--subscribe', '*'],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            results.append(phase('with viewer, 1 Foxglove client on every channel', proc))
        return {'publish_rate_hz': RATE, 'phases': results}
    finally:
        _stop(viewer, sim, node)


def summary(result) -> dict:
    """The figures the targets need: the viewer's CPU share of a core with a client (or
    without one, if no client ran) and the simulator's mean RTF alone and with the viewer
    (the least of the viewer phases)."""
    phases = result['phases']
    viewer = phases[-1]
    return {'viewer_cpu_share': viewer['viewer_cpu_percent'] / 100.0,
            'viewer_phase': viewer['phase'],
            'simulator_rtf_alone': phases[0]['simulator_rtf_mean'],
            'simulator_rtf_with_viewer': min(p['simulator_rtf_mean'] for p in phases[1:])}


def _stop(viewer, sim, node):
    """Stop what ``run`` started (SIGINT, then SIGKILL after 10 s)."""
    import rclpy
    for p in (viewer, sim):
        if p is not None and p.poll() is None:
            os.killpg(p.pid, 2)
            try:
                p.wait(10)
            except subprocess.TimeoutExpired:
                os.killpg(p.pid, 9)
    if node is not None:
        node.destroy_node()
    rclpy.try_shutdown()


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--seconds', type=float, default=10.0, help='length of each phase')
    parser.add_argument('--no-client', action='store_true', help='skip the client phase')
    args = parser.parse_args(argv)
    out = summary(run(args.seconds, not args.no_client))
    print(json.dumps(out))
    ok = out['viewer_cpu_share'] <= 0.05 and \
        out['simulator_rtf_with_viewer'] >= 0.99 * out['simulator_rtf_alone']
    print(f'{"PASS" if ok else "MISS"}: viewer {100 * out["viewer_cpu_share"]:.2f} % of a core '
          f'({out["viewer_phase"]}; target ≤ 5 %), simulator RTF '
          f'{out["simulator_rtf_with_viewer"]:.4f} with it, {out["simulator_rtf_alone"]:.4f} '
          'alone')
    return 0


if __name__ == '__main__':
    sys.exit(main())
