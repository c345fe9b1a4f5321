"""The orbit and the environment's torque → standard messages (the simulator node's, for
scenes with an ``orbit.model``; nothing is built without one).

* ``orbit`` (nav_msgs/Odometry): ``header.frame_id`` the inertial frame (``frame_id``),
  ``child_frame_id`` the orbit frame (``orbit.frame_id``, LVLH: x along the velocity, z to
  nadir). The pose is the spacecraft's position (m) and the orbit frame's orientation in
  the inertial frame; the twist is the inertial velocity (m/s) and the orbit frame's
  rate (rad/s), resolved in the orbit frame as Odometry's convention asks (REP-105:
  the twist is in ``child_frame_id``).
* ``/tf``: ``frame_id`` → orbit frame, the rotation only (the body's own transform has no
  translation either, so both frames share the origin in a 3D view).
* ``environment_torque`` (geometry_msgs/WrenchStamped, the body frame ``child_frame_id``):
  the environment's torque at the sample (N·m): the sum of the terms on (the gravity
  gradient, the magnetorquers' m × B with the dipole held at the sample, the facets' solar
  radiation pressure and drag).
"""
import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import TransformStamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message

from ..engine.specs import frame_id_problem
from ..physics import rotation
from .state_messages import type_name
from ..physics.orbit import frames

NS = 1_000_000_000


class OrbitMessages:
    """Messages of the orbit for one engine configuration (``EngineConfig``)."""

    def __init__(self, config, frame_id: str, child_frame_id: str, orbit_frame_id: str):
        problem = frame_id_problem(orbit_frame_id)
        if problem:
            raise ValueError(f'orbit.frame_id {orbit_frame_id!r} {problem}')
        if orbit_frame_id in (frame_id, child_frame_id):
            raise ValueError(f'orbit.frame_id {orbit_frame_id!r} must differ from frame_id '
                             'and child_frame_id')
        self.config = config
        self.stamp = Time()
        self.odometry = Odometry()
        self.transform = TransformStamped()
        env = config.environment
        self.torque = WrenchStamped() if env.terms else None
        # the facets' terms read the loops' array (principal axes); re-made per sample only
        # where it is anchored to an interval (SGP4, NRLMSIS)
        self._facets = None if env.sunlight is None or not env.sunlight.terms else \
            env.elements(0.0, config.body.to_principal)
        if self._facets is not None:  # imported here, as mass_inertia below
            from ..physics.environment.facets_kernel import facets_torque
            self._facets_torque = facets_torque
        # the whole mass distribution (wheel rotors included), principal frame; imported
        # here: engine.actuators loads the gyrostat's kernels (numba), which a node's start
        # before its first engine does not need (spacecraft.py)
        from ..engine.actuators import mass_inertia
        self._inertia = mass_inertia(config.actuators, config.body)
        for msg in (self.odometry, self.transform) + ((self.torque,) if self.torque else ()):
            msg.header.stamp = self.stamp
        self.set_frames(frame_id, child_frame_id, orbit_frame_id)

    def set_frames(self, frame_id: str, child_frame_id: str, orbit_frame_id: str):
        self.odometry.header.frame_id = self.transform.header.frame_id = frame_id
        self.odometry.child_frame_id = self.transform.child_frame_id = orbit_frame_id
        if self.torque is not None:
            self.torque.header.frame_id = child_frame_id

    def topics(self):
        """(relative topic name, message) pairs (``/tf`` carries ``transform``)."""
        out = (('orbit', self.odometry),)
        return out + ((('environment_torque', self.torque),) if self.torque else ())

    def topic_types(self):
        return [(name, type_name(msg)) for name, msg in self.topics()]

    def fill(self, block, i: int, stamp_ns: int):
        """Write sample ``i`` of a SampleBlock (its time, and the attitude for the torque)."""
        self.stamp.sec, self.stamp.nanosec = divmod(int(stamp_ns), NS)
        t = int(block.t_ns[i]) / NS
        r, v = self.config.environment.orbit.state(t)
        axes = frames.lvlh_axes(r, v)
        x, y, z, w = frames.lvlh_attitude(r, v).tolist()
        pose = self.odometry.pose.pose
        pose.position.x, pose.position.y, pose.position.z = r.tolist()
        for q in (pose.orientation, self.transform.transform.rotation):
            q.x, q.y, q.z, q.w = x, y, z, w
        twist = self.odometry.twist.twist
        twist.linear.x, twist.linear.y, twist.linear.z = (axes.T @ v).tolist()
        twist.angular.x, twist.angular.y, twist.angular.z = \
            (axes.T @ frames.lvlh_rate(r, v)).tolist()
        if self.torque is not None:
            env = self.config.environment
            tau = np.zeros(3)
            if env.gravity_gradient:
                tau += gravity_gradient(env.orbit.mu, self._inertia, block.q[i], r)
            if self._facets is not None:
                if env.anchored:
                    self._facets = env.elements(t, self.config.body.to_principal)
                tau += self._facets_torque(np.asarray(block.q[i], float), t, self._facets)
            tau = self.config.body.to_body(tau)
            if env.magnetorquers and block.dipole is not None:  # body frame already
                b = rotation.rotate(rotation.conjugate(block.attitude[i]),
                                    env.magnetic.field.at(t))
                tau += np.cross(block.dipole[i], b)
            w = self.torque.wrench.torque
            w.x, w.y, w.z = (float(c) for c in tau)


    def serialized(self, block, i: int, stamp_ns: int):
        """[(topic, CDR bytes)] of sample ``i`` (offline bags: the live node's topics)."""
        self.fill(block, i, stamp_ns)
        return [(name, serialize_message(msg)) for name, msg in self.topics()]


