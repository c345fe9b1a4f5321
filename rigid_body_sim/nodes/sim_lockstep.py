"""Lockstep's exchange on the simulator's side, cut to what one exchange needs. A mixin
of the node (``simulator.py``); the hold and its checks are ``sim_holds.py``'s.

Per exchange the simulator takes one command and publishes one control instant's
state: everything it does in between is CPU of every exchange (the issue's target is
100 µs of it). So the command of the held instant for a simulation of one spacecraft
(the common case, and the benchmark's: ``tools.lockstep``) goes the short way: its CDR
bytes decoded into a tuple (no message objects), checked against the held stamp taken
apart once per instant, applied, and the instant released; every other command
(another stamp, frame or spacecraft, a NaN) goes the general way,
``vector3_stamped`` then ``_route``, which counts and rejects it as before. Both ways
accept exactly the same commands: a command stamped with the held instant's stamp is
one the general checks let through (neither ahead of the node's stamp nor older than
``command_timeout``; before t = 0 stamps are not judged at all), so only its value and
frame are left to check. As fast as possible, that command's call then steps to the next
instant, publishes it and holds it at once (``_direct_exchange``).

Where it may (``sim_rcl.Compiled``), that loop of exchanges runs without Python at all:
wait, take, decode, check, apply, step, pack and publish in one compiled call of rcl's C
functions (``rcl_loop``), which hands anything unusual to ``_on_torque_bytes``.

The wait for that command is the node's loop's, not the executor's (``_serve_exchange``):
in lockstep the node's own ``torque_command`` is taken out of the executor and read from
an rcl wait set of that one subscription, and the executor is turned for everything else
once per EXECUTOR_SLICE_S while an instant is held. Why, measured with
``tools.lockstep_floor`` (a bare rclpy exchange, loaded machine): the events executor's
turn and its listener in Fast DDS's receiving thread cost ~10 µs of the thread and a
few of the receiver per exchange (3 runs at load 6.9: process CPU 99 (84-130) µs through
the executor, 70 (70-74) through the wait set; the thread 54 against 40). The simulator
itself, runs alternating with and without it (load 7-10, 9 each): 333 (243-359) µs ->
271 (228-358).
"""
import math
import os
import struct
import time

from geometry_msgs.msg import Vector3Stamped
from rclpy._rclpy_pybind11 import RCLError
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

from . import rcl_direct
from .commands import stamped_fields, vector3_stamped
from .state_messages import N_VALUES

_AWAITING = {('', 'torque')}  # the unnamed spacecraft's torque command only (_awaiting)
# held for the exchange's command, the executor (services, parameters, SimulateSteps, other
# commands) turns this often, without waiting: a turn with nothing to do costs ~28 µs of
# CPU and ~0.1 ms of wall, loaded up to 1.5 ms (a hand-over to its thread), so not once an
# exchange; and each slice costs two turns of run's loop besides (run_once, its subscriber
# counts every SUBSCRIBER_REFRESH_S), ~0.2 ms of the thread's CPU a slice at load 12. So a
# call is answered within 0.1 s, as a named spacecraft's command is read (_serve_exchange),
# not 0.02 s: in process (tools.lockstep_parts' timers, 5,000 exchanges at 100 Hz, 3 runs
# alternating at load 12-13) run_once and the executor's turns 4.6-9.9 -> 2.6-3.2 µs of
# the thread per exchange.
EXECUTOR_SLICE_S = 0.1
# held for torque_command and something else (a dipole_command, a named spacecraft's):
# the executor waits at most this long, so that a torque_command that came meanwhile is
# read by the next turn of the loop
MIXED_WAIT_S = 0.001
_CDR_LE = b'\x00\x01'  # plain CDR, little-endian (commands.stamped_fields' encodings)


