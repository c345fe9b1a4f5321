"""The flood's figures from the simulator's side, for docs/bench (issue: survive floods).

``python -m rigid_body_sim.tools.flood_report [--seconds 30] [--rate 10000] [--out docs/bench]``

Starts a simulator (real time, 50 Hz publishing, splitting2), lets it settle, then runs
``tools.flood`` against it (``rate`` valid commands per second and as many garbage ones:
NaN, wrong frame, future and stale stamps) and records from the simulator's diagnostics
and topics: its achieved real-time factor during the flood, the samples it published
against those due, what it accepted and rejected per class, and its RSS before and
after. Then the flood stops, and recovery (the held command timed out to zero torque after
``command_timeout``) is bounded by the first 1 Hz diagnostics report that shows it. Prints
one JSON line; ``--out`` writes DIR/flood.json.
"""
from . import argument_parser, stop
import json
import math
import os
import random
import subprocess
import sys
import time

from ..bench.common import report
from .live_simulator import _rss_mb
from .soak import _exe

RATE_HZ = 50.0


def run(seconds: float, rate: float) -> dict:
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(101, 200)))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import QuaternionStamped
    ns = f'/flood_{os.getpid()}'
    sim = subprocess.Popen(_exe('simulator') + [
        '--ros-args', '-r', f'__ns:={ns}', '-p', f'publish_rate:={RATE_HZ}',
        '-p', 'integrator:=splitting2'], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rclpy.init()
    node = rclpy.create_node('flood_report')
    diags, samples = [], []
    node.create_subscription(DiagnosticArray, '/diagnostics', lambda a: diags.extend(
        (time.monotonic(), {kv.key: kv.value for kv in s.values}) for s in a.status
        if s.hardware_id == f'{ns}/attitude_simulator'), 100)
    node.create_subscription(QuaternionStamped, f'{ns}/attitude',
                             lambda m: samples.append(time.monotonic()), 100)

    def spin_until(done, timeout):
        end = time.monotonic() + timeout
        while not done() and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        return done()

    try:
        if not spin_until(lambda: len(samples) > 50 and diags, 60.0):
            raise RuntimeError('the simulator did not start publishing within 60 s')
        rss0 = _rss_mb(sim.pid)
        flood = subprocess.Popen([sys.executable, '-m', 'rigid_body_sim.tools.flood', ns,
                                  '--rate', str(rate), '--duration', str(seconds)],
                                 stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        t0, n0 = time.monotonic(), len(diags)
        spin_until(lambda: flood.poll() is not None, seconds + 120.0)
        t1 = time.monotonic()
        sent = json.loads(flood.stdout.read().strip().splitlines()[-1])
        rss1 = _rss_mb(sim.pid)
        published = sum(t0 <= t <= t1 for t in samples)
        # recovery: the last command is held for command_timeout, then zero torque
        spin_until(lambda: diags[-1][1].get('torque_applied') == 'false'
                   and diags[-1][0] > t1, 30.0)
        recovered = diags[-1][0] - t1 if diags[-1][1].get('torque_applied') == 'false' \
            else None
        during = [d for t, d in diags[n0:] if t0 < t <= t1][1:]  # the first spans the start
        last = [d for t, d in diags if t <= t1 + 1.5][-1]
        rtf = [float(d['real_time_factor_achieved']) for d in during]
        return {
            'flood_seconds': round(t1 - t0, 2), 'sent': sent['sent'],
            'sent_rate_hz': round(sent['rate_achieved']),
            'accepted': int(last['commands_accepted']),
            'rejected': {k.split('.', 1)[1]: int(v) for k, v in last.items()
                         if k.startswith('commands_rejected.')},
            'rtf_during': [min(rtf, default=math.nan), max(rtf, default=math.nan)],
            'samples_published': published, 'samples_due': int((t1 - t0) * RATE_HZ),
            'missed_deadlines': int(last['missed_deadlines']),
            'rss_mb_before': round(rss0, 1), 'rss_mb_after': round(rss1, 1),
            'zero_torque_reported_within_s': None if recovered is None else round(recovered, 2),
            'simulator_alive': sim.poll() is None}
    finally:
        stop(sim)
        node.destroy_node()
        rclpy.try_shutdown()


def main(argv=None) -> int:
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--seconds', type=float, default=30.0)
    parser.add_argument('--rate', type=float, default=10_000.0)
    parser.add_argument('--out', help='directory for flood.json (e.g. docs/bench)')
    args = parser.parse_args(argv)
    for name in ('seconds', 'rate'):
        value = getattr(args, name)
        if not math.isfinite(value) or value <= 0:
            parser.error(f'--{name} {value}: must be a positive number')
    result = run(args.seconds, args.rate)
    result['command'] = ('python -m rigid_body_sim.tools.flood_report --seconds '
                         f'{args.seconds:g} --rate {args.rate:g}')
    report(result, args.out, 'flood.json')
    return 0


if __name__ == '__main__':
    sys.exit(main())
