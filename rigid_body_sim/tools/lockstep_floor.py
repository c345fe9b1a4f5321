"""Lockstep floor: the least an rclpy process spends per exchange with our controller.

``python -m rigid_body_sim.tools.lockstep_floor [--periods 2000] [--runs 3] [--out docs/bench]
[--config MODE:TAKEN:TRANSPORT:LOOP ...] [--cpu CORE] [--interleave]``

The simulator's side of a lockstep exchange (``tools.lockstep``) with everything of ours
taken out: a bare rclpy node publishes the state the controller answers in lockstep (one
nav_msgs/Odometry, CDR bytes made once by rclpy's serialiser: no physics, no message
building, no /clock), then waits until the command is taken. What it
spends per exchange (process CPU, its own thread's, wall) is what rclpy and the middleware
cost whatever the simulator does. Measured for each Fast DDS publication mode
(``RMW_FASTRTPS_PUBLICATION_MODE``: the nodes use SYNCHRONOUS in lockstep, ASYNCHRONOUS
otherwise, ``process.py`` says why; the synchronous rows with its heartbeat profile),
with the command taken as a message or as bytes (the simulator takes bytes), over Fast
DDS's default transports or shared memory only (``FASTDDS_BUILTIN_TRANSPORTS=SHM``, both
processes), and taken by turning the events executor or from an rcl wait set of the one
subscription (the simulator's loop does the latter: ``nodes/sim_lockstep.py``), or
('rcl') with every exchange of the run in one compiled call of rcl's C functions, no
Python and no GIL between them (``nodes/rcl_direct.py``). Each configuration runs in its
own process, ``--runs`` times (``--interleave``: in rounds, one run of each configuration
per round, so that the load's changes weigh on each alike); figures are the runs' medians,
and each run gives its threads' parts (``threads_us``: 'main' is this one, ``dds.shm``
Fast DDS's shared-memory receiver, ``dds.ev`` its timed events, ...). ``--cpu CORE``
runs both processes on that one core, as ``tools.lockstep --cpu`` does.
"""
import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import tempfile
import time

from ..bench.common import report
from ..engine.lockstep import clock_seconds as _clocks, thread_clocks as _threads
from . import argument_parser, command_line, stop
from .lockstep import SCENE, _exe, _on_cpu

RATE = 100.0  # control rate [Hz]: the instants the states are stamped with
# (publication mode, command taken as, transports, loop): floor()'s and _measure's
CONFIGS = (('ASYNCHRONOUS', 'message', 'default', 'executor'),
           ('ASYNCHRONOUS', 'bytes', 'default', 'executor'),
           ('SYNCHRONOUS', 'message', 'default', 'executor'),
           ('SYNCHRONOUS', 'bytes', 'default', 'executor'),
           ('SYNCHRONOUS', 'bytes', 'shm', 'executor'),
           ('SYNCHRONOUS', 'bytes', 'default', 'waitset'),
           ('SYNCHRONOUS', 'bytes', 'shm', 'waitset'),
           ('SYNCHRONOUS', 'bytes', 'default', 'rcl'))


def _config(text: str) -> tuple:
    """--config's MODE:TAKEN:TRANSPORT:LOOP, checked."""
    parts = tuple(text.split(':'))
    choices = (('ASYNCHRONOUS', 'SYNCHRONOUS'), ('message', 'bytes'), ('default', 'shm'),
               ('executor', 'waitset', 'rcl'))
    if len(parts) != 4 or any(p not in c for p, c in zip(parts, choices)):
        raise argparse.ArgumentTypeError(
            f'{text!r}: expected MODE:TAKEN:TRANSPORT:LOOP, each one of '
            + ' / '.join('|'.join(c) for c in choices))
    return parts


def _per_thread(threads, before, after, main: float, periods: int) -> dict:
    """µs per exchange spent in each kind of thread between the two readings; this
    thread's (``main``, its own CPU seconds) as 'main'."""
    out = {'main': 1e6 * main / periods}
    for (name, _), c0, c1 in zip(threads, before, after):
        out[name] = out.get(name, 0.0) + 1e6 * max(c1 - c0, 0.0) / periods
    return {k: round(v, 1) for k, v in sorted(out.items()) if v >= 0.05}


