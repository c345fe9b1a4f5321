"""Incoming torque commands: checked, counted and warned about before the engine sees them.

A command with NaN/Inf, a frame other than the body frame, or a stamp too far in the
future or older than ``command_timeout`` is rejected, counted by reason (reported in
diagnostics) and warned about (throttled per reason); it is never applied.
"""
import math
import struct
import time

# lockstep_*: with lockstep, a command whose stamp is not the held control instant's;
# unknown_spacecraft: on the simulator's own topic, a frame_id naming no spacecraft
REJECT_REASONS = ('non_finite', 'wrong_frame', 'future_stamp', 'stale_stamp', 'lockstep_stale',
                  'lockstep_unexpected', 'unknown_spacecraft')
WARN_THROTTLE_S = 2.0


class Rejections:
    """Rejected inputs counted by reason (one of ``reasons``; reported in diagnostics as
    ``<prefix>.<reason>``) and warned about, throttled per reason; ``outcome``: what the
    warning says happens instead (e.g. the torque is not applied)."""

    def __init__(self, node, reasons, prefix: str, outcome: str):
        self._log = node.get_logger()
        self.rejected = dict.fromkeys(reasons, 0)
        self._prefix, self._outcome = prefix, outcome
        self._next_warn = {}

    def counts(self) -> dict:
        return {f'{self._prefix}.{r}': n for r, n in self.rejected.items()}

    def reject(self, reason: str, source: str, detail: str) -> bool:
        """Count ``reason`` and warn (throttled); returns False."""
        self.rejected[reason] += 1
        now = time.monotonic()
        if now >= self._next_warn.get(reason, 0.0):
            self._next_warn[reason] = now + WARN_THROTTLE_S
            self._log.warn(f'{source} rejected ({reason}): {detail}; {self._outcome} '
                           f'({self.rejected[reason]} {reason} rejections so far)')
        return False


class CommandFilter(Rejections):
    """Validates commands against the simulator's parameters ``params`` (a live dict).
    ``what``: the command's quantity (torque; dipole on ``dipole_command``, counted as
    ``dipole_commands_rejected.<reason>``)."""

    def __init__(self, node, params, what: str = 'torque'):
        super().__init__(node, REJECT_REASONS, 'commands_rejected' if what == 'torque' else
                         f'{what}_commands_rejected', f'{what} not applied')
        self.params, self.what = params, what

    def accept(self, header, vector, source: str, now_stamp_ns) -> bool:
        """True if the command may be applied; ``now_stamp_ns``: this node's current stamp,
        None before t = 0 (held for subscribers or a controller: the node's stamps have not
        started, so a stamp cannot be judged against them; the value and frame still are)."""
        p = self.params
        x, y, z = vector.x, vector.y, vector.z
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return self.reject('non_finite', source, f'{self.what} ({x}, {y}, {z}) is not '
                               'finite')
        frame = header.frame_id.lstrip('/')
        if frame not in ('', p['child_frame_id']):
            return self.reject('wrong_frame', source, f'frame_id {header.frame_id!r}: '
                               f'{self.what} must be in the body frame '
                               f'{p["child_frame_id"]!r} (or frame_id empty)')
        stamp = header.stamp.sec + 1e-9 * header.stamp.nanosec
        if stamp != 0.0 and now_stamp_ns is not None:
            now = now_stamp_ns * 1e-9
            if stamp - now > p['command_stamp_tolerance']:
                hint = ' (does the sender use_sim_time? this node publishes /clock)' \
                    if p['publish_clock'] else ''
                return self.reject('future_stamp', source, f'stamp {stamp:.6f} is '
                                    f'{stamp - now:.3g} s ahead of this node\'s stamps{hint}')
            if now - stamp > p['command_timeout']:
                return self.reject('stale_stamp', source, f'stamp {stamp:.6f} is '
                                    f'{now - stamp:.3g} s old, more than command_timeout')
        return True


class _Fields:
    """Attribute access to a decoded message's fields (``header.stamp.sec``, ``vector.x``)."""

    def __init__(self, **fields):
        self.__dict__.update(fields)


_ENDIAN = {b'\x00\x01': '<', b'\x00\x00': '>'}  # plain CDR: little-, big-endian
# per encapsulation: (stamp and frame id's length, the payload of n doubles for n = 3, 4)
_LAYOUTS = {kind: (struct.Struct(order + 'iII'), {n: struct.Struct(f'{order}{n}d')
                                                  for n in (3, 4)})
            for kind, order in _ENDIAN.items()}


def stamped_fields(data: bytes, n: int = 3):
    """(sec, nanosec, frame_id, *n doubles) of a stamped message whose payload after the
    header is ``n`` doubles (geometry_msgs/Vector3Stamped: 3, QuaternionStamped: 4), from
    its plain-CDR bytes (a raw subscription's), or None for another encoding or bytes
    that are not one. Plain tuples and precompiled structs: lockstep takes one command
    per exchange, and each object or format parse there is CPU of every exchange
    (sim_lockstep.py)."""
    layout = _LAYOUTS.get(data[:2])
    if layout is None or len(data) < 16:
        return None
    sec, nanosec, size = layout[0].unpack_from(data, 4)
    at = 4 + ((12 + size + 7) & ~7)  # the doubles: 8-aligned after the frame id
    if size < 1 or len(data) < at + 8 * n or data[15 + size] != 0:
        return None
    try:
        frame_id = data[16:15 + size].decode()
    except UnicodeDecodeError:
        return None
    return (sec, nanosec, frame_id) + layout[1][n].unpack_from(data, at)


