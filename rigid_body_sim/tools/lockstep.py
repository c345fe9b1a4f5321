"""Lockstep round trip: simulator and controller processes exchanging state and command.

``python -m rigid_body_sim.tools.lockstep [--periods 2000] [--seconds 5] [--rates 100 1000]
[--runs 3] [--cpu CORE]``

For each control rate (publishing at the same rate, the slew scene, ``splitting4``):
* as fast as possible (``real_time_factor: 0``), ``--periods`` control periods: the
  simulator's own figures (``engine.lockstep.RoundTrips``, logged at the end of its run):
  wall time from publishing a control instant's state to applying its command, and the
  simulator's CPU per control period (stepping, publishing and receiving; target ≤ 100 µs),
  the process's (every thread: that is the figure) and its own thread's, and each other
  thread's part (``sim_threads_us``: Fast DDS's shared-memory receiver ``dds.shm``, its
  timed events ``dds.ev``, ...) and how often each slept and was woken per period
  (``sim_wakes_per_period``);
* at real time (``real_time_factor: 1``), ``--seconds`` of sim time: the achieved control
  rate, exchanges per wall second between t = 0 and the end (the simulator's log stamps).
Real processes and real DDS, in a ROS domain of their own; nothing else is started.
With ``--runs N`` each run is repeated N times: every figure is the median of the runs,
and ``runs`` keeps each run's, for their min and max. With ``--cpu CORE`` both processes,
every thread, run on that one core (the simulator's ``cpu_affinity``; the controller
started on it).
"""
import os
import random
import re
import statistics
import subprocess
import sys
import tempfile

from ..bench.common import report
from . import argument_parser, command_line, stop

SCENE = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(
    __file__)))), 'config', 'slew.yaml')
SUMMARY = re.compile(r'lockstep: (\d+) exchanges, round trip (\d+) µs wall on average \(max '
                     r'(\d+) µs\), simulator CPU (\d+) µs per control period'
                     r'(?: \((\d+) µs in its own thread\))?')
STAMP = re.compile(r'\[(\d+\.\d+)\]')
# RoundTrips.thread_parts and .wakes, after the summary: 'main 84, dds.shm 22.5, dds.ev 4'
THREADS = re.compile(r'; by thread to the end: ([^;]*) µs')
WAKES = re.compile(r'; wake-ups per period: ([^;\n]*)')
PART = re.compile(r'(\S+) ([\d.]+)')


def _exe(name):
    exe = os.path.join(sys.prefix, 'lib', 'rigid_body_sim', name)
    if os.path.exists(exe):
        return [exe]
    return [sys.executable, '-m', f'rigid_body_sim.nodes.{name}']


def _stamp(line):
    m = STAMP.search(line)
    return float(m.group(1)) if m else None


def overrides(rtf: float, duration: float, rate: float, cpu: int = -1) -> str:
    """A params file (its path; the caller removes it) putting the simulator and the
    controller in lockstep at ``rate`` (Hz) for ``duration`` (s) at ``rtf``, the
    simulator on CPU ``cpu`` (-1: anywhere)."""
    with tempfile.NamedTemporaryFile('w', suffix='.yaml', delete=False) as f:
        f.write('/**/attitude_simulator:\n  ros__parameters:\n'
                f'    real_time_factor: {rtf}\n    publish_clock: true\n'
                f'    integrator: splitting4\n    duration: {duration}\n'
                f'    publish_rate: {rate}\n    control_rate: {rate}\n    lockstep: true\n'
                '    wait_for_subscribers: 0\n    wait_for_subscribers_timeout: 60.0\n'
                f'    lockstep_timeout: 30.0\n    cpu_affinity: {cpu}\n'
                '/**/attitude_controller:\n  ros__parameters:\n    lockstep: true\n'
                f'    control_rate: {rate}\n')
    return f.name


def _on_cpu(cpu: int):
    """A ``preexec_fn`` putting the child on CPU ``cpu`` (its threads inherit it), or None
    for -1."""
    return None if cpu < 0 else lambda: os.sched_setaffinity(0, {cpu})


