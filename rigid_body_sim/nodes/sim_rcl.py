"""The simulator's side of the compiled exchanges (``rcl_loop``): when they may run, their
tables, and their outcome written back into the engine and the node.

``Compiled.run`` is asked by ``sim_lockstep.Exchange._exchanges`` before each wait for the
held instant's command. It runs the compiled loop only where that loop does what the
Python way would do, exchange for exchange: as fast as possible, the unnamed spacecraft
alone, its direct period possible (``DirectPeriod.prepared``), a body whose principal axes
are its own (the command's torque then is the principal one: ``to_principal``'s matrix
product is not repeated in compiled code, whose sums could round otherwise), the command
alone acting, sim-time stamps, no /clock subscriber, every state topic templated, a
command of the held layout taken the short way before (``_layout``), the round trips'
first CPU reading taken. Anything else, and ``RIGID_BODY_SIM_RCL_LOOP=0`` (for A/B
runs), leaves the exchange to the Python way; where rcl's functions cannot be had
(``rcl_direct.Unavailable``) the reason is logged once and Python runs.
"""
import ctypes
import os
import struct

import numpy as np
from rclpy._rclpy_pybind11 import RCLError

from ..engine.lockstep import CPU_EVERY
from . import rcl_loop as L
from .state_messages import N_VALUES

_MARK_D = struct.unpack('<d', bytes(range(0x11, 0x19)))[0]  # eight distinct nonzero bytes
_MARK_I = 0x11223344


def template_fields(pack, get, row) -> tuple:
    """(the template's bytes with a zero stamp and values, [(offset, kind, row index)])
    of a topic's ``pack`` and ``get`` (``state_messages._Templates``) over its ``row``,
    found by packing a marker into each of the row's first 2 + N_VALUES places in turn;
    None if a field is not where a plain number would be."""
    base_row = list(row)
    base_row[:2 + N_VALUES] = [0, 0] + [0.0] * N_VALUES
    base = pack(*get(base_row))
    fields = []
    for src in range(2 + N_VALUES):
        probe = list(base_row)
        probe[src] = _MARK_I if src < 2 else _MARK_D
        marker = struct.pack('<i' if src == 0 else '<I' if src == 1 else '<d', probe[src])
        got = pack(*get(probe))
        if len(got) != len(base):
            return None
        at = 0
        while True:
            at = got.find(marker, at)
            if at < 0:
                break
            fields.append((at, L.DOUBLE if src >= 2 else L.INT32 if src == 0 else L.UINT32,
                           src))
            at += len(marker)
        diff = sum(a != b for a, b in zip(got, base))
        if diff != sum(len(marker) - marker.count(0) for a, _, s in fields if s == src):
            return None
    return base, sorted(fields)


