"""``attitude_simulator``: live rigid-body attitude simulation on standard ROS 2 topics.

A thin shell over :class:`rigid_body_sim.engine.Engine`: it declares the parameters
(``engine.specs.SIMULATOR``), paces the engine against the wall clock, turns its samples
into messages (``StateMessages``), and turns commands, parameter changes and ``~/reset``
into engine calls.

Time stamps. Every message carries the sim time of the state it holds, mapped to ROS time
in one way: with ``publish_clock: true`` the stamp is the sim time (and equals /clock);
otherwise it is the wall-clock time at which the run started plus sim time divided by
``real_time_factor`` (1 when running as fast as possible). Consecutive samples are
therefore exactly one sample period apart whatever the load, and all topics of one sample
share the stamp. A sample published later than ``deadline_tolerance`` (wall time) after
its due time counts as a missed deadline in diagnostics, with the worst lateness of each
diagnostics period; it never bends a stamp.

Pacing. The engine processes its events (samples, command expiry) up to the sim time the
wall clock allows; between those, the executor serves callbacks and the ``auto`` pilot
runs in small slices. With ``real_time_factor: 0`` the engine runs in chunks of at most
``CHUNK_WALL_S`` wall seconds between executor turns.

Lockstep (``lockstep: true``, ``engine/lockstep.py``). The engine never advances past a
control instant (a multiple of the ``control_rate`` period in sim time) until the command
stamped with that instant's state stamp has been applied there; it reports a pause after
``lockstep_timeout`` and keeps waiting. Whatever the pacing and the load, the run is then
the offline run's.
"""
import sys
import time
from dataclasses import replace

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.parameter import Parameter

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Float64MultiArray
from std_srvs.srv import Trigger

from ..engine import NS, Engine, EngineConfig, lockstep, specs
from ..physics import IntegrationError
from ..scene import SceneError, params_files_record
from .commands import CommandFilter
from .common import (changed_values, declare_parameters, diagnostic_status, qos_profile,
                     validate_update)
from .process import events_executor, run_node
from .usage import ros_arguments
from .sim_services import AVAILABLE as SIM_SERVICES, SimulationServices
from .sensor_messages import SensorMessages, sensors_summary
from .orbit_messages import OrbitPublishers
from .state_messages import StateMessages

try:  # /tf only where tf2_msgs exists (a full ROS install); the PyPI venv has none
    from tf2_msgs.msg import TFMessage
except ImportError:  # pragma: no cover - depends on the installation
    TFMessage = None

NODE_NAME = 'attitude_simulator'
SPECS = specs.SIMULATOR
CHUNK_WALL_S = 0.02          # longest stretch of engine work between executor turns
LIVE_BLOCK = 16              # samples per engine call (each is published before the next)
SUBSCRIBER_REFRESH_S = 0.25  # how often matched-subscriber counts are re-read
# wait_for_subscribers: the counts must hold this long, as the replies of the peers already
# running to a new participant's announcement arrive within a few milliseconds of each other
SUBSCRIBER_SETTLE_S = 0.2
DIAGNOSTICS_PERIOD_S = 1.0   # wall clock
MAX_LAG_S = 1.0              # behind the wall-clock target by more: drop the backlog
PILOT_SLICE_S = 0.002        # least time for auto's pilot per loop turn (as fast as possible)
QUIT_GRACE_S = 0.5           # a quit request's reply goes out before the node goes away
# parameters after whose change the engine configures its method again
NUMERICS = {'integrator', 'step', 'accuracy', 'publish_rate', 'duration', 'dissipation.model',
            'dissipation.coefficient'}
STATE_DEPTH = 100            # history of state topics: reliable delivery survives short stalls
ACK_EVERY = STATE_DEPTH // 2  # as fast as possible: wait for acknowledgements this often
ACK_TIMEOUT = Duration(seconds=1.0)  # then go on (a subscriber that hangs stalls no run)


def check_parameters(p):
    """Validate a full set of coerced values (frames, inertia, ...); ValueError(reason)."""
    if p['lockstep']:
        lockstep.period_ns(p)
    return EngineConfig.from_parameters(p)


