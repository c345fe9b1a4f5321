"""One spacecraft of the simulator node: its engine, its messages and publishers, its inputs.

The node (``simulator.py``) holds one per spacecraft and steps them in the same tick
(``engine/fleet.py`` says how a scene declares them). One engine per spacecraft rather
than one batch kernel over all: each carries its own events (commands and their expiry,
sensor readings), its own method (``auto`` chooses per body; wheels and CMGs take the
gyrostat method) and its own faults, which the batch kernels (one fixed method over
torque-free bodies) do not.

The unnamed spacecraft (a scene without ``spacecraft``) publishes in the node's namespace,
exactly as the single-body simulator always has; a named one publishes the same topics
under ``<name>/`` and takes commands there. /tf and /clock are the node's, shared.
"""
import time

from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rclpy._rclpy_pybind11 import RCLError
from sensor_msgs.msg import MagneticField
from std_msgs.msg import Float64MultiArray

from ..engine import EngineConfig, lockstep
from .commands import CommandFilter
from .common import qos_profile
from .orbit_messages import OrbitPublishers
from .joint_commands import JointCommands
from .magnetic_messages import TOPIC as MAGNETOMETER_TOPIC, MagnetometerMessages
from .sensor_messages import SensorMessages
from .state_messages import StateMessages

STATE_DEPTH = 100            # history of state topics: reliable delivery survives short stalls


def check_parameters(p, controller=None):
    """Validate one spacecraft's full set of coerced values; ValueError(reason).
    ``controller``: in lockstep, the controller's values from the same params files, so
    that ``auto`` chooses as the offline run of the scene does (lockstep.law_bandwidth)."""
    if p['lockstep']:
        lockstep.period_ns(p)
        return EngineConfig.from_parameters(p, law_bandwidth=lockstep.law_bandwidth(controller))
    return EngineConfig.from_parameters(p)


