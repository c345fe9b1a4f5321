"""Samples → standard messages: the one place that turns engine samples into ROS messages.

Shared by the live simulator node (publishes the messages) and offline runs (serialise
them into the bag), so both carry the same topics, types, frames and stamps. Every
message of one sample carries the identical stamp.

Why CDR templates: converting a Python message to its C struct costs more than sending it
(rclpy publishing nine state messages at 100 Hz: ~6 % of a core as messages, ~3 % as
bytes). These messages have a fixed layout once their frame ids are set, so each is
serialised once by rclpy with marker values, the markers' offsets are found in the bytes,
and every sample packs its numbers between the template's constant bytes (``encoded``).
The templates are checked against rclpy's serialiser when built; a topic whose check
fails is serialised by rclpy.
"""
import operator
import random
import struct

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import (PoseStamped, Quaternion, QuaternionStamped, TransformStamped,
                               Vector3, Vector3Stamped)
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64

from ..engine.samples import ROW_PATH_MAX

# sensor_msgs/Imu conventions: the orientation and rate are the simulated truth, exact to
# float64 round-off, so their covariance is that (a diagonal of TRUTH_VARIANCE; all zeros
# would mean "unknown"); no acceleration is simulated: element 0 of its covariance is -1.
TRUTH_VARIANCE = 1e-18


