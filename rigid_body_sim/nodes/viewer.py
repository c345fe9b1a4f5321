"""``attitude_viewer``: the live simulation in Foxglove, served from this process.

A separate node, so a viewer problem never stops the simulation. It subscribes to the
simulator's state and serves it with the Foxglove SDK's WebSocket server (default
ws://127.0.0.1:8765) on the channels described in :mod:`rigid_body_sim.viewer.view`.

Topics (relative names, remappable):
    sub ``imu`` (sensor_msgs/Imu: the attitude base_link → world and ω in base_link of one
        sample, one stamp; the simulator's ideal IMU, the same values as its ``attitude``
        and ``angular_velocity``), ``orbit`` (nav_msgs/Odometry, scenes with an orbit),
        ``attitude_target`` (QuaternionStamped), ``/diagnostics``. For a formation, each
        spacecraft's ``<name>/imu`` and ``<name>/orbit``: the simulator's status lists the
        spacecraft (``spacecraft_names``), so one spawned is drawn and one deleted taken out
        within a diagnostics period (the simulator publishes one at each spawn and delete).
    The simulator's ``resets`` diagnostics value (counting ``~/reset``, ResetSimulation and
    set_state) restarts the drift baselines and the traces: sim time keeps running across a
    reset, so the stamps alone do not show one.
    pub ``/diagnostics`` (this node's status: subscriptions, samples served, client
        messages refused by reason).

The body (for the inertia box, T and the energy ellipsoid) comes from the simulator's
``inertia`` parameter, asked over its parameter service (a formation's spacecraft's from
their statuses' ``inertia``: a spawned one has no parameter); the pointing error's target from
the controller's ``target_attitude`` or the latest ``attitude_target`` message. L (world) is
R(q)·Iω from the same sample, equal to the simulator's ``angular_momentum`` to round-off: one
subscription instead of three keeps the viewer's cost low (see ``bench/viewer.py``).
The orbit's Sun and field are dated by the simulator's ``epoch`` and the sim time of each
sample, which its diagnostics give (``viewer/orbit_view.py``).
"""
import json
import sys
import time

import numpy as np
from rclpy.node import Node

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import QuaternionStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import ParameterType
from sensor_msgs.msg import Imu

from ..physics.body import RigidBody
from ..viewer import geometry, orbit_view, view as fox
from ..viewer.specs import LOOPBACK, VIEWER
from .common import declare_parameters, diagnostic_status, qos_profile
from .process import events_executor, run_node
from .state_messages import imu_state

