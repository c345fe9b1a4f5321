"""Magnetometer readings → sensor_msgs/MagneticField (the simulator's ``magnetic_field``
topic, live and in offline bags alike).

The field in T, body frame (``child_frame_id``), stamped at the reading's instant; the
covariance diagonal is the white noise's variance (the constant bias and the rods'
coupling are not noise: they are the ``magnetometer.*`` parameters, in the bag's run
configuration).
"""
from builtin_interfaces.msg import Time
from rclpy.serialization import serialize_message
from sensor_msgs.msg import MagneticField

NS = 1_000_000_000
TOPIC = 'magnetic_field'
TYPE = 'sensor_msgs/msg/MagneticField'


class MagnetometerMessages:
    """``settings``: ``engine.magnetic_specs.MagnetometerSettings``."""

    def __init__(self, settings, child_frame_id: str = 'base_link'):
        self.msg = MagneticField()
        for i in (0, 4, 8):
            self.msg.magnetic_field_covariance[i] = settings.noise ** 2
        self.set_frame(child_frame_id)

    def set_frame(self, child_frame_id: str):
        self.msg.header.frame_id = child_frame_id

    def messages(self, readings, stamp_ns=lambda t: t):
        """(sim t_ns, message) per reading, in time order; the message is filled in place
        just before it is yielded."""
        msg = self.msg
        for t, b in zip(readings.t_ns.tolist(), readings.field.tolist()):
            stamp = Time()
            stamp.sec, stamp.nanosec = divmod(int(stamp_ns(t)), NS)
            msg.header.stamp = stamp
            f = msg.magnetic_field
            f.x, f.y, f.z = b
            yield t, msg

    def serialized(self, readings):
        """[(sim t_ns, topic, CDR bytes)] stamped with sim time (offline bags)."""
        return [(t, TOPIC, serialize_message(msg)) for t, msg in self.messages(readings)]
