"""Recorder load test: N topics at R Hz for T s through a real recorder process.

    python -m rigid_body_sim.tools.recorder_load [--rate 1000] [--duration 60] [--kill]

starts ``recorder`` and a publisher process (3 topics of the simulator's types:
``attitude`` QuaternionStamped, ``odometry`` Odometry, ``kinetic_energy`` Float64), then
compares the bag's per-topic counts with what the publisher sent and prints messages/s
and loss. ``publish`` is also the deterministic test publisher: message ``i`` carries
``i`` in quaternion.w / pose.position.x / data, so readers can check field values.
"""
from __future__ import annotations

import argparse

from . import argument_parser
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from typing import Any

TOPICS = {'attitude': 'geometry_msgs/msg/QuaternionStamped',
          'odometry': 'nav_msgs/msg/Odometry',
          'kinetic_energy': 'std_msgs/msg/Float64'}


def make_message(topic: str, i: int, stamp_ns: int) -> Any:
    """Message number ``i`` of ``topic`` (its value encodes ``i``)."""
    from geometry_msgs.msg import QuaternionStamped
    from nav_msgs.msg import Odometry
    from std_msgs.msg import Float64
    if topic == 'kinetic_energy':
        return Float64(data=float(i))
    msg = QuaternionStamped() if topic == 'attitude' else Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    msg.header.frame_id = 'world'
    if topic == 'attitude':
        msg.quaternion.w = float(i)
    else:
        msg.child_frame_id = 'body'
        msg.pose.pose.position.x = float(i)
    return msg


def publish(args: argparse.Namespace) -> int:
    """Publish ``count`` messages per topic at ``rate`` Hz (sleep-paced), print counts."""
    import rclpy
    from rclpy.qos import QoSProfile

    from rigid_body_sim.bag.schema import message_class
    rclpy.init()
    node = rclpy.create_node('loadtest_publisher', namespace=args.namespace)
    topics = args.topics.split(',')
    pubs = {t: node.create_publisher(message_class(TOPICS[t]), t, QoSProfile(depth=args.depth))
            for t in topics}
    deadline = time.monotonic() + args.wait
    while time.monotonic() < deadline and \
            min(p.get_subscription_count() for p in pubs.values()) < args.subscribers:
        time.sleep(0.02)
    time.sleep(args.settle)  # let the subscriber side finish matching
    sent = dict.fromkeys(topics, 0)
    count = int(args.rate * args.duration)
    start = time.monotonic()
    for i in range(count):
        delay = start + i / args.rate - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        now = time.time_ns()
        for topic, pub in pubs.items():
            pub.publish(make_message(topic, i, now))
            sent[topic] += 1
    elapsed = time.monotonic() - start
    print(json.dumps({'sent': sent, 'elapsed': elapsed}), flush=True)
    time.sleep(args.linger)  # keep the writers alive for reliable retransmissions
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


def _exe(name: str) -> str:
    for path in (os.path.join(sys.prefix, 'lib', 'rigid_body_sim', name),
                 os.path.join(os.path.dirname(sys.executable), name)):
        if os.path.exists(path):
            return path
    raise FileNotFoundError(name)


