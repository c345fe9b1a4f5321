"""Samples → standard messages: the one place that turns engine samples into ROS messages.

Shared by the live simulator node (publishes the messages) and offline runs (serialise
them into the bag), so both carry the same topics, types, frames and stamps. Every
message of one sample carries the identical stamp.
"""
from builtin_interfaces.msg import Time
from geometry_msgs.msg import (PoseStamped, Quaternion, QuaternionStamped, TransformStamped,
                               Vector3, Vector3Stamped)
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64

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
                 torque: bool = False):
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
        for msg in self.stamped():
            msg.header.stamp = self.stamp
        self.set_frames(frame_id, child_frame_id)

    def stamped(self):
        extra = (self.torque,) if self.torque is not None else ()
        return (self.attitude, self.pose, self.transform, self.odometry, self.angular_velocity,
                self.angular_momentum, self.angular_momentum_body, self.imu) + extra

    def topics(self):
        """(relative topic name, message) pairs, in publishing order."""
        out = (('attitude', self.attitude), ('pose', self.pose), ('transform', self.transform),
               ('odometry', self.odometry), ('angular_velocity', self.angular_velocity),
               ('angular_momentum', self.angular_momentum),
               ('angular_momentum_body', self.angular_momentum_body),
               ('kinetic_energy', self.kinetic_energy), ('imu', self.imu))
        return out + ((('torque_command', self.torque),) if self.torque is not None else ())

    def topic_types(self):
        return [(name, type_name(msg)) for name, msg in self.topics()]

    def set_frames(self, frame_id: str, child_frame_id: str):
        for msg in (self.attitude, self.pose, self.transform, self.odometry,
                    self.angular_momentum):
            msg.header.frame_id = frame_id
        for msg in (self.angular_velocity, self.angular_momentum_body, self.imu) + \
                ((self.torque,) if self.torque is not None else ()):
            msg.header.frame_id = child_frame_id
        self.transform.child_frame_id = child_frame_id
        self.odometry.child_frame_id = child_frame_id

    def fill(self, block, i: int, stamp_ns: int):
        """Write sample ``i`` of a SampleBlock into every message, stamped ``stamp_ns``."""
        self.stamp.sec, self.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        q = self.quaternion
        q.x, q.y, q.z, q.w = block.attitude[i].tolist()
        w = self.omega
        w.x, w.y, w.z = block.angular_velocity[i].tolist()
        v = self.angular_momentum.vector
        v.x, v.y, v.z = block.angular_momentum[i].tolist()
        v = self.angular_momentum_body.vector
        v.x, v.y, v.z = block.angular_momentum_body[i].tolist()
        self.kinetic_energy.data = float(block.kinetic_energy[i])
        if self.torque is not None:
            v = self.torque.vector
            v.x, v.y, v.z = block.torque[i].tolist()

    def serialized(self, block, i: int, stamp_ns: int):
        """[(topic, CDR bytes)] of sample ``i``."""
        self.fill(block, i, stamp_ns)
        return [(name, serialize_message(msg)) for name, msg in self.topics()]


def type_name(msg) -> str:
    """'pkg/msg/Type' of a message instance."""
    module = type(msg).__module__.split('.')[0]
    return f'{module}/msg/{type(msg).__name__}'
