"""``attitude_simulator``: live rigid-body attitude simulation on standard ROS 2 topics.

A thin shell over :class:`rigid_body_sim.engine.Engine`: it declares the parameters
(``engine.specs.SIMULATOR``), paces the engine against the wall clock, turns its samples
into messages (``StateMessages``), and turns commands, parameter changes and ``~/reset``
into engine calls. It publishes through ``sim_publish.Publishing`` (time stamps there).

Pacing. The engine processes its events (samples, command expiry) up to the sim time the
wall clock allows; between those, the executor serves callbacks and the ``auto`` pilot
runs in small slices. With ``real_time_factor: 0`` the engine runs in chunks of at most
``CHUNK_WALL_S`` wall seconds between executor turns.

Spacecraft (``engine/fleet.py``, ``spacecraft.py``). A scene may declare several; each has
its engine, topics under ``<name>/`` and commands, and all are stepped in the same tick
(sample period by sample period, up to LIVE_BLOCK of them between executor turns). /tf
holds ``frame_id`` -> ``<name>/<child_frame_id>``. The node's own ``torque_command`` and
``wrench_command`` route a command by its frame_id to the spacecraft of that body frame;
one naming no spacecraft is counted (``unknown_spacecraft``) and rejected. Spawning and
deleting at run time: ``sim_spawn.py``. Without spacecraft, the node keeps running (and
publishing /clock) and says so in diagnostics.

Lockstep (``lockstep: true``, ``engine/lockstep.py``). The engine never advances past a
control instant (a multiple of the ``control_rate`` period in sim time) until the command
stamped with that instant's state stamp has been applied there; it reports a pause after
``lockstep_timeout`` and keeps waiting. Whatever the pacing and the load, the run is then
the offline run's. With several spacecraft it holds each instant until every spacecraft
in the loop (``<name>.lockstep``) has answered, each on its own topics; with a B-dot
controller the dipole_command too (``lockstep.awaited``).
"""
import sys
import time
from dataclasses import replace

from rclpy.node import Node

from geometry_msgs.msg import Vector3Stamped, WrenchStamped
from std_srvs.srv import Trigger

from ..engine import NS, fleet, lockstep, specs
from ..physics import IntegrationError
from ..scene import SceneError, params_files_record
from .commands import CommandFilter
from .common import (check_overrides, declare_parameters,
                     overridden_warnings, qos_profile, validate_update)
from .process import events_executor, pin_process, run_node
from .usage import ros_arguments
from .sim_services import AVAILABLE as SIM_SERVICES, SimulationServices
from .sim_control import Control
from .sim_fleet import Fleet, check_parameters
from .sim_acks import Acknowledgements
from .sim_holds import Holds
from .sim_lockstep import Exchange
from .sim_publish import Publishing
from .sim_warm import Warming
from .sim_status import summary

NODE_NAME = 'attitude_simulator'
SPECS = specs.SIMULATOR
CHUNK_WALL_S = 0.02          # longest stretch of engine work between executor turns
LIVE_BLOCK = 16              # samples per engine call (each is published before the next)
SUBSCRIBER_REFRESH_S = 0.25  # how often matched-subscriber counts are re-read
MAX_LAG_S = 1.0              # behind the wall-clock target by more: drop the backlog
PILOT_SLICE_S = 0.002        # least time for auto's pilot per loop turn (as fast as possible)


