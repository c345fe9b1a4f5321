"""The sample-to-message path: CDR templates give the messages rclpy's serialiser gives."""
from dataclasses import replace

import numpy as np
from rclpy.serialization import deserialize_message

from rigid_body_sim.engine import SampleBlock
from rigid_body_sim.nodes.state_messages import StateMessages
from rigid_body_sim.physics.body import RigidBody


def _block(n=3, seed=0):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return SampleBlock(np.arange(n, dtype=np.int64), q, rng.normal(size=(n, 3)) * 1e3,
                       rng.normal(size=(n, 3)), RigidBody.from_inertia([1.0, 2.0, 3.0]))


def test_encoded_bytes_decode_to_the_filled_messages():
    """Every topic's template bytes decode (with rclpy) to the messages ``fill`` sets, for
    several samples and stamps, with no topic falling back to rclpy's serialiser; a topic
    added on top (the node's /tf) too."""
    from tf2_msgs.msg import TFMessage
    encoder = StateMessages('map', 'body', torque=True)
    encoder.add_topic('/tf', TFMessage(transforms=[encoder.transform]))
    reference = StateMessages('map', 'body', torque=True)
    reference.add_topic('/tf', TFMessage(transforms=[reference.transform]))
    block = _block()
    for i, stamp in enumerate((0, 1_700_000_000_123_456_789, 2**31 * 10**9 - 1)):
        data = encoder.encoded(block, i, stamp)
        reference.fill(block, i, stamp)
        topics = dict(reference.topics())
        assert set(data) == set(topics) and len(topics) == 11
        for name, msg in topics.items():
            assert deserialize_message(data[name], type(msg)) == msg, name
        assert reference.attitude.header.stamp.sec * 10**9 + \
            reference.attitude.header.stamp.nanosec == stamp
    assert encoder._templates.fallback == []


def test_templates_follow_a_change_of_frames():
    """Frame ids are strings inside the bytes: after set_frames the bytes carry the new ones
    (the layout changes with their length)."""
    msgs = StateMessages('world', 'base_link')
    block = _block()
    before = deserialize_message(msgs.encoded(block, 0, 5)['attitude'],
                                 type(msgs.attitude))
    msgs.set_frames('a_much_longer_inertial_frame_name', 'b')
    data = msgs.encoded(block, 0, 5)
    after = deserialize_message(data['attitude'], type(msgs.attitude))
    odo = deserialize_message(data['odometry'], type(msgs.odometry))
    assert before.header.frame_id == 'world'
    assert after.header.frame_id == 'a_much_longer_inertial_frame_name'
    assert (odo.header.frame_id, odo.child_frame_id) == ('a_much_longer_inertial_frame_name',
                                                         'b')
    assert after.quaternion == before.quaternion
    assert odo.pose.pose.orientation == after.quaternion


def test_joint_states_are_exact_size_cdr_that_rosbags_reads():
    """rclpy's serialize_message pads a JointState to a multiple of 8 that the CDR header
    does not declare; the bytes we publish and record are the exact size, which rosbags
    (an independent, strict reader) decodes to the same values, and rclpy too."""
    from rosbags.typesys import Stores, get_typestore
    from sensor_msgs.msg import JointState

    from rigid_body_sim.nodes.state_messages import joint_state_cdr
    store = get_typestore(Stores.ROS2_JAZZY)
    cases = [(['rw_x'], [], [1.5]), (['rw_x', 'rw_y', 'rw_z', 'rw_skew'], [], [1.0, -2, 3, 4]),
             (['g1', 'g2', 'g3', 'g4'], [0.1, 0.2, 0.3, 0.4], [1.0, 2, 3, 4]), ([], [], [])]
    for names, position, velocity in cases:
        msg = JointState(name=names, position=position, velocity=velocity)
        msg.header.frame_id = 'base_link'
        msg.header.stamp.sec, msg.header.stamp.nanosec = 12, 345
        data = joint_state_cdr(msg)
        got = store.deserialize_cdr(data, 'sensor_msgs/msg/JointState')
        assert list(got.name) == names and got.velocity.tolist() == velocity
        assert got.position.tolist() == position and got.header.frame_id == 'base_link'
        assert deserialize_message(data, JointState) == msg


def test_encoded_subsets_hold_only_their_topics_and_decode_right():
    """The live node builds only the subscribed topics (``only``); each subset, alternated
    with others as subscribers come and go, gives exactly its topics, each decoding to
    the sample's message."""
    encoder = StateMessages('map', 'body')
    reference = StateMessages('map', 'body')
    block = _block(4, seed=3)
    subsets = [frozenset({'attitude'}), frozenset({'odometry', 'kinetic_energy', 'imu'}),
               None, frozenset({'attitude'}), frozenset()]
    for i, only in enumerate(subsets):
        stamp = 1_000_000_007 * (i + 1)
        data = encoder.encoded(block, i % len(block), stamp, only)
        reference.fill(block, i % len(block), stamp)
        topics = dict(reference.topics())
        assert set(data) == (set(topics) if only is None else set(only))
        for name, raw in data.items():
            assert deserialize_message(raw, type(topics[name])) == topics[name], (only, name)
    assert encoder.built()['attitude'] == 3 and encoder.built()['pose'] == 1


