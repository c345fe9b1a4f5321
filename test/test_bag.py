"""BagWriter / reader / recover / `rigid-body-sim bag` on real files (no ROS graph needed)."""
import os
import subprocess
from pathlib import Path

import pytest
import yaml
from cli_inprocess import run_cli

from rigid_body_sim.bag import BagError, BagWriter, message_definition, type_hash
from rigid_body_sim.bag.reader import is_finished, read_info
from rigid_body_sim.bag.schema import DEFAULT_QOS_YAML, parse_qos_yaml

SEP = '=' * 80


def _serialize(topic, i, t):
    from rclpy.serialization import serialize_message

    from rigid_body_sim.tools.recorder_load import make_message
    return serialize_message(make_message(topic, i, t))


def write_bag(directory, n=300, period_ns=10_000_000, **kwargs):
    """n messages on each of attitude/odometry/kinetic_energy, ``period_ns`` apart."""
    w = BagWriter(str(directory), **kwargs)
    for topic, type_name in (('attitude', 'geometry_msgs/msg/QuaternionStamped'),
                             ('odometry', 'nav_msgs/msg/Odometry'),
                             ('kinetic_energy', 'std_msgs/msg/Float64')):
        w.add_topic('/' + topic, type_name)
    w.add_run_configuration({'scene': 'tumbling_box', 'integrator': 'rk4',
                             'parameters': {'dt': 0.01, 'inertia': [1.0, 2.0, 3.0]}})
    t0 = 1_700_000_000_000_000_000
    for i in range(n):
        t = t0 + i * period_ns
        for topic in ('attitude', 'odometry', 'kinetic_energy'):
            w.write('/' + topic, _serialize(topic, i, t), t, t - 1000)
    w.close()
    return w


def cli(*args):
    """`rigid-body-sim bag ARGS` in this process: its exit status, output and error lines
    are the command's, not its interpreter's (an interpreter's start-up less, issue 32)."""
    return run_cli('bag', *args)


def test_schema_text_is_rosbag2_full_text():
    text = message_definition('geometry_msgs/msg/QuaternionStamped')
    root = open(os.path.join(os.environ['AMENT_PREFIX_PATH'].split(os.pathsep)[-1], 'share',
                             'geometry_msgs', 'msg', 'QuaternionStamped.msg')).read()
    assert text.startswith(root)
    headers = [line for line in text.splitlines() if line.startswith('MSG: ')]
    assert headers == ['MSG: geometry_msgs/Quaternion', 'MSG: std_msgs/Header',
                       'MSG: builtin_interfaces/Time']
    assert f'\n\n{SEP}\nMSG: geometry_msgs/Quaternion\n' in text
    odom = message_definition('nav_msgs/msg/Odometry')
    assert odom.count('MSG: ') == 9 and odom.count('MSG: geometry_msgs/Quaternion') == 1


def test_type_hash_matches_rosbags():
    from rosbags.typesys import Stores, get_typestore
    store = get_typestore(Stores.ROS2_JAZZY)
    for name in ('geometry_msgs/msg/QuaternionStamped', 'nav_msgs/msg/Odometry',
                 'std_msgs/msg/Float64', 'diagnostic_msgs/msg/DiagnosticArray'):
        assert type_hash(name) == store.hash_rihs01(name)


def test_default_qos_yaml_v9():
    [qos] = parse_qos_yaml(DEFAULT_QOS_YAML)
    assert qos['reliability'] == 'reliable' and qos['depth'] == 10
    assert 'deadline: {sec: 9223372036, nsec: 854775807}' in DEFAULT_QOS_YAML


