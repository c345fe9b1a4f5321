"""mcap_recorder with real nodes: live recording, three readers, signals, crash recovery."""
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import yaml
from ros_helpers import spin_until, venv_exe

from rigid_body_sim.bag.reader import is_finished, read_info
from rigid_body_sim.bag.schema import parse_qos_yaml

TOPICS = {'attitude': 'geometry_msgs/msg/QuaternionStamped', 'odometry': 'nav_msgs/msg/Odometry',
          'kinetic_energy': 'std_msgs/msg/Float64'}


def start_recorder(ros_process, namespace, output, *params):
    args = [venv_exe('recorder'), '--ros-args', '-r', f'__ns:={namespace}',
            '-p', f'output:={output}']
    for p in params:
        args += ['-p', p]
    return ros_process(*args, env={'PYTHONUNBUFFERED': '1'})


def start_publisher(ros_process, namespace, rate, duration, subscribers=1, topics=TOPICS,
                    linger=1.0, depth=10):
    return ros_process(sys.executable, '-m', 'rigid_body_sim.tools.recorder_load', 'publish',
                       '--namespace', namespace, '--rate', str(rate), '--duration',
                       str(duration), '--subscribers', str(subscribers),
                       '--topics', ','.join(topics), '--linger', str(linger),
                       '--depth', str(depth))


def sent_counts(proc, timeout=60):
    assert proc.wait(timeout) == 0, proc.output()
    return json.loads(proc.output().strip().splitlines()[-1])['sent']


