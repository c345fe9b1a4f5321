"""``attitude_viewer``: the live simulation in Foxglove, served from this process.

A separate node, so a viewer problem never stops the simulation. It subscribes to the
simulator's state and serves it with the Foxglove SDK's WebSocket server (default
ws://127.0.0.1:8765) on the channels described in :mod:`rigid_body_sim.viewer.view`.

Topics (relative names, remappable):
    sub ``imu`` (sensor_msgs/Imu: the attitude base_link → world and ω in base_link of one
        sample, one stamp; the simulator's ideal IMU, the same values as its ``attitude``
        and ``angular_velocity``), ``attitude_target`` (QuaternionStamped), ``/diagnostics``.
    The simulator's ``resets`` diagnostics value (counting ``~/reset``, ResetSimulation and
    set_state) restarts the drift baselines and the traces: sim time keeps running across a
    reset, so the stamps alone do not show one.
    pub ``/diagnostics`` (this node's status: subscriptions, samples served, client
        messages refused by reason).

The body (for the inertia box, T and the energy ellipsoid) comes from the simulator's
``inertia`` parameter, asked over its parameter service; the pointing error's target from
the controller's ``target_attitude`` or the latest ``attitude_target`` message. L (world) is
R(q)·Iω from the same sample, equal to the simulator's ``angular_momentum`` to round-off: one
subscription instead of three keeps the viewer's cost low (see ``bench/viewer.py``).
"""
import sys
import time

import numpy as np
from rclpy.node import Node

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped
from sensor_msgs.msg import Imu

from ..physics.body import RigidBody
from ..viewer import view as fox
from ..viewer.specs import LOOPBACK, VIEWER
from .common import declare_parameters, diagnostic_status, qos_profile
from .process import events_executor, run_node

NODE_NAME = 'attitude_viewer'
DIAGNOSTICS_PERIOD_S = 1.0   # wall clock
WAIT_NOTICE_S = 2.0          # no state after this long: say once that we wait


class Listener:
    """Counts client subscriptions (foxglove.websocket.ServerListener)."""

    def __init__(self):
        self.subscriptions = 0

    def on_subscribe(self, client, channel):
        self.subscriptions += 1

    def on_unsubscribe(self, client, channel):
        self.subscriptions -= 1