def vector3_stamped_fields(data: bytes):
    """(sec, nanosec, frame_id, x, y, z) of a geometry_msgs/Vector3Stamped's CDR bytes, or
    None (``stamped_fields``)."""
    return stamped_fields(data, 3)


_LITTLE = _LAYOUTS[b'\x00\x01']


def vector3_stamped_cdr(sec: int, nanosec: int, frame_id: str, x, y, z) -> bytes:
    """A geometry_msgs/Vector3Stamped's plain-CDR bytes (little-endian), as rclpy's
    serialiser writes them but for the alignment padding (zeros here, uninitialised
    there): what the lockstep controller publishes, without building a message object
    and setting its checked fields one by one for every exchange."""
    frame = frame_id.encode()
    head = b'\x00\x01\x00\x00' + _LITTLE[0].pack(sec, nanosec, len(frame) + 1) + frame
    pad = -(len(head) - 3) % 8  # the terminating zero, then up to the 8-aligned vector
    return head + bytes(1 + pad) + _LITTLE[1][3].pack(x, y, z)


def _header(sec, nanosec, frame_id):
    return _Fields(stamp=_Fields(sec=sec, nanosec=nanosec), frame_id=frame_id)


def quaternion_stamped(data: bytes):
    """A geometry_msgs/QuaternionStamped's fields from its CDR bytes, as rclpy's
    deserialiser gives them (``vector3_stamped`` says why; the lockstep controller takes
    the simulator's attitude this way)."""
    fields = stamped_fields(data, 4)
    if fields is not None:
        sec, nanosec, frame_id, x, y, z, w = fields
        return _Fields(header=_header(sec, nanosec, frame_id),
                       quaternion=_Fields(x=x, y=y, z=z, w=w))
    from geometry_msgs.msg import QuaternionStamped
    from rclpy.serialization import deserialize_message
    return deserialize_message(data, QuaternionStamped)


def vector3_stamped(data: bytes):
    """A geometry_msgs/Vector3Stamped's fields from its CDR bytes (a raw subscription's),
    as rclpy's deserialiser gives them; another encoding (or bytes that are not one) goes
    to rclpy's, which raises for bad bytes as a subscription would. Why: rclpy building
    the message's Python objects cost ~45 µs of a lockstep exchange's ~600 (taking
    messages raw then decoding them here: a few µs)."""
    fields = vector3_stamped_fields(data)
    if fields is not None:
        sec, nanosec, frame_id, x, y, z = fields
        return _Fields(header=_header(sec, nanosec, frame_id), vector=_Fields(x=x, y=y, z=z))
    from geometry_msgs.msg import Vector3Stamped
    from rclpy.serialization import deserialize_message
    return deserialize_message(data, Vector3Stamped)


# nav_msgs/Odometry after its two frame ids (8-aligned): pose.position, pose.orientation,
# the pose's 36 covariances, twist.linear, twist.angular
_ODOMETRY_ORIENTATION, _ODOMETRY_ANGULAR, _ODOMETRY_TAIL = 24, 24 + 32 + 288 + 24, 24 + 8 * 36
_ODOMETRY_SIZE = _ODOMETRY_ANGULAR + _ODOMETRY_TAIL


def odometry_state(data: bytes):
    """(attitude, angular velocity) of a nav_msgs/Odometry's CDR bytes (a raw
    subscription's): its header and pose orientation as a QuaternionStamped's fields, and
    its twist's angular rate with the header's stamp and ``child_frame_id`` as a
    Vector3Stamped's, as rclpy's deserialiser gives them (the other fields are not read);
    another encoding goes to rclpy's, which raises for bad bytes as a subscription would.
    Why: in lockstep the controller takes the state as one odometry message, so that the
    simulator writes one message per exchange instead of attitude and angular_velocity
    (each write costs the simulator's process tens of µs: docs/live-nodes.md)."""
    layout = _LAYOUTS.get(data[:2])
    if layout is not None and len(data) >= 16:
        sec, nanosec, size = layout[0].unpack_from(data, 4)
        at = 4 + ((12 + size + 3) & ~3)  # the child frame id's length: 4-aligned
        if size >= 1 and len(data) >= at + 4 and data[15 + size] == 0:
            (child,) = struct.unpack_from(layout[0].format[0] + 'I', data, at)
            end = at + 4 + child
            pose = 4 + ((end - 4 + 7) & ~7)  # the doubles: 8-aligned after it
            if child >= 1 and len(data) >= pose + _ODOMETRY_SIZE and data[end - 1] == 0:
                try:
                    frame_id, child_frame_id = data[16:15 + size].decode(), \
                        data[at + 4:end - 1].decode()
                except UnicodeDecodeError:
                    frame_id = None
                if frame_id is not None:
                    x, y, z, w = layout[1][4].unpack_from(data, pose + _ODOMETRY_ORIENTATION)
                    wx, wy, wz = layout[1][3].unpack_from(data, pose + _ODOMETRY_ANGULAR)
                    return (_Fields(header=_header(sec, nanosec, frame_id),
                                    quaternion=_Fields(x=x, y=y, z=z, w=w)),
                            _Fields(header=_header(sec, nanosec, child_frame_id),
                                    vector=_Fields(x=wx, y=wy, z=wz)))
    from nav_msgs.msg import Odometry
    from rclpy.serialization import deserialize_message
    msg = deserialize_message(data, Odometry)
    return (_Fields(header=msg.header, quaternion=msg.pose.pose.orientation),
            _Fields(header=_Fields(stamp=msg.header.stamp, frame_id=msg.child_frame_id),
                    vector=msg.twist.twist.angular))
