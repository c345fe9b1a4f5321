"""Soak: the live graph at real time for a long while; memory, pacing and loss over time.

    python -m rigid_body_sim.tools.soak [--minutes 60] [--every 10] [--out docs/bench]

Starts the recorder, the simulator (default scene, open-ended, 100 Hz), the controller
(slew and hold) and the Foxglove viewer (on a free port; ``--no-viewer`` leaves it out) as
separate processes, and every ``--every`` seconds samples each
process's resident memory and the simulator's diagnostics (achieved real-time factor,
missed deadlines). At the end it stops them with SIGINT and counts the `attitude`
messages in the bag against the samples the simulator published meanwhile.

Writes ``soak.csv`` (one row per sampling) and prints one JSON summary line: RSS growth
per hour of each process (least-squares slope after the first minute), the real-time
factor range, missed deadlines, and lost messages.
"""
from . import argument_parser
import csv
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np


def _rss_mb(pid):
    try:
        with open(f'/proc/{pid}/status') as f:
            return next(int(line.split()[1]) for line in f
                        if line.startswith('VmRSS:')) / 1024.0
    except (OSError, StopIteration):
        return float('nan')


def _attitude_stamps(bag):
    """Header stamps (ns) of the recorded attitude messages, in order."""
    import glob
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory
    out = []
    for path in sorted(glob.glob(os.path.join(bag, '*.mcap'))):
        with open(path, 'rb') as f:
            for _, c, _, msg in make_reader(f, decoder_factories=[DecoderFactory()]) \
                    .iter_decoded_messages():
                if c.topic.endswith('/attitude'):
                    out.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
    return np.array(sorted(out), dtype=np.int64)


def _exe(name):
    path = os.path.join(sys.prefix, 'lib', 'rigid_body_sim', name)
    return [path] if os.path.exists(path) else [sys.executable, '-m',
                                                f'rigid_body_sim.nodes.{name}']


def main(argv=None) -> int:
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--minutes', type=float, default=60.0)
    parser.add_argument('--every', type=float, default=10.0, help='seconds between samples')
    parser.add_argument('--out', default='out/soak', help='directory for soak.csv and the bag')
    parser.add_argument('--no-viewer', action='store_true', help='without the Foxglove viewer')
    args = parser.parse_args(argv)
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(101, 200)))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from ..scene import load
    os.makedirs(args.out, exist_ok=True)
    scene = load('default')
    ns = f'/soak_{os.getpid()}'
    bag = tempfile.mkdtemp(prefix='soak_bag_', dir=args.out)
    os.rmdir(bag)
    common = ['--ros-args', '-r', f'__ns:={ns}', '--params-file', scene.path]
    procs = {'recorder': subprocess.Popen(_exe('recorder') + ['--ros-args', '-r', f'__ns:={ns}',
                                                              '-p', f'output:={bag}'],
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)}
    time.sleep(2.0)
    # open-ended: a second params file, since -p loses against the scene's node section
    forever = os.path.join(args.out, 'open_ended.yaml')
    with open(forever, 'w') as f:
        f.write('/**/attitude_simulator:\n  ros__parameters:\n    duration: 0.0\n')
    procs['simulator'] = subprocess.Popen(_exe('simulator') + common + ['--params-file', forever],
                                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    procs['controller'] = subprocess.Popen(_exe('controller') + common,
                                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    if not args.no_viewer:
        procs['viewer'] = subprocess.Popen(_exe('viewer') + [
            '--ros-args', '-r', f'__ns:={ns}', '-p', 'port:=0'],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rclpy.init()
    node = rclpy.create_node('soak_probe')
    diag = {}
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda a: [
        diag.update({kv.key: kv.value for kv in s.values}) for s in a.status
        if s.hardware_id == f'{ns}/attitude_simulator'], 10)
    rows, start = [], time.monotonic()
    first_t = None
    try:
        while time.monotonic() - start < args.minutes * 60:
            end = time.monotonic() + args.every
            while time.monotonic() < end:
                rclpy.spin_once(node, timeout_sec=0.1)
            if not diag:
                continue
            t_sim = float(diag['sim_time'])
            first_t = t_sim if first_t is None else first_t
            rows.append({'wall_s': round(time.monotonic() - start, 1), 'sim_s': t_sim,
                         'rtf': float(diag['real_time_factor_achieved']),
                         'missed_deadlines': int(diag['missed_deadlines']),
                         **{f'rss_mb_{k}': round(_rss_mb(p.pid), 1) for k, p in procs.items()}})
            print(json.dumps(rows[-1]), flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        last_t = float(diag.get('sim_time', 'nan')) if diag else float('nan')
        for name in ('viewer', 'controller', 'simulator', 'recorder'):
            if name not in procs:
                continue
            procs[name].send_signal(signal.SIGINT)
            try:
                procs[name].wait(30)
            except subprocess.TimeoutExpired:
                procs[name].kill()
        node.destroy_node()
        rclpy.try_shutdown()
    stamps = _attitude_stamps(bag)
    period_ns = round(1e9 / scene.simulator['publish_rate'])
    # every sample is stamped exactly one period after the previous: a gap is a loss
    lost = int(np.sum(np.diff(stamps) // period_ns - 1)) if len(stamps) > 1 else None
    with open(os.path.join(args.out, 'soak.csv'), 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]) if rows else ['wall_s'])
        w.writeheader()
        w.writerows(rows)
    growth = {}
    late = [r for r in rows if r['wall_s'] >= 60.0] or rows
    for k in (k for k in (rows[0] if rows else {}) if k.startswith('rss_mb_')):
        if len(late) >= 2:
            slope = np.polyfit([r['wall_s'] for r in late], [r[k] for r in late], 1)[0]
            growth[k.replace('rss_mb_', '')] = round(slope * 3600.0, 2)
    summary = {'minutes': round((time.monotonic() - start) / 60.0, 2),
               'rss_growth_mb_per_hour': growth,
               'rtf_range': [min((r['rtf'] for r in rows), default=None),
                             max((r['rtf'] for r in rows), default=None)],
               'missed_deadlines': rows[-1]['missed_deadlines'] if rows else None,
               'attitude_recorded': len(stamps), 'attitude_lost': lost,
               'sim_seconds': None if first_t is None else round(last_t - first_t, 1)}
    print(json.dumps(summary), flush=True)
    return 0


if __name__ == '__main__':
    sys.exit(main())
