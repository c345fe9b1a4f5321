"""What the demo sees of the live graph (``demo.run``): the simulator's state, the
controller's command and the nodes' diagnostics, kept for the status line and the summary
(``demo_summary``)."""
import math

import numpy as np

from .demo_nodes import CONTROLLER_ID, SIMULATOR_ID
from .demo_summary import stamp_origin


class Watcher:
    """Subscribes to the simulator's state and the controller's command; keeps what the
    summary needs."""

    def __init__(self, node, target, time_scale=1.0, ns='', controller_id=CONTROLLER_ID):
        from diagnostic_msgs.msg import DiagnosticArray
        from geometry_msgs.msg import QuaternionStamped, Vector3Stamped
        from std_msgs.msg import Float64
        from .nodes.common import qos_profile
        self.target = target
        self.controller_id = controller_id  # the shown spacecraft's controller's status
        self.q = self.w = self.L = None
        self.T = None
        self.stamp = None  # of the last sample (s)
        self.t0 = None  # first stamp seen: the time origin until the simulator's is known
        self.origin = 0.0 if time_scale is None else None  # stamp of the simulator's t = 0
        self.time_scale = time_scale or 1.0  # sim seconds per stamp second (rtf w/o /clock)
        self.phase = None  # the controller's mission phase (free, detumble, slew), if any
        self.rtf = math.nan
        self._rtf_reports = 0
        self.torque_seen = False
        self.free = {'T': [], 'L': []}  # T and |L| while no torque has been commanded yet
        qos = qos_profile('reliable', 100)
        # ns: a formation's spacecraft shown ('leader/'); '' for a scene of one
        node.create_subscription(QuaternionStamped, ns + 'attitude', self._on_attitude, qos)
        node.create_subscription(Vector3Stamped, ns + 'angular_velocity', self._on_w, qos)
        node.create_subscription(Vector3Stamped, ns + 'angular_momentum', self._on_L, qos)
        node.create_subscription(Float64, ns + 'kinetic_energy', self._on_T, qos)
        node.create_subscription(Vector3Stamped, ns + 'torque_command', self._on_torque, qos)
        node.create_subscription(DiagnosticArray, '/diagnostics', self._on_diag, qos)

    def _on_attitude(self, msg):
        o = msg.quaternion
        self.q = np.array((o.x, o.y, o.z, o.w))
        self.stamp = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        self.t0 = self.stamp if self.t0 is None else self.t0

    @property
    def t(self):
        """Sim time of the last sample, from the simulator's t = 0 (its diagnostics say
        which stamp that is), not from the first sample this node happened to get."""
        if self.stamp is None:
            return 0.0
        origin = self.t0 if self.origin is None else self.origin
        return (self.stamp - origin) * self.time_scale

    def _on_w(self, msg):
        v = msg.vector
        self.w = np.array((v.x, v.y, v.z))

    def _on_L(self, msg):
        v = msg.vector
        self.L = np.array((v.x, v.y, v.z))
        if not self.torque_seen:
            self.free['L'].append(float(np.linalg.norm(self.L)))

    def _on_T(self, msg):
        self.T = msg.data
        if not self.torque_seen:
            self.free['T'].append(msg.data)

    def _on_torque(self, msg):
        v = msg.vector
        if v.x or v.y or v.z:
            self.torque_seen = True

    def _on_diag(self, msg):
        for status in msg.status:  # only this graph's nodes': /diagnostics is the domain's
            if status.hardware_id == self.controller_id:
                for kv in status.values:
                    if kv.key == 'mission_phase' and kv.value != 'waiting':
                        self.phase = kv.value
            if status.hardware_id == SIMULATOR_ID:
                values = {kv.key: kv.value for kv in status.values}
                if self.origin is None and 'sim_time' in values:
                    self.origin = stamp_origin(msg.header.stamp, values['sim_time'],
                                               self.time_scale) * 1e-9
                for kv in status.values:
                    # the simulator's first report spans its start-up, not its pacing
                    if kv.key == 'real_time_factor_achieved':
                        self._rtf_reports += 1
                        try:
                            if self._rtf_reports > 1:
                                self.rtf = float(kv.value)
                        except ValueError:
                            pass

    def error_deg(self):
        if self.q is None:
            return math.nan
        from .physics import rotation
        return math.degrees(float(rotation.angle_between(self.q, self.target)))

    def ended_in(self):
        """The phase the run is in: the controller's mission phase when it reported one."""
        if self.phase:
            return self.phase
        return 'controlled' if self.torque_seen else 'free'

    def status(self):
        """The status line; empty until the first sample (no NaN placeholders)."""
        if self.t0 is None or self.w is None or self.L is None or self.T is None:
            return ''
        parts = [f't = {self.t:7.2f} s']
        # the first diagnostics come after 1 s, and their rate covers the start-up wait
        if math.isfinite(self.rtf) and self.t >= 1.0:
            parts.append(f'rtf {self.rtf:5.2f}')
        parts += [f'error {self.error_deg():7.3f}°', f'|ω| {np.linalg.norm(self.w):.3e} rad/s',
                  f'T {self.T:.6e} J', f'|L| {np.linalg.norm(self.L):.6e} kg·m²/s',
                  f'[{self.ended_in()}]']
        return '  '.join(parts)
