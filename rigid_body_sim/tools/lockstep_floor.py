"""Lockstep floor: the least an rclpy process spends per exchange with our controller.

``python -m rigid_body_sim.tools.lockstep_floor [--periods 2000] [--runs 3] [--out docs/bench]``

The simulator's side of a lockstep exchange (``tools.lockstep``) with everything of ours
taken out: a bare rclpy node publishes the two states the controller answers (attitude and
angular_velocity, CDR bytes made once by rclpy's serialiser: no physics, no message
building, no /clock), then turns the events executor until the command is taken. What it
spends per exchange (process CPU, its own thread's, wall) is what rclpy and the middleware
cost whatever the simulator does. Measured for each Fast DDS publication mode
(``RMW_FASTRTPS_PUBLICATION_MODE``: the nodes use SYNCHRONOUS in lockstep, ASYNCHRONOUS
otherwise, ``process.py`` says why; the synchronous rows with its heartbeat profile) and
with the command taken as a message or as bytes (the simulator takes bytes). Each
configuration runs in its own process, ``--runs`` times; figures are the runs' medians.
"""
import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time

from ..bench.common import report
from . import argument_parser, command_line, stop
from .lockstep import SCENE, _exe

RATE = 100.0  # control rate [Hz]: the instants the states are stamped with
MODES = ('ASYNCHRONOUS', 'SYNCHRONOUS')


def _measure(periods: int, raw: bool) -> dict:
    """In this process (its environment chose the publication mode): the figures."""
    import rclpy
    from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
    from rclpy.experimental import EventsExecutor
    from rclpy.serialization import serialize_message
    from ..nodes.common import qos_profile
    from ..nodes.spacecraft import STATE_DEPTH
    ns = f'/lockstep_floor_{os.getpid()}'
    with tempfile.NamedTemporaryFile('w', suffix='.yaml', delete=False) as f:
        f.write('/**/attitude_controller:\n  ros__parameters:\n    lockstep: true\n'
                f'    control_rate: {RATE}\n')
    ctl = subprocess.Popen(_exe('controller') + [
        '--ros-args', '-r', f'__ns:={ns}', '--params-file', SCENE, '--params-file', f.name],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    rclpy.init()
    try:
        node = rclpy.create_node('lockstep_floor', namespace=ns)
        state = qos_profile('reliable', STATE_DEPTH)
        attitude = node.create_publisher(QuaternionStamped, 'attitude', state)
        rate = node.create_publisher(Vector3Stamped, 'angular_velocity', state)
        got = []
        node.create_subscription(Vector3Stamped, 'torque_command', got.append,
                                 qos_profile('reliable'), raw=raw)
        executor = EventsExecutor(context=node.context)
        executor.add_node(node)
        q, w = QuaternionStamped(), Vector3Stamped()
        q.header.frame_id, w.header.frame_id, q.quaternion.w = 'world', 'base_link', 1.0
        deadline = time.monotonic() + 60.0
        while min(attitude.get_subscription_count(), rate.get_subscription_count()) < 1:
            if time.monotonic() > deadline:
                raise RuntimeError('the controller did not subscribe within 60 s')
            executor.spin_once(timeout_sec=0.05)
        # states for every instant, serialised before the measurement (ours cost nothing)
        period = round(1e9 / RATE)
        frames = []
        for k in range(100 + periods):
            q.header.stamp.sec, q.header.stamp.nanosec = divmod(k * period, 10**9)
            w.header.stamp = q.header.stamp
            frames.append((serialize_message(q), serialize_message(w)))

        def exchange(k):
            attitude.publish(frames[k][0])
            rate.publish(frames[k][1])
            n, until = len(got), time.monotonic() + 10.0
            while len(got) == n:
                if time.monotonic() > until:
                    raise RuntimeError(f'no command for instant {k} within 10 s')
                executor.spin_once(timeout_sec=1.0)
        for k in range(100):  # discovery settled, caches warm
            exchange(k)
        c0, t0, w0 = time.process_time(), time.thread_time(), time.monotonic()
        for k in range(100, 100 + periods):
            exchange(k)
        c1, t1, w1 = time.process_time(), time.thread_time(), time.monotonic()
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
        stop(ctl)
        os.unlink(f.name)
    return {'cpu_per_exchange_us': 1e6 * (c1 - c0) / periods,
            'thread_cpu_per_exchange_us': 1e6 * (t1 - t0) / periods,
            'wall_per_exchange_us': 1e6 * (w1 - w0) / periods}


def floor(mode: str, raw: bool, periods: int, runs: int) -> dict:
    """``runs`` runs of one configuration, each in a process of its own: the medians."""
    env = dict(os.environ, RMW_FASTRTPS_PUBLICATION_MODE=mode,
               ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', str(random.randint(101, 200))))
    if mode == 'SYNCHRONOUS' and not env.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        from ..nodes.process import heartbeat_profile  # as the nodes publish in lockstep
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = heartbeat_profile()
    got = []
    for _ in range(runs):
        out = subprocess.run([sys.executable, '-m', __spec__.name, '--one', str(periods)]
                             + (['--raw'] if raw else []), env=env, capture_output=True,
                             text=True, timeout=600)
        if out.returncode != 0:
            raise RuntimeError(f'floor run ({mode}, raw {raw}) exited {out.returncode}:\n'
                               + out.stderr[-2000:])
        got.append(json.loads(out.stdout.strip().splitlines()[-1]))
    row = {'publication_mode': mode, 'command_taken_as': 'bytes' if raw else 'message',
           'exchanges': periods}
    for key in got[0]:
        row[key] = statistics.median(g[key] for g in got)
        row[key + '_runs'] = [g[key] for g in got]
    return row


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--periods', type=int, default=2000, help='exchanges per run')
    parser.add_argument('--runs', type=int, default=3, help='runs per configuration')
    parser.add_argument('--out', help='directory for lockstep_floor.json (e.g. docs/bench)')
    parser.add_argument('--one', type=int, help=argparse.SUPPRESS)
    parser.add_argument('--raw', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one:  # one run, in this process (floor() starts these)
        print(json.dumps(_measure(args.one, args.raw)))
        return 0
    rows = []
    for mode in MODES:
        for raw in (False, True):
            r = floor(mode, raw, args.periods, args.runs)
            rows.append(r)
            print(f'{mode}, command as {r["command_taken_as"]}: process CPU '
                  f'{r["cpu_per_exchange_us"]:.0f} µs per exchange (runs '
                  f'{", ".join(f"{v:.0f}" for v in r["cpu_per_exchange_us_runs"])}), its '
                  f'thread {r["thread_cpu_per_exchange_us"]:.0f} µs, wall '
                  f'{r["wall_per_exchange_us"]:.0f} µs', flush=True)
    if args.out:
        report({'command': command_line(__spec__, argv), 'control_rate_hz': RATE,
                'rows': rows}, args.out, 'lockstep_floor.json')
        from ..bench import report as summary
        summary.write(args.out)  # the benchmarks page's figures, this floor's with them
    return 0


if __name__ == '__main__':
    sys.exit(main())