class StateMessages:
    """Messages for one body's state, built once; ``fill`` updates them all in place.

    Frames (REP-103/105): attitude, pose, transform, odometry and the inertial angular
    momentum are in ``frame_id``; angular velocity and body angular momentum in
    ``child_frame_id``. The quaternion rotates child-frame vectors into ``frame_id``.
    ``imu`` (sensor_msgs/Imu, ``child_frame_id``): the orientation and body rate as an ideal
    IMU reports them (the noisy gyro and star tracker are topics of their own:
    ``sensor_messages.py``).
    ``torque``: also a ``torque_command`` message (body frame) holding the sample's applied
    torque — for offline bags of controlled scenes, where no controller node publishes it.
    """

    def __init__(self, frame_id: str = 'world', child_frame_id: str = 'base_link',
                 torque: bool = False, actuators=None):
        self.stamp = Time()
        self.quaternion = Quaternion()
        self.omega = Vector3()
        self.attitude = QuaternionStamped(quaternion=self.quaternion)
        self.pose = PoseStamped()
        self.pose.pose.orientation = self.quaternion
        self.transform = TransformStamped()
        self.transform.transform.rotation = self.quaternion
        self.odometry = Odometry()
        self.odometry.pose.pose.orientation = self.quaternion
        self.odometry.twist.twist.angular = self.omega
        self.angular_velocity = Vector3Stamped(vector=self.omega)
        self.angular_momentum = Vector3Stamped()
        self.angular_momentum_body = Vector3Stamped()
        self.kinetic_energy = Float64()
        self.imu = Imu(orientation=self.quaternion, angular_velocity=self.omega)
        for i in (0, 4, 8):
            self.imu.orientation_covariance[i] = TRUTH_VARIANCE
            self.imu.angular_velocity_covariance[i] = TRUTH_VARIANCE
        self.imu.linear_acceleration_covariance[0] = -1.0
        self.torque = Vector3Stamped() if torque else None
        # wheels / CMGs (an engine ActuatorConfig): one joint per wheel (velocity: speed
        # relative to the body, rad/s; no position) and per gimbal (position rad, velocity
        # rad/s), in the body frame
        self.actuators = actuators
        self.wheels = self.gimbals = None
        if actuators is not None and actuators.wheels:
            self.wheels = JointState(name=list(actuators.wheel_names))
        if actuators is not None and actuators.cmgs:
            self.gimbals = JointState(name=list(actuators.cmg_names))
        for msg in self.stamped():
            msg.header.stamp = self.stamp
        self._extra = []
        self._builds = {}  # {frozenset of topics built (None: all): samples}
        self.set_frames(frame_id, child_frame_id)

    def stamped(self):
        extra = tuple(m for m in (self.torque, self.wheels, self.gimbals) if m is not None)
        return (self.attitude, self.pose, self.transform, self.odometry, self.angular_velocity,
                self.angular_momentum, self.angular_momentum_body, self.imu) + extra

    def topics(self):
        """(relative topic name, message) pairs, in publishing order."""
        out = (('attitude', self.attitude), ('pose', self.pose), ('transform', self.transform),
               ('odometry', self.odometry), ('angular_velocity', self.angular_velocity),
               ('angular_momentum', self.angular_momentum),
               ('angular_momentum_body', self.angular_momentum_body),
               ('kinetic_energy', self.kinetic_energy), ('imu', self.imu))
        out += tuple((name, msg) for name, msg in (
            ('wheel_states', self.wheels), ('gimbal_states', self.gimbals)) if msg is not None)
        out += (('torque_command', self.torque),) if self.torque is not None else ()
        return out + tuple(self._extra)

    def _joints(self):
        """The JointState topics: their arrays are the scene's length, so rclpy serialises
        them (no template)."""
        return [(name, msg) for name, msg in (('wheel_states', self.wheels),
                                               ('gimbal_states', self.gimbals))
                if msg is not None]

    def topic_types(self):
        return [(name, type_name(msg)) for name, msg in self.topics()]

    def set_frames(self, frame_id: str, child_frame_id: str):
        for msg in (self.attitude, self.pose, self.transform, self.odometry,
                    self.angular_momentum):
            msg.header.frame_id = frame_id
        for msg in (self.angular_velocity, self.angular_momentum_body, self.imu) + tuple(
                m for m in (self.torque, self.wheels, self.gimbals) if m is not None):
            msg.header.frame_id = child_frame_id
        self.transform.child_frame_id = child_frame_id
        self.odometry.child_frame_id = child_frame_id
        self._templates = None  # the frame ids are in the bytes: rebuild on next use

    def fill(self, block, i: int, stamp_ns: int):
        """Write sample ``i`` of a SampleBlock into every message, stamped ``stamp_ns``."""
        self._assign(block.values(i), *divmod(int(stamp_ns), 1_000_000_000))
        if self.actuators is not None:
            self._fill_actuators(block, i)

    def _assign(self, v, sec, nanosec):
        """Set the messages from SampleBlock.values order (see there) and a stamp."""
        self.stamp.sec, self.stamp.nanosec = sec, nanosec
        q = self.quaternion
        q.x, q.y, q.z, q.w = v[0:4]
        w = self.omega
        w.x, w.y, w.z = v[4:7]
        a = self.angular_momentum.vector
        a.x, a.y, a.z = v[7:10]
        a = self.angular_momentum_body.vector
        a.x, a.y, a.z = v[10:13]
        self.kinetic_energy.data = v[13]
        if self.torque is not None:
            a = self.torque.vector
            a.x, a.y, a.z = v[14:17]

    def _fill_actuators(self, block, i: int):
        row = block.actuators[i].tolist()  # Actuators.row: speeds, momenta, angles, rates
        n, k = self.actuators.wheels, self.actuators.cmgs
        if self.wheels is not None:
            self.wheels.velocity = row[:n]
        if self.gimbals is not None:
            self.gimbals.position = row[2 * n:2 * n + k]
            self.gimbals.velocity = row[2 * n + k:2 * n + 2 * k]

    def add_topic(self, name: str, msg):
        """One more message built on these (e.g. the node's /tf, a TFMessage holding
        ``transform``), published from the same templates."""
        self._extra.append((name, msg))
        self._templates = None

    def prepare(self):
        """Build the CDR templates now (the first build imports and runs rclpy's
        serialiser, ~30 ms), not on the first sample."""
        if self._templates is None:
            self._templates = _Templates(self)

    def serialized(self, block, i: int, stamp_ns: int):
        """[(topic, CDR bytes)] of sample ``i``, every topic."""
        return list(self.encoded(block, i, stamp_ns).items())

    def encoded(self, block, i: int, stamp_ns: int, only=None) -> dict:
        """{topic: CDR bytes} of sample ``i`` (as rclpy's serialize_message writes them);
        ``only``: a frozenset of the topics to build (the live node's subscribed ones: a
        topic nobody subscribes to costs nothing), None for every topic."""
        return {name: data[0] for name, data in
                self._encode(block, [i], [block.values(i)], [stamp_ns], only).items()}

    def encoded_block(self, block, stamps, only=None, rows=None) -> dict:
        """{topic: [CDR bytes of each sample of ``block``]}, sample ``i`` stamped
        ``stamps[i]`` (ns): what ``encoded`` gives sample by sample, made a block at a
        time (as fast as possible the live node sends a block topic by topic: converting
        its rows at once and packing a topic's samples in one loop halved the Python of
        a sample). ``only`` as for ``encoded``. ``rows``: the samples' values computed
        already (``SampleBlock.values`` each; lockstep's direct period, whose ``block``
        is None: no wheels or CMGs)."""
        return self._encode(block, range(len(stamps)),
                            block_rows(block) if rows is None else rows, stamps, only)

    def _encode(self, block, index, rows, stamps, only):
        self.prepare()
        self._builds[only] = self._builds.get(only, 0) + len(rows)  # cheap: once a call
        out = self._templates.encode_rows(rows, stamps, only)
        for name, msg in self._joints() if self.actuators is not None else ():
            if only is None or name in only:
                out[name] = []
                for i, stamp in zip(index, stamps):
                    self.stamp.sec, self.stamp.nanosec = divmod(int(stamp), 1_000_000_000)
                    self._fill_actuators(block, i)
                    out[name].append(joint_state_cdr(msg))
        return out

    def built(self) -> dict:
        """{topic: messages built so far by ``encoded``}, every topic (0: never built)."""
        out = dict.fromkeys((name for name, _ in self.topics()), 0)
        for only, n in self._builds.items():
            for name in out if only is None else only:
                if name in out:
                    out[name] += n
        return out