def exchange(rate: float, rtf: float, duration: float, timeout: float = 600.0,
             cpu: int = -1) -> dict:
    """One lockstep run of simulator + controller; the simulator's figures. ``cpu``: both
    processes on that core (-1: where the OS puts them)."""
    env = dict(os.environ, PYTHONUNBUFFERED='1',
               ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', str(random.randint(101, 200))))
    ns = f'/lockstep_bench_{os.getpid()}_{int(rate)}_{int(rtf)}'
    over = overrides(rtf, duration, rate, cpu)
    args = ['--ros-args', '-r', f'__ns:={ns}', '--params-file', SCENE, '--params-file', over]
    ctl = subprocess.Popen(_exe('controller') + args, env=env, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, start_new_session=True,
                           preexec_fn=_on_cpu(cpu))
    try:
        sim = subprocess.run(_exe('simulator') + args, env=env, capture_output=True,
                             text=True, timeout=timeout)
    finally:
        stop(ctl)
        os.unlink(over)
    log = sim.stdout + sim.stderr
    m = SUMMARY.search(log)
    if sim.returncode != 0 or m is None:
        raise RuntimeError(f'simulator exited {sim.returncode} without its lockstep summary:\n'
                           + log[-2000:])
    lines = log.splitlines()
    t0 = next(_stamp(x) for x in lines if 'starting at t = 0' in x)
    t1 = next(_stamp(x) for x in lines if 'reached at t =' in x)
    n = int(m.group(1))
    parts, wakes = THREADS.search(log), WAKES.search(log)
    return {'control_rate_hz': rate, 'real_time_factor': rtf, 'exchanges': n,
            'round_trip_wall_us': int(m.group(2)), 'round_trip_wall_max_us': int(m.group(3)),
            'sim_cpu_per_period_us': int(m.group(4)),
            'sim_thread_cpu_per_period_us': int(m.group(5)) if m.group(5) else None,
            'sim_threads_us': {k: float(v) for k, v in PART.findall(parts.group(1))}
            if parts else {},
            'sim_wakes_per_period': {k: float(v) for k, v in PART.findall(wakes.group(1))}
            if wakes else {},
            'achieved_rate_hz': n / (t1 - t0) if t1 > t0 else None}


def repeated(runs: int, *args, **kwargs) -> dict:
    """``exchange(*args, **kwargs)`` ``runs`` times: each figure the runs' median, ``runs``
    each run's."""
    got = [exchange(*args, **kwargs) for _ in range(runs)]
    if runs == 1:
        return got[0]
    out = {}
    for key, value in got[0].items():
        values = [g[key] for g in got]
        out[key] = statistics.median(values) if isinstance(value, (int, float)) and \
            None not in values else value
    # each thread's part and wake-ups: their medians over the runs (0 in a run without)
    for key in ('sim_threads_us', 'sim_wakes_per_period'):
        kinds = sorted({k for g in got for k in g[key]})
        out[key] = {k: statistics.median(g[key].get(k, 0.0) for g in got) for k in kinds}
    out['runs'] = got
    return out


def spread(row: dict, key: str) -> str:
    """'median (min-max)' of ``key`` over a repeated row's runs, or its one value."""
    values = [r[key] for r in row.get('runs', [row])]
    if None in values:
        return 'not reported'
    if len(values) == 1:
        return f'{values[0]:.0f}'
    return f'{row[key]:.0f} ({min(values):.0f}-{max(values):.0f})'


def others(row: dict) -> str:
    """', dds.shm 22, dds.ev 4': the parts of the simulator's CPU per exchange outside its
    own thread (``sim_threads_us``, medians), the larger first; '' without them."""
    parts = sorted(((v, k) for k, v in row.get('sim_threads_us', {}).items()
                    if k != 'main' and v >= 0.5), reverse=True)
    return ''.join(f', {k} {v:.0f}' for v, k in parts)


TARGET_CPU = 'lockstep simulator CPU per exchange as fast as possible (µs)'
TARGET_RATE = 'lockstep exchanges/s at real time, {rate:g} Hz control'


def targets_from(rows, load, core: int = -1) -> list:
    """The section's rows of targets.csv: the simulator's process CPU per exchange as fast
    as possible, the worse rate's median (target ≤ 100 µs), and at real time the achieved
    control rate at each rate (target: the rate; 1 % short passes, for the run's start
    and end); ``load``: the load average before and after; ``core``: the CPU both
    processes ran on (-1: none), said in the CPU row's note."""
    from ..bench import targets
    fast = max((r['as_fast_as_possible'] for r in rows),
               key=lambda f: f['sim_cpu_per_period_us'])
    cpu = fast['sim_cpu_per_period_us']
    out = [targets.simple(TARGET_CPU, cpu, 100.0, cpu <= 100.0, '; '.join(
        f'{r["control_rate_hz"]:g} Hz: {spread(r["as_fast_as_possible"], "sim_cpu_per_period_us")}'
        f' ({spread(r["as_fast_as_possible"], "sim_thread_cpu_per_period_us")} in its thread'
        f'{others(r["as_fast_as_possible"])})' for r in rows) +
        f'; load {load[0]:.1f}-{load[1]:.1f}' + (f'; both on CPU {core}' if core >= 0 else ''))]
    for r in rows:
        real, rate = r['real_time'], r['control_rate_hz']
        got = real['achieved_rate_hz'] or 0.0
        values = [x['achieved_rate_hz'] or 0.0 for x in real.get('runs', [real])]
        out.append(targets.simple(TARGET_RATE.format(rate=rate), got, rate, got >= 0.99 * rate,
                                  f'runs {min(values):.1f}-{max(values):.1f}; load '
                                  f'{load[0]:.1f}-{load[1]:.1f}'))
    return out


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--periods', type=int, default=2000,
                        help='control periods as fast as possible, per rate')
    parser.add_argument('--seconds', type=float, default=5.0,
                        help='sim seconds at real time, per rate')
    parser.add_argument('--rates', type=float, nargs='+', default=[100.0, 1000.0],
                        help='control rates [Hz]')
    parser.add_argument('--runs', type=int, default=1,
                        help='runs per rate and mode (figures: their median)')
    parser.add_argument('--cpu', type=int, default=-1,
                        help='both processes (every thread) on this CPU core; -1: anywhere')
    parser.add_argument('--out', help='directory for lockstep.json (e.g. docs/bench), which '
                        'the benchmarks page renders')
    args = parser.parse_args(argv)
    rows = []
    # CPU figures grow with the machine's load (Fast DDS's sending thread spins while it
    # waits, caches are shared): the 1-minute load average before and after goes with them
    load = [os.getloadavg()[0]]
    for rate in args.rates:
        fast = repeated(args.runs, rate, 0.0, args.periods / rate, cpu=args.cpu)
        real = repeated(args.runs, rate, 1.0, args.seconds, cpu=args.cpu)
        rows.append({'control_rate_hz': rate, 'as_fast_as_possible': fast, 'real_time': real})
        print(f'control {rate:g} Hz: as fast as possible {fast["exchanges"]} exchanges, round '
              f'trip {spread(fast, "round_trip_wall_us")} µs wall (max '
              f'{fast["round_trip_wall_max_us"]:.0f} µs), simulator CPU '
              f'{spread(fast, "sim_cpu_per_period_us")} µs per period ('
              f'{spread(fast, "sim_thread_cpu_per_period_us")} µs in its own thread'
              f'{others(fast)}), '
              f'{fast["achieved_rate_hz"]:.0f} exchanges/s; at real time '
              f'{real["achieved_rate_hz"]:.1f} exchanges/s (target {rate:g}), simulator CPU '
              f'{real["sim_cpu_per_period_us"]:.0f} µs per period', flush=True)
    load.append(os.getloadavg()[0])
    print(f'load average {load[0]:.2f} before, {load[1]:.2f} after '
          f'({os.cpu_count()} CPUs)', flush=True)
    if args.out:
        report({'command': command_line(__spec__, argv), 'rows': rows,
                'load_average': load, 'cpus': os.cpu_count(), 'cpu_affinity': args.cpu},
               args.out, 'lockstep.json')
        from ..bench import report as summary
        t_rows = targets_from(rows, load, args.cpu)
        summary.replace_targets(args.out, tuple(r['target'] for r in t_rows), t_rows,
                                command=command_line(__spec__, argv), after='live')
        summary.write(args.out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
