"""Spacecraft per simulator process at real time: CPU for N spacecraft, every topic at 10 Hz.

``python -m rigid_body_sim.tools.fleet [--counts 1 10 100] [--seconds 10] [--unobserved]``

For each N, one simulator process runs a scene of N spacecraft (``spacecraft: [sc_0, ...]``,
each its own tumble, torque-free: ``auto`` takes the closed form) at real_time_factor 1,
publishing at 10 Hz. This process subscribes to every state topic of every spacecraft and
to /tf (raw bytes: its own cost stays out of the simulator's), so that the simulator
publishes them all (it skips topics nobody listens to; ``--unobserved`` measures that
case). Prints per N: the simulator's CPU (% of one core, /proc utime+stime over
``--seconds``), the real-time factor it achieved, its missed deadlines and the messages it
published per topic per simulated second (its diagnostics; 10: every topic at its rate), and
those received here (one Python executor: at 100 spacecraft it falls behind before the
simulator does).
"""
from ..bench.common import report
from . import argument_parser, command_line, stop
import os
import random
import subprocess
import sys
import tempfile
import time

from .live_simulator import _cpu_seconds, _rss_mb

RATE = 10.0
TOPICS = ('attitude', 'pose', 'transform', 'odometry', 'angular_velocity', 'angular_momentum',
          'angular_momentum_body', 'kinetic_energy', 'imu')


def scene_text(n: int) -> str:
    """A params file of ``n`` spacecraft, each tumbling its own way."""
    rng = random.Random(n)
    lines = ['/**/attitude_simulator:', '  ros__parameters:',
             f'    spacecraft: [{", ".join(f"sc_{i}" for i in range(n))}]',
             f'    publish_rate: {RATE}', '    real_time_factor: 1.0']
    for i in range(n):
        w = [round(rng.uniform(-1.0, 1.0), 3) for _ in range(3)]
        lines += [f'    sc_{i}:', f'      initial_angular_velocity: {w}']
    return '\n'.join(lines) + '\n'