class Viewer(Node):
    def __init__(self):
        super().__init__(NODE_NAME)
        p = self.p = declare_parameters(self, VIEWER)
        log = self.get_logger()
        if p['host'] not in LOOPBACK:
            log.warn(f'host {p["host"]}: serving the simulation beyond this machine, to '
                     'anyone who can reach the port (the Foxglove protocol has no '
                     'authentication)')
        import foxglove
        self.listener = Listener()
        self.server, self.rejections = fox.start_server(p['host'], p['port'],
                                                        listener=self.listener)
        self.server_port = self.server.port
        self.mcap = foxglove.open_mcap(p['mcap_output'], allow_overwrite=True) \
            if p['mcap_output'] else None
        from ..bag.schema import message_definition
        self.view = fox.View(body_size=p['body_size'], trace_length=p['trace_length'],
                             scene_period_ns=round(1e9 / p['scene_rate']),
                             diagnostics_definition=message_definition(fox.DIAGNOSTICS_TYPE))
        log.info(f'Foxglove: ws://{p["host"]}:{self.server_port} — open in Foxglove '
                 f'(app or https://app.foxglove.dev): Open connection → Foxglove WebSocket'
                 + (f'; also writing {p["mcap_output"]}' if self.mcap else ''))
        qos = qos_profile(p['qos'], 100)
        # one topic carries q and ω of a sample (one stamp, no joining): the cheapest to take
        self.create_subscription(Imu, 'imu', self._on_imu, qos)
        self.create_subscription(QuaternionStamped, 'attitude_target', self._on_target, qos)
        # raw: forwarded as the CDR bytes received (this node's own status comes back too)
        self.create_subscription(DiagnosticArray, '/diagnostics', self._on_diagnostics,
                                 qos_profile('reliable', 100), raw=True)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics',
                                               qos_profile('reliable', 10))
        self.target = None
        self.samples = self.transforms = 0
        self.last_stamp_ns = 0
        self.started = time.monotonic()
        self.said_waiting = False
        self.reported = self.rejections.snapshot()
        ns = self.get_namespace().rstrip('/')
        self._simulator = f'{ns}/{p["simulator_node"]}'  # its diagnostics' hardware_id
        self._resets = None  # the simulator's resets count last seen
        from rclpy.parameter_client import AsyncParameterClient
        self._params = {'inertia': AsyncParameterClient(self, p['simulator_node']),
                        'target_attitude': AsyncParameterClient(self, p['controller_node'])}
        self._asked = set()
        self.create_timer(0.5, self._poll)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._diagnostics)

    # --- state ---------------------------------------------------------------------------
    def _on_imu(self, msg):
        s = msg.header.stamp
        stamp = s.sec * 1_000_000_000 + s.nanosec
        o = msg.orientation
        q = (o.x, o.y, o.z, o.w)
        self.view.transform(stamp, q)
        self.transforms += 1
        self.last_stamp_ns = stamp
        if self.view.body is not None:
            w = msg.angular_velocity
            self.samples += 1
            self.view.sample(stamp, q, (w.x, w.y, w.z), self.target)

    def _on_target(self, msg):
        o = msg.quaternion
        self.target = (o.x, o.y, o.z, o.w)

    # --- the simulator's body and the controller's target ----------------------------------
    def _poll(self):
        if not self.said_waiting and self.transforms == 0 and \
                time.monotonic() - self.started > WAIT_NOTICE_S:
            self.said_waiting = True
            self.get_logger().info(
                f'waiting for the simulator: no state on {self.resolve_topic_name("imu")} '
                'yet (serving Foxglove meanwhile)')
        for name, client in self._params.items():
            if name not in self._asked and client.services_are_ready():
                self._asked.add(name)
                client.get_parameters([name], callback=lambda f, n=name: self._got(n, f))

    def _got(self, name, future):
        try:
            value = future.result().values[0]
        except Exception as exc:  # noqa: BLE001 - the node went away mid-call: ask again
            self._asked.discard(name)
            self.get_logger().warn(f'could not read {name}: {exc}')
            return
        values = list(value.double_array_value)
        if name == 'inertia' and values:
            try:
                self.view.set_body(RigidBody.from_inertia(values))
                self.get_logger().info(f'body: principal moments '
                                       f'{self.view.body.principal_moments.tolist()} kg·m²')
            except ValueError as exc:
                self.get_logger().error(f'simulator inertia: {exc}')
        elif name == 'target_attitude' and len(values) == 4 and self.target is None:
            q = np.asarray(values)
            self.target = tuple(q / np.linalg.norm(q))

    # --- diagnostics -----------------------------------------------------------------------
    def _on_diagnostics(self, cdr):
        # logged at the latest state's stamp, so it lines up with the state in playback
        self.view.publish_diagnostics(self.last_stamp_ns or time.time_ns(), cdr)
        if b'resets' in cdr:  # decoded only when it may be the simulator's (~1 Hz)
            self._check_reset(cdr)

    def _check_reset(self, cdr):
        from rclpy.serialization import deserialize_message
        for status in deserialize_message(cdr, DiagnosticArray).status:
            if status.hardware_id != self._simulator:
                continue
            value = next((kv.value for kv in status.values if kv.key == 'resets'), None)
            if value is None or not value.isdigit():
                continue
            n = int(value)
            if self._resets is not None and n != self._resets:
                # a new count, or a restarted simulator (back to 0): a new run
                self.view.reset()
                self.get_logger().info(
                    f'simulator reset (resets = {n}): drift baselines and polhode/herpolhode '
                    'traces restarted')
            self._resets = n

    def _diagnostics(self):
        counts = self.rejections.snapshot()
        new = {k: counts[k] - self.reported[k] for k in counts if counts[k] > self.reported[k]}
        if new:
            self.get_logger().warn('ignored client messages: ' + ', '.join(
                f'{n} {k}' for k, n in new.items()) + ' (answered with an error status)')
            self.reported = counts
        waiting = self.transforms == 0
        status = diagnostic_status(
            f'{self.get_name()}: foxglove', self.get_fully_qualified_name(),
            'WARN' if waiting else 'OK',
            'waiting for the simulator' if waiting else
            f'serving ws://{self.p["host"]}:{self.server_port}',
            dict({'port': self.server_port, 'subscriptions': self.listener.subscriptions,
                  'transforms_served': self.transforms, 'samples_served': self.samples,
                  'body_known': self.view.body is not None,
                  'rejected_' + 'invalid_message': counts['invalid_message'],
                  'rejected_unknown_channel': counts['unknown_channel']}))
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)

    def close(self):
        self.server.stop()
        if self.mcap is not None:
            self.mcap.close()


def main(args=None):
    """Entry point of ``ros2 run rigid_body_sim viewer``; returns the exit code."""
    return run_node(NODE_NAME, Viewer, run=_spin, args=args, exit_codes={fox.PortInUse: 1},
                    close=lambda node: node.close())


def _spin(node):
    """rclpy's C++ events executor, turned from here: the Python executor rebuilds its wait
    set at every message (50 Hz), which cost more than the viewer's own work. Turned in
    short spin_once calls rather than spin(), which in rclpy 7.1 neither returns on SIGINT
    nor lets the parameter client's futures settle without busy-looping."""
    with events_executor(node) as executor:
        while node.context.ok():
            executor.spin_once(timeout_sec=0.1)


if __name__ == '__main__':
    sys.exit(main())
