"""Lockstep: the live simulator holds every control instant until it has that instant's command.

The contract (docs/live-nodes.md, "Lockstep"): control instants are the multiples of the
control period on the sim-time axis (``control_rate``, the controller's). At each one the
simulator publishes the state and holds; a controller answers with a command stamped with
that state's stamp; the simulator applies it from that instant and goes on to the next.
It never advances past an instant without its command and never guesses one: after
``lockstep_timeout`` (wall time) it reports that it is paused and keeps waiting.

This module is the ROS-free part: the checks on the parameters, and the round-trip
statistics (sim-side wall and CPU per exchange) that the node reports.
"""
import os
import re
import threading
import time

from .config import NS, seconds_to_ns


def period_ns(p) -> int:
    """The control period (ns) of coerced simulator parameters ``p`` with ``lockstep`` on;
    ValueError naming the parameter if lockstep cannot hold: stamps must be sim time
    (``publish_clock``, so that a controller can tell the instants), every control instant
    must be a sample instant (the state published there is the one answered), and a held
    command must last until the next instant (as the in-process law's torque does)."""
    period = seconds_to_ns(1.0 / p['control_rate'], 'control period')
    sample = seconds_to_ns(1.0 / p['publish_rate'], 'sample period')
    if not p['publish_clock']:
        raise ValueError('lockstep needs publish_clock: true (stamps are then sim time, so '
                         'a controller can tell the control instants)')
    if period % sample:
        raise ValueError(f'lockstep: control_rate {p["control_rate"]:g} Hz must divide '
                         f'publish_rate {p["publish_rate"]:g} Hz (every control instant is a '
                         f'sample instant: periods {period} ns and {sample} ns)')
    if p['command_timeout'] * NS < period:
        raise ValueError(f'lockstep: command_timeout {p["command_timeout"]:g} s is shorter '
                         f'than the control period {period / NS:g} s (the command would '
                         'expire before the next instant)')
    return period


def awaited(p, rods: bool, controller) -> tuple:
    """The commands lockstep waits for at each control instant from one spacecraft, with
    its simulator values ``p`` (``lockstep``: false leaves it out of the loop), ``rods``
    whether it has magnetorquers, ``controller`` its controller's values from the params
    files: ``torque``, and with rods and a controller in ``bdot`` mode ``dipole`` too
    (the B-dot law's dipole for that instant). ValueError if the magnetometer does not
    read at every control instant: the law answers an instant from its reading there."""
    if not p['lockstep']:
        return ()
    if not (rods and (controller or {}).get('mode') == 'bdot'):
        return ('torque',)
    period = period_ns(p)
    if not p['magnetometer.enabled'] or \
            period % seconds_to_ns(1.0 / p['magnetometer.rate'], 'magnetometer period'):
        raise ValueError(f'lockstep with B-dot: magnetometer.rate {p["magnetometer.rate"]:g} '
                         f'Hz (enabled: {p["magnetometer.enabled"]}) must read at every '
                         f'control instant (control_rate {p["control_rate"]:g} Hz): the law '
                         'answers each instant from its reading there')
    return ('torque', 'dipole')


def controller_values(params_files, namespace: str = '/') -> dict:
    """The values the scene's controller (``attitude_controller`` beside the simulator, in
    ``namespace``) takes from ``params_files``, later files winning, as rcl reads them."""
    from ..params_file import fully_qualified, node_parameters
    fqn = fully_qualified('attitude_controller', namespace)
    values = {}
    for path in params_files:
        values.update({k: v.value for k, v in node_parameters(path, fqn).items()})
    return values


def law_bandwidth(controller) -> float:
    """The rate scale (1/s) of the controller's law with the values ``controller`` (its
    defaults where the files give none): what the offline run's in-process law tells
    ``auto``. 0 (unknown) without values or when they are not a valid law, which the
    controller node itself then refuses."""
    if not controller:
        return 0.0
    from .config import ControlSettings
    from .specs import CONTROLLER
    known = {s.name for s in CONTROLLER}  # the scene record (scene.*) is not the law's
    try:
        return ControlSettings.from_parameters(
            {k: v for k, v in controller.items() if k in known}).bandwidth()
    except ValueError:
        return 0.0


def thread_clocks() -> list:
    """(kind, CPU clock id) of each other thread of this process, its kind its name
    without the trailing numbers (Fast DDS names its threads dds.shm.<port>,
    dds.udp.<port>, dds.ev.<n>, ...); [] where /proc does not list them (not Linux)."""
    out = []
    try:
        tids = os.listdir('/proc/self/task')
    except OSError:
        return out
    me = threading.get_native_id()
    for tid in tids:
        if int(tid) == me:
            continue
        try:
            with open(f'/proc/self/task/{tid}/comm') as f:
                name = re.sub(r'[.\d]+$', '', f.read().strip())
        except OSError:  # ended meanwhile
            continue
        # the thread's CPU clock (Linux: MAKE_THREAD_CPUCLOCK(tid, CPUCLOCK_SCHED))
        out.append((name, (~int(tid) << 3) | 6))
    return out


def clock_seconds(threads) -> list:
    """Each of ``threads``' (``thread_clocks``) CPU seconds so far (0 for one that ended)."""
    out = []
    for _, clock in threads:
        try:
            out.append(time.clock_gettime(clock))
        except OSError:
            out.append(0.0)
    return out


