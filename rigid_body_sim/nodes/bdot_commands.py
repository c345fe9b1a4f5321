"""The controller's ``bdot`` mode on the graph: magnetometer readings in, the rods' dipole
out (``bdot.Bdot``, the law the offline engine runs in process).

sub ``magnetic_field`` (sensor_msgs/MagneticField, T, body frame): each new reading (by
its stamp; zero: now) updates Ḃ by the difference with the previous one. pub
``dipole_command`` (geometry_msgs/Vector3Stamped, body frame ``child_frame_id``, A·m²) at
each control tick while the mode is ``bdot``: the last dipole, zero before the second
reading. Readings that are not finite or not in the body frame are rejected and counted.

Lockstep (the controller's ``lockstep``): as the offline engine's in-process law
(``engine.magnetic.BdotSource``), the law takes only the reading at each control instant,
at that instant (``step``, from the controller's answer, once the reading is in), and
the dipole goes out with every answer, zero while the mode is not ``bdot``.
"""
import math

import numpy as np
from geometry_msgs.msg import Vector3Stamped
from sensor_msgs.msg import MagneticField

from .. import bdot
from .common import stamp_to_seconds


class BdotCommands:
    """For the controller node ``node`` with its values ``p`` (gain, rods' limits)."""

    def __init__(self, node, p, i_min: float, qos, lockstep_ns: int = 0, on_reading=None,
                 command_qos=None):
        self.node, self.p = node, p
        self.lockstep_ns, self.on_reading = lockstep_ns, on_reading
        self.reading = None  # lockstep: (t_ns, field) of the last reading at a control instant
        limits = np.asarray(p['bdot.max_dipole'], float)
        self.law = bdot.Bdot(bdot.gain_from_parameters(p, i_min),
                             np.where(limits > 0.0, limits, np.inf))
        self.dipole = np.zeros(3)
        self.readings = self.rejected = self.published = 0
        self.pub = node.create_publisher(Vector3Stamped, 'dipole_command', command_qos or qos)
        node.create_subscription(MagneticField, 'magnetic_field', self._on_field, qos)

    def _on_field(self, msg):
        b = msg.magnetic_field
        frame = msg.header.frame_id.lstrip('/')
        if not (math.isfinite(b.x) and math.isfinite(b.y) and math.isfinite(b.z)) or \
                frame not in ('', self.p['child_frame_id']):
            self.rejected += 1
            return
        self.readings += 1
        if self.lockstep_ns:
            t_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            if t_ns % self.lockstep_ns == 0:
                self.reading = (t_ns, (b.x, b.y, b.z))
                self.on_reading(msg.header.stamp)
            return
        t = stamp_to_seconds(msg.header.stamp) or self.node.get_clock().now().nanoseconds * 1e-9
        m = self.law.update(t, (b.x, b.y, b.z))
        if m is not None:
            self.dipole = m

    def ready(self, t_ns: int) -> bool:
        """Lockstep: the reading of control instant ``t_ns`` is in."""
        return self.reading is not None and self.reading[0] == t_ns

    def step(self, t_ns: int, active: bool):
        """Lockstep: the law at control instant ``t_ns`` from its reading, as the offline
        engine runs it (its time ``t_ns * 1e-9``); the rods rest while not ``active``."""
        if not active:
            self.dipole = np.zeros(3)
            return
        m = self.law.update(t_ns * 1e-9, self.reading[1])
        self.dipole = np.zeros(3) if m is None else m

    def publish(self, stamp):
        msg = Vector3Stamped()
        msg.header.stamp.sec, msg.header.stamp.nanosec = stamp.sec, stamp.nanosec  # or decoded
        msg.header.frame_id = self.p['child_frame_id']
        msg.vector.x, msg.vector.y, msg.vector.z = (float(v) for v in self.dipole)
        self.pub.publish(msg)
        self.published += 1

    def values(self) -> dict:
        return {'bdot_gain': self.law.gain, 'dipole_norm': float(np.linalg.norm(self.dipole)),
                'magnetometer_readings': self.readings,
                'magnetometer_readings_rejected': self.rejected,
                'dipole_commands_published': self.published,
                'dipole_saturated': self.law.saturated}