def gravity_gradient(mu: float, inertia, q_principal, r) -> np.ndarray:
    """τ = 3μ/r³ ĉ × (I ĉ) (principal frame, N·m), ĉ the radial unit vector in the
    principal frame, for attitude ``q_principal`` (principal → inertial) at position r;
    ``inertia`` (3, 3) in the principal frame."""
    r = np.asarray(r, float)
    rn = float(np.linalg.norm(r))
    c = rotation.rotate(rotation.conjugate(np.asarray(q_principal, float)), r / rn)
    return 3.0 * mu / rn ** 3 * np.cross(c, inertia @ c)


class OrbitPublishers:
    """The simulator node's publishers of the orbit's messages (its one hook: build this
    for a scene with an orbit, call :meth:`publish` per sample)."""

    def __init__(self, node, config, p, qos, tf_qos, tf_type=None, prefix=''):
        self.msgs = OrbitMessages(config, p['frame_id'], p['child_frame_id'],
                                  p['orbit.frame_id'])
        self.pubs = [(node.create_publisher(type(msg), prefix + name, qos), msg)
                     for name, msg in self.msgs.topics()]
        if tf_type is not None:  # /tf where tf2_msgs exists (as the node's own transform)
            self.pubs.append((node.create_publisher(tf_type, '/tf', tf_qos),
                              tf_type(transforms=[self.msgs.transform])))
        self.active = []  # the publishers with subscribers (refresh)
        self.published = 0  # messages published (the simulator's diagnostics)

    def refresh(self):
        """Only topics with subscribers are filled and published: a topic nobody
        subscribes to costs nothing (a late subscriber joins here)."""
        self.active = [(p, m) for p, m in self.pubs if p.get_subscription_count() > 0]

    def destroy(self, node):
        for publisher, _ in self.pubs:
            node.destroy_publisher(publisher)
        self.pubs, self.active = [], []

    def publish(self, block, i: int, stamp_ns: int):
        if not self.active:
            return
        self.msgs.fill(block, i, stamp_ns)
        for publisher, msg in self.active:
            publisher.publish(msg)
            self.published += 1