N_VALUES = 17  # SampleBlock.values
# Markers: doubles and 32-bit stamp fields with bit patterns no state value or frame id
# produces by accident (a collision would fail the check below, not corrupt a message).
MARKERS = [struct.unpack('<d', struct.pack('<Q', 0x3E5A_C3B1_7D00_0000 + (k << 24) + 0x9F2E))[0]
           for k in range(N_VALUES)]
SEC_MARKER, NSEC_MARKER = 0x6B3C_5D2E, 0x2C5A_3B1D


class _Templates:
    """Each topic's CDR bytes as one Struct: the template's constant bytes as ``s`` fields,
    the sample's stamp and numbers between them, packed in one call per topic from one
    shared row (stamp, values, every template's constants) by an itemgetter (~0.6 µs a
    topic, against ~1 µs for patching a bytearray field by field and copying it)."""

    def __init__(self, msgs: StateMessages):
        self.msgs = msgs
        msgs._assign(MARKERS, SEC_MARKER, NSEC_MARKER)
        self.row = [0, 0] + [0.0] * N_VALUES  # sec, nsec, the values; then the constants
        self.topics = []  # (name, Struct.pack, itemgetter over self.row)
        self.fallback = []  # (name, msg): layout not verified, serialised by rclpy
        self._only = {}  # {frozenset of topics (None: all): [(name, pack, get)]}
        joints = {name for name, _ in msgs._joints()}
        templated = [(name, msg) for name, msg in msgs.topics() if name not in joints]
        for name, msg in templated:
            self.topics.append((name, *self._compile(*_layout(serialize_message(msg)))))
        rng = random.Random(0)
        check = [rng.uniform(-1e3, 1e3) for _ in range(N_VALUES)]
        sec, nsec = rng.randrange(1 << 31), rng.randrange(10 ** 9)
        msgs._assign(check, sec, nsec)
        got = self.encode(check, sec, nsec)
        # compared as messages: alignment padding is left uninitialised by rclpy's serialiser
        bad = {name for name, msg in templated
               if deserialize_message(got[name], type(msg)) != msg}
        self.fallback = [(name, msg) for name, msg in templated if name in bad]
        self.topics = [t for t in self.topics if t[0] not in bad]
        self._only.clear()

    def _compile(self, data, fields, stamps):
        """(pack, get) of one template: its bytes cut at the numbers' and stamps' offsets."""
        parts = sorted([(o, packer.size, f'{packer.size // 8}d',
                         list(range(2 + k, 2 + k + packer.size // 8)))
                        for o, packer, k in fields] +
                       [(o, _STAMP.size, 'iI', [0, 1]) for o in stamps])
        fmt, index, at = ['<'], [], 0
        for offset, size, code, items in parts + [(len(data), 0, '', [])]:
            if offset > at:  # the constant bytes before this field
                fmt.append(f'{offset - at}s')
                index.append(len(self.row))
                self.row.append(bytes(data[at:offset]))
            fmt.append(code)
            index += items
            at = offset + size
        get = operator.itemgetter(*index) if len(index) > 1 else \
            (lambda row, i=index[0]: (row[i],))
        return struct.Struct(''.join(fmt)).pack, get

    def _topics(self, only):
        topics = self._only.get(only)
        if topics is None:
            topics = self._only[only] = [t for t in self.topics
                                         if only is None or t[0] in only]
        return topics

    def encode_rows(self, rows, stamps, only=None) -> dict:
        """{topic: [bytes of each row]}: ``encode`` over rows (SampleBlock.values each)
        and their stamps (ns), one list comprehension a topic."""
        for v in rows:
            if len(v) != N_VALUES:  # the unpacking below would shift the constants
                raise ValueError(f'a sample has {N_VALUES} values (SampleBlock.values), '
                                 f'not {len(v)}')
        constants = self.row[2 + N_VALUES:]
        full = [[*divmod(int(stamp), 1_000_000_000), *v, *constants]
                for v, stamp in zip(rows, stamps)]
        if len(full) == 1:  # a sample at a time (real time): no comprehension per topic
            row = full[0]
            out = {name: [pack(*get(row))] for name, pack, get in self._topics(only)}
        else:
            out = {name: [pack(*get(row)) for row in full]
                   for name, pack, get in self._topics(only)}
        fallback = [(n, m) for n, m in self.fallback if only is None or n in only] \
            if self.fallback else ()
        for name, _ in fallback:
            out[name] = []
        for v, stamp in zip(rows, stamps) if fallback else ():
            self.msgs._assign(v, *divmod(int(stamp), 1_000_000_000))
            for name, msg in fallback:
                out[name].append(serialize_message(msg))
        return out

    def encode(self, v, sec, nsec, only=None) -> dict:
        """{topic: bytes} of one sample's values (SampleBlock.values) and stamp."""
        return {name: data[0] for name, data in
                self.encode_rows([v], [sec * 1_000_000_000 + nsec], only).items()}


def block_rows(block) -> list:
    """[SampleBlock.values(i) for every i], bit for bit, at once: a long block's fields
    are converted for all its rows already (SampleBlock.values: why), so one
    concatenation and one tolist replace six tolist calls a row."""
    if len(block) > ROW_PATH_MAX or 'attitude' in block.__dict__:
        return np.concatenate((block.attitude, block.angular_velocity, block.angular_momentum,
                               block.angular_momentum_body, block.kinetic_energy[:, None],
                               block.torque), axis=1).tolist()
    return [block.values(i) for i in range(len(block))]


_STAMP = struct.Struct('<iI')
_MARKER_BYTES = [struct.pack('<d', m) for m in MARKERS]


def _layout(data: bytes):
    """(bytearray, fields, stamp offsets) of one marked message; runs of consecutive
    values are merged into one Struct (e.g. a quaternion's four doubles)."""
    found = []
    for k, pattern in enumerate(_MARKER_BYTES):
        start = data.find(pattern)
        while start >= 0:
            found.append((start, k))
            start = data.find(pattern, start + 1)
    found.sort()
    fields = []
    for offset, k in found:
        if fields and fields[-1][0] + 8 * fields[-1][1] == offset and \
                fields[-1][2] + fields[-1][1] == k:
            fields[-1][1] += 1
        else:
            fields.append([offset, 1, k])
    stamp = _STAMP.pack(SEC_MARKER, NSEC_MARKER)
    stamps, start = [], data.find(stamp)
    while start >= 0:
        stamps.append(start)
        start = data.find(stamp, start + 1)
    return (bytearray(data), [(o, struct.Struct(f'<{n}d'), k) for o, n, k in fields], stamps)


_CLOCK = struct.Struct('<4siI')
_CDR_LE = b'\x00\x01\x00\x00'  # encapsulation: plain CDR, little-endian


def clock_cdr(t_ns: int) -> bytes:
    """A rosgraph_msgs/Clock at ``t_ns`` as the CDR bytes rclpy's serialize_message writes
    (a publish of bytes skips converting a Python message to its C struct)."""
    return _CLOCK.pack(_CDR_LE, *divmod(int(t_ns), 1_000_000_000))


def joint_state_cdr(msg) -> bytes:
    """A sensor_msgs/JointState as CDR bytes of its exact size. rclpy's serialize_message
    pads the payload to a multiple of 8 without saying so in the encapsulation header;
    DDS delivers it unpadded, and strict readers (rosbags) refuse the padded form."""
    def string(o, text):
        return ((o + 3) & ~3) + 4 + len(text.encode()) + 1

    o = string(8, msg.header.frame_id)  # offsets from the payload start; stamp = 8 bytes
    o = ((o + 3) & ~3) + 4
    for name in msg.name:
        o = string(o, name)
    for values in (msg.position, msg.velocity, msg.effort):
        o = ((o + 3) & ~3) + 4
        if len(values):
            o = ((o + 7) & ~7) + 8 * len(values)
    return serialize_message(msg)[:4 + o]


def type_name(msg) -> str:
    """'pkg/msg/Type' of a message instance."""
    module = type(msg).__module__.split('.')[0]
    return f'{module}/msg/{type(msg).__name__}'


def imu_state(data: bytes):
    """(stamp ns, q (x, y, z, w), ω (x, y, z)) of a sensor_msgs/Imu from its CDR bytes (a
    raw subscription's); another encoding, or bytes that are not one, go to rclpy's
    deserialiser, which raises for bad bytes as a subscription would. Why: rclpy building
    an Imu's Python objects (three covariance arrays) was the largest part of the
    viewer's cost a sample; these are a few µs."""
    from .commands import _ENDIAN
    order = _ENDIAN.get(data[:2])
    if order is not None and len(data) >= 16:
        sec, nanosec, size = struct.unpack_from(order + 'iII', data, 4)
        at = 4 + ((12 + size + 7) & ~7)  # the orientation: 8-aligned after the frame id
        if size >= 1 and len(data) >= at + 128 and data[15 + size] == 0:
            q = struct.unpack_from(order + '4d', data, at)
            # the orientation's 9-element covariance lies between it and the rate
            w = struct.unpack_from(order + '3d', data, at + 104)
            return sec * 1_000_000_000 + nanosec, q, w
    msg = deserialize_message(data, Imu)
    o, v, s = msg.orientation, msg.angular_velocity, msg.header.stamp
    return s.sec * 1_000_000_000 + s.nanosec, (o.x, o.y, o.z, o.w), (v.x, v.y, v.z)