class Simulator(Control, Fleet, Holds, Exchange, Publishing, Warming, Node):
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
            base = [replace(s, default=record.get(s.name, s.default))
                    for s in specs.SIMULATOR_DECLARED]
            # each spacecraft's own keys (<name>.<key>) are declared after the node-level
            # ones, which are their defaults; every key is checked against both at once
            names = self._declared_names()
            check_overrides(self, base + fleet.craft_specs(names))
            for line in overridden_warnings(self):
                self.get_logger().warning(line)
            self._p = declare_parameters(self, base, check=False)
            self._p.update(declare_parameters(self, fleet.craft_specs(names, self._p),
                                              check=False))
            self.scene_record = {s.name: self._p.pop(s.name) for s in specs.SCENE_RECORD}
            self._specs = SPECS + tuple(fleet.craft_specs(names))
            check_parameters(self._p)
            pin_process(self._p['cpu_affinity'])  # its threads, the middleware's among them
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        self._log = self.get_logger()
        self._qos = qos_profile(self._p['qos'])
        keep_all = self._create_publishers()
        # commands on the node's own topics: the unnamed spacecraft's, or routed by frame_id
        self._commands = CommandFilter(self, self._p)  # what reaches no spacecraft
        self._command_subs = [
            # raw: decoded from the bytes (commands.py, sim_lockstep.py: why)
            self.create_subscription(Vector3Stamped, 'torque_command', self._on_torque_bytes,
                                     self._qos, raw=True),
            self.create_subscription(WrenchStamped, 'wrench_command', lambda m: self._route(
                m.header, m.wrench.torque, 'wrench_command'), self._qos)]
        self._exchange_sub = None  # lockstep: torque_command read by the loop (sim_lockstep)
        if self._p['lockstep']:
            self._serve_exchange()
        # lockstep: the controller's values from the same params files (auto's choice)
        self._controller_values = lockstep.controller_values(
            ros_arguments()[0], self.get_namespace()) if self._p['lockstep'] else None
        self._crafts = {}  # name ('' = unnamed) -> Spacecraft, in the order they came
        self._spawned = {}  # name -> its own values (BODY_KEYS), for spawned spacecraft
        self._idle_ns = 0  # sim time while there is no spacecraft
        self._scene_names = names or ['']  # what reset_simulation's SCOPE_SPAWNED restores
        try:
            for name in self._scene_names:
                self._add(name, 0)
        except ValueError as exc:
            raise SceneError(str(exc)) from None
        self._period_ns = self._sample_period()
        self.create_service(Trigger, '~/reset', self._on_reset)
        self.paused = False
        self._quit_at = None  # wall time at which a requested quit ends the loop
        self._sim_services = SimulationServices(self) if SIM_SERVICES else None
        self._fault = None
        self._missed = self._missed_at_last_diag = 0
        self._published = 0  # state messages published (diagnostics: messages_published)
        self._resets = 0  # ~/reset and set_state: viewers restart their drift and traces on it
        self._worst_late = 0.0
        self._acks = Acknowledgements(self._acked_publishers, self._log, keep_all)
        # lockstep: the next control instant to hold (ns), the instant held (None: free to
        # advance), when its hold began (wall), whether its pause was reported
        self._lockstep = lockstep.period_ns(self._p) if self._p['lockstep'] else 0
        self._instant, self._held, self._held_since, self._paused_reported = 0, None, 0.0, False
        self._held_fields = None  # the held instant's stamp as (sec, nanosec): sim_lockstep
        self._awaiting = set()  # (spacecraft name, kind) the held instant still waits for
        self._lockstep_pauses = 0
        self._round_trips = lockstep.RoundTrips()
        self._base_stamp(self.get_clock().now().nanoseconds)
        self._started = False  # run() sets it at t = 0, after the holds for subscribers
        self._anchor()
        self._last_diag = (time.monotonic(), 0)
        self._next_diag_wall = 0.0
        self._next_refresh_wall = 0.0
        self.add_on_set_parameters_callback(
            lambda params: validate_update(self._specs, self._p, params, self._check))
        self.add_post_set_parameters_callback(self._apply_parameters)
        if self.scene_record['scene.name']:
            self._log.info(f"scene {self.scene_record['scene.name']} (params files' sha256 "
                           f"{self.scene_record['scene.sha256'][:12]}...)")
        self._log.info(summary(self))
        self._warn_method()

    def _warn_method(self):
        """A fixed method's step outside its stability or far from the accuracy budget
        (the engine checks it whenever it configures one): said, not refused, live."""
        for craft in self._crafts.values():
            for _, message in craft.engine.method_warnings:
                self._log.warning(craft.prefix + message)

    # ------------------------------------------------------------------ time
    def _anchor(self):
        """Pace from now: the engine's sim time corresponds to the wall time now."""
        self._wall_anchor, self._sim_anchor = time.monotonic(), self.t_ns

    @property
    def t_ns(self) -> int:
        """The simulation's sim time: its spacecraft's (the latest), or its own when empty."""
        return max((c.engine.t_ns for c in self._crafts.values()), default=self._idle_ns)

    @property
    def selection_pending(self) -> bool:
        return any(c.engine.selection_pending for c in self._crafts.values())

    def _due_wall(self, t_ns: int) -> float:
        return self._wall_anchor + (t_ns - self._sim_anchor) / (NS * self._p['real_time_factor'])

    # ------------------------------------------------------------------ loop
    def _advance(self, until_ns: int, deadline: float, late: bool = True,
                 most: int = LIVE_BLOCK):
        """Engine events up to ``until_ns`` (or the deadline), publishing every sample
        (``late``: count lateness against the wall clock; not when stepping). One spacecraft
        runs up to LIVE_BLOCK samples per engine call; several are stepped in the same tick
        of at most LIVE_BLOCK sample periods, each engine to the tick's end in turn.
        ``most``: samples per engine call of one spacecraft (``_catch_up``: why fewer)."""
        if self._lockstep:  # never past the next control instant, and not while one is held
            if self._held is not None:
                return
            until_ns = min(until_ns, self._instant)
        if not self._crafts:
            return self._idle(until_ns)
        while not self._fault:
            live = [c for c in self._crafts.values() if not c.engine.finished]
            if not live:
                break
            single = len(live) == 1
            target = until_ns if single else min(
                until_ns, (self.t_ns // self._period_ns + LIVE_BLOCK) * self._period_ns)
            for craft in live:
                try:
                    block = craft.engine.advance(target, deadline if single else None,
                                                 max_samples=most if single else None)
                except IntegrationError as exc:
                    return self._set_fault(f'{craft.prefix}integrator failed: {exc}', craft)
                except Exception as exc:  # noqa: BLE001 - never die with a traceback on bad input
                    return self._set_fault(f'{craft.prefix}physics error: '
                                           f'{type(exc).__name__}: {exc}', craft)
                self._publish(craft, block, late)
                if craft.engine.method != craft.method:
                    craft.method = e = craft.engine.method
                    self._log.info(f'{craft.prefix}integrator {e}, step '
                                   f'{craft.engine.step_max:.6g} s ({craft.engine.reason})')
            engine = live[0].engine
            if self._lockstep and engine.t_ns == self._instant and not engine.finished \
                    and self._hold():
                break
            if ((len(block) < most or most < LIVE_BLOCK) if single else target >= until_ns) or \
                    time.monotonic() > deadline:
                break
        if self.finished and not self._fault:
            self._log.info(f'duration {self._p["duration"]:g} s reached at t = '
                           f'{self.t_ns / NS:.6g} s; stopping')
            if self._lockstep:
                self._log.info(self._round_trips.summary())
            self._publish_diagnostics()

    def _idle(self, until_ns):
        """No spacecraft: sim time runs on (stamps, /clock) from sample instant to sample
        instant; as fast as possible (no end), LIVE_BLOCK of them per call."""
        p = self._period_ns
        end = until_ns // p * p if until_ns < sys.maxsize else \
            (self._idle_ns // p + LIVE_BLOCK) * p
        while self._idle_ns < end:
            self._idle_ns = (self._idle_ns // p + 1) * p
            self._tick_clock(self._idle_ns)

    def _catch_up(self, now=None):
        """Real-time modes: process what is due by the wall clock."""
        rtf = self._p['real_time_factor']
        if rtf == 0 or self._fault or self.finished or self.paused:
            return
        now = time.monotonic() if now is None else now
        target = self._sim_anchor + int((now - self._wall_anchor) * rtf * NS)
        if self._lockstep and self.selection_pending:
            return
        # the samples now due, and no further: after the last one the engine would look for
        # the next event up to ``target`` in one more compiled call, for nothing (~30 µs, a
        # sixth of the node's CPU a sample at real time); events between are processed at
        # the next turn, as those after ``target`` always were
        p = self._period_ns
        due = target // p - self.t_ns // p
        self._advance(target, now + CHUNK_WALL_S * 5,
                      most=min(due, LIVE_BLOCK) if due > 0 else LIVE_BLOCK)
        if (target - self.t_ns) / (rtf * NS) > MAX_LAG_S:  # cannot keep up
            self._anchor()

    def run_once(self) -> float:
        """Advance what is due; returns the seconds the executor may wait before the next call."""
        if self._exchange_sub is not None:  # lockstep: the commands that came (sim_lockstep)
            self._take_commands()
        now = time.monotonic()
        if now >= self._next_refresh_wall:
            self._refresh_subscribers()
            self._next_refresh_wall = now + SUBSCRIBER_REFRESH_S
        rtf = self._p['real_time_factor']
        wait = 0.1
        if self._lockstep and self._held is not None:
            wait = self._check_held(now)
        elif self._lockstep and self.selection_pending:
            wait = 0.0  # auto's pilot first: its choice may not depend on the wall clock
        elif not (self._fault or self.finished or self.paused):
            if rtf == 0:
                self._advance(self._instant if self._lockstep else sys.maxsize,
                              now + CHUNK_WALL_S)
                # held at the instant just published: wait for its command in this turn
                # (a turn of the executor with nothing to do cost ~40 µs per exchange)
                wait = self._check_held(now) if self._lockstep and self._held is not None \
                    else 0.0
            else:
                p = self._period_ns
                # lockstep: a command that came before the next sample is due leaves
                # nothing to do until then (an engine call that finds no event cost ~20 µs
                # of every exchange at 1 kHz); what lies between waits, as in _catch_up
                if not self._lockstep or self._sample_due(now):
                    self._catch_up(now)
                wait = self._due_wall((self.t_ns // p + 1) * p) - time.monotonic()
        pending = [c.engine for c in self._crafts.values() if c.engine.selection_pending]
        if pending:  # auto's pilot in the idle time, in small slices
            until = time.monotonic() + max(min(wait, CHUNK_WALL_S) * 0.8, PILOT_SLICE_S)
            for engine in pending:
                engine.work(until)
        now = time.monotonic()
        if now >= self._next_diag_wall:
            self._publish_diagnostics()
        return min(max(wait, 0.0), self._next_diag_wall - now, 0.1)

    def _sample_due(self, now) -> bool:
        """Whether a spacecraft's next sample (or the end of its run) is due by ``now``."""
        due = [min(e.next_sample_ns, e.end_ns) for e in (c.engine for c in self._crafts.values())
               if not e.finished]
        return not due or self._due_wall(min(due)) <= now

    def run(self):
        """Spin until shutdown or ``duration`` is reached.

        On rclpy's C++ events executor: the loop turns at every sample (100 Hz), and the
        Python SingleThreadedExecutor rebuilds its wait set over every service and
        subscription each turn (~0.6 ms; the simulator has ~20), which cost more than the
        physics."""
        self._warm()
        with events_executor(self) as executor:
            self._wait_for_subscribers(executor)
            self._base_stamp(self.get_clock().now().nanoseconds)
            self._started = True
            self._mark_t0()
            self._anchor()  # pace from the first turn of the loop, not from construction
            # the context's own state, read at every turn: rclpy's Context.ok takes its lock
            # and enters the handle first, ~1 µs a call hot and ~10 of every lockstep
            # exchange on a loaded machine (each turn starts with cold caches after a wait)
            ok = self.context.handle.ok
            while ok() and not self.finished and not (
                    self._quit_at is not None and time.monotonic() >= self._quit_at):
                self._turn(executor, self.run_once())
            if self.finished and self._paced and self.context.ok():
                # the last samples are still in flight when the run ends: a recorder that
                # was waited for must get them before this process takes its writers away
                self._wait_acked()
                self._log.info(self._acks.summary())

    @property
    def finished(self) -> bool:
        """Every spacecraft reached the duration (an empty simulation runs until stopped)."""
        return bool(self._crafts) and all(c.engine.finished for c in self._crafts.values())

    # ------------------------------------------------------------------ inputs
    def _on_command(self, craft, header, vector, source, dipole=False):
        """A torque command, or with ``dipole`` the magnetorquers' (dipole_command): the
        same checks, counted apart; in lockstep, what the held instant awaits
        (``craft.awaited``) goes through its handshake."""
        engine = craft.engine
        if self._fault or engine.finished:
            return
        check = craft.dipoles if dipole else craft.commands
        now = self.stamp_ns(engine.t_ns) if self._started else None  # None: before t = 0
        if not check.accept(header, vector, source, now):
            return
        kind = 'dipole' if dipole else 'torque'
        if self._lockstep and kind in craft.awaited:
            return self._on_lockstep_command(craft, header, vector, source, kind)
        self._catch_up()  # what was due before the arrival runs with the previous command
        apply = engine.apply_dipole_command if dipole else engine.apply_command
        apply((vector.x, vector.y, vector.z))

    def _actuators_ready(self, craft) -> bool:
        """Before a joint command: False if the run stopped, else what was due ran."""
        if self._fault or craft.engine.finished:
            return False
        self._catch_up()
        return True

    def _on_actuator(self, craft, msg):
        """Wheel torques then gimbal rates; a bad one is counted by the engine's actuators
        (diagnostics) and warned about (throttled); the last valid command stays."""
        if self._fault or craft.engine.finished:
            return
        self._catch_up()
        try:
            craft.engine.apply_actuator_command(msg.data)
        except ValueError as exc:
            craft.warn_actuator(self._log, exc)

    # ------------------------------------------------------------------ status
    def _clear_fault(self):
        """The simulation runs again once no spacecraft is left in a fault."""
        if not any(c.fault for c in self._crafts.values()):
            self._fault = None

    def _set_fault(self, reason: str, craft=None):
        """Stop the simulation (every spacecraft), ``craft`` the one that failed."""
        self._fault = reason
        if craft is not None:
            craft.fault = reason
        self._log.error(f'simulation stopped: {reason}; fix parameters and call ~/reset')
        self._publish_diagnostics()

def main(args=None):
    """Entry point of ``ros2 run rigid_body_sim simulator``; returns the exit code."""
    return run_node(NODE_NAME, Simulator, run=lambda node: node.run(), args=args,
                    lockstep=True)


if __name__ == '__main__':
    sys.exit(main())
