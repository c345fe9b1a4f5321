"""Live floor: the most samples a second rclpy and Fast DDS deliver on the nine state topics.

``python -m rigid_body_sim.tools.live_floor [--seconds 6] [--runs 3]``

The simulator as fast as possible (``tools.live_simulator --subscribe``) with everything
of ours taken out: a bare rclpy process publishes the nine state topics of one sample as
CDR bytes made once (no physics, no message building, no /clock), with the node's QoS,
acknowledgement cadence (``sim_acks``: keep-all, a wait every KEEP_ALL_WINDOW messages a
topic) and order (blocks of LIVE_BLOCK samples, topic by topic), as fast as it can. The
same subscriber as the live bench's takes every message
(``live_simulator.SUBSCRIBERS['raw']``). What it takes a second, divided by the node's
100 Hz, is the real-time factor no node publishing these topics this way can pass on this
machine under its present load. Prints one JSON line per run, then a summary line.
"""
import json
import os
import random
import statistics
import subprocess
import sys
import time

from . import argument_parser, stop
from .live_simulator import PUBLISH_RATE, SUBSCRIBERS, _cpu_seconds, _subscribe_all


def publish(ns: str) -> None:
    """The publishing process: the nine topics, paced as the node is, until stopped."""
    import rclpy
    from rclpy.node import Node
    from ..engine import SampleBlock
    from ..nodes.process import prefer_asynchronous_publication
    from ..nodes.simulator import LIVE_BLOCK
    from ..nodes.sim_acks import Acknowledgements, paced_qos
    from ..nodes.state_messages import StateMessages
    from ..physics.body import RigidBody
    import numpy as np
    prefer_asynchronous_publication()  # as the nodes do (process.py)
    rclpy.init()
    node = Node('live_floor', namespace=ns)
    msgs = StateMessages()
    block = SampleBlock(np.zeros(1, dtype=np.int64), np.array([[0.0, 0.0, 0.0, 1.0]]),
                        np.array([[0.1, 1.0, 0.2]]), np.zeros((1, 3)),
                        RigidBody.from_inertia([1.0, 2.0, 3.0]))
    data = msgs.encoded(block, 0, 0)
    pubs = [(node.create_publisher(type(m), name, paced_qos('reliable')), data[name])
            for name, m in msgs.topics()]
    acks = Acknowledgements(lambda: [p for p, _ in pubs], node.get_logger(), True)
    sends = [(p.handle.publish_raw, d) for p, d in pubs]
    try:
        while rclpy.ok():
            if any(p.get_subscription_count() == 0 for p, _ in pubs):
                time.sleep(0.05)  # the node publishes only what is subscribed
                continue
            for send, d in sends:  # a block topic by topic, as the node sends it
                for _ in range(LIVE_BLOCK):
                    send(d)
            for _ in range(LIVE_BLOCK):
                acks.published()
    except KeyboardInterrupt:
        pass
    except Exception:  # noqa: BLE001 - a publish after Ctrl-C shut the context down
        if rclpy.ok():
            raise
    finally:
        rclpy.try_shutdown()


def run_once(seconds: float) -> dict:
    """One publishing process, measured ``seconds`` after a 2 s warm-up."""
    import rclpy
    from rclpy.node import Node
    from ..nodes.process import events_executor
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.randint(101, 200)))
    ns = f'/floor_{os.getpid()}_{random.randrange(1 << 30)}'
    rclpy.init()
    probe = Node('live_floor_probe')
    counts, first = {}, []
    subs = _subscribe_all(probe, ns, counts, 'raw', first)
    proc = subprocess.Popen([sys.executable, '-m', __spec__.name, '--publisher', ns],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        with events_executor(probe) as executor:
            def spin(until, done=lambda: False):
                while time.monotonic() < until and not done():
                    executor.spin_once(timeout_sec=0.05)
            spin(time.monotonic() + 30, lambda: bool(first))
            spin(time.monotonic() + 2.0)
            taken0, wall0 = dict(counts), time.monotonic()
            cpu0, own0 = _cpu_seconds(proc.pid), _cpu_seconds(os.getpid())
            spin(wall0 + seconds)
            wall = time.monotonic() - wall0
            cpu = (_cpu_seconds(proc.pid) - cpu0) / wall
            own = (_cpu_seconds(os.getpid()) - own0) / wall
            taken = min(counts[k] - taken0[k] for k in counts) / wall
    finally:
        stop(proc)
        for s in subs:
            probe.destroy_subscription(s)
        probe.destroy_node()
        rclpy.try_shutdown()
    return {'samples_per_s': taken, 'real_time_factor': taken / PUBLISH_RATE,
            'publisher_cpu_share': cpu, 'publisher_cpu_us_per_sample':
            1e6 * cpu / taken if taken else None, 'subscriber_cpu_share': own}


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--seconds', type=float, default=6.0)
    parser.add_argument('--runs', type=int, default=3)
    parser.add_argument('--publisher', metavar='NS', help=argparse_hidden())
    args = parser.parse_args(argv)
    if args.publisher:
        publish(args.publisher)
        return 0
    runs = []
    for _ in range(args.runs):
        # each run in its own process: rclpy is initialised once a process
        out = subprocess.run([sys.executable, '-c', f'import json; from {__spec__.name} '
                              f'import run_once; print(json.dumps(run_once({args.seconds})))'],
                             capture_output=True, text=True, timeout=120 + args.seconds)
        line = out.stdout.strip().splitlines()[-1] if out.stdout.strip() else ''
        if out.returncode != 0 or not line:
            print(f'run failed: {out.stderr.strip()[-300:]}', file=sys.stderr)
            return 1
        runs.append(json.loads(line))
        print(line, flush=True)
    rtf = [r['real_time_factor'] for r in runs]
    print(json.dumps({'floor_real_time_factor_runs': rtf,
                      'floor_real_time_factor_median': statistics.median(rtf),
                      'subscriber': SUBSCRIBERS['raw'], 'load': os.getloadavg()[0]}))
    return 0


def argparse_hidden():
    import argparse
    return argparse.SUPPRESS


if __name__ == '__main__':
    sys.exit(main())