def wait_output(proc, text, timeout=20.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if text in proc.output():
            return True
        assert proc.poll() is None, proc.output()
        time.sleep(0.05)
    raise AssertionError(f'{text!r} not in output:\n{proc.output()}')


def spinner(node):
    from rclpy.executors import SingleThreadedExecutor
    executor = SingleThreadedExecutor(context=node.context)
    executor.add_node(node)
    return executor


def rosbags_values(path, namespace):
    """{topic: [value i, ...]} via rosbags AnyReader + Jazzy typestore."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    out = {}
    with AnyReader([Path(path)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        for conn, _, raw in r.messages(connections=r.connections):
            out.setdefault(conn.topic[len(namespace) + 1:], []).append(
                _value(conn.topic.rsplit('/', 1)[-1], r.deserialize(raw, conn.msgtype)))
    return out


def _value(topic, msg):
    return {'attitude': lambda: msg.quaternion.w, 'odometry': lambda: msg.pose.pose.position.x,
            'kinetic_energy': lambda: msg.data}[topic]()


def test_record_live_three_readers(ros_process, namespace, rclpy_node, tmp_path):
    """Live recording read back by mcap, mcap-ros2-support and rosbags == what a subscriber saw."""
    from rclpy.qos import QoSProfile
    from rclpy.serialization import deserialize_message

    from rigid_body_sim.bag.schema import message_class
    bag = tmp_path / 'live'
    rec = start_recorder(ros_process, namespace, bag, 'flush_period:=0.2')
    seen = {t: [] for t in TOPICS}
    for topic in TOPICS:
        rclpy_node.create_subscription(message_class(TOPICS[topic]), f'{namespace}/{topic}',
                                       lambda raw, t=topic: seen[t].append(raw),
                                       QoSProfile(depth=1000), raw=True)
    # depth 1000: reliable delivery survives scheduling stalls on a loaded machine (README)
    pub = start_publisher(ros_process, namespace, rate=200, duration=2, subscribers=2,
                          depth=1000)
    assert spin_until(rclpy_node, lambda: all(len(v) == 400 for v in seen.values()), 30,
                      spinner(rclpy_node))
    sent = sent_counts(pub)
    assert rec.stop() == 0, rec.output()
    assert sent == {t: 400 for t in TOPICS}
    mcap_file = bag / 'live_0.mcap'
    assert is_finished(str(mcap_file))

    expected = {t: [_value(t, deserialize_message(raw, message_class(TOPICS[t])))
                    for raw in seen[t]] for t in TOPICS}
    assert expected['attitude'] == [float(i) for i in range(400)]

    from mcap.reader import make_reader
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        stored = {}
        for schema, channel, message in reader.iter_messages():
            stored.setdefault(channel.topic.rsplit('/', 1)[-1], []).append(message.data)
            assert schema.encoding == 'ros2msg' and channel.message_encoding == 'cdr'
            assert message.publish_time <= message.log_time
        qos = parse_qos_yaml(channel.metadata['offered_qos_profiles'])
        # DDS discovery does not carry history/depth: rosbag2 stores unknown/0 as well.
        assert qos[0]['reliability'] == 'reliable' and qos[0]['durability'] == 'volatile'
    assert stored == seen   # byte-identical CDR, same order

    from mcap_ros2.reader import read_ros2_messages
    decoded = {}
    for m in read_ros2_messages(str(mcap_file)):
        topic = m.channel.topic.rsplit('/', 1)[-1]
        decoded.setdefault(topic, []).append(_value(topic, m.ros_msg))
    assert decoded == expected
    assert rosbags_values(bag, namespace) == expected

    info = read_info(str(bag))
    assert info.run_configuration['recorder']['flush_period'] == 0.2
    assert info.run_configuration['package_version']


def test_sigterm_finishes_file(ros_process, namespace, tmp_path):
    bag = tmp_path / 'term'
    rec = start_recorder(ros_process, namespace, bag)
    sent = sent_counts(start_publisher(ros_process, namespace, rate=300, duration=1.5))
    rec.signal(signal.SIGTERM)
    assert rec.wait(15) == 0, rec.output()
    assert is_finished(str(bag / 'term_0.mcap'))
    assert yaml.safe_load((bag / 'metadata.yaml').read_text())
    got = {name.rsplit('/', 1)[-1]: t.count for name, t in read_info(str(bag)).topics.items()}
    assert got == sent


def test_sigkill_then_recover(ros_process, namespace, rclpy_node, tmp_path):
    """SIGKILL mid-stream: everything up to the last flush survives `bag recover`."""
    from rclpy.qos import QoSProfile
    from std_msgs.msg import Float64

    from rigid_body_sim.bag.schema import message_class
    bag = tmp_path / 'killed'
    flush = 0.3
    rec = start_recorder(ros_process, namespace, bag, f'flush_period:={flush}')
    seen = []
    counts = {topic: 0 for topic in TOPICS}

    def count(topic):
        def on_message(_):
            counts[topic] += 1
        return on_message
    rclpy_node.create_subscription(Float64, f'{namespace}/kinetic_energy',
                                   lambda m: seen.append(m.data), QoSProfile(depth=1000))
    for topic in ('attitude', 'odometry'):  # the publisher waits for 2 subscribers on each
        rclpy_node.create_subscription(message_class(TOPICS[topic]), f'{namespace}/{topic}',
                                       count(topic), QoSProfile(depth=1000), raw=True)
    # depth 1000, as the README advises for high-rate publishers: with 10, a recorder
    # stalled by a loaded machine for 20 ms loses messages before any SIGKILL
    start_publisher(ros_process, namespace, rate=500, duration=4, subscribers=2, depth=1000)
    assert spin_until(rclpy_node, lambda: len(seen) >= 1000, 30, spinner(rclpy_node))
    snapshot = tmp_path / 'snapshot' / 'killed'  # what was on disk a moment before the kill
    shutil.copytree(bag, snapshot)
    rec.signal(signal.SIGKILL)
    counts['kinetic_energy'] = len(seen)
    received = dict(counts)
    rec.wait(10)
    assert not is_finished(str(bag / 'killed_0.mcap'))

    # A new recorder beside it points at the unfinished file.
    rec2 = start_recorder(ros_process, namespace, tmp_path / 'next', 'topics:=["nothing"]')
    wait_output(rec2, 'rigid-body-sim bag recover')
    assert f'rigid-body-sim bag recover {bag} ' in rec2.output()

    # the hint is a command that works as printed (PATH without the venv's bin, as here)
    hint = next(line for line in rec2.output().splitlines() if 'bag recover' in line)
    command = hint[hint.index('recover it with: ') + len('recover it with: '):].split()
    command[-1] = str(tmp_path / 'fixed')
    res = subprocess.run(command, capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    values = rosbags_values(tmp_path / 'fixed', namespace)
    assert sorted(values) == sorted(TOPICS)
    # What the periodic flushes had put on disk before the kill (the snapshot, recovered the
    # same way): 1000 messages took 2 s at 500 Hz, several flush periods, and the chunks
    # (768 KiB) were far from full, so only the flush timer wrote them.
    res = subprocess.run(command[:-2] + [str(snapshot), str(tmp_path / 'fixed_snapshot')],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    before = rosbags_values(tmp_path / 'fixed_snapshot', namespace)
    # Each topic: a gap-free prefix (the publisher writes i into each message) holding all
    # that was flushed before the kill. Not compared with what this test's subscriber had
    # received: under load the recorder's executor can be a second or more behind when the
    # kill lands (665 messages once, load ~10), and what it had not taken was never its own.
    for topic, got in values.items():
        assert got == [float(i) for i in range(len(got))], topic
        assert 0 < len(before.get(topic, [])) <= len(got), (topic, len(before.get(topic, [])),
                                                            len(got), received)

    # Once recovered, a recorder starting beside it no longer warns (the file is untouched)
    assert rec2.stop() == 0, rec2.output()
    assert not is_finished(str(bag / 'killed_0.mcap'))
    rec3 = start_recorder(ros_process, namespace, tmp_path / 'third', 'topics:=["nothing"]')
    wait_output(rec3, 'recording to')
    assert 'unfinished bag file' not in rec3.output().replace(
        f'unfinished bag file {bag / "killed_0.mcap"} was recovered into', ''), rec3.output()
    assert f'was recovered into {tmp_path / "fixed"}' in rec3.output(), rec3.output()


def test_split_and_metadata(ros_process, namespace, tmp_path):
    bag = tmp_path / 'split'
    rec = start_recorder(ros_process, namespace, bag, 'max_bag_duration:=1.0')
    sent = sent_counts(start_publisher(ros_process, namespace, rate=100, duration=3.5))
    assert rec.stop() == 0, rec.output()
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    files = meta['relative_file_paths']
    assert files[:4] == [f'split_{i}.mcap' for i in range(4)]
    info = read_info(str(bag))
    assert meta['message_count'] == info.message_count == sum(sent.values())
    for entry, f in zip(meta['files'], info.files):
        assert os.path.join(bag, entry['path']) == f.path and is_finished(f.path)
        assert entry['message_count'] == f.count
        assert entry['duration']['nanoseconds'] == f.end_ns - f.start_ns < 10**9
    assert meta['starting_time']['nanoseconds_since_epoch'] == info.start_ns
    assert meta['duration']['nanoseconds'] == info.end_ns - info.start_ns
    counts = {t['topic_metadata']['name'].rsplit('/', 1)[-1]: t['message_count']
              for t in meta['topics_with_message_count']}
    assert counts == sent


def test_load_3_topics_1khz_no_loss(ros_process, namespace, tmp_path):
    """Short version of `python -m rigid_body_sim.tools.recorder_load` (60 s): 3 x 1 kHz x 5 s.

    The publisher keeps 1000 samples so reliable QoS can repair a scheduling stall of the
    recorder process (shared CI machine); with depth 10 a stall > 10 ms loses a burst
    that no subscriber can get back.
    """
    bag = tmp_path / 'load'
    rec = start_recorder(ros_process, namespace, bag)
    sent = sent_counts(start_publisher(ros_process, namespace, rate=1000, duration=5,
                                       depth=1000))
    assert rec.stop() == 0, rec.output()
    got = {name.rsplit('/', 1)[-1]: t.count for name, t in read_info(str(bag)).topics.items()}
    assert sent == {t: 5000 for t in TOPICS}
    assert got == sent


def test_all_follows_discovery_and_run_configuration(ros_process, namespace, tmp_path):
    """`all:=true` picks up topics that appear later; simulator parameters are stored."""
    bag = tmp_path / 'all'
    fake_sim = ros_process(sys.executable, '-c', (
        'import rclpy; from rclpy.node import Node; rclpy.init(); '
        f'n = Node("attitude_simulator", namespace="{namespace}"); '
        'n.declare_parameter("scene.name", "tumbling_box"); '
        'n.declare_parameter("integrator", "rk4");'
        'n.declare_parameter("dt", 0.005); rclpy.spin(n)'))
    rec = start_recorder(ros_process, namespace, bag, 'all:=true')
    wait_output(rec, 'stored the run configuration')
    time.sleep(1.0)
    sent = sent_counts(start_publisher(ros_process, namespace, rate=100, duration=1,
                                       topics=['kinetic_energy']))
    assert rec.stop() == 0, rec.output()
    fake_sim.stop()
    info = read_info(str(bag))
    assert info.topics[f'{namespace}/kinetic_energy'].count == sent['kinetic_energy'] == 100
    config = info.run_configuration
    assert config['scene'] == 'tumbling_box' and config['integrator'] == 'rk4'
    assert config['simulator_parameters']['dt'] == 0.005 and config['mode'] == 'live'


def test_records_the_simulators_scene_and_its_hash(ros_process, namespace, tmp_path):
    """The real simulator started with a scene file, outside the demo: the bag's run record
    names the scene and holds the file's SHA-256, as an offline run's record does."""
    from rigid_body_sim.scene import content_sha256, resolve
    scene = resolve('tennis_racket')
    bag = tmp_path / 'sim'
    rec = start_recorder(ros_process, namespace, bag, 'config_timeout:=120.0')
    wait_output(rec, f'subscribed to {namespace}/attitude', timeout=30)  # at its start
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '--params-file', scene, '-p', 'wait_for_subscribers:=1',
                      env={'PYTHONUNBUFFERED': '1'})
    # matched before t = 0, so whatever it publishes from then on reaches the recorder
    wait_output(sim, 'starting at t = 0', timeout=60)
    wait_output(rec, 'stored the run configuration', timeout=120)
    time.sleep(1.0)
    sim.stop()
    assert rec.stop() == 0, rec.output()
    info = read_info(str(bag))
    assert info.topics[f'{namespace}/attitude'].count > 0
    config = info.run_configuration
    assert config['simulator_parameters']['duration'] == 10.0  # the file's
    assert config['scene'] == 'tennis_racket'
    assert config['scene_sha256'] == content_sha256([scene])


LIMITED = ('import os, resource, sys; n = int(sys.argv[1]); '
           'resource.setrlimit(resource.RLIMIT_FSIZE, (n, n)); '
           'os.execv(sys.argv[2], sys.argv[2:])')


def test_full_disk_stops_recording_with_a_clear_error(ros_process, namespace, rclpy_node,
                                                      tmp_path):
    """The bag file hits a size limit (RLIMIT_FSIZE, as a full disk would refuse it): the
    recorder says which file and why, exits 1 without a traceback, the simulator keeps
    publishing, and the printed recover command keeps what was written before."""
    from geometry_msgs.msg import QuaternionStamped
    bag = tmp_path / 'bag'
    sim = ros_process(venv_exe('simulator'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', 'publish_rate:=200.0')
    seen = []
    rclpy_node.create_subscription(QuaternionStamped, f'{namespace}/attitude', seen.append, 100)
    assert spin_until(rclpy_node, lambda: seen, 60.0)
    rec = ros_process(sys.executable, '-c', LIMITED, '300000', venv_exe('recorder'),
                      '--ros-args', '-r', f'__ns:={namespace}', '-p', f'output:={bag}',
                      '-p', 'flush_period:=0.2')
    assert rec.wait(120) == 1, rec.output()[-3000:]
    out = rec.output()
    assert f'cannot write {bag}/bag_0.mcap: File too large' in out, out[-3000:]
    assert 'Traceback' not in out
    n = len(seen)
    assert spin_until(rclpy_node, lambda: len(seen) > n + 100, 30.0)  # still publishing
    assert sim.poll() is None
    hint = next(line for line in out.splitlines() if 'bag recover' in line)
    command = hint[hint.index(' kept: ') + len(' kept: '):].split()
    res = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    recovered = read_info(command[-1])
    assert recovered.message_count > 1000, recovered.message_count


def test_a_settled_recorder_looks_at_its_matches_less_often(ros_process, namespace, tmp_path,
                                                             rclpy_node):
    """The matches report (``~/matched_publishers``) is looked at every 0.05 s while it
    changes and every 0.25 s once settled: each look is a wake-up of the recorder's
    executor, 60% of an idle recorder's CPU at 20 Hz (issue 32). A publisher that appears
    while it is quiet is still reported, with its node, and the looks are fast again."""
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from std_msgs.msg import String
    logger = namespace.strip('/').replace('/', '.') + '.mcap_recorder'
    rec = ros_process(venv_exe('recorder'), '--ros-args', '-r', f'__ns:={namespace}',
                      '-p', f'output:={tmp_path / "bag"}', '--log-level', f'{logger}:=debug',
                      env={'PYTHONUNBUFFERED': '1'})
    quiet, fast = 'matched publishers every 0.25 s', 'matched publishers every 0.05 s'
    wait_output(rec, quiet, 90.0)
    reports = []
    rclpy_node.create_subscription(
        String, f'{namespace}/mcap_recorder/matched_publishers',
        lambda msg: reports.append(json.loads(msg.data)),
        QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.TRANSIENT_LOCAL))
    assert spin_until(rclpy_node, lambda: reports, 30.0)
    assert reports[-1]['matched'][f'{namespace}/attitude'] == [], reports
    rclpy_node.create_publisher(QuaternionStamped, f'{namespace}/attitude', 10)
    me = f'{rclpy_node.get_namespace().rstrip("/")}/{rclpy_node.get_name()}'
    assert spin_until(rclpy_node, lambda: reports[-1]['matched'][f'{namespace}/attitude'] == [
        me], 60.0), reports
    wait_output(rec, fast, 30.0)
    assert rec.output().index(quiet) < rec.output().index(fast)
    deadline = time.monotonic() + 60.0  # settled again
    while rec.output().count(quiet) < 2 and time.monotonic() < deadline:
        time.sleep(0.1)
    assert rec.output().count(quiet) == 2, rec.output()[-3000:]
