"""A topic nobody subscribes to costs nothing (issue 29): the live simulator builds and
publishes only the state topics that have subscribers, and a subscriber that joins later
gets messages. Real simulator, real messages; observed through the per-topic
``messages_built.<topic>`` counters in its diagnostics, not through timing."""
from geometry_msgs.msg import QuaternionStamped
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy

from ros_helpers import venv_exe
from test_simulator import Probe, start_simulator


def test_unsubscribed_topics_are_not_built_and_a_late_subscriber_gets_messages(
        ros_process, namespace, rclpy_node):
    start_simulator(ros_process, namespace, publish_rate=50.0)
    probe = Probe(rclpy_node, namespace)
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    attitude, odometry = [], []
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude',
                                   attitude.append, qos)

    def built(d, topic):
        return int(d.get(f'messages_built.{topic}', -1))
    probe.wait_diag(lambda d, s: built(d, 'attitude') >= 50, 60.0,
                    'a second of attitude messages built')
    # built is not yet received on a loaded machine: wait for delivery, don't assume it
    probe.wait_for(lambda: len(attitude) > 10, 30.0, 'attitude messages received')
    d = probe.diag()
    # before, every topic was built for every sample as soon as one had a subscriber
    for topic in ('odometry', 'pose', 'imu', 'angular_momentum', 'kinetic_energy'):
        assert built(d, topic) == 0, (topic, d)
    rclpy_node.create_subscription(Odometry, f'{namespace}/odometry', odometry.append, qos)
    probe.wait_for(lambda: len(odometry) >= 20, 60.0, 'odometry for the late subscriber')
    probe.wait_diag(lambda d, s: built(d, 'odometry') >= 20, 30.0, 'odometry built')
    assert built(probe.diag(), 'pose') == 0
    last = odometry[-1].header.stamp  # one sample's topics share its stamp
    probe.wait_for(lambda: any(m.header.stamp == last for m in attitude), 30.0,
                   'the late subscriber\'s sample on attitude too')


def test_orbit_topics_nobody_subscribes_to_are_not_published(ros_process, namespace,
                                                             rclpy_node, tmp_path):
    """The gravity-gradient scene publishes its orbit topics (orbit, environment_torque,
    the orbit frame on /tf) only once someone subscribes. Before, the node filled and
    published all three at every sample, for nobody."""
    import os
    from geometry_msgs.msg import WrenchStamped
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    endless = tmp_path / 'endless.yaml'  # the scene's own section wins over -p
    endless.write_text('/**/attitude_simulator:\n  ros__parameters:\n    duration: 0.0\n')
    ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                '--params-file', os.path.join(repo, 'config', 'gravity_gradient.yaml'),
                '--params-file', str(endless), cwd=repo)
    probe = Probe(rclpy_node, namespace)
    attitude, torque = [], []
    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude',
                                   attitude.append, qos)
    probe.wait_for(lambda: len(attitude) > 20, 120.0, 'attitude messages received')
    seen = len(attitude)  # fixed: the subscription goes on receiving while we wait
    probe.wait_diag(lambda d, s: int(d.get('messages_built.attitude', 0)) > seen,
                    30.0, 'diagnostics after those messages')
    assert int(probe.diag()['orbit_messages_published']) == 0, probe.diag()
    rclpy_node.create_subscription(WrenchStamped, f'{namespace}/environment_torque',
                                   torque.append, qos)
    probe.wait_for(lambda: len(torque) >= 10, 60.0, 'environment_torque for a subscriber')
    probe.wait_diag(lambda d, s: int(d['orbit_messages_published']) >= 10, 30.0,
                    'orbit messages counted')