class Simulator(Node):
    """The ``attitude_simulator`` node.

    Build, then call :meth:`run` (or drive :meth:`run_once`).
    """

    def __init__(self, **kwargs):
        # undeclared names reach our on-set check, which refuses them with a reason
        super().__init__(NODE_NAME, allow_undeclared_parameters=True, **kwargs)
        try:
            # the scene it runs (SCENE_RECORD), for a recorder's run record: by default
            # from the params files; not physics, so kept out of the engine's values
            record = params_files_record(ros_arguments()[0])
            self._p = declare_parameters(self, [replace(s, default=record.get(s.name, s.default))
                                                for s in specs.SIMULATOR_DECLARED])
            self.scene_record = {s.name: self._p.pop(s.name) for s in specs.SCENE_RECORD}
            self._engine = Engine(check_parameters(self._p), blocking_selection=False,
                                  check_method=True)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        self._log = self.get_logger()
        actuators = self._engine.config.actuators
        self._msgs = StateMessages(self._p['frame_id'], self._p['child_frame_id'],
                                   actuators=actuators)
        for note in actuators.notes if actuators is not None else ():
            self._log.info(note)
        self._clock_msg = Clock()
        qos = qos_profile(self._p['qos'])
        state_qos = qos_profile(self._p['qos'], STATE_DEPTH)
        pub = self.create_publisher
        if TFMessage is not None:
            self._msgs.add_topic('/tf', TFMessage(transforms=[self._msgs.transform]))
        # every state message of a sample is published as CDR bytes (state_messages: why)
        self._pubs = [(pub(type(msg), name, qos_profile('reliable', 100) if name == '/tf'
                           else state_qos), name) for name, msg in self._msgs.topics()]
        self._sensor_msgs, self._sensor_pubs = None, {}  # gyro / star_tracker, if simulated
        if self._engine.config.sensors is not None:
            self._sensor_msgs = SensorMessages(self._engine.config.sensors, *self.frames)
            self._sensor_pubs = {name: pub(type(msg), name, state_qos)
                                 for name, msg in self._sensor_msgs.topics()}
        self._orbit = None  # the orbit's topics, for a scene with one (orbit_messages)
        if self._engine.config.environment is not None:
            try:
                self._orbit = OrbitPublishers(self, self._engine.config, self._p, state_qos,
                                              qos_profile('reliable', 100), TFMessage)
            except ValueError as exc:
                raise SceneError(str(exc)) from None
        self._clock_pub = None
        if self._p['publish_clock']:
            self._clock_pub = pub(Clock, '/clock', qos_profile('reliable'))
        self._diag_pub = pub(DiagnosticArray, '/diagnostics', qos_profile('reliable'))
        self._active = []
        self._commands = CommandFilter(self, self._p)
        self._command_subs = [
            self.create_subscription(Vector3Stamped, 'torque_command', lambda m: self._on_command(
                m.header, m.vector, 'torque_command'), qos),
            self.create_subscription(WrenchStamped, 'wrench_command', lambda m: self._on_command(
                m.header, m.wrench.torque, 'wrench_command'), qos)]
        if actuators is not None:  # ros2_control forward-command convention
            self._actuator_warn = 0.0
            self.create_subscription(Float64MultiArray, 'actuator_command',
                                     self._on_actuator_command, qos)
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.paused = False
        self._quit_at = None  # wall time at which a requested quit ends the loop
        self._sim_services = SimulationServices(self) if SIM_SERVICES else None
        self._fault = None
        self._missed = self._missed_at_last_diag = 0
        self._resets = 0  # ~/reset and set_state: viewers restart their drift and traces on it
        self._worst_late = 0.0
        self._unacked, self._ack_warn = 0, 0.0  # samples since the last wait for acks
        self._method = self._engine.method
        # lockstep: the next control instant to hold (ns), the instant held (None: free to
        # advance), when its hold began (wall), whether its pause was reported
        self._lockstep = lockstep.period_ns(self._p) if self._p['lockstep'] else 0
        self._instant, self._held, self._held_since, self._paused_reported = 0, None, 0.0, False
        self._lockstep_pauses = 0
        self._round_trips = lockstep.RoundTrips()
        self._base_stamp(self.get_clock().now().nanoseconds)
        self._anchor()
        self._last_diag = (time.monotonic(), 0)
        self._next_diag_wall = 0.0
        self._next_refresh_wall = 0.0
        self.add_on_set_parameters_callback(
            lambda params: validate_update(SPECS, self._p, params, check_parameters))
        self.add_post_set_parameters_callback(self._apply_parameters)
        if self.scene_record['scene.name']:
            self._log.info(f"scene {self.scene_record['scene.name']} (params files' sha256 "
                           f"{self.scene_record['scene.sha256'][:12]}...)")
        self._log.info(self._summary())
        self._warn_method()

    def _warn_method(self):
        """A fixed method's step outside its stability or far from the accuracy budget
        (the engine checks it whenever it configures one): said, not refused, live."""
        for _, message in self._engine.method_warnings:
            self._log.warning(message)

    # ------------------------------------------------------------------ time
    def _base_stamp(self, epoch_ns: int):
        """Stamps from now on: epoch_ns at the current sim time, then sim time / rtf."""
        self._stamp0, self._sim0 = int(epoch_ns), self._engine.t_ns
        self._rtf = self._p['real_time_factor'] or 1.0

    def stamp_ns(self, t_ns: int) -> int:
        """The header stamp (ns) of the state at sim time ``t_ns`` (see module docstring)."""
        if self._p['publish_clock']:
            return t_ns
        return self._stamp0 + round((t_ns - self._sim0) / self._rtf)

    def _anchor(self):
        """Pace from now: the engine's sim time corresponds to the wall time now."""
        self._wall_anchor, self._sim_anchor = time.monotonic(), self._engine.t_ns

    def _due_wall(self, t_ns: int) -> float:
        return self._wall_anchor + (t_ns - self._sim_anchor) / (NS * self._p['real_time_factor'])

    # ------------------------------------------------------------------ loop
    def _advance(self, until_ns: int, deadline: float, late: bool = True):
        """Engine events up to ``until_ns`` (or the deadline), publishing every sample
        (``late``: count lateness against the wall clock; not when stepping)."""
        engine = self._engine
        if self._lockstep:  # never past the next control instant, and not while one is held
            if self._held is not None:
                return
            until_ns = min(until_ns, self._instant)
        while not (self._fault or engine.finished):
            try:
                block = engine.advance(until_ns, deadline, max_samples=LIVE_BLOCK)
            except IntegrationError as exc:
                return self._set_fault(f'integrator failed: {exc}')
            except Exception as exc:  # noqa: BLE001 - never die with a traceback on bad input
                return self._set_fault(f'physics error: {type(exc).__name__}: {exc}')
            self._publish(block, late)
            if self._lockstep and engine.t_ns == self._instant and not engine.finished:
                self._hold()
                break
            if engine.method != self._method:
                self._method = engine.method
                self._log.info(f'integrator {engine.method}, step {engine.step_max:.6g} s '
                               f'({engine.reason})')
            if len(block) < LIVE_BLOCK or time.monotonic() > deadline:
                break
        if engine.finished and not self._fault:
            self._log.info(f'duration {self._p["duration"]:g} s reached at t = {engine.t:.6g} s;'
                           ' stopping')
            if self._lockstep:
                self._log.info(self._round_trips.summary())
            self._publish_diagnostics()

    def _publish(self, block, late=True):
        msgs, rtf = self._msgs, (self._p['real_time_factor'] if late else 0)
        if block.sensors is not None:  # readings at their own instants, stamped likewise
            for _, name, msg in self._sensor_msgs.messages(block.sensors, self.stamp_ns):
                self._sensor_pubs[name].publish(msg)
        for i in range(len(block)):
            t_ns = int(block.t_ns[i])
            data = msgs.encoded(block, i, self.stamp_ns(t_ns)) if self._active else None
            if self._clock_pub is not None:
                self._clock_msg.clock.sec, self._clock_msg.clock.nanosec = divmod(t_ns, NS)
                self._clock_pub.publish(self._clock_msg)
            for publisher, name in self._active:
                publisher.publish(data[name])
            if self._orbit is not None:
                self._orbit.publish(block, i, self.stamp_ns(t_ns))
            if self._paced and self._active:
                self._unacked += 1
                if self._unacked >= ACK_EVERY:
                    self._wait_acked()
            if rtf > 0:
                late = time.monotonic() - self._due_wall(t_ns)
                self._worst_late = max(self._worst_late, late)
                if late > self._p['deadline_tolerance']:
                    self._missed += 1

    @property
    def _paced(self) -> bool:
        """Publishing waits for acknowledgements: as fast as possible, or when subscribers
        were waited for (a recorder: it must get every sample, even if it lags)."""
        return not self._p['real_time_factor'] or self._p['wait_for_subscribers'] > 0

    def _wait_acked(self):
        """Hold until reliable subscribers have acknowledged what was published, so that
        no more than ACK_EVERY samples are ever unacknowledged and the STATE_DEPTH history
        never overwrites one a subscriber (a recorder) has not got. A subscriber that keeps
        up acknowledges within milliseconds: then this costs nothing."""
        self._unacked = 0
        slow = [name for p, name in self._active if not p.wait_for_all_acked(ACK_TIMEOUT)]
        if slow and time.monotonic() >= self._ack_warn:
            self._ack_warn = time.monotonic() + 5.0
            self._log.warning(f'subscribers of {", ".join(slow)} acknowledge nothing for '
                              f'{ACK_TIMEOUT.nanoseconds / NS:g} s; going on without them')

    def _catch_up(self, now=None):
        """Real-time modes: process what is due by the wall clock."""
        rtf = self._p['real_time_factor']
        if rtf == 0 or self._fault or self._engine.finished or self.paused:
            return
        now = time.monotonic() if now is None else now
        target = self._sim_anchor + int((now - self._wall_anchor) * rtf * NS)
        if self._lockstep and self._engine.selection_pending:
            return
        self._advance(target, now + CHUNK_WALL_S * 5)
        if (target - self._engine.t_ns) / (rtf * NS) > MAX_LAG_S:  # cannot keep up
            self._anchor()

    def run_once(self) -> float:
        """Advance what is due; returns the seconds the executor may wait before the next call."""
        now = time.monotonic()
        if now >= self._next_refresh_wall:
            self._refresh_subscribers()
            self._next_refresh_wall = now + SUBSCRIBER_REFRESH_S
        engine, rtf = self._engine, self._p['real_time_factor']
        wait = 0.1
        if self._lockstep and self._held is not None:
            wait = self._check_held(now)
        elif self._lockstep and engine.selection_pending:
            wait = 0.0  # auto's pilot first: its choice may not depend on the wall clock
        elif not (self._fault or engine.finished or self.paused):
            if rtf == 0:
                self._advance(self._instant if self._lockstep else sys.maxsize,
                              now + CHUNK_WALL_S)
                wait = 0.0
            else:
                self._catch_up(now)
                p = engine.config.sample_period_ns
                wait = self._due_wall((engine.t_ns // p + 1) * p) - time.monotonic()
        if engine.selection_pending:  # auto's pilot in the idle time, in small slices
            engine.work(time.monotonic() + max(min(wait, CHUNK_WALL_S) * 0.8, PILOT_SLICE_S))
        now = time.monotonic()
        if now >= self._next_diag_wall:
            self._publish_diagnostics()
        return min(max(wait, 0.0), self._next_diag_wall - now, 0.1)

    def _refresh_subscribers(self):
        self._active = [(p, name) for p, name in self._pubs if p.get_subscription_count() > 0]

    def run(self):
        """Spin until shutdown or ``duration`` is reached.

        On rclpy's C++ events executor: the loop turns at every sample (100 Hz), and the
        Python SingleThreadedExecutor rebuilds its wait set over every service and
        subscription each turn (~0.6 ms; the simulator has ~20), which cost more than the
        physics."""
        with events_executor(self) as executor:
            self._wait_for_subscribers(executor)
            self._base_stamp(self.get_clock().now().nanoseconds)
            self._anchor()  # pace from the first turn of the loop, not from construction
            while self.context.ok() and not self._engine.finished and not (
                    self._quit_at is not None and time.monotonic() >= self._quit_at):
                executor.spin_once(timeout_sec=self.run_once())
            if self._engine.finished and self._paced and self.context.ok():
                # the last samples are still in flight when the run ends: a recorder that
                # was waited for must get them before this process takes its writers away
                self._wait_acked()

    def _wait_for_subscribers(self, executor):
        """Hold t = 0 until every state publisher has ``wait_for_subscribers`` matched
        subscriptions (a recorder subscribed at its start: the bag then holds every sample
        from the first), or ``wait_for_subscribers_timeout`` has passed: then start anyway,
        with a warning naming the topics still without them."""
        n = self._p['wait_for_subscribers']
        if n <= 0 and not self._lockstep:
            return
        pubs = [p for p, _ in self._pubs] + list(self._sensor_pubs.values())

        def missing():
            """Topics with fewer than n matched subscriptions, or with one discovered but
            not matched yet (discovery delivers a node's subscriptions one by one); with
            lockstep, also a command topic without a matched publisher (the controller must
            get the state of t = 0)."""
            commands = [s.topic_name for s in self._command_subs]
            return [p.topic_name for p in pubs if p.get_subscription_count() < max(
                n, len(self.get_subscriptions_info_by_topic(p.topic_name)))] + (
                commands[:1] if self._lockstep and not any(
                    s.get_publisher_count() for s in self._command_subs) else [])
        timeout = self._p['wait_for_subscribers_timeout']
        self._log.info(f'waiting up to {timeout:g} s for {n} matched subscription(s) on each '
                       f'of {len(pubs)} state topics before t = 0 (wait_for_subscribers)'
                       + (' and a controller on torque_command (lockstep)'
                          if self._lockstep else ''))
        now = time.monotonic()
        deadline, settled = now + timeout, now + SUBSCRIBER_SETTLE_S
        paused, self.paused = self.paused, True  # commands arriving meanwhile advance nothing
        while self.context.ok() and time.monotonic() < deadline and self._quit_at is None:
            if missing():
                settled = time.monotonic() + SUBSCRIBER_SETTLE_S
            elif time.monotonic() >= settled:
                break
            executor.spin_once(timeout_sec=0.02)
        self.paused = paused
        left = missing()
        if left:
            self._log.warning(f'starting at t = 0 without {n} subscription(s) on '
                              f'{", ".join(left)} after {timeout:g} s (wait_for_subscribers); '
                              'they miss the first samples')
        else:
            self._log.info('every state topic has its subscribers; starting at t = 0')
        self._refresh_subscribers()
        self._last_diag = (time.monotonic(), self._engine.t_ns)  # the rate leaves the wait out

    @property
    def finished(self) -> bool:
        return self._engine.finished

    # ------------------------------------------------------------------ simulation control
    @property
    def engine(self):
        return self._engine

    @property
    def frames(self):
        """(frame_id, child_frame_id): the inertial and the body frame."""
        return self._p['frame_id'], self._p['child_frame_id']

    def pause(self):
        """Stop advancing sim time (what was due runs first)."""
        if not self.paused:
            self._catch_up()
            self.paused = True

    def play(self):
        """Advance again, paced from now."""
        self.paused = False
        self._anchor()

    def step(self, n: int):
        """While paused: advance ``n`` sample periods, publishing each sample; a problem
        text, or None."""
        e = self._engine
        if self._fault or e.finished:
            return f'cannot step: {self._fault or "the run reached its duration"}'
        p = e.config.sample_period_ns
        self._advance((e.t_ns // p + n) * p, float('inf'), late=False)
        return self._fault

    def reset(self):
        self._on_reset(None, Trigger.Response())

    def set_state(self, attitude, angular_velocity):
        """The body in a new state now (attitude body → frame_id, ω body frame)."""
        self._catch_up()
        self._engine.set_state(attitude, angular_velocity)
        self._fault = None
        self._log.info(f'state set at t = {self._engine.t:.6g} s')
        self._new_run()

    @property
    def parameters(self) -> dict:
        """The parameters' values now (a copy)."""
        return dict(self._p)

    def load_values(self, values: dict):
        """Set ``values`` ({name: value}) at once, as a params file would at start-up, then
        reset to the initial state they give (load_world); a problem text, or None (then
        nothing changed)."""
        if values:
            result = self.set_parameters_atomically([
                Parameter(k, self.get_parameter(k).type_, v) for k, v in values.items()])
            if not result.successful:
                return result.reason
        self.reset()
        return None

    def quit(self):
        """End the run loop shortly: the reply to the request still reaches the caller."""
        self._log.info('quitting on request (set_simulation_state QUITTING)')
        self._quit_at = time.monotonic() + QUIT_GRACE_S

    # ------------------------------------------------------------------ inputs
    def _on_command(self, header, vector, source):
        if self._fault or self._engine.finished:
            return
        if not self._commands.accept(header, vector, source, self.stamp_ns(self._engine.t_ns)):
            return
        if self._lockstep:
            return self._on_lockstep_command(header, vector, source)
        self._catch_up()  # what was due before the arrival runs with the previous command
        self._engine.apply_command((vector.x, vector.y, vector.z))

    # ------------------------------------------------------------------ lockstep
    def _hold(self):
        """The state of control instant ``_instant`` is out: hold until its command."""
        self._held, self._held_since = self._instant, time.monotonic()
        self._paused_reported = False
        self._round_trips.sent()

    def _check_held(self, now) -> float:
        """Held: after ``lockstep_timeout`` report the pause once (log and diagnostics);
        never guess a command. Returns the executor's wait."""
        late = now - self._held_since - self._p['lockstep_timeout']
        if late < 0:
            return -late
        if not self._paused_reported:
            self._paused_reported = True
            self._lockstep_pauses += 1
            self._log.warning(f'lockstep: paused at t = {self._held / NS:.9g} s: no command '
                              f'stamped {self._held_stamp()} for {self._p["lockstep_timeout"]:g}'
                              ' s (lockstep_timeout); waiting for it, nothing is extrapolated')
            self._publish_diagnostics()
        return 0.1

    def _held_stamp(self) -> str:
        sec, nsec = divmod(self.stamp_ns(self._held), NS)
        return f'{sec}.{nsec:09d}'

    def _on_lockstep_command(self, header, vector, source):
        """Apply the command for the held instant; any other is counted and rejected
        (stale: an instant already answered; unexpected: no instant held with that stamp)."""
        stamp = header.stamp.sec * NS + header.stamp.nanosec
        if self._held is not None and stamp == self.stamp_ns(self._held):
            self._engine.apply_command((vector.x, vector.y, vector.z))
            self._round_trips.applied()
            if self._paused_reported:
                self._log.info(f'lockstep: command for t = {self._held / NS:.9g} s arrived '
                               f'after {time.monotonic() - self._held_since:.3g} s; resuming')
                self._anchor()  # real time: pace on from here, not catching up on the pause
            self._held, self._instant = None, self._instant + self._lockstep
            return
        last = self.stamp_ns(self._instant - self._lockstep)
        reason = 'lockstep_stale' if stamp <= last else 'lockstep_unexpected'
        held = f'the held instant\'s stamp is {self._held_stamp()}' if self._held is not None \
            else 'no control instant is held'
        self._commands.reject(reason, source, f'stamp {header.stamp.sec}.'
                              f'{header.stamp.nanosec:09d}: {held}')

    def _on_actuator_command(self, msg):
        """Wheel torques then gimbal rates; a bad one is counted by the engine's actuators
        (diagnostics) and warned about (throttled); the last valid command stays."""
        if self._fault or self._engine.finished:
            return
        self._catch_up()
        try:
            self._engine.apply_actuator_command(msg.data)
        except ValueError as exc:
            now = time.monotonic()
            if now >= self._actuator_warn:
                self._actuator_warn = now + 2.0
                n = self._engine.actuators.rejected
                self._log.warn(f'actuator_command rejected: {exc}; the last valid command is '
                               f'held ({n} rejections so far)')

    def _on_reset(self, request, response):
        self._engine.reset()
        self._fault = None
        e = self._engine
        response.success = True
        response.message = (f'reset to the initial state at t = {e.t:.6g} s; integrator '
                            f'{e.method} ({e.reason})')
        self._log.info(response.message)
        self._new_run()
        return response

    def _new_run(self):
        """A reset or a set state: counted in diagnostics (``resets``), published now, before
        the new state's first sample, so that subscribers (the viewer) see the count change
        before that sample."""
        self._resets += 1
        self._publish_diagnostics()

    def _apply_parameters(self, params):
        changed = changed_values(SPECS, self._p, params)
        if not changed:
            return
        self._catch_up()  # what was due runs under the old values
        stamp_now = self.stamp_ns(self._engine.t_ns)
        self._p.update(changed)
        self._engine.reconfigure(check_parameters(self._p))
        self._commands.params = self._p
        if 'real_time_factor' in changed or 'publish_clock' in changed:
            self._base_stamp(stamp_now)  # stamps stay continuous across the change
        if {'inertia', 'initial_attitude', 'initial_angular_velocity'} & changed.keys():
            self._log.info('inertia and initial state take effect on ~/reset')
        if 'frame_id' in changed or 'child_frame_id' in changed:
            self._msgs.set_frames(self._p['frame_id'], self._p['child_frame_id'])
            if self._sensor_msgs is not None:
                self._sensor_msgs.set_frames(self._p['frame_id'], self._p['child_frame_id'])
        if self._p['publish_clock'] and self._clock_pub is None:
            self._clock_pub = self.create_publisher(Clock, '/clock', qos_profile('reliable'))
        self._anchor()
        self._refresh_subscribers()
        self._next_diag_wall = time.monotonic()
        self._log.info('parameters changed: ' + ', '.join(f'{k}={v}' for k, v in changed.items())
                       + f' -> {self._summary()}')
        if changed.keys() & NUMERICS:  # the engine checked the method again
            self._warn_method()

    # ------------------------------------------------------------------ status
    def _set_fault(self, reason: str):
        self._fault = reason
        self._log.error(f'simulation stopped: {reason}; fix parameters and call ~/reset')
        self._publish_diagnostics()

    def _summary(self) -> str:
        p, e = self._p, self._engine
        duration = 'until stopped' if p['duration'] == 0 else f"{p['duration']:g} s"
        rtf = 'as fast as possible' if p['real_time_factor'] == 0 else \
            f'{p["real_time_factor"]:g}x real time'
        return (f'{NODE_NAME}: integrator {e.method} ({e.reason}), step {e.step_max:.6g} s, '
                f'publish {NS / e.config.sample_period_ns:g} Hz, {rtf}, '
                f'clock {"on" if p["publish_clock"] else "off"}, '
                f'frames {p["frame_id"]} <- {p["child_frame_id"]}, qos {p["qos"]}, '
                f'duration {duration}' + sensors_summary(e.config.sensors))

    def _publish_diagnostics(self):
        now, e = time.monotonic(), self._engine
        wall0, t0 = self._last_diag
        achieved = (e.t_ns - t0) / NS / (now - wall0) if now > wall0 else 0.0
        self._last_diag = (now, e.t_ns)
        self._next_diag_wall = now + DIAGNOSTICS_PERIOD_S
        values = {**e.diagnostics(), 'real_time_factor_target': self._p['real_time_factor'],
                  **(self._lockstep_values() if self._lockstep else {}),
                  'real_time_factor_achieved': achieved, **self._commands.counts(),
                  'missed_deadlines': self._missed,
                  'missed_deadlines_in_period': self._missed - self._missed_at_last_diag,
                  'worst_lateness_in_period': self._worst_late,
                  'deadline_tolerance': self._p['deadline_tolerance'],
                  'fault': self._fault or '', 'resets': self._resets}
        missed = self._missed - self._missed_at_last_diag
        if self._fault:
            level, message = 'ERROR', f'stopped: {self._fault}'
        elif self._lockstep and self._held is not None and self._paused_reported:
            level, message = 'WARN', (f'lockstep: paused at t = {self._held / NS:.9g} s, '
                                      f'waiting for the command stamped {self._held_stamp()}')
        elif e.finished:
            level, message = 'OK', f'duration reached at t = {e.t:.6g} s'
        elif missed:
            level, message = 'WARN', (
                f'{missed} missed deadlines in the last {now - wall0:.2g} s (published up to '
                f'{self._worst_late * 1e3:.0f} ms late, tolerance '
                f'{self._p["deadline_tolerance"] * 1e3:.0f} ms)')
        else:
            level, message = 'OK', f'running, t = {e.t:.3f} s'
        self._missed_at_last_diag = self._missed
        self._worst_late = 0.0  # worst lateness per diagnostics period
        array = DiagnosticArray(status=[diagnostic_status(
            f'{self.get_name()}: simulation', self.get_fully_qualified_name(), level, message,
            values)])
        array.header.stamp.sec, array.header.stamp.nanosec = divmod(self.stamp_ns(e.t_ns), NS)
        self._diag_pub.publish(array)


    def _lockstep_values(self) -> dict:
        held = self._held is not None
        return {'lockstep_paused': held and self._paused_reported,
                'lockstep_held_since_s': time.monotonic() - self._held_since if held else 0.0,
                'lockstep_pauses': self._lockstep_pauses, **self._round_trips.values()}


def main(args=None):
    """Entry point of ``ros2 run rigid_body_sim simulator``; returns the exit code."""
    return run_node(NODE_NAME, Simulator, run=lambda node: node.run(), args=args)


if __name__ == '__main__':
    sys.exit(main())