NODE_NAME = 'attitude_viewer'
DIAGNOSTICS_PERIOD_S = 1.0   # wall clock
WAIT_NOTICE_S = 2.0          # no state after this long: say once that we wait
IGRF_PERIOD_S = 1.0          # wall seconds between drawings of an IGRF field
ASK_AGAIN_S = 3.0            # a parameter request unanswered this long is sent again
# the simulator's values that date and place the orbit's Sun and field (absent ones: unset)
ENVIRONMENT_PARAMETERS = ['orbit.model', 'epoch', 'publish_clock',
                          'environment.magnetic_field']


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
        self._qos = qos_profile(p['qos'], 100)
        self.create_subscription(QuaternionStamped, 'attitude_target', self._on_target,
                                 self._qos)
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
        self._subs = {}      # spacecraft name ('' unnamed) -> its subscriptions
        self._inertia = {}   # spacecraft name -> the inertia text its body was built from
        self._next_orbit = {}  # spacecraft name -> (stamp, wall time) of its next orbit drawing
        self.sim_time = orbit_view.SimTime()
        self.environment = None  # orbit_view.Environment once the simulator's values are read
        self._publish_clock = False
        self._watch('')
        from rclpy.parameter_client import AsyncParameterClient
        simulator = AsyncParameterClient(self, p['simulator_node'])
        self._asks = {  # what is asked of whom, and when (None: answered)
            'inertia': (simulator, ['inertia']),
            'target_attitude': (AsyncParameterClient(self, p['controller_node']),
                                ['target_attitude']),
            'environment': (simulator, ENVIRONMENT_PARAMETERS)}
        self._asked = {}  # ask -> monotonic time of the request in flight (absent: not asked)
        self.create_timer(0.5, self._poll)
        self.create_timer(DIAGNOSTICS_PERIOD_S, self._diagnostics)

    # --- the spacecraft and their state ----------------------------------------------------
    def _watch(self, name):
        """Subscribe to spacecraft ``name``'s state (``<name>/imu``, ``<name>/orbit``)."""
        if name in self._subs:
            return
        self.view.add_craft(name)
        prefix = f'{name}/' if name else ''
        # one topic carries q and ω of a sample (one stamp, no joining): the cheapest to take,
        # raw and decoded by imu_state (state_messages: why)
        self._subs[name] = [
            self.create_subscription(Imu, prefix + 'imu',
                                     lambda m, n=name: self._on_imu(m, n), self._qos,
                                     raw=True),
            self.create_subscription(Odometry, prefix + 'orbit',
                                     lambda m, n=name: self._on_orbit(m, n), self._qos)]

    def _unwatch(self, name):
        for sub in self._subs.pop(name, []):
            self.destroy_subscription(sub)
        self._inertia.pop(name, None)
        self._next_orbit.pop(name, None)
        self.view.remove_craft(name, self.last_stamp_ns or time.time_ns())

    def _on_imu(self, data, name=''):
        stamp, q, w = imu_state(data)
        self.view.transform(stamp, q, name)
        self.transforms += 1
        self.last_stamp_ns = stamp
        craft = self.view.crafts.get(name)
        if craft is not None and craft.body is not None:
            self.samples += 1
            self.view.sample(stamp, q, w, self.target if not name else None, name)

    def _on_orbit(self, msg, name=''):
        """The orbit's state: drawn at the scene's rate (the path and the field cost more
        than a sample)."""
        s = msg.header.stamp
        stamp = s.sec * 1_000_000_000 + s.nanosec
        env, now = self.environment, time.monotonic()
        due_stamp, due_wall = self._next_orbit.get(name, (0, 0.0))
        period = self.view.scene_period_ns
        # a stamp far behind the last drawing: the simulator started again (publish_clock)
        if (due_stamp - 2 * period <= stamp < due_stamp) or now < due_wall:
            return
        # IGRF in full costs 70 ms a call: drawn at most once a wall second
        slow = env is not None and env.field_model != 'dipole'
        self._next_orbit[name] = (stamp + period, now + IGRF_PERIOD_S if slow else 0.0)
        pose, v = msg.pose.pose, msg.twist.twist.linear
        r = (pose.position.x, pose.position.y, pose.position.z)
        o = pose.orientation  # LVLH → world; the twist is resolved in LVLH (REP-105)
        v_world = geometry.rotate_vector((o.x, o.y, o.z, o.w), (v.x, v.y, v.z))
        size = self.view.body_size
        try:
            frame = orbit_view.OrbitFrame(r, v_world, size=size, stamp_ns=stamp) \
                if env is None else env.frame(r, v_world, self.sim_time(stamp), size, stamp)
        except ValueError as exc:  # not a closed orbit: nothing to draw
            self.get_logger().warn(f'{msg.child_frame_id}: {exc}', throttle_duration_sec=10.0)
            return
        self.view.set_orbit(frame, name)

    def _on_target(self, msg):
        o = msg.quaternion
        self.target = (o.x, o.y, o.z, o.w)

    # --- the simulator's values and the controller's target --------------------------------
    def _poll(self):
        if not self.said_waiting and self.transforms == 0 and \
                time.monotonic() - self.started > WAIT_NOTICE_S:
            self.said_waiting = True
            self.get_logger().info(
                f'waiting for the simulator: no state on {self.resolve_topic_name("imu")} '
                'yet (serving Foxglove meanwhile)')
        now = time.monotonic()
        for ask, (client, names) in self._asks.items():
            sent = self._asked.get(ask, -1.0)
            if sent is None:
                continue  # answered
            # a request unanswered for ASK_AGAIN_S is sent again: a reply can be lost (a
            # server that has not yet matched this client's reply reader drops it, and a
            # server that went away never answers), and rclpy's future then never settles
            if sent >= 0.0 and now - sent < ASK_AGAIN_S:
                continue
            if client.services_are_ready():
                self._asked[ask] = now
                client.get_parameters(names, callback=lambda f, a=ask: self._got(a, f))

    def _got(self, ask, future):
        if self._asked.get(ask) is None:
            return  # a late reply to a request sent again: the first one counted
        try:
            values = future.result().values
        except Exception as exc:  # noqa: BLE001 - the node went away mid-call: ask again
            self._asked.pop(ask, None)
            self.get_logger().warn(f'could not read {ask}: {exc}')
            return
        self._asked[ask] = None
        if ask == 'environment':
            self._set_environment(dict(zip(ENVIRONMENT_PARAMETERS, values)))
            return
        numbers = list(values[0].double_array_value)
        if ask == 'inertia' and numbers:
            self._set_body('', numbers)
        elif ask == 'target_attitude' and len(numbers) == 4 and self.target is None:
            q = np.asarray(numbers)
            self.target = tuple(q / np.linalg.norm(q))

    def _set_body(self, name, inertia):
        craft = f'spacecraft {name}: ' if name else ''
        try:
            self.view.set_body(RigidBody.from_inertia(inertia), name)
        except ValueError as exc:
            self.get_logger().error(f'{craft}simulator inertia: {exc}')
            return
        self.get_logger().info(f'{craft}body: principal moments '
                               f'{self.view.crafts[name].body.principal_moments.tolist()} kg·m²')

    def _set_environment(self, values):
        """The simulator's epoch and field model: the Sun and the field along the orbit."""
        from ..engine.environment_specs import parse_epoch
        def text(value):
            return value.string_value if value.type == ParameterType.PARAMETER_STRING else ''
        clock = values['publish_clock']
        self._publish_clock = clock.type == ParameterType.PARAMETER_BOOL and clock.bool_value
        if text(values['orbit.model']) in ('', 'none'):
            return  # no orbit: nothing of it to draw
        model = text(values['environment.magnetic_field'])
        model = model if model in orbit_view.FIELD_MODELS else 'dipole'
        try:
            epoch = parse_epoch(text(values['epoch']))
            self.environment = orbit_view.Environment(epoch, model)
        except ValueError as exc:
            self.get_logger().error(f'the Sun and the field are not drawn: {exc}')
            return
        self.get_logger().info(
            f'orbit: the Sun and the {model} field drawn for epoch '
            f'{self.environment.epoch.isoformat()}'
            + ('' if epoch else ' (the scene gives no epoch: J2000 assumed)'))

    # --- diagnostics -----------------------------------------------------------------------
    def _on_diagnostics(self, cdr):
        # logged at the latest state's stamp, so it lines up with the state in playback
        self.view.publish_diagnostics(self.last_stamp_ns or time.time_ns(), cdr)
        if b'resets' in cdr:  # decoded only when it may be the simulator's (~1 Hz)
            self._check_reset(cdr)

    def _check_reset(self, cdr):
        """The simulator's statuses: its reset count, its spacecraft (a formation's names,
        each one's inertia) and the (stamp, sim time) pair that dates the orbit's samples."""
        from rclpy.serialization import deserialize_message
        array = deserialize_message(cdr, DiagnosticArray)
        stamp = array.header.stamp.sec * 1_000_000_000 + array.header.stamp.nanosec
        simulation = f'{self.p["simulator_node"]}: simulation'
        names, sim_time, rtf = None, [], None
        for status in array.status:
            if status.hardware_id != self._simulator:
                continue
            values = {kv.key: kv.value for kv in status.values}
            if 'sim_time' in values:
                sim_time.append(_number(values['sim_time']))
            if status.name != simulation:  # one spacecraft of a formation
                self._craft_status(status.name.split(': ', 1)[-1], values)
                continue
            rtf = _number(values.get('real_time_factor_target', ''))
            if 'spacecraft_names' in values:
                names = [n.strip() for n in values['spacecraft_names'].split(',') if n.strip()]
            else:
                names = ['']  # one unnamed spacecraft: the node's own topics
            value = values.get('resets')
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
        if names is not None:
            self._follow(names)
        sim_time = [t for t in sim_time if t is not None]
        # dated only once publish_clock is known: it sets the slope
        if sim_time and rtf is not None and self._asked.get('environment', -1) is None:
            self.sim_time.set(stamp, max(sim_time), rtf, self._publish_clock)

    def _follow(self, names):
        """The simulator's spacecraft now: new ones watched, deleted ones taken out (the
        unnamed one's subscriptions stay: a single-body scene may come back)."""
        for name in names:
            if name not in self._subs:
                self._watch(name)
                self.get_logger().info(f'spacecraft {name}: drawn from {name}/imu')
        for name in [n for n in self._subs if n and n not in names]:
            self._unwatch(name)
            self.get_logger().info(f'spacecraft {name}: gone from the simulation, taken out '
                                   'of the scene')

    def _craft_status(self, name, values):
        """A formation's spacecraft's status: its body from its ``inertia``."""
        text = values.get('inertia')
        if name not in self._subs or not text or self._inertia.get(name) == text:
            return
        self._inertia[name] = text
        try:
            inertia = [float(x) for x in json.loads(text)]
        except (ValueError, TypeError):
            self.get_logger().error(f'spacecraft {name}: inertia {text!r} is not a list of '
                                    'numbers')
            return
        self._set_body(name, inertia)

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
                  'spacecraft_drawn': ', '.join(self.view.drawn()),
                  'rejected_' + 'invalid_message': counts['invalid_message'],
                  'rejected_unknown_channel': counts['unknown_channel']}))
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diag_pub.publish(array)

    def close(self):
        self.server.stop()
        if self.mcap is not None:
            self.mcap.close()


def _number(text):
    try:
        return float(text)
    except ValueError:
        return None


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
