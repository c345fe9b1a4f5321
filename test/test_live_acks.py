"""As fast as possible, the simulator waits for its readers' acknowledgements once per
KEEP_ALL_WINDOW messages a topic, not every 50 samples, and none of them loses a sample
(issue 29, ``nodes/sim_acks.py``). Real simulator process, real messages; the waits are
counted by the node, not timed."""
import math
import re

from tf2_msgs.msg import TFMessage
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from rigid_body_sim.nodes.sim_acks import KEEP_ALL_WINDOW
from test_simulator import IMU_TOPICS, start_simulator
from ros_helpers import spin_until

PERIOD_NS = 10_000_000  # publish_rate 100 Hz
# 2,001 samples: four windows and the end's wait (the old every-50-samples pacing: 41
# waits). 40 s (4,001 samples) cost this test's process twice the ~40,000 messages it
# takes in Python, for the same assertions (issue 32)
DURATION_S = 20.0


def test_as_fast_as_possible_waits_once_a_window_and_every_topic_gets_every_sample(
        ros_process, namespace, rclpy_node):
    """Every state topic subscribed (keep-all, reliable), 2,001 samples as fast as
    possible: each topic receives all of them from t = 0, and the node waited for
    acknowledgements once per KEEP_ALL_WINDOW samples and once at the end. Before, it
    stopped every 50 samples (41 waits here), each a heartbeat round trip of
    milliseconds: three quarters of the run's wall time."""
    assert KEEP_ALL_WINDOW >= 500
    got = {topic: [] for topic in IMU_TOPICS}
    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE)

    def stamp(m):  # kinetic_energy (std_msgs/Float64) has no header: its count is checked
        return m.header.stamp.sec * 10 ** 9 + m.header.stamp.nanosec \
            if hasattr(m, 'header') else None
    for topic, msg_type in IMU_TOPICS.items():
        rclpy_node.create_subscription(msg_type, f'{namespace}/{topic}',
                                       lambda m, out=got[topic]: out.append(stamp(m)), qos)
    # /tf too: wait_for_subscribers holds t = 0 for every state topic's subscriber
    got['/tf'] = []
    rclpy_node.create_subscription(TFMessage, '/tf', lambda m: got['/tf'].append(
        stamp(m.transforms[0])), qos)
    sim = start_simulator(ros_process, namespace, real_time_factor=0.0, publish_clock=True,
                          publish_rate=100.0, duration=DURATION_S, wait_for_subscribers=1)
    samples = round(DURATION_S * 1e9 / PERIOD_NS) + 1
    assert spin_until(rclpy_node, lambda: sim.poll() is not None and all(
        len(v) >= samples for v in got.values()), 180.0), (
        {t: len(v) for t, v in got.items()}, sim.output()[-3000:])
    assert sim.wait(30) == 0, sim.output()[-3000:]
    expected = [k * PERIOD_NS for k in range(samples)]
    for topic, stamps in got.items():
        assert len(stamps) == samples, (topic, len(stamps))
        if stamps[0] is not None:
            assert stamps == expected, (topic, stamps[:3], stamps[-3:])
    found = re.search(r'(\d+) waits for acknowledgements.*?(\d+) messages not sent',
                      sim.output())
    assert found, sim.output()[-3000:]
    waits, not_sent = int(found.group(1)), int(found.group(2))
    assert 1 <= waits <= math.ceil(samples / KEEP_ALL_WINDOW) + 1 and not_sent == 0, \
        found.group(0)


SUBSCRIBER = r'''
import sys, rclpy
from geometry_msgs.msg import QuaternionStamped
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
rclpy.init()
node = rclpy.create_node('stalled_reader')
first = []
def got(m):
    if not first:
        first.append(m)
        print('first message', flush=True)
node.create_subscription(QuaternionStamped, sys.argv[1] + '/attitude', got, QoSProfile(
    history=HistoryPolicy.KEEP_ALL, depth=1, reliability=ReliabilityPolicy.RELIABLE))
print('subscribed', flush=True)
rclpy.spin(node)
'''


def test_a_stopped_reliable_subscriber_holds_no_run_and_kills_no_node(ros_process, namespace):
    """A keep-all subscriber whose process is stopped (SIGSTOP) mid-run acknowledges
    nothing: the paced history fills, the waits time out and then publishes on its topic
    are refused. The simulator counts and warns, reaches its duration and exits 0 (a
    refused publish raised RCLError out of the loop with a keep-all history unhandled)."""
    import signal
    import sys
    from ros_helpers import wait_output
    reader = ros_process(sys.executable, '-c', SUBSCRIBER, namespace)
    assert wait_output(reader, 'subscribed', 120), reader.output()[-3000:]
    # t = 0 held until attitude's reader is matched (the other topics have none: 5 s)
    sim = start_simulator(ros_process, namespace, real_time_factor=0.0, publish_clock=True,
                          publish_rate=100.0, duration=80.0, wait_for_subscribers=1,
                          wait_for_subscribers_timeout=5.0)
    try:
        assert wait_output(reader, 'first message', 120), reader.output()[-3000:]
        reader.signal(signal.SIGSTOP)
        assert sim.wait(240) == 0, sim.output()[-3000:]
    finally:
        reader.signal(signal.SIGCONT)
    out = sim.output()
    assert 'Traceback' not in out and 'duration 80 s reached' in out, out[-3000:]
    assert f'{namespace}/attitude' in out and 'acknowledge' in out, out[-3000:]
    assert re.search(r'\d+ waits for acknowledgements', out), out[-3000:]