PRIMES = 60  # instants tried a second apart before the measurement, until one is answered


class NoCommand(RuntimeError):
    """No command answered a state within the time allowed."""


def _compiled(node, sub, pub, frames):
    """The 'rcl' loop's ``exchanges(k0, k1)``: exchanges k0 .. k1-1 in one compiled call
    of rcl's C functions, no Python and no GIL between them (``nodes/rcl_direct.py``)."""
    import ctypes
    import numpy as np
    from ..nodes import rcl_direct
    direct = rcl_direct.Exchange(node.context, sub, pub)
    arrays, data = rcl_direct.frames_array(frames, direct.allocator)
    loop, out = direct.loops['floor_loop'], np.zeros(2, dtype=np.int64)
    args = (direct.wait_set, direct.sub, direct.pub, ctypes.addressof(arrays))

    def exchanges(k0, k1):
        loop(*args, k0, k1, direct.into, 10_000_000_000, out)  # 10 s, as by_wait_set
        k, ret = out.tolist()
        if ret == rcl_direct.RET_TIMEOUT:
            raise NoCommand(f'no command for instant {k} within 10 s')
        if ret != rcl_direct.RET_OK:
            raise RuntimeError(rcl_direct.error(direct.lib, ret, f'exchange {k}'))
    exchanges.kept = (direct, arrays, data)  # alive as long as the loop
    exchanges(0, 0)  # compiled now, not in the first exchanges
    return exchanges