def wake_ups() -> dict:
    """{thread id: (kind, times it has slept and been woken)} of each thread of this
    process (its voluntary context switches: each wait for a message, a lock or a timer
    that was not met at once), this one's kind 'main', the others' as ``thread_clocks``';
    {} where /proc does not list them."""
    out = {}
    try:
        tids = os.listdir('/proc/self/task')
    except OSError:
        return out
    me = str(threading.get_native_id())
    for tid in tids:
        try:
            with open(f'/proc/self/task/{tid}/comm') as f:
                name = 'main' if tid == me else re.sub(r'[.\d]+$', '', f.read().strip())
            with open(f'/proc/self/task/{tid}/status') as f:
                woken = next(int(x.split()[1]) for x in f if x.startswith('voluntary_ctxt'))
        except (OSError, StopIteration):  # ended meanwhile
            continue
        out[tid] = (name, woken)
    return out


# the CPU clocks are read at the first CPU_EVERY exchanges, then at every CPU_EVERY-th:
# each read is a system call (~0.45 µs hot, several on a loaded machine, for two clocks
# per exchange), and the CPU per period is a difference over the window they span
CPU_EVERY = 64


class RoundTrips:
    """Sim-side cost of the exchanges: wall time from publishing a control instant's state
    to applying its command, and the simulator's CPU per control period (stepping,
    publishing and receiving included): the process's, and its own thread's (the rest is
    the middleware's threads), averaged over the periods between the first and the last
    command whose CPU was read (CPU_EVERY); and at the end each thread's part
    (``thread_parts``: in lockstep, synchronous, mostly Fast DDS's shared-memory receiver,
    which takes each command and wakes the waiting thread)."""

    def __init__(self):
        self.count = 0
        self.compiled = 0  # of them, exchanges run in one compiled call (nodes/sim_rcl.py)
        self.wall_total = self.wall_max = 0.0
        self._sent = None      # wall time when the held instant's state went out
        self._first = self._last = None  # (exchanges, cpu, thread cpu) at two commands
        self._threads = ()  # the other threads at the first read, and their CPU seconds

    def sent(self):
        self._sent = time.monotonic()  # (the CPU clocks are read at commands, below)

    def applied(self):
        wall = time.monotonic()
        if self._sent is None:
            return
        rt = wall - self._sent
        self.count = n = self.count + 1
        self.wall_total += rt
        if rt > self.wall_max:
            self.wall_max = rt
        self._sent = None
        if n <= CPU_EVERY or not n % CPU_EVERY:
            read = (n, time.process_time(), time.thread_time())
            if self._first is None:
                self._first = read
                threads = thread_clocks()  # once a run (~0.1 ms): thread_parts
                self._threads = (threads, clock_seconds(threads), wake_ups())
            else:
                self._last = read

    def values(self) -> dict:
        """Means in µs (CPU over the periods between two commands applied)."""
        n, first, last = self.count, self._first, self._last
        periods = last[0] - first[0] if last is not None else 0
        return {'lockstep_exchanges': n,
                'lockstep_round_trip_wall_us': 1e6 * self.wall_total / n if n else 0.0,
                'lockstep_round_trip_wall_max_us': 1e6 * self.wall_max,
                'lockstep_cpu_per_period_us':
                    1e6 * (last[1] - first[1]) / periods if periods else 0.0,
                'lockstep_thread_cpu_per_period_us':
                    1e6 * (last[2] - first[2]) / periods if periods else 0.0}

    def thread_parts(self) -> dict:
        """Where the process's CPU went, from the first command whose CPU was read to now
        (the end of the run): µs per control period in each kind of thread
        (``thread_clocks``), the one applying the commands as 'main', and as 'ended' what
        threads that ended meanwhile spent (the process's CPU less the others'). {} before
        two commands."""
        if self._first is None or self.count <= self._first[0]:
            return {}
        main, cpu = time.thread_time(), time.process_time()
        before = {clock: c for (_, clock), c in zip(*self._threads[:2])}
        threads = thread_clocks()
        n, first = self.count - self._first[0], self._first
        parts = {'main': main - first[2]}
        for (name, clock), c in zip(threads, clock_seconds(threads)):
            # a thread started meanwhile: all of its CPU
            parts[name] = parts.get(name, 0.0) + max(c - before.get(clock, 0.0), 0.0)
        parts['ended'] = max(cpu - first[1] - sum(parts.values()), 0.0)
        return {k: round(1e6 * v / n, 1) for k, v in sorted(parts.items(), key=lambda kv:
                                                               -kv[1]) if 1e6 * v / n >= 0.05}

    def wakes(self) -> dict:
        """How often each kind of thread (``wake_ups``) slept and was woken per control
        period, from the first command whose CPU was read to now; threads that ended
        meanwhile are not counted. {} before two commands."""
        if self._first is None or self.count <= self._first[0]:
            return {}
        before, n, out = self._threads[2], self.count - self._first[0], {}
        for tid, (name, woken) in wake_ups().items():
            out[name] = out.get(name, 0) + woken - before.get(tid, (name, 0))[1]
        return {k: round(v / n, 2) for k, v in sorted(out.items(), key=lambda kv: -kv[1])
                if v / n >= 0.005}

    def summary(self) -> str:
        v = self.values()
        parts = ', '.join(f'{k} {p:g}' for k, p in self.thread_parts().items())
        wakes = ', '.join(f'{k} {w:g}' for k, w in self.wakes().items())
        return (f'lockstep: {v["lockstep_exchanges"]} exchanges, round trip '
                f'{v["lockstep_round_trip_wall_us"]:.0f} µs wall on average (max '
                f'{v["lockstep_round_trip_wall_max_us"]:.0f} µs), simulator CPU '
                f'{v["lockstep_cpu_per_period_us"]:.0f} µs per control period ('
                f'{v["lockstep_thread_cpu_per_period_us"]:.0f} µs in its own thread)'
                + (f'; by thread to the end: {parts} µs' if parts else '')
                + (f'; wake-ups per period: {wakes}' if wakes else '')
                + (f'; {self.compiled} compiled' if self.compiled else ''))
