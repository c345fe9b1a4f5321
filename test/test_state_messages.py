"""The sample-to-message path: CDR templates give the messages rclpy's serialiser gives."""
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