def benchmark(args: argparse.Namespace) -> int:
    from rigid_body_sim.bag.reader import read_info
    from rigid_body_sim.bag.recover import recover
    workdir = tempfile.mkdtemp(prefix='rbs_loadtest_')
    ns = f'/loadtest_{os.getpid()}'
    bag = os.path.join(workdir, 'bag')
    topics = list(TOPICS)
    env = dict(os.environ, PYTHONUNBUFFERED='1')
    rec = subprocess.Popen([_exe('recorder'), '--ros-args', '-r', f'__ns:={ns}',
                            '-p', f'output:={bag}', '-p', f'topics:={json.dumps(topics)}',
                            '-p', f'flush_period:={args.flush_period}'],
                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                           env=env, start_new_session=True)
    cmd = [sys.executable, '-m', 'rigid_body_sim.tools.recorder_load', 'publish',
           '--namespace', ns,
           '--rate', str(args.rate), '--duration', str(args.duration),
           '--topics', ','.join(topics), '--linger', '1', '--depth', str(args.pub_depth)]
    if args.kill_after:
        # SIGKILL mid-stream: how much of the tail is lost (bounded by flush_period)?
        pub = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, env=env)
        time.sleep(args.kill_after)
        kill_ns = time.time_ns()
        os.killpg(rec.pid, signal.SIGKILL)
        rec.wait(timeout=30)
        pub.wait(timeout=args.duration + 60)
        recover(bag, bag + '_recovered')
        info = read_info(bag + '_recovered')
        lost_s = (kill_ns - info.end_ns) / 1e9
        print(f'SIGKILL at {args.kill_after:.1f} s (flush_period {args.flush_period} s): '
              f'recovered {info.message_count} messages; the recovered bag ends {lost_s:.3f} s '
              f'before the kill (~{lost_s * args.rate * len(topics):.0f} messages lost)')
        if not args.keep:
            shutil.rmtree(workdir, ignore_errors=True)
        return 0 if lost_s <= args.flush_period * 1.5 else 1
    pub = subprocess.run(cmd, capture_output=True, text=True, env=env)
    report = json.loads(pub.stdout.strip().splitlines()[-1])
    os.killpg(rec.pid, signal.SIGKILL if args.kill else signal.SIGINT)
    rec.wait(timeout=30)
    if args.kill:
        recover(bag, bag + '_recovered')
        bag += '_recovered'
    counts = {name.rsplit('/', 1)[-1]: t.count for name, t in read_info(bag).topics.items()}
    sent = report['sent']
    total_sent = sum(sent.values())
    total_got = sum(counts.get(t, 0) for t in sent)
    print(f'published {total_sent} messages in {report["elapsed"]:.2f} s '
          f'({total_sent / report["elapsed"]:.0f} msg/s over {len(sent)} topics)')
    for topic in sent:
        print(f'  {topic}: sent {sent[topic]}, recorded {counts.get(topic, 0)}, '
              f'lost {sent[topic] - counts.get(topic, 0)}')
    print(f'recorded {total_got} ({total_got / report["elapsed"]:.0f} msg/s), '
          f'lost {total_sent - total_got}' + (' after SIGKILL + recover' if args.kill else ''))
    if total_got < total_sent:
        print('  gaps (kinetic_energy message numbers): ' + _gaps(bag))
    if not args.keep:
        shutil.rmtree(workdir, ignore_errors=True)
    else:
        print(f'bag kept in {bag}')
    return 0 if args.kill or total_sent == total_got else 1


def _gaps(bag: str) -> str:
    """Missing message numbers as ranges with their time into the run (loss diagnosis)."""
    from rclpy.serialization import deserialize_message
    from std_msgs.msg import Float64

    from rigid_body_sim.bag.reader import iter_messages
    msgs = [m for m in iter_messages(bag) if m.topic.endswith('/kinetic_energy')]
    values = [int(deserialize_message(m.data, Float64).data) for m in msgs]
    gaps = [f'{a + 1}..{b - 1} at {(m.log_time_ns - msgs[0].log_time_ns) / 1e9:.2f} s'
            for a, b, m in zip(values, values[1:], msgs[1:]) if b != a + 1]
    return ', '.join(gaps) or 'none inside (lost at the end)'


def main(argv: list[str] | None = None) -> int:
    parser = argument_parser(__spec__, __doc__)
    sub = parser.add_subparsers(dest='cmd')
    pub = sub.add_parser('publish', help='the load/test publisher')
    pub.add_argument('--namespace', default='/')
    pub.add_argument('--topics', default=','.join(TOPICS))
    pub.add_argument('--rate', type=float, default=1000.0)
    pub.add_argument('--duration', type=float, default=5.0)
    pub.add_argument('--depth', type=int, default=10, help='publisher QoS depth')
    pub.add_argument('--wait', type=float, default=20.0, help='max s to wait for subscribers')
    pub.add_argument('--subscribers', type=int, default=1)
    pub.add_argument('--settle', type=float, default=0.5)
    pub.add_argument('--linger', type=float, default=1.0)
    for p in (parser,):
        p.add_argument('--rate', type=float, default=1000.0, help='Hz per topic')
        p.add_argument('--duration', type=float, default=60.0, help='seconds')
        p.add_argument('--flush-period', type=float, default=1.0)
        p.add_argument('--kill', action='store_true', help='SIGKILL the recorder, then recover')
        p.add_argument('--kill-after', type=float, default=0.0, metavar='S',
                       help='SIGKILL the recorder S s after start, recover, report the loss')
        p.add_argument('--pub-depth', type=int, default=10, help='publisher QoS depth')
        p.add_argument('--keep', action='store_true', help='keep the bag')
    args = parser.parse_args(argv)
    try:
        return publish(args) if args.cmd == 'publish' else benchmark(args)
    except KeyboardInterrupt:
        return 130
    except Exception as exc:  # a benchmark: one line, no traceback
        print(f'error: {type(exc).__name__}: {exc}', file=sys.stderr)
        return 1


if __name__ == '__main__':
    sys.exit(main())