def test_three_readers_and_metadata(tmp_path):
    bag = tmp_path / 'run'
    write_bag(bag, n=300)
    mcap_file = bag / 'run_0.mcap'
    assert is_finished(str(mcap_file))

    # 1. mcap seeking reader: header, schemas, channel metadata, counts.
    from mcap.reader import make_reader
    with open(mcap_file, 'rb') as f:
        reader = make_reader(f)
        assert reader.get_header().profile == 'ros2'
        summary = reader.get_summary()
        assert sorted(s.name for s in summary.schemas.values()) == [
            'geometry_msgs/msg/QuaternionStamped', 'nav_msgs/msg/Odometry',
            'std_msgs/msg/Float64']
        assert all(s.encoding == 'ros2msg' for s in summary.schemas.values())
        for ch in summary.channels.values():
            assert ch.message_encoding == 'cdr'
            assert parse_qos_yaml(ch.metadata['offered_qos_profiles'])[0]['history'] == 'keep_last'
            assert ch.metadata['topic_type_hash'].startswith('RIHS01_')
        assert summary.statistics.message_count == 900
        seeking = [(c.topic, m.log_time) for _, c, m in reader.iter_messages()]
    assert len(seeking) == 900

    # 2. mcap-ros2-support decoder.
    from mcap_ros2.reader import read_ros2_messages
    values = {}
    for m in read_ros2_messages(str(mcap_file)):
        msg = m.ros_msg
        v = {'/attitude': lambda: msg.quaternion.w, '/odometry': lambda: msg.pose.pose.position.x,
             '/kinetic_energy': lambda: msg.data}[m.channel.topic]()
        values.setdefault(m.channel.topic, []).append(v)
    assert all(v == [float(i) for i in range(300)] for v in values.values())

    # 3. rosbags AnyReader on the directory (uses metadata.yaml and checks type hashes).
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    with AnyReader([Path(bag)], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        att = [r.deserialize(raw, c.msgtype).quaternion.w
               for c, _, raw in r.messages([c for c in r.connections if c.topic == '/attitude'])]
        assert r.message_count == 900
    assert att == [float(i) for i in range(300)]

    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['version'] == 9 and meta['relative_file_paths'] == ['run_0.mcap']
    assert meta['message_count'] == 900 and meta['duration']['nanoseconds'] == 299 * 10**7
    assert {t['topic_metadata']['name']: t['message_count']
            for t in meta['topics_with_message_count']} == {
        '/attitude': 300, '/odometry': 300, '/kinetic_energy': 300}


def test_split_files_consistent(tmp_path):
    bag = tmp_path / 'split'
    write_bag(bag, n=400, period_ns=10_000_000, max_bag_duration=1.0)
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert meta['relative_file_paths'] == ['split_0.mcap', 'split_1.mcap', 'split_2.mcap',
                                           'split_3.mcap']
    info = read_info(str(bag))
    assert info.message_count == meta['message_count'] == 1200
    for entry, f in zip(meta['files'], info.files):
        assert not os.path.isabs(entry['path']) and (bag / entry['path']).is_file()
        assert entry['message_count'] == f.count
        assert entry['starting_time']['nanoseconds_since_epoch'] == f.start_ns
        assert entry['duration']['nanoseconds'] == f.end_ns - f.start_ns < 10**9
    assert info.run_configuration['scene'] == 'tumbling_box'   # repeated in every file
    assert sum(f['message_count'] for f in meta['files']) == 1200
    # size split too
    write_bag(tmp_path / 'sized', n=2000, max_bag_size=40_000, flush_period=0.0)
    assert len(read_info(str(tmp_path / 'sized')).files) > 2
    assert read_info(str(tmp_path / 'sized')).message_count == 6000


def test_writer_rejects_bad_use(tmp_path):
    (tmp_path / 'full').mkdir()
    (tmp_path / 'full' / 'x').write_text('x')
    with pytest.raises(BagError, match='not empty'):
        BagWriter(str(tmp_path / 'full'))
    w = BagWriter(str(tmp_path / 'ok'))
    with pytest.raises(BagError, match='not installed'):
        w.add_topic('/x', 'no_such_msgs/msg/Nope')
    with pytest.raises(BagError, match='not added'):
        w.write('/y', b'', 1)
    w.close()


def test_recover_truncated_file(tmp_path):
    bag = tmp_path / 'run'
    write_bag(bag, n=3000, flush_period=0.0, chunk_size=16_000)
    data = (bag / 'run_0.mcap').read_bytes()
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(data[:len(data) // 2])
    res = cli('info', str(cut))
    assert res.returncode == 1 and 'bag recover' in res.stderr and 'Traceback' not in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    res = cli('recover', str(cut), str(tmp_path / 'fixed.mcap'))
    assert res.returncode == 0, res.stderr
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    with AnyReader([tmp_path / 'fixed.mcap'],
                   default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        vals = [r.deserialize(raw, c.msgtype).data for c, _, raw in
                r.messages([c for c in r.connections if c.topic == '/kinetic_energy'])]
    assert 500 < len(vals) < 3000 and vals == [float(i) for i in range(len(vals))]
    assert read_info(str(tmp_path / 'fixed.mcap')).run_configuration['integrator'] == 'rk4'


def test_cli_info(tmp_path):
    write_bag(tmp_path / 'run', n=50)
    res = cli('info', str(tmp_path / 'run'))
    assert res.returncode == 0, res.stderr
    assert 'Messages:          150' in res.stdout
    assert 'Topic: /attitude | Type: geometry_msgs/msg/QuaternionStamped | Count: 50' in res.stdout
    assert 'Duration:          0.490s' in res.stdout
    assert 'scene: tumbling_box' in res.stdout and 'integrator: rk4' in res.stdout


@pytest.mark.parametrize('case', ['missing', 'empty_dir', 'corrupt', 'profile', 'garbage_chunk'])
def test_cli_bad_input(tmp_path, case):
    path = tmp_path / 'bad.mcap'
    if case == 'empty_dir':
        path = tmp_path / 'empty'
        path.mkdir()
    elif case == 'corrupt':
        path.write_bytes(os.urandom(2000))
    elif case == 'profile':
        from mcap.writer import Writer
        with open(path, 'wb') as f:
            w = Writer(f)
            w.start(profile='ros1', library='x')
            w.finish()
    elif case == 'garbage_chunk':
        write_bag(tmp_path / 'run', n=100)
        data = bytearray((tmp_path / 'run' / 'run_0.mcap').read_bytes())
        data[200:4000] = os.urandom(3800)
        path.write_bytes(bytes(data))
    res = cli('info', str(path))
    assert res.returncode != 0
    assert res.stderr.startswith('error: ') and len(res.stderr.strip().splitlines()) == 1
    assert 'Traceback' not in res.stderr + res.stdout


def test_chunk_indexes_are_held_packed_and_the_file_is_unchanged(tmp_path, monkeypatch):
    """A recorder flushing every second writes 3,600 chunks an hour; the writer holds their
    indexes packed as bytes (over 4x smaller with a dozen topics), and the finished file's
    summary (chunk indexes as a seeking reader sees them, messages) is the same as with the
    mcap Writer's own."""
    import sys

    from mcap.reader import make_reader

    from rigid_body_sim.bag import writer as writer_module
    t0 = 1_700_000_000_000_000_000
    # serialised once: rclpy leaves alignment padding uninitialised, so two serialisations
    # of one message may differ in bytes (and so in compressed size)
    topics = [f'/state_{k}' for k in range(12)]  # a dozen topics, as the recorder has
    data = {i: _serialize('attitude', i, t0 + i * 10_000_000) for i in range(200)}

    def record(directory):
        w = BagWriter(str(directory))
        for topic in topics:
            w.add_topic(topic, 'geometry_msgs/msg/QuaternionStamped')
        for i in range(200):
            t = t0 + i * 10_000_000
            for topic in topics:
                w.write(topic, data[i], t, t)
            if i % 10 == 9:
                w.flush()  # one chunk per flush, as the recorder's flush period makes
        held = list(w._file._indexes)
        w.close()
        with open(directory / f'{directory.name}_0.mcap', 'rb') as f:
            summary = make_reader(f).get_summary()
            f.seek(0)
            messages = [(c.topic, m.log_time, m.data) for _, c, m in make_reader(f)
                        .iter_messages()]
        return held, summary.chunk_indexes, messages

    held, packed_indexes, packed_messages = record(tmp_path / 'packed')
    assert len(held) == 1 and isinstance(held[0], writer_module._PackedChunkIndexes)
    assert held[0].count == 20
    monkeypatch.setattr(writer_module._File, 'pack_chunk_indexes', lambda self: None)
    plain, plain_indexes, plain_messages = record(tmp_path / 'plain')
    assert len(plain) == 20
    assert packed_indexes == plain_indexes and len(packed_indexes) == 20
    assert packed_messages == plain_messages and len(packed_messages) == 2400

    def size(index):  # memory held per chunk index: the object and what only it refers to
        if isinstance(index, writer_module._PackedChunkIndexes):
            return sys.getsizeof(index) + sys.getsizeof(index.records)
        d = index.message_index_offsets
        return (sys.getsizeof(index) + sys.getsizeof(index.__dict__) + sys.getsizeof(d)
                + sum(sys.getsizeof(v) for v in d.values()))
    assert sum(map(size, held)) * 4 < sum(map(size, plain))


def test_the_source_revision_is_read_without_taking_the_index_lock(monkeypatch):
    """The bag's run configuration names the checkout's commit (+dirty). `git status`
    refreshes the index under .git/index.lock unless told not to: a git killed meanwhile
    (its 2 s timeout on a loaded machine, a recorder's group SIGKILLed) left the lock in
    the user's checkout, and every later git command there failed."""
    from rigid_body_sim.bag import writer
    seen = []
    real = subprocess.run

    def run(args, *a, **k):
        seen.append(list(args))
        return real(args, *a, **k)
    monkeypatch.setattr(writer.subprocess, 'run', run)
    writer.git_revision.cache_clear()
    try:
        revision = writer.git_revision()
    finally:
        writer.git_revision.cache_clear()
    status = [a for a in seen if 'status' in a]
    assert status and all('--no-optional-locks' in a for a in status), seen
    assert revision is None or len(revision.split('+')[0]) == 40, revision
