"""Sensor readings → standard messages, for the live simulator and offline bags alike.

* ``gyro``: sensor_msgs/Imu in the body frame (``child_frame_id``): angular_velocity is the
  reading; its covariance diagonal is the variance of the stationary part of the error,
  (N²/h + σ_gm²) per axis (angle random walk per reading plus the Gauss–Markov bias; the
  turn-on bias and the rate random walk are not stationary and are not in it). No
  orientation and no acceleration: element 0 of both covariances is −1 (REP-145 / the Imu
  message's convention).
* ``star_tracker``: geometry_msgs/QuaternionStamped in ``frame_id``, the type of the
  simulator's ``attitude`` topic (body → frame_id, x, y, z, w). The type has no covariance
  field: the noise is the ``sensors.star_tracker.noise`` parameter, recorded in the bag's
  run configuration.
* ``sun_direction``: geometry_msgs/Vector3Stamped in the body frame (``child_frame_id``),
  the unit vector to the Sun; none while the spacecraft is in the Earth's shadow.
"""
from builtin_interfaces.msg import Time
from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu

from ..sensors.gauss_markov import gauss_markov_sigma

NS = 1_000_000_000


class SensorMessages:
    """The messages of the enabled sensors (``settings``: ``sensors.specs.SensorSettings``)."""

    def __init__(self, settings, frame_id: str = 'world', child_frame_id: str = 'base_link'):
        self.gyro = self.star = self.sun = None
        if settings.gyro is not None:
            g = settings.gyro
            self.gyro = Imu()
            variance = g.angle_random_walk ** 2 / g.period + \
                gauss_markov_sigma(g.bias_instability) ** 2
            for i in (0, 4, 8):
                self.gyro.angular_velocity_covariance[i] = variance
            self.gyro.orientation_covariance[0] = -1.0
            self.gyro.linear_acceleration_covariance[0] = -1.0
        if settings.star_tracker is not None:
            self.star = QuaternionStamped()
        if getattr(settings, 'sun', None) is not None:
            self.sun = Vector3Stamped()
        self.set_frames(frame_id, child_frame_id)

    def set_frames(self, frame_id: str, child_frame_id: str):
        if self.gyro is not None:
            self.gyro.header.frame_id = child_frame_id
        if self.star is not None:
            self.star.header.frame_id = frame_id
        if self.sun is not None:
            self.sun.header.frame_id = child_frame_id

    def topics(self):
        """(relative topic name, message) of the enabled sensors."""
        return tuple((name, msg) for name, msg in (('gyro', self.gyro),
                                                   ('star_tracker', self.star),
                                                   ('sun_direction', self.sun))
                     if msg is not None)

    def topic_types(self):
        return [(name, f'{type(msg).__module__.split(".")[0]}/msg/{type(msg).__name__}')
                for name, msg in self.topics()]

    def messages(self, readings, stamp_ns=lambda t: t, only=None):
        """(sim t_ns, topic, message) of every reading, in time order (gyro first at a shared
        instant); each message is filled in place just before it is yielded. ``only``: the
        topics to build (the live node's subscribed ones), None for both."""
        events = [(int(t), 0, i) for i, t in enumerate(readings.gyro_t_ns)
                  if only is None or 'gyro' in only] + \
            [(int(t), 1, i) for i, t in enumerate(readings.star_t_ns)
             if only is None or 'star_tracker' in only] + \
            [(int(t), 2, i) for i, t in enumerate(readings.sun_t_ns)
             if only is None or 'sun_direction' in only]
        for t, kind, i in sorted(events):
            stamp = Time()
            stamp.sec, stamp.nanosec = divmod(int(stamp_ns(t)), NS)
            if kind == 0:
                msg = self.gyro
                v = msg.angular_velocity
                v.x, v.y, v.z = readings.gyro[i].tolist()
                msg.header.stamp = stamp
                yield t, 'gyro', msg
            elif kind == 1:
                msg = self.star
                q = msg.quaternion
                q.x, q.y, q.z, q.w = readings.star[i].tolist()
                msg.header.stamp = stamp
                yield t, 'star_tracker', msg
            else:
                msg = self.sun
                v = msg.vector
                v.x, v.y, v.z = readings.sun[i].tolist()
                msg.header.stamp = stamp
                yield t, 'sun_direction', msg

    def serialized(self, readings):
        """[(sim t_ns, topic, CDR bytes)] stamped with sim time (offline bags)."""
        return [(t, name, serialize_message(msg)) for t, name, msg in self.messages(readings)]


def sensors_summary(settings) -> str:
    """'; sensors: gyro 50 Hz, star_tracker 5 Hz (1 outage), seed 1' (empty if none)."""
    if settings is None:
        return ''
    parts = []
    if settings.gyro is not None:
        parts.append(f'gyro {NS / settings.gyro.period_ns:g} Hz')
    s = settings.star_tracker
    if s is not None:
        parts.append(f'star_tracker {NS / s.period_ns:g} Hz ({len(s.outages)} outages)')
    if getattr(settings, 'sun', None) is not None:
        parts.append(f'sun_sensor {NS / settings.sun.period_ns:g} Hz')
    return f'; sensors: {", ".join(parts)}, seed {settings.seed}'