def test_a_sample_of_the_wrong_length_is_refused():
    """A row that is not SampleBlock.values' 17 numbers is a clear error, not bytes with
    the template's constants shifted."""
    import pytest
    from rigid_body_sim.nodes.state_messages import N_VALUES
    msgs = StateMessages()
    msgs.prepare()
    with pytest.raises(ValueError, match=f'{N_VALUES} values'):
        msgs._templates.encode([0.0] * (N_VALUES - 1), 0, 0)


def test_imu_state_reads_what_rclpy_reads_whatever_the_frame_id():
    """The viewer takes the simulator's imu raw: the stamp, q and ω read from the bytes
    are rclpy's, for frame ids of every alignment; bytes that are no Imu raise as a
    subscription's deserialiser does."""
    import pytest
    from rigid_body_sim.nodes.state_messages import imu_state
    from rclpy.serialization import serialize_message
    block = _block(2, seed=5)
    for child in ('b', 'ab', 'abc', 'base_link', 'a_body_frame_of_odd_length'):
        msgs = StateMessages('world', child)
        msgs.fill(block, 1, 1_700_000_000_987_654_321)
        got = imu_state(serialize_message(msgs.imu))
        m = msgs.imu
        assert got == (1_700_000_000_987_654_321,
                       (m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w),
                       (m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z))
        assert imu_state(msgs.encoded(block, 1, 1_700_000_000_987_654_321)['imu']) == got
    with pytest.raises(Exception):
        imu_state(b'\x00\x01\x00\x00\x01\x02')


def test_a_block_of_samples_is_published_topic_by_topic():
    """Spacecraft.publish_states sends every sample of a block on one topic before the next
    topic (Fast DDS then sends a writer's messages together), each topic in sample order;
    a refused publish is reported with its topic and the rest still go out."""
    from types import SimpleNamespace
    from rclpy._rclpy_pybind11 import RCLError
    from rigid_body_sim.nodes.spacecraft import Spacecraft
    sent, refused = [], []

    def sender(topic, fail_on=None):
        def send(data):
            if data == fail_on:
                raise RCLError('history full')
            sent.append((topic, data))
        return send
    craft = SimpleNamespace(active_raw=[
        (sender('attitude'), SimpleNamespace(topic_name='/attitude'), 'attitude'),
        (sender('pose', fail_on='p1'), SimpleNamespace(topic_name='/pose'), 'pose')])
    states = {'attitude': [f'a{i}' for i in range(3)], 'pose': [f'p{i}' for i in range(3)]}
    Spacecraft.publish_states(craft, states, lambda topic, exc: refused.append(topic))
    assert sent == [('attitude', 'a0'), ('attitude', 'a1'), ('attitude', 'a2'),
                    ('pose', 'p0'), ('pose', 'p2')]
    assert refused == ['/pose']
    sent.clear()  # one sample of the block (sample by sample: lockstep, /clock subscribed)
    Spacecraft.publish_states(craft, states, lambda topic, exc: refused.append(topic), 2)
    assert sent == [('attitude', 'a2'), ('pose', 'p2')]


def test_a_block_encoded_at_once_is_each_sample_encoded_bit_for_bit():
    """``encoded_block`` (the live node's path) gives, for every sample of a block, the
    bytes ``encoded`` gives for that sample alone, for short blocks (converted row by row)
    and long ones (converted field by field), every topic and subsets; JointStates (bytes
    from rclpy, whose padding is left unset) decode alike. Its rows are SampleBlock.values'
    exactly."""
    from types import SimpleNamespace
    from rigid_body_sim.nodes.state_messages import block_rows
    joints = SimpleNamespace(wheels=2, cmgs=1, wheel_names=['w1', 'w2'], cmg_names=['g1'])
    for n in (1, 3, 4, 5, 16):
        block = _block(n, seed=n)
        assert block_rows(block) == [block.values(i) for i in range(n)]
        block = replace(block, actuators=np.arange(n * 8.0).reshape(n, 8))
        stamps = [1_700_000_000_000_000_000 + 10_000_000 * i + 7 for i in range(n)]
        for only in (None, frozenset({'attitude', 'imu', 'wheel_states'}), frozenset()):
            msgs = StateMessages('map', 'body', torque=True, actuators=joints)
            got = msgs.encoded_block(block, stamps, only)
            one = [msgs.encoded(block, i, stamps[i], only) for i in range(n)]
            assert set(got) == set(one[0])
            assert set(got) == ({name for name, _ in msgs.topics()} if only is None else only)
            for name, data in got.items():
                if name.endswith('_states'):  # rclpy's bytes: its padding is not set
                    kind = type(dict(msgs.topics())[name])
                    data = [deserialize_message(d, kind) for d in data]
                    assert data == [deserialize_message(o[name], kind) for o in one]
                else:
                    assert data == [o[name] for o in one], (n, only, name)
            assert msgs.built()['attitude'] == (0 if only == frozenset() else 2 * n)