class Compiled:
    """One simulator's compiled exchanges (module docstring)."""

    def __init__(self, log):
        from .rcl_direct import Unavailable, load
        self._key = None
        self.tables = None
        self.exchange = None
        self.loop = None
        if os.environ.get('RIGID_BODY_SIM_RCL_LOOP', '').strip() == '0':
            self.why = 'RIGID_BODY_SIM_RCL_LOOP=0'
            return
        try:
            lib, _ = load()
            self._c = L.functions(lib)
            self.loop = L.loop
            self.why = None
        except Unavailable as exc:
            self.why = str(exc)
            log.info(f'lockstep: exchanges taken in Python ({exc})')

    def warm(self, engine) -> bool:
        """Compile the loop for ``engine``'s argument types (a call that returns at once:
        no room); False where it cannot run at all."""
        if self.loop is None:
            return False
        i8, u8 = np.zeros(8, dtype=np.int64), np.zeros(8, dtype=np.uint8)
        ints, f = np.zeros(L.N_INTS, dtype=np.int64), np.zeros(64)
        self.loop(*self._c, i8, i8.copy(), i8[:0], i8[:0], u8,
                  np.zeros((0, 3), dtype=np.int64), i8[:3], u8[:1], f,
                  np.zeros(16, dtype=np.int64), engine.dynamics.environment, np.zeros(4),
                  np.zeros(3), ints, np.zeros(L.N_FLOATS))
        return ints[L.CODE] == L.ROOM

    def unable(self, node, craft):
        """Why the next exchanges may not run compiled (module docstring), in words; None
        if they may."""
        e = craft.engine
        direct, rt, acks = node._direct, node._round_trips, node._acks
        # in order, each read only if those before held (a later one needs them)
        for fails, why in (
                (lambda: self.loop is None, self.why),
                (lambda: node._held is None or node._awaiting != {('', 'torque')},
                 'no instant held for the torque command alone'),
                (lambda: node._layout is None, 'no command taken the short way yet'),
                (lambda: direct is None or direct.engine is not e, 'no direct period'),
                (lambda: len(node._crafts) != 1 or node._fault, 'several spacecraft or a fault'),
                (lambda: node._p['real_time_factor'] or node.paused, 'real time or paused'),
                (lambda: not node._p['publish_clock'] or node._clock_subscribed, '/clock'),
                (lambda: craft.orbit is not None or craft.sensor_msgs is not None or
                 craft.msgs.actuators is not None or e.actuators is not None or
                 len(e.sources) != 1, 'an orbit, sensors, actuators or torque sources'),
                (lambda: not e._aligned, 'principal axes not the body\'s'),
                (lambda: not e._torque_seen or node._paused_reported, 'no torque yet, or paused'),
                (lambda: e.t_ns != node._held or e.config.sample_period_ns != node._lockstep or
                 e._next_sample != node._held + node._lockstep or
                 e.command.timeout_ns <= node._lockstep, 'samples off the control instants'),
                (lambda: rt._first is None or rt._sent is None, 'round trips not started'),
                (lambda: acks.window - acks.pending <= 1, 'acknowledgements due'),
                (lambda: not direct.prepared(), 'the period is not direct')):
            if fails():
                return why
        return None

    def close(self):
        """The rcl wait set and message go (the node's teardown)."""
        if self.exchange is not None:
            self.exchange.close()
            self.exchange, self._key, self.tables = None, None, None

    def _build(self, node, craft):
        """The tables of ``craft``'s templated topics and the command's layout."""
        from .rcl_direct import Exchange, Uint8Array
        kept = node._packing
        msgs = craft.msgs
        if kept is None or kept[0] is not craft.active_raw or kept[1] is not msgs._templates:
            kept = node._packers(craft)
        key = (kept, node._layout, craft.active_raw)
        if key == self._key:
            return self.tables
        self._key, self.tables = key, None
        if kept[2] is None:
            return None
        if self.exchange is None:
            self.exchange = Exchange(node.context, node._exchange_sub)
        row, bases, fields, at = kept[1].row, [], [], 0
        for _, pack, get, _ in kept[2]:
            got = template_fields(pack, get, row)
            if got is None:
                return None
            bases.append(got[0])
            fields += [(at + o, kind, src) for o, kind, src in got[1]]
            at += len(got[0])
        out = np.frombuffer(b''.join(bases), dtype=np.uint8).copy()  # each topic's bytes
        arrays = (Uint8Array * max(len(bases), 1))()
        starts = np.cumsum([0] + [len(b) for b in bases])
        for i, b in enumerate(bases):
            arrays[i].buffer = out.ctypes.data + int(starts[i])
            arrays[i].buffer_length = arrays[i].buffer_capacity = len(b)
            arrays[i].allocator = self.exchange.allocator
        pubs = [pub for _, pub, _ in craft.active_raw]
        length, _, (size, frame), _ = node._layout
        at_doubles = 4 + ((12 + size + 7) & ~7)
        self.tables = {
            'pubs': np.array([p.handle.pointer for p in pubs], dtype=np.int64),
            'msgs': np.array([ctypes.addressof(arrays[i]) for i in range(len(bases))],
                             dtype=np.int64),
            'out': out,
            'fields': np.array(fields, dtype=np.int64).reshape(-1, 3),
            'lay': np.array([length, size, at_doubles], dtype=np.int64),
            'frame': np.frombuffer(frame, dtype=np.uint8).copy(),
            'h': np.array([self.exchange.wait_set, self.exchange.sub,
                           node.context.handle.pointer], dtype=np.int64),
            'into': L.array_words(self.exchange._into),
            'keep': (arrays, pubs, [p[1] for p in kept[2]]),
            'names': [name for _, _, _, name in kept[2]]}
        if len(self.tables['pubs']) != len(bases):
            self.tables = None
        return self.tables

    def run(self, node, until: float):
        """The compiled exchanges until the wall time ``until``: None if they may not run
        (the caller takes the Python way); else (its outcome code, the bytes of a command
        taken and left to ``_on_torque_bytes``, or None)."""
        craft = node._crafts.get('')
        if craft is None or self.unable(node, craft) is not None:
            return None
        t = self._build(node, craft)
        if t is None:
            return None
        e, rt, acks = craft.engine, node._round_trips, node._acks
        mt = e.command.max_torque
        mx, my, mz = (mt,) * 3 if isinstance(mt, float) else map(float, mt)
        ints = np.zeros(L.N_INTS, dtype=np.int64)
        ints[[L.T, L.PERIOD, L.END, L.TIMEOUT, L.HELD_SEC, L.HELD_NSEC, L.ROOM_LEFT, L.COUNT,
              L.CPU_EVERY]] = (e.t_ns, node._lockstep, node._direct._end,
                               e.command.timeout_ns, *node._held_fields,
                               acks.window - acks.pending - 1, rt.count, CPU_EVERY)
        fl = np.zeros(L.N_FLOATS)
        fl[[L.MAX_X, L.MAX_Y, L.MAX_Z, L.UNTIL_WALL, L.HOLD_TIMEOUT, L.HELD_SINCE, L.SENT,
            L.WALL_TOTAL, L.WALL_MAX]] = (mx, my, mz, until, node._p['lockstep_timeout'],
                                          node._held_since, rt._sent, rt.wall_total,
                                          rt.wall_max)
        q, m = e._q.copy(), e._m.copy()
        direct = node._direct
        self.loop(*self._c, t['h'], t['into'], t['pubs'], t['msgs'], t['out'], t['fields'],
                  t['lay'], t['frame'], direct.f, direct.ticks, e.dynamics.environment, q, m,
                  ints, fl)
        code, done = int(ints[L.CODE]), int(ints[L.DONE])
        if done:
            self._commit(node, craft, ints, fl, q, m, done)
        if code == L.REFUSED:
            j = int(ints[L.REFUSED_TOPIC])
            acks.refused(t['names'][j], RCLError(self._error(int(ints[L.RET]), 'publish')))
        elif code == L.ERROR:
            raise RCLError(self._error(int(ints[L.RET]), 'take or wait'))
        return code, (self.exchange.taken() if code == L.OTHER else None)

    def _error(self, ret, what):
        from .rcl_direct import error
        return error(self.exchange.lib, ret, f'lockstep exchange ({what})')

    @staticmethod
    def _commit(node, craft, ints, fl, q, m, done):
        """``done`` exchanges ran: the engine, the command, the hold, the round trips,
        the counts as the Python way leaves them after as many."""
        e, rt, acks, cmd = craft.engine, node._round_trips, node._acks, craft.engine.command
        t = int(ints[L.T])
        e._q, e._m, e.t_ns = q, m, t
        e._next_sample = t + e.config.sample_period_ns
        e.steps += int(ints[L.STEPS_DONE])
        e._integ.nfev += int(ints[L.EVALS_DONE])
        cmd.torque, cmd.expiry = np.array((fl[L.CMD_X], fl[L.CMD_Y], fl[L.CMD_Z])), \
            t - node._lockstep + cmd.timeout_ns
        cmd.accepted += done
        cmd.saturated += int(ints[L.SATURATED])
        e._tau_body = e._tau_p = cmd.torque  # (aligned: Engine._update_torque)
        e._anchor = None
        node._instant = node._held = t
        node._held_since = float(fl[L.HELD_SINCE])
        node._held_fields = (int(ints[L.HELD_SEC]), int(ints[L.HELD_NSEC]))
        node._awaiting = {('', 'torque')}
        node._clock_ns = t
        rt.count, rt.wall_total, rt.wall_max = int(ints[L.COUNT]), float(fl[L.WALL_TOTAL]), \
            float(fl[L.WALL_MAX])
        rt._sent = float(fl[L.SENT])
        rt.compiled += done
        if ints[L.LAST_N]:
            rt._last = (int(ints[L.LAST_N]), float(fl[L.LAST_CPU]), float(fl[L.LAST_THREAD]))
        if craft.active:
            msgs, only = craft.msgs, craft.active_names
            msgs._builds[only] = msgs._builds.get(only, 0) + done
            node._published += done * len(craft.active)
        acks.pending += done