class Spacecraft:
    """``name`` ('' for the unnamed one), ``values`` its simulator values
    (``fleet.craft_values``), started at sim time ``start_ns``. ``tf``: the node's /tf
    publisher (None without tf2_msgs); ``on_command(craft, header, vector, source)`` and
    ``on_actuator(craft, msg)``: the node's command handlers."""

    def __init__(self, node, name, values, start_ns=0, tf=None, qos=None, state_qos=None,
                 on_command=None, on_actuator=None, controller=None, ready=None):
        self.name, self.p, self.controller = name, values, controller
        self.prefix = f'{name}/' if name else ''
        # imported here: the physics and numba (~0.4 CPU-s) load with the first engine, not
        # at the node's start, so that parameters refused before it never load them
        from ..engine import Engine
        self.engine = Engine(check_parameters(values, controller), blocking_selection=False,
                             check_method=True, start_ns=start_ns)
        self.method = self.engine.method
        self.fault = None
        actuators = self.engine.config.actuators
        self.notes = list(actuators.notes) if actuators is not None else []
        self.msgs = StateMessages(values['frame_id'], values['child_frame_id'],
                                  actuators=actuators)
        if tf is not None:
            from tf2_msgs.msg import TFMessage
            self.msgs.add_topic('/tf', TFMessage(transforms=[self.msgs.transform]))
        pub = node.create_publisher
        # every state message of a sample is published as CDR bytes (state_messages: why)
        self.pubs = [(tf if name == '/tf' else pub(type(msg), self.prefix + name, state_qos),
                      name) for name, msg in self.msgs.topics()]
        self.sensor_msgs, self.sensor_pubs = None, {}  # gyro / star_tracker, if simulated
        if self.engine.config.sensors is not None:
            self.sensor_msgs = SensorMessages(self.engine.config.sensors, *self.frames)
            self.sensor_pubs = {name: pub(type(msg), self.prefix + name, state_qos)
                                for name, msg in self.sensor_msgs.topics()}
        self.orbit = None  # the orbit's topics, for a scene with one (orbit_messages)
        if self.engine.config.environment is not None:
            tf_type = None
            if tf is not None:  # /tf exists where tf2_msgs does (a full ROS install)
                from tf2_msgs.msg import TFMessage as tf_type
            self.orbit = OrbitPublishers(node, self.engine.config, values, state_qos,
                                         getattr(node, '_tf_qos', qos_profile('reliable', 100)),
                                         tf_type,
                                         prefix=self.prefix)
        self.active, self.active_names, self.active_raw = [], frozenset(), []
        self.commands = CommandFilter(node, values)
        sub = node.create_subscription
        self.command_subs = [  # the unnamed one's are the node's (it routes them)
            sub(Vector3Stamped, self.prefix + 'torque_command', lambda m: on_command(
                self, m.header, m.vector, self.prefix + 'torque_command'), qos),
            sub(WrenchStamped, self.prefix + 'wrench_command', lambda m: on_command(
                self, m.header, m.wrench.torque, self.prefix + 'wrench_command'), qos)
        ] if name else []
        # magnetorquers: dipole_command, checked by the torque commands' rules; the
        # magnetometer's readings on magnetic_field (magnetic_messages)
        self.dipoles, self.mag_msgs, self.mag_pub = None, None, None
        magnetics = self.engine.magnetics
        if magnetics is not None and magnetics.hold is not None:
            self.dipoles = CommandFilter(node, values, what='dipole')
            self.command_subs.append(sub(
                Vector3Stamped, self.prefix + 'dipole_command', lambda m: on_command(
                    self, m.header, m.vector, self.prefix + 'dipole_command', dipole=True),
                qos))
        if magnetics is not None and magnetics.meter is not None:
            self.mag_msgs = MagnetometerMessages(magnetics.meter.settings,
                                                 values['child_frame_id'])
            self.mag_pub = pub(MagneticField, self.prefix + MAGNETOMETER_TOPIC, state_qos)
        self.actuator_warn = 0.0
        self.joints = None
        if actuators is not None:  # ros2_control forward-command convention
            self.command_subs.append(sub(Float64MultiArray, self.prefix + 'actuator_command',
                                         lambda m: on_actuator(self, m), qos))
            # ros2_control's joint_state_topic_hardware_interface (joint_commands.py)
            self.joints = JointCommands(node, self.engine, qos, lambda: ready(self),
                                        prefix=self.prefix)
            self.command_subs.append(self.joints.subscription)

    @property
    def entity(self) -> str:
        """Its entity name (simulation_interfaces): the name, or the body frame if unnamed."""
        return self.name or self.p['child_frame_id']

    @property
    def frames(self):
        """(frame_id, child_frame_id): the inertial and the body frame."""
        return self.p['frame_id'], self.p['child_frame_id']

    def publishers(self):
        return [p for p, _ in self.pubs] + list(self.sensor_pubs.values()) + \
            ([self.mag_pub] if self.mag_pub is not None else [])

    def refresh(self):
        """Only topics with subscribers are built and published (a late one joins here)."""
        self.active = [(p, name) for p, name in self.pubs if p.get_subscription_count() > 0]
        self.active_names = frozenset(name for _, name in self.active)
        # rcl's publish of CDR bytes, bound once: Publisher.publish's checks and handle
        # context cost as much again per message (1.5 against 0.75 µs of CPU)
        self.active_raw = [(p.handle.publish_raw, p, name) for p, name in self.active]
        if self.orbit is not None:
            self.orbit.refresh()

    def publish_states(self, states, refused, at=None):
        """The state messages of consecutive samples (``states``: {topic: [CDR bytes of
        each sample]}, StateMessages.encoded_block) on the subscribed topics, topic by
        topic: Fast DDS's sending thread puts a writer's consecutive messages into one
        datagram, one shared-memory push and one wake-up of the reader, so a block sent
        topic by topic cost its publisher 34-41 µs of CPU a sample against 82 sample by
        sample (nine raw topics, keep-all, one reader in another process). Each topic
        keeps its order. ``at``: only that sample's. ``refused(topic, exc)``: a publish
        refused because a paced reader's history is full (sim_acks)."""
        for send, publisher, name in self.active_raw:
            data = states[name]
            for message in data if at is None else data[at:at + 1]:
                try:
                    send(message)
                except RCLError as exc:
                    refused(publisher.topic_name, exc)

    def set_values(self, values):
        """New simulator values (a parameter change): the engine reconfigures at once."""
        self.engine.reconfigure(check_parameters(values, self.controller))
        old, self.p = self.p, values
        self.commands.params = values
        if self.dipoles is not None:
            self.dipoles.params = values
        if (old['frame_id'], old['child_frame_id']) != self.frames:
            self.msgs.set_frames(*self.frames)
            if self.sensor_msgs is not None:
                self.sensor_msgs.set_frames(*self.frames)
            if self.mag_msgs is not None:
                self.mag_msgs.set_frame(self.frames[1])

    def publish_sensors(self, block, stamp_ns) -> int:
        """The block's sensor readings, at their own instants, stamped by ``stamp_ns``;
        returns the most messages published on one topic (the node's acknowledgement
        window counts them)."""
        counts = {}
        if block.sensors is not None:
            only = frozenset(n for n, p in self.sensor_pubs.items()
                             if p.get_subscription_count() > 0)
            for _, name, msg in self.sensor_msgs.messages(block.sensors, stamp_ns, only):
                self.sensor_pubs[name].publish(msg)
                counts[name] = counts.get(name, 0) + 1
        if block.magnetometer is not None and self.mag_pub.get_subscription_count() > 0:
            for _, msg in self.mag_msgs.messages(block.magnetometer, stamp_ns):
                self.mag_pub.publish(msg)
                counts[''] = counts.get('', 0) + 1
        return max(counts.values(), default=0)

    def destroy(self, node):
        """Take its publishers and subscriptions off the graph (the shared /tf stays)."""
        for p, name in self.pubs:
            if name != '/tf':
                node.destroy_publisher(p)
        for p in list(self.sensor_pubs.values()) + \
                ([self.mag_pub] if self.mag_pub is not None else []):
            node.destroy_publisher(p)
        for s in self.command_subs:
            node.destroy_subscription(s)
        if self.orbit is not None:
            self.orbit.destroy(node)
        self.pubs, self.sensor_pubs, self.command_subs, self.active = [], {}, [], []
        self.active_raw = []
        self.active_names = frozenset()

    def warn_actuator(self, log, exc):
        """A rejected actuator command: warned about, throttled (the engine counts it)."""
        now = time.monotonic()
        if now >= self.actuator_warn:
            self.actuator_warn = now + 2.0
            log.warn(f'{self.prefix}actuator_command rejected: {exc}; the last valid command '
                     f'is held ({self.engine.actuators.rejected} rejections so far)')