def command_layout(data: bytes, fields):
    """The layout of a torque command's CDR bytes ``data``, whose ``stamped_fields`` are
    ``fields``, for the next commands of the same layout (``Exchange._on_torque_bytes``):
    (the length of ``data``; a precompiled ``unpack_from`` giving (sec, nanosec, the frame
    id's size, its bytes with their nul, x, y, z); that (size, bytes); the frame id), or
    None for bytes that are not little-endian or go on past the doubles. Why: one struct
    call in place of ``stamped_fields``' slices, checks, decode and tuples, per exchange."""
    if not data.startswith(_CDR_LE):
        return None
    size = len(fields[2].encode()) + 1
    at = 4 + ((12 + size + 7) & ~7)  # the doubles: 8-aligned after the frame id
    if len(data) != at + 24:
        return None
    unpack = struct.Struct(f'<4xiII{size}s{at - 16 - size}x3d').unpack_from
    return len(data), unpack, (size, data[16:16 + size]), fields[2]


class Exchange:
    """The node's torque_command callback (raw bytes) with lockstep's short way.
    ``_held_fields``: the held instant's stamp as a command carries it, (sec, nanosec),
    or None (``sim_holds``: set by ``_hold``, cleared by ``_release``). ``_direct``: the
    DirectPeriod of the unnamed spacecraft's engine (``_direct_exchange``), or None."""

    _direct = None
    _compiled = None  # sim_rcl.Compiled (lockstep: _warm)
    _layout = None  # command_layout's, of the last command the short way took
    _packing = None  # _packers': (active_raw, templates, packers, constants)

    def _serve_exchange(self):
        """Lockstep: the node's torque_command (``_command_subs[0]``, raw) leaves the
        executor, which serves what the node lists (rclpy's ``Node._subscriptions``): the
        loop reads it (``_take_commands`` at every turn, ``_turn`` waits for it while an
        instant is held). A command on it for a named spacecraft (routed by frame_id) is
        read at the loop's next turn, at most 0.1 s later. Put back for the node's own
        teardown (``destroy_node``)."""
        self._exchange_sub = sub = self._command_subs[0]
        self._subscriptions.remove(sub)
        self._exchange_wait = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, self.context.handle)
        self._executor_due = 0.0  # wall time of the executor's next turn while held
        self._compiled = None  # sim_rcl.Compiled, made by _warm
        self._context_ok = self.context.handle.ok  # (simulator.run: why not Context.ok)

    def _warm(self):
        """And the compiled exchanges' loop (``sim_rcl``), before t = 0: compiled per
        process (~1-2 s), it must not stall a held instant."""
        super()._warm()
        craft = self._crafts.get('')
        if self._exchange_sub is None or craft is None or \
                os.environ.get('RIGID_BODY_SIM_RCL_LOOP', '').strip() == '0':
            return
        from .sim_rcl import Compiled
        start = time.monotonic()
        self._compiled = Compiled(self._log)
        if self._compiled.warm(craft.engine):
            self._log.info(f'lockstep: compiled exchanges ready in '
                           f'{time.monotonic() - start:.3g} s')

    def destroy_node(self):
        if self._compiled is not None:
            self._compiled.close()
        sub = getattr(self, '_exchange_sub', None)
        if sub is not None and sub not in self._subscriptions:
            self._subscriptions.append(sub)
        super().destroy_node()

    def _take_commands(self):
        """Every torque_command that came, each to ``_on_torque_bytes`` (non-blocking)."""
        take = self._exchange_sub.handle.take_message
        got = take(Vector3Stamped, True)
        while got is not None:
            self._on_torque_bytes(got[0])
            got = take(Vector3Stamped, True)

    def _turn(self, executor, wait: float):
        """One turn of ``run``'s loop after ``run_once`` asked for ``wait`` s: held for the
        exchange's command only, the wait set waits for it (and the executor turns once
        per EXECUTOR_SLICE_S); else the executor waits, at most MIXED_WAIT_S while the
        held instant awaits a torque_command too."""
        if self._exchange_sub is None:
            return executor.spin_once(timeout_sec=wait)
        if self._held is None or ('', 'torque') not in self._awaiting:
            return executor.spin_once(timeout_sec=wait)
        if self._awaiting != _AWAITING:
            return executor.spin_once(timeout_sec=min(wait, MIXED_WAIT_S))
        now = time.monotonic()
        if now >= self._executor_due:
            self._executor_due = now + EXECUTOR_SLICE_S
            return executor.spin_once(timeout_sec=0.0)
        self._exchanges(min(now + wait, self._executor_due, self._next_refresh_wall))

    def _packers(self, craft):
        """``_packing``, made for ``craft``'s subscribed state topics (``_direct_exchange``
        uses it while they and the templates are the same): (``craft.active_raw``, the
        templates, the packers [(publish_raw, pack, get, topic name)] in that order, the
        templates' constant bytes), what ``StateMessages.encoded_block`` packs a sample's
        row of values with (``state_messages._Templates``); packers None if a topic has
        no template (rclpy then serialises it: ``encoded_block``). Why: building the
        block's dict of lists for one sample and publishing from it cost ~2.4 µs hot
        where packing the row costs 0.6."""
        msgs = craft.msgs
        msgs.prepare()
        templates, raw = msgs._templates, craft.active_raw
        topics = {name: (pack, get) for name, pack, get in templates.topics}
        packers = [(send, *topics[name], pub.topic_name) for send, pub, name in raw] \
            if all(name in topics for _, _, name in raw) else None
        self._packing = (raw, templates, packers, templates.row[2 + N_VALUES:])
        return self._packing

    def _exchanges(self, until: float):
        """Held for the exchange's command only: wait for it (an rcl wait set of that one
        subscription) and take it, then, as long as each command steps to the next
        instant and holds it at once (``_direct_exchange``), the next, until the wall
        time ``until`` (``run_once``'s wait: diagnostics due, the held instant's
        ``lockstep_timeout``; the executor's next turn; the subscriber counts' refresh).
        Back to ``run``'s loop as soon as an instant is not held for the exchange only
        (released but not stepped to: ``run_once`` goes on). Why a loop of its own: a
        turn of ``run``'s loop per exchange (``run_once``'s checks, the loop's) cost ~15
        µs of the simulator's CPU per exchange on the loaded machine."""
        ok, monotonic = self._context_ok, time.monotonic
        handle = self._exchange_sub.handle
        take, wait_set = handle.take_message, self._exchange_wait
        timeout = self._p['lockstep_timeout']
        compiled = self._compiled
        # waited for first, then taken: once a command is handled the next cannot have
        # come yet (its state just went out), and a take that finds nothing costs as
        # much as the one that finds it (~5 µs on the loaded machine)
        while ok():
            now = monotonic()
            if now >= until:
                return
            # the exchanges in one compiled call where they may (sim_rcl.Compiled.run)
            got = None if compiled is None else compiled.run(self, until)
            if got is not None:
                code, data = got
                if code == rcl_direct.OTHER:  # a command it left to the Python way
                    self._on_torque_bytes(data)
                    if self._held is None or self._awaiting != _AWAITING:
                        return
                    until = min(until, self._held_since + timeout)
                if code in (rcl_direct.OTHER, rcl_direct.REFUSED):
                    continue
                if code != rcl_direct.ROOM:  # (ROOM: this exchange the Python way)
                    return
            wait_set.clear_entities()
            wait_set.add_subscription(handle)
            wait_set.wait(int(1e9 * (until - now)))
            if not ok():  # shut down meanwhile (Ctrl-C): the subscription goes with it
                return
            got = take(Vector3Stamped, True)
            if got is None:
                continue
            self._on_torque_bytes(got[0])
            if self._held is None or self._awaiting != _AWAITING:
                return
            until = min(until, self._held_since + timeout)  # its pause is run_once's

    def _on_torque_bytes(self, data):
        layout = self._layout
        if layout is not None and len(data) == layout[0] and data.startswith(_CDR_LE):
            sec, nanosec, size, frame, x, y, z = layout[1](data)
            if (size, frame) == layout[2]:  # the frame of the last command taken
                if (sec, nanosec) == self._held_fields and \
                        self._take_held((sec, nanosec, layout[3], x, y, z)):
                    return
                return self._route_torque(data)
        fields = stamped_fields(data, 3)  # vector3_stamped_fields', a call fewer
        if fields is not None and fields[:2] == self._held_fields:
            layout = command_layout(data, fields)
            if self._take_held(fields):
                self._layout = layout  # (read at the next command only)
                return
        self._route_torque(data)

    def _route_torque(self, data):
        """The general way: decoded into a message, routed, checked and counted."""
        m = vector3_stamped(data)
        self._route(m.header, m.vector, 'torque_command')

    def _take_held(self, fields) -> bool:
        """The held instant's command, stamped with its stamp, for the one unnamed
        spacecraft when the instant awaits only it: applied and the instant released
        (True). False to go the general way: several spacecraft, a frame other than the
        body's, a value that is not finite, a run stopped."""
        _, _, frame, x, y, z = fields
        craft = self._crafts.get('')
        if craft is None or len(self._crafts) != 1 or self._awaiting != _AWAITING or \
                self._fault or craft.engine.finished or \
                frame.lstrip('/') not in ('', craft.p['child_frame_id']) or \
                not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return False
        craft.engine.apply_command((x, y, z))
        if self._direct is None or self._direct.engine is not craft.engine:
            # imported here (once per engine): it loads numba, which a node refused for
            # its parameters before any engine never needs (spacecraft.py)
            from ..engine.lockstep_direct import DirectPeriod
            self._direct = DirectPeriod(craft.engine)
        self._awaiting.clear()
        self._release()
        self._direct_exchange(craft)
        return True

    def _direct_exchange(self, craft):
        """As fast as possible, right after the held instant's command is applied: the
        next control instant stepped to in one compiled call (``engine.lockstep_direct``),
        its state published from the values that call wrote, and the instant held, in
        this same turn, where the loop's next turn went through ``_advance``,
        ``Engine.advance`` and ``_publish`` for one sample (the simulator's CPU per
        exchange, ``tools.lockstep`` alternating both ways at load 12, 2 runs each:
        219 -> 183 µs at 100 Hz, 218 -> 150 at 1 kHz). The messages are those, bit for
        bit (test_sim_exchange, test_lockstep_direct). Nothing happens
        (the loop's next turn goes the general way) at real time, paused, with sensors,
        an orbit or actuators, or where the period is not one plain stretch
        (``DirectPeriod.step``)."""
        if self._p['real_time_factor'] or self.paused or self._fault or \
                craft.orbit is not None or craft.sensor_msgs is not None or \
                craft.msgs.actuators is not None:
            return
        t_ns = self._instant
        values = self._direct.step(t_ns)  # (made for craft's engine by _take_held)
        if values is None:
            return
        # Publishing._publish's path for one sample in lockstep, without a deadline
        self._tick_clock(t_ns)
        acks = self._acks
        if craft.active:
            kept, msgs = self._packing, craft.msgs
            if kept is None or kept[0] is not craft.active_raw or \
                    kept[1] is not msgs._templates:
                kept = self._packers(craft)
            packers = kept[2]
            if packers is None:
                states = msgs.encoded_block(None, (self.stamp_ns(t_ns),), craft.active_names,
                                            (values,))
                craft.publish_states(states, acks.refused, 0)
            else:
                only = craft.active_names  # counted as encoded_block counts them
                msgs._builds[only] = msgs._builds.get(only, 0) + 1
                row = [*divmod(self.stamp_ns(t_ns), 1_000_000_000), *values, *kept[3]]
                for send, pack, get, topic in packers:
                    try:
                        send(pack(*get(row)))
                    except RCLError as exc:  # a paced reader's history is full (sim_acks)
                        acks.refused(topic, exc)
            self._published += len(craft.active)
        acks.published()  # paced: as fast as possible (above)
        # what the instant just answered awaited (_take_held), without asking each
        # spacecraft again
        self._hold({('', 'torque')})
