"""Benchmark of the ``attitude_simulator`` node (real process, real DDS).

``python -m rigid_body_sim.tools.live_simulator [--integrator auto] [--subscribe]
[--subscriber raw|messages] [--seconds 6]``

Prints, for 1 kHz physics (step 1 ms) and 100 Hz publishing:
* µs per physics step of ``Propagator.step`` in-process (no ROS), torque-free and torqued;
* achieved real-time factor with ``real_time_factor: 0`` (from the node's diagnostics);
* CPU use of the node process at ``real_time_factor: 1`` in % of one core (/proc utime+stime).
``--subscribe`` adds a subscriber on every state topic (otherwise unobserved topics are
skipped by the node, as in a deployment where nobody listens to them); ``--subscriber``
says how it takes them (``SUBSCRIBERS``; by default serialized, as rosbag2 and the
recorder do), and the figures report the samples a second it took and its CPU.
``run(...)`` returns the figures as a dict for the bench command.
"""
from . import argument_parser, stop
import os
import random
import subprocess
import sys
import time

import numpy as np

STEP, PUBLISH_RATE = 0.001, 100.0


def step_cost_us(integrator: str, n: int = 3000) -> dict:
    from ..physics import Propagator, RigidBody
    body = RigidBody.from_inertia([1.0, 2.0, 3.0])
    out = {}
    for label, torque in (('free', None), ('torque', np.array([0.0, 0.0, 0.01]))):
        p = Propagator(body, angular_velocity=[0.05, 1.0, 0.0], integrator=integrator)
        p.step(STEP, torque)
        best = float('inf')
        for _ in range(3):
            t0 = time.perf_counter()
            for _ in range(n):
                p.step(STEP, torque)
            best = min(best, (time.perf_counter() - t0) / n * 1e6)
        out[label] = best
    return out


def _start(ns, integrator, rtf):
    exe = os.path.join(sys.prefix, 'lib', 'rigid_body_sim', 'simulator')
    cmd = [exe if os.path.exists(exe) else sys.executable, *([] if os.path.exists(exe) else
           ['-m', 'rigid_body_sim.nodes.simulator']),
           '--ros-args', '-r', f'__ns:={ns}', '-p', f'integrator:={integrator}',
           '-p', f'step:={STEP}', '-p', f'publish_rate:={PUBLISH_RATE}',
           '-p', f'real_time_factor:={rtf}']
    return subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)


def _rss_mb(pid):
    with open(f'/proc/{pid}/status') as f:
        return next(int(line.split()[1]) for line in f if line.startswith('VmRSS:')) / 1024.0


def _cpu_seconds(pid):
    with open(f'/proc/{pid}/stat') as f:
        fields = f.read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


STATE_TOPICS = ('attitude', 'pose', 'imu', 'transform', 'odometry', 'angular_velocity',
                'angular_momentum', 'angular_momentum_body', 'kinetic_energy')
SUBSCRIBERS = {
    # what the figures were measured with (docs/benchmarks.md says which)
    'raw': 'one reliable keep-all subscription a topic taking the serialized messages (as '
           'rosbag2 and our recorder do), on rclpy\'s events executor',
    'messages': 'one reliable depth-10 subscription a topic taking deserialized Python '
                'messages, on rclpy\'s events executor'}


def _subscribe_all(probe, ns, counts, subscriber, first):
    """A subscription on every state topic of the simulator in ``ns``, each counting the
    messages it takes into ``counts[topic]``; the first message's wall time into ``first``."""
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from ..nodes.state_messages import StateMessages
    raw = subscriber == 'raw'
    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE) \
        if raw else QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    types = {name: type(msg) for name, msg in StateMessages().topics()}
    subs = []
    for topic in STATE_TOPICS:
        counts[topic] = 0

        def take(_, topic=topic):
            counts[topic] += 1
            if not first:
                first.append(time.monotonic())
        subs.append(probe.create_subscription(types[topic], f'{ns}/{topic}', take, qos,
                                              raw=raw))
    return subs


