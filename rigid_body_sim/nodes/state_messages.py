"""The simulator's state topics as standard messages, built once and filled in place.

Shared by the live simulator node and offline runs, so both publish/record the same
topics with the same types, frames and stamps.
"""
from builtin_interfaces.msg import Time
from geometry_msgs.msg import (PoseStamped, Quaternion, QuaternionStamped, TransformStamped, Vector3,
                               Vector3Stamped)
from nav_msgs.msg import Odometry
from std_msgs.msg import Float64


class StateMessages:
    """Messages for one body's state; ``fill`` updates them all, allocating nothing.

    Frames (REP-103/105): attitude, pose, transform, odometry and the inertial angular
    momentum are in ``frame_id``; angular velocity and body angular momentum in
    ``child_frame_id``. The quaternion rotates child-frame vectors into ``frame_id``.
    """

    def __init__(self, frame_id: str = 'world', child_frame_id: str = 'base_link'):
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
        for msg in self.stamped():
            msg.header.stamp = self.stamp
        self.set_frames(frame_id, child_frame_id)

    def stamped(self):
        return (self.attitude, self.pose, self.transform, self.odometry, self.angular_velocity,
                self.angular_momentum, self.angular_momentum_body)

    def topics(self):
        """(relative topic name, message) pairs, in publishing order."""
        return (('attitude', self.attitude), ('pose', self.pose), ('transform', self.transform),
                ('odometry', self.odometry), ('angular_velocity', self.angular_velocity),
                ('angular_momentum', self.angular_momentum),
                ('angular_momentum_body', self.angular_momentum_body), ('kinetic_energy', self.kinetic_energy))

    def set_frames(self, frame_id: str, child_frame_id: str):
        for msg in (self.attitude, self.pose, self.transform, self.odometry, self.angular_momentum):
            msg.header.frame_id = frame_id
        for msg in (self.angular_velocity, self.angular_momentum_body):
            msg.header.frame_id = child_frame_id
        self.transform.child_frame_id = child_frame_id
        self.odometry.child_frame_id = child_frame_id

    def fill(self, stamp_ns: int, attitude, angular_velocity, angular_momentum, angular_momentum_body,
             kinetic_energy: float):
        """Write one state (floats or sequences of floats) into every message."""
        self.stamp.sec, self.stamp.nanosec = divmod(int(stamp_ns), 1_000_000_000)
        q = self.quaternion
        q.x, q.y, q.z, q.w = (float(v) for v in attitude)
        w = self.omega
        w.x, w.y, w.z = (float(v) for v in angular_velocity)
        v = self.angular_momentum.vector
        v.x, v.y, v.z = (float(x) for x in angular_momentum)
        v = self.angular_momentum_body.vector
        v.x, v.y, v.z = (float(x) for x in angular_momentum_body)
        self.kinetic_energy.data = float(kinetic_energy)


def type_name(msg) -> str:
    """'pkg/msg/Type' of a message instance."""
    module = type(msg).__module__.split('.')[0]
    return f'{module}/msg/{type(msg).__name__}'