def measure(n: int, seconds: float, observe: bool = True) -> dict:
    import rclpy
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from diagnostic_msgs.msg import DiagnosticArray
    from geometry_msgs.msg import (PoseStamped, QuaternionStamped, TransformStamped,
                                   Vector3Stamped)
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu
    from std_msgs.msg import Float64
    types = {'attitude': QuaternionStamped, 'pose': PoseStamped, 'transform': TransformStamped,
             'odometry': Odometry, 'angular_velocity': Vector3Stamped,
             'angular_momentum': Vector3Stamped, 'angular_momentum_body': Vector3Stamped,
             'kinetic_energy': Float64, 'imu': Imu}
    ns = f'/fleet_{os.getpid()}_{n}'
    node = rclpy.create_node(f'fleet_bench_{n}')
    received, diags = [0], []
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)

    def count(_):
        received[0] += 1
    def on_diagnostics(array):
        stamp = array.header.stamp.sec + 1e-9 * array.header.stamp.nanosec  # sim time
        diags.extend((stamp, s) for s in array.status
                     if s.hardware_id == f'{ns}/attitude_simulator'
                     and s.name.endswith(': simulation'))
    subs = [node.create_subscription(DiagnosticArray, '/diagnostics', on_diagnostics, 10)]
    if observe:  # and /tf, which holds one message per spacecraft and sample
        from tf2_msgs.msg import TFMessage
        subs += [node.create_subscription(types[t], f'{ns}/sc_{i}/{t}', count, qos, raw=True)
                 for i in range(n) for t in TOPICS]
        subs.append(node.create_subscription(TFMessage, '/tf', count, qos, raw=True))
    with tempfile.NamedTemporaryFile('w', suffix='.yaml', delete=False) as f:
        f.write(scene_text(n))
    exe = os.path.join(sys.prefix, 'lib', 'rigid_body_sim', 'simulator')
    proc = subprocess.Popen([exe, '--ros-args', '-r', f'__ns:={ns}', '--params-file', f.name],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        # discovery: until every topic of every spacecraft has delivered (or 120 s)
        # messages per sample: each state topic of each spacecraft, and each one's /tf
        expected = n * (len(TOPICS) + 1) if observe else 0
        deadline, start = time.monotonic() + 120.0, time.monotonic()
        while time.monotonic() < deadline and (
                not diags or (observe and sum(s.get_publisher_count() for s in subs[1:])
                              < n * len(TOPICS) + 1)):
            rclpy.spin_once(node, timeout_sec=0.05)
        matched = time.monotonic() - start
        end = time.monotonic() + 2.0  # warm-up
        while time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        diags.clear()
        received[0] = 0
        cpu0, wall0 = _cpu_seconds(proc.pid), time.monotonic()
        while time.monotonic() < wall0 + seconds:
            rclpy.spin_once(node, timeout_sec=0.01)
        wall = time.monotonic() - wall0
        cpu = (_cpu_seconds(proc.pid) - cpu0) / wall
        values = [{kv.key: kv.value for kv in s.values} for _, s in diags]
        achieved = sorted(float(v['real_time_factor_achieved']) for v in values)
        # the simulator's own count, first to last diagnostics, per simulated second (the
        # stamps: this process's lag in taking the diagnostics does not enter)
        published = None
        if len(diags) >= 2 and observe:
            span = diags[-1][0] - diags[0][0]
            published = (int(values[-1]['messages_published'])
                         - int(values[0]['messages_published'])) / span / expected
        return {'spacecraft': n, 'cpu_percent_of_one_core': 100.0 * cpu,
                'published_per_topic_per_s': published,
                'achieved_real_time_factor': achieved[len(achieved) // 2] if achieved else None,
                'missed_deadlines': int(values[-1]['missed_deadlines']) - int(
                    values[0]['missed_deadlines']) if values else None,  # in the window
                'messages_per_topic_per_s': received[0] / wall / expected if expected else None,
                'discovery_s': matched, 'rss_mb': _rss_mb(proc.pid)}
    finally:
        stop(proc)
        os.unlink(f.name)
        for s in subs:
            node.destroy_subscription(s)
        node.destroy_node()


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--counts', type=int, nargs='+', default=[1, 10, 100],
                        help='numbers of spacecraft to measure')
    parser.add_argument('--seconds', type=float, default=10.0, help='wall seconds measured')
    parser.add_argument('--unobserved', action='store_true',
                        help='no subscriber: the simulator publishes nothing but diagnostics')
    parser.add_argument('--out', help='directory for fleet.json (e.g. docs/bench), which '
                        'the benchmarks page renders')
    args = parser.parse_args(argv)
    import rclpy
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(101, 200)))
    rclpy.init()
    try:
        observed = 'no subscribers' if args.unobserved else \
            f'{len(TOPICS)} topics and /tf each, all subscribed'
        print(f'spacecraft per simulator process at real time, {RATE:g} Hz, {observed}')
        rows = []
        for n in args.counts:
            r = measure(n, args.seconds, not args.unobserved)
            rows.append({'spacecraft': n, **r})
            rate, out = r['messages_per_topic_per_s'], r['published_per_topic_per_s']
            rtf = r['achieved_real_time_factor']
            print(f'  N = {n:4d}: CPU {r["cpu_percent_of_one_core"]:5.1f} % of one core, '
                  f'real-time factor {"-" if rtf is None else f"{rtf:.3f}"}, missed '
                  f'deadlines {r["missed_deadlines"]}, per topic '
                  f'{"-" if out is None else f"{out:.2f}"}/s published, '
                  f'{"-" if rate is None else f"{rate:.2f}"}/s received here, '
                  f'RSS {r["rss_mb"]:.0f} MB (discovery {r["discovery_s"]:.1f} s)', flush=True)
        if args.out:
            report({'command': command_line(__spec__, argv),
                    'rate_hz': RATE, 'observed': observed, 'seconds': args.seconds,
                    'rows': rows}, args.out, 'fleet.json')
    finally:
        rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