def _measure(periods: int, raw: bool, loop: str = 'executor') -> dict:
    """In this process (its environment chose the publication mode and the transports):
    the figures. ``loop``: 'executor' turns the events executor until the command has
    been taken; 'waitset' takes it from an rcl wait set of the one subscription; 'rcl'
    as 'waitset', every exchange after instant 0 in one compiled call (``_compiled``)."""
    import rclpy
    from geometry_msgs.msg import Vector3Stamped
    from nav_msgs.msg import Odometry
    from rclpy.experimental import EventsExecutor
    from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
    from rclpy.serialization import serialize_message
    from ..nodes.common import qos_profile
    from ..nodes.spacecraft import STATE_DEPTH
    ns = f'/lockstep_floor_{os.getpid()}'
    with tempfile.NamedTemporaryFile('w', suffix='.yaml', delete=False) as f:
        f.write('/**/attitude_controller:\n  ros__parameters:\n    lockstep: true\n'
                f'    control_rate: {RATE}\n')
    ctl = subprocess.Popen(_exe('controller') + [
        '--ros-args', '-r', f'__ns:={ns}', '--params-file', SCENE, '--params-file', f.name],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    rclpy.init()
    try:
        node = rclpy.create_node('lockstep_floor', namespace=ns)
        state = qos_profile('reliable', STATE_DEPTH)
        odometry = node.create_publisher(Odometry, 'odometry', state)
        got = []
        sub = node.create_subscription(Vector3Stamped, 'torque_command', got.append,
                                       qos_profile('reliable'), raw=raw)
        executor = EventsExecutor(context=node.context)
        if loop == 'executor':
            executor.add_node(node)
        o = Odometry()
        o.header.frame_id, o.child_frame_id, o.pose.pose.orientation.w = \
            'world', 'base_link', 1.0
        deadline = time.monotonic() + 60.0
        # the controller's command writer matched too: a command it sent before would be
        # lost for this volatile subscription (1 run in about 10 waited 10 s for instant 0)
        while min(odometry.get_subscription_count(), sub.get_publisher_count()) < 1:
            if time.monotonic() > deadline:
                raise RuntimeError('the controller did not subscribe and publish within 60 s')
            executor.spin_once(timeout_sec=0.05) if loop == 'executor' else time.sleep(0.05)
        # states for every instant, serialised before the measurement (ours cost nothing)
        period = round(1e9 / RATE)
        frames = []
        for k in range(PRIMES + 100 + periods):
            o.header.stamp.sec, o.header.stamp.nanosec = divmod(k * period, 10**9)
            frames.append(serialize_message(o))
        send = odometry.handle.publish_raw
        wait_set = _rclpy.WaitSet(1, 0, 0, 0, 0, 0, node.context.handle)
        take, handle = sub.handle.take_message, sub.handle

        def by_executor(k, within=10.0):
            n, until = len(got), time.monotonic() + within
            while len(got) == n:
                if time.monotonic() > until:
                    raise NoCommand(f'no command for instant {k} within {within:g} s')
                executor.spin_once(timeout_sec=min(within, 1.0))

        def by_wait_set(k, within=10.0):
            until = time.monotonic() + within
            while take(Vector3Stamped, raw) is None:
                if time.monotonic() > until:
                    raise NoCommand(f'no command for instant {k} within {within:g} s')
                wait_set.clear_entities()
                wait_set.add_subscription(handle)
                wait_set.wait(round(min(within, 1.0) * 1e9))
        answer = by_executor if loop == 'executor' else by_wait_set

        def exchanges(k0, k1):
            for k in range(k0, k1):
                send(frames[k])
                answer(k)
        if loop == 'rcl':  # every exchange in one compiled call (nodes/rcl_direct.py),
            exchanges = _compiled(node, sub, odometry, frames)  # compiled before instant 0
        # The first instants are sent a second apart until one is answered: our writer's
        # and reader's matches (above) say nothing of the controller's reader and writer,
        # which drop what was sent before they matched (a CI run under load waited 10 s
        # for instant 0). The controller answers an instant once, so instant 0 sent again
        # got no second command where its first was lost (a suite run under load: no
        # command for 60 s): each try is a new instant.
        first = 0
        while True:
            send(frames[first])
            try:
                answer(first, within=1.0)
                break
            except NoCommand:
                first += 1
                if first == PRIMES:
                    raise
        exchanges(first + 1, first + 100)  # discovery settled, caches warm
        threads = _threads()
        # the process's window holds the threads' (each thread's share, summed, is then
        # within the process's CPU; the other order let the DDS threads run outside it)
        c0 = time.process_time()
        before = _clocks(threads)
        t0, w0 = time.thread_time(), time.monotonic()
        exchanges(first + 100, first + 100 + periods)
        t1, w1 = time.thread_time(), time.monotonic()
        after = _clocks(threads)
        c1 = time.process_time()
        threads = _per_thread(threads, before, after, t1 - t0, periods)
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
        stop(ctl)
        os.unlink(f.name)
    return {'cpu_per_exchange_us': 1e6 * (c1 - c0) / periods,
            'thread_cpu_per_exchange_us': 1e6 * (t1 - t0) / periods,
            'wall_per_exchange_us': 1e6 * (w1 - w0) / periods,
            'threads_us': threads, 'cpus': sorted(os.sched_getaffinity(0))}


def _env(mode: str, transport: str) -> dict:
    """The environment of a run of ``mode`` over ``transport`` (see ``floor``)."""
    env = dict(os.environ, RMW_FASTRTPS_PUBLICATION_MODE=mode,
               ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', str(random.randint(101, 200))))
    if transport == 'shm':
        env['FASTDDS_BUILTIN_TRANSPORTS'] = 'SHM'
    if mode == 'SYNCHRONOUS' and not env.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        from ..nodes.process import heartbeat_profile  # as the nodes publish in lockstep
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = heartbeat_profile()
    return env


def _run(mode: str, raw: bool, periods: int, transport: str, loop: str, cpu: int) -> dict:
    """One run of one configuration, in a process of its own: its figures."""
    out = subprocess.run([sys.executable, '-m', __spec__.name, '--one', str(periods),
                          '--loop', loop] + (['--raw'] if raw else []),
                         env=_env(mode, transport), capture_output=True, text=True,
                         timeout=600, preexec_fn=_on_cpu(cpu))
    if out.returncode != 0:
        raise RuntimeError(f'floor run ({mode}, raw {raw}, {transport}, {loop}) exited '
                           f'{out.returncode}:\n' + out.stderr[-2000:])
    return json.loads(out.stdout.strip().splitlines()[-1])


def _row(mode: str, raw: bool, periods: int, transport: str, loop: str, got) -> dict:
    """One configuration's row from its runs' figures ``got``: the medians, and each run's."""
    row = {'publication_mode': mode, 'command_taken_as': 'bytes' if raw else 'message',
           'transport': transport, 'loop': loop, 'exchanges': periods}
    for key in got[0]:
        if key in ('threads_us', 'cpus'):
            row[key + '_runs'] = [g[key] for g in got]
            continue
        row[key] = statistics.median(g[key] for g in got)
        row[key + '_runs'] = [g[key] for g in got]
    return row


def floor(mode: str, raw: bool, periods: int, runs: int, transport: str = 'default',
          loop: str = 'executor', cpu: int = -1) -> dict:
    """``runs`` runs of one configuration, each in a process of its own: the medians.
    ``transport``: Fast DDS's built-in transports (FASTDDS_BUILTIN_TRANSPORTS: 'default'
    is UDPv4 and shared memory, 'shm' shared memory only), for both processes; ``cpu``:
    both on that core (the run's process, and the controller it starts, inherit it)."""
    return _row(mode, raw, periods, transport, loop,
                [_run(mode, raw, periods, transport, loop, cpu) for _ in range(runs)])


def interleaved(configs, periods: int, runs: int, cpu: int = -1) -> list:
    """``floor``'s rows of ``configs`` (MODE, TAKEN, TRANSPORT, LOOP), their runs in
    rounds, one run of each configuration per round: a load that changes meanwhile
    weighs on each alike."""
    got = [[] for _ in configs]
    for _ in range(runs):
        for runs_of, (mode, taken, transport, loop) in zip(got, configs):
            runs_of.append(_run(mode, taken == 'bytes', periods, transport, loop, cpu))
    return [_row(mode, taken == 'bytes', periods, transport, loop, g)
            for (mode, taken, transport, loop), g in zip(configs, got)]


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--periods', type=int, default=2000, help='exchanges per run')
    parser.add_argument('--runs', type=int, default=3, help='runs per configuration')
    parser.add_argument('--out', help='directory for lockstep_floor.json (e.g. docs/bench)')
    parser.add_argument('--cpu', type=int, default=-1,
                        help='both processes (every thread) on this CPU core; -1: anywhere')
    parser.add_argument('--one', type=int, help=argparse.SUPPRESS)
    parser.add_argument('--raw', action='store_true', help=argparse.SUPPRESS)
    parser.add_argument('--loop', default='executor', help=argparse.SUPPRESS)
    parser.add_argument('--config', type=_config, action='append', help='only this '
                        'configuration, MODE:TAKEN:TRANSPORT:LOOP (e.g. '
                        'SYNCHRONOUS:bytes:shm:waitset); repeatable')
    parser.add_argument('--interleave', action='store_true', help='the configurations\' '
                        'runs in rounds, one of each per round, rather than one after another')
    args = parser.parse_args(argv)
    if args.one:  # one run, in this process (floor() starts these)
        print(json.dumps(_measure(args.one, args.raw, args.loop)))
        return 0
    configs = args.config or CONFIGS
    if args.interleave:
        rows = interleaved(configs, args.periods, args.runs, args.cpu)
    else:
        rows = [floor(mode, taken == 'bytes', args.periods, args.runs, transport, loop,
                      args.cpu) for mode, taken, transport, loop in configs]
    for r in rows:
        print(f'{r["publication_mode"]}, command as {r["command_taken_as"]}, '
              f'{r["transport"]} transports, {r["loop"]}: process CPU '
              f'{r["cpu_per_exchange_us"]:.0f} µs per exchange (runs '
              f'{", ".join(f"{v:.0f}" for v in r["cpu_per_exchange_us_runs"])}), its '
              f'thread {r["thread_cpu_per_exchange_us"]:.0f} µs (runs '
              f'{", ".join(f"{v:.0f}" for v in r["thread_cpu_per_exchange_us_runs"])}), '
              f'wall {r["wall_per_exchange_us"]:.0f} µs; threads (first run): '
              + ', '.join(f'{k} {v:.0f}' for k, v in r['threads_us_runs'][0].items()),
              flush=True)
    if args.out:
        report({'command': command_line(__spec__, argv), 'control_rate_hz': RATE,
                'rows': rows, 'cpu_affinity': args.cpu}, args.out, 'lockstep_floor.json')
        from ..bench import report as summary
        summary.write(args.out)  # the benchmarks page's figures, this floor's with them
    return 0


if __name__ == '__main__':
    sys.exit(main())
