"""Flood a simulator with torque commands: valid ones and each kind of garbage, at a rate.

    python -m rigid_body_sim.tools.flood NAMESPACE [--rate HZ] [--duration S]

Publishes ``rate`` valid commands per second and ``rate`` garbage commands per second
(NaN, a wrong frame, a stamp in the future, a stale stamp, in turn) on
NAMESPACE/torque_command, then prints one JSON line with what it sent per class. The
test suite floods for a few seconds; soak runs flood for longer.
"""
from . import argument_parser
import json
import math
import sys
import time

CLASSES = ('valid', 'non_finite', 'wrong_frame', 'future_stamp', 'stale_stamp')


def main(argv=None) -> int:
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('namespace')
    parser.add_argument('--rate', type=float, default=10_000.0, help='valid commands per s, '
                        'and as many garbage ones')
    parser.add_argument('--duration', type=float, default=30.0, help='seconds')
    args = parser.parse_args(argv)
    import rclpy
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.qos import QoSProfile
    rclpy.init()
    node = rclpy.create_node('flood')
    # the simulator's command QoS (reliable, keep last 10): a slow reader loses the oldest
    pub = node.create_publisher(Vector3Stamped, f'{args.namespace}/torque_command',
                                QoSProfile(depth=10))
    deadline = time.monotonic() + 30.0
    while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    msgs = {c: Vector3Stamped() for c in CLASSES}
    for c, m in msgs.items():
        m.header.frame_id = 'wrong_frame' if c == 'wrong_frame' else 'base_link'
        m.vector.z = math.nan if c == 'non_finite' else 1e-3
    msgs['future_stamp'].header.stamp.sec = 2_100_000_000   # years ahead (int32 seconds)
    msgs['stale_stamp'].header.stamp.sec = 1                   # far behind
    sent = dict.fromkeys(CLASSES, 0)
    garbage = CLASSES[1:]
    period = 1.0 / args.rate
    start = time.monotonic()
    k = 0
    try:
        while time.monotonic() - start < args.duration:
            pub.publish(msgs['valid'])
            sent['valid'] += 1
            bad = garbage[k % len(garbage)]
            pub.publish(msgs[bad])
            sent[bad] += 1
            k += 1
            lag = start + k * period - time.monotonic()
            if lag > 0:
                time.sleep(lag)
    except KeyboardInterrupt:
        pass
    elapsed = time.monotonic() - start
    print(json.dumps({'sent': sent, 'seconds': elapsed,
                      'rate_achieved': sent['valid'] / elapsed}), flush=True)
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == '__main__':
    sys.exit(main())