def run(integrator='auto', subscribe=False, seconds=6.0, subscriber='raw') -> dict:
    import rclpy
    from rclpy.node import Node
    from diagnostic_msgs.msg import DiagnosticArray
    from ..nodes.process import events_executor
    from ..nodes.simulator import NODE_NAME
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(101, 200)))
    # Discovery as the environment has it (default SUBNET, multicast), as a user's graph
    # would: with ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST Fast DDS discovers by unicast, and
    # here one start in two then took 2.2-3.2 s to match although the node was publishing
    # after 0.7 s (0.66-0.74 s in 8 of 8 starts with SUBNET).
    result = {'integrator': integrator, 'step_s': STEP, 'publish_rate_hz': PUBLISH_RATE,
              'discovery_range': os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE', 'SUBNET'),
              'subscribers_on_all_topics': subscribe,
              'subscriber': SUBSCRIBERS[subscriber] if subscribe else None,
              'step_cost_us': {}}
    rclpy.init()
    probe = Node('simulator_bench')
    try:
        for rtf in (0.0, 1.0):
            ns = f'/bench_{os.getpid()}_{int(rtf)}'
            diags = []
            sub = probe.create_subscription(
                DiagnosticArray, '/diagnostics',
                lambda a: diags.extend(s for s in a.status
                                       if s.hardware_id == f'{ns}/{NODE_NAME}'),
                10)
            subs, first, counts = [], [], {}
            if subscribe:
                subs += _subscribe_all(probe, ns, counts, subscriber, first)
            else:  # only the first message's time
                from geometry_msgs.msg import QuaternionStamped
                subs.append(probe.create_subscription(
                    QuaternionStamped, f'{ns}/attitude',
                    lambda m: first or first.append(time.monotonic()), 10))
            started = time.monotonic()
            proc = _start(ns, integrator, rtf)
            try:
                with events_executor(probe) as executor:
                    def spin(until, done=lambda: False):
                        while time.monotonic() < until and not done():
                            executor.spin_once(timeout_sec=0.05)
                    spin(time.monotonic() + 20, lambda: bool(diags))
                    spin(time.monotonic() + 2.0)  # warm-up: discovery, integrator selection
                    diags.clear()
                    taken0 = dict(counts)
                    cpu0, wall0 = _cpu_seconds(proc.pid), time.monotonic()
                    own0 = _cpu_seconds(os.getpid())
                    spin(wall0 + seconds)
                    wall = time.monotonic() - wall0
                    own = (_cpu_seconds(os.getpid()) - own0) / wall
                    cpu = (_cpu_seconds(proc.pid) - cpu0) / wall
                    taken = {k: counts[k] - taken0[k] for k in counts}
                values = [{kv.key: kv.value for kv in s.values} for s in diags]
                achieved = [float(v['real_time_factor_achieved']) for v in values]
                key = 'rtf0' if rtf == 0 else 'rtf1'
                rtf_achieved = float(np.median(achieved)) if achieved else None
                waited = [float(v.get('acknowledgement_wait_s', 'nan')) for v in values]
                result[key] = {
                    'achieved_real_time_factor': rtf_achieved,
                    'cpu_percent_of_one_core': 100.0 * cpu,
                    # the node's CPU (all its threads) per sample published: the machine's
                    # load disturbs it less than the wall-clock figures
                    'cpu_us_per_sample': 1e6 * cpu / (rtf_achieved * PUBLISH_RATE)
                    if rtf_achieved else None,
                    # share of the wall time spent waiting for acknowledgements
                    'ack_wait_share': (waited[-1] - waited[0]) / seconds
                    if len(waited) > 1 else None,
                    'integrator_used': values[-1]['integrator'] if values else None,
                    'step_used_s': float(values[-1]['step']) if values else None,
                    'missed_deadlines': int(values[-1]['missed_deadlines']) if values else None,
                    'first_message_s': first[0] - started if first else None,
                    # the bench's subscriber: its process's CPU, and the samples a second it
                    # took on its slowest topic (all delivered: the node's rate)
                    'subscriber_cpu_percent_of_one_core': 100.0 * own,
                    'subscriber_samples_per_s': min(taken.values()) / wall if taken else None,
                    'rss_mb': _rss_mb(proc.pid)}
                if values:
                    result['step_cost_us'].setdefault(values[-1]['integrator'], None)
            finally:
                stop(proc)
                probe.destroy_subscription(sub)
                for s in subs:
                    probe.destroy_subscription(s)
    finally:
        probe.destroy_node()
        rclpy.try_shutdown()
    for name in set(result['step_cost_us']) | {'splitting2', 'exact'}:
        result['step_cost_us'][name] = step_cost_us(name)
    return result


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--integrator', default='auto')
    parser.add_argument('--subscribe', action='store_true', help='subscribe to every state topic')
    parser.add_argument('--subscriber', choices=sorted(SUBSCRIBERS), default='raw',
                        help='with --subscribe, how each topic is taken: ' + '; '.join(
                            f'{k}: {v}' for k, v in sorted(SUBSCRIBERS.items())))
    parser.add_argument('--seconds', type=float, default=6.0)
    args = parser.parse_args(argv)
    r = run(args.integrator, args.subscribe, args.seconds, args.subscriber)
    print(f'simulator benchmark: integrator {args.integrator}, step {STEP * 1e3:g} ms, '
          f'publish {PUBLISH_RATE:g} Hz, '
          f'subscribers on all topics: {r["subscriber"] if args.subscribe else "none"}')
    for key, label in (('rtf0', 'real_time_factor 0 (as fast as possible)'),
                       ('rtf1', 'real_time_factor 1')):
        v = r.get(key, {})
        rtf = v.get('achieved_real_time_factor')
        print(f'  {label}: achieved RTF {rtf if rtf is None else f"{rtf:.2f}"}, '
              f'CPU {v.get("cpu_percent_of_one_core", float("nan")):.1f} % of one core '
              f'({v.get("cpu_us_per_sample") or float("nan"):.0f} us a sample), '
              f'waiting for acks {100 * (v.get("ack_wait_share") or 0.0):.0f} % of the time, '
              f'integrator {v.get("integrator_used")} step {v.get("step_used_s")}, '
              f'missed deadlines {v.get("missed_deadlines")}; the subscriber took '
              f'{v.get("subscriber_samples_per_s") or 0:.0f} samples/s on its slowest topic '
              f'with {v.get("subscriber_cpu_percent_of_one_core", float("nan")):.1f} % of a '
              'core')
    for name, cost in r['step_cost_us'].items():
        print(f'  Propagator.step {name}: {cost["free"]:.1f} us torque-free, '
              f'{cost["torque"]:.1f} us with torque')
    import json
    fast, real = r.get('rtf0', {}), r.get('rtf1', {})
    cpu = real.get('cpu_percent_of_one_core')
    print(json.dumps({'real_time_factor': fast.get('achieved_real_time_factor'),
                      'cpu_us_per_sample': fast.get('cpu_us_per_sample'),
                      'cpu_share_at_real_time': None if cpu is None else cpu / 100.0,
                      'first_message_s': real.get('first_message_s'),
                      'rss_mb': real.get('rss_mb'), 'subscribed': args.subscribe,
                      'subscriber': r['subscriber'],
                      'subscriber_samples_per_s': fast.get('subscriber_samples_per_s'),
                      'subscriber_cpu_share': None if fast.get(
                          'subscriber_cpu_percent_of_one_core') is None else
                      fast['subscriber_cpu_percent_of_one_core'] / 100.0}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
