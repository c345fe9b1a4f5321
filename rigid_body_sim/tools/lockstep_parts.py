"""Lockstep parts: where the simulator's own thread spends a lockstep exchange.

``python -m rigid_body_sim.tools.lockstep_parts [--periods 3000] [--rate 100] [--runs 3]``

The exchange of ``tools.lockstep`` as fast as possible (the slew scene, ``splitting4``, a
controller process in lockstep), with the simulator built in this process so that each
part of its loop can be timed: this thread's CPU (``time.thread_time``) around the engine's
call, the state's bytes, their write, the command taken and applied, the wait, and the
whole loop (``loop``: what neither ``run_once`` nor the wait spent), per exchange from
t = 0 to the end. The parts nest (``PARTS`` says how), and each timer adds ~0.5 µs. Each
run is a process of its own; figures: the runs' medians, with min-max. The exchange timed
is the Python way's (``RIGID_BODY_SIM_RCL_LOOP=0``): the compiled one runs none of these
parts.
"""
import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import time

from . import argument_parser, stop
from .lockstep import SCENE, _exe, overrides

# (label, module, class, method): what is timed, in the simulator's process. A command
# (``command``: decoded, checked, applied) is taken at the top of a turn of the loop
# (``take``, within ``run_once``) or, while an instant is held, by the exchanges' own loop
# (``exchanges``, within ``wait``); as fast as possible the held instant's (``held``)
# steps to and publishes the next instant at once (``direct``, ``direct.step`` its
# engine's call: nodes/sim_lockstep.py). ``engine`` and ``publish`` are the general
# way's (t = 0, and wherever the direct period declines); ``bytes`` and ``write`` are
# within either ``publish`` or ``direct``.
PARTS = (('engine', 'rigid_body_sim.engine.core', 'Engine', 'advance'),
         ('publish', 'rigid_body_sim.nodes.simulator', 'Simulator', '_publish'),
         ('take', 'rigid_body_sim.nodes.simulator', 'Simulator', '_take_commands'),
         ('exchanges', 'rigid_body_sim.nodes.simulator', 'Simulator', '_exchanges'),
         ('command', 'rigid_body_sim.nodes.simulator', 'Simulator', '_on_torque_bytes'),
         ('held', 'rigid_body_sim.nodes.simulator', 'Simulator', '_take_held'),
         ('direct', 'rigid_body_sim.nodes.simulator', 'Simulator', '_direct_exchange'),
         ('direct.step', 'rigid_body_sim.engine.lockstep_direct', 'DirectPeriod', 'step'),
         ('bytes', 'rigid_body_sim.nodes.state_messages', 'StateMessages',
          'encoded_block'),
         ('write', 'rigid_body_sim.nodes.spacecraft', 'Spacecraft', 'publish_states'),
         ('hold', 'rigid_body_sim.nodes.simulator', 'Simulator', '_hold'),
         ('wait', 'rigid_body_sim.nodes.simulator', 'Simulator', '_turn'),
         ('run_once', 'rigid_body_sim.nodes.simulator', 'Simulator', 'run_once'))


def _timed(spent: dict):
    """Wrap each of PARTS so that its thread CPU (ns) adds up in ``spent``."""
    import importlib
    clock = time.thread_time_ns
    for label, module, cls, name in PARTS:
        owner = getattr(importlib.import_module(module), cls)
        inner = getattr(owner, name)

        def timed(*args, _inner=inner, _label=label, **kwargs):
            t0 = clock()
            try:
                return _inner(*args, **kwargs)
            finally:
                spent[_label] += clock() - t0
        setattr(owner, name, timed)


def _measure(periods: int, rate: float) -> dict:
    """In this process: the simulator's parts per exchange (µs) and its thread's total."""
    from ..nodes import simulator
    from ..nodes.process import run_node
    ns = f'/lockstep_parts_{os.getpid()}'
    over = overrides(0.0, periods / rate, rate)
    args = ['--ros-args', '-r', f'__ns:={ns}', '--params-file', SCENE, '--params-file', over]
    ctl = subprocess.Popen(_exe('controller') + args, stdout=subprocess.DEVNULL,
                           stderr=subprocess.DEVNULL, start_new_session=True)
    spent = dict.fromkeys((p[0] for p in PARTS), 0)
    got = {}
    run = simulator.Simulator.run

    def measured(node):
        """The node's run, its timers zeroed at t = 0 (after the wait for the controller)."""
        real = simulator.Simulator._mark_t0

        def mark(self):
            real(self)
            spent.update(dict.fromkeys(spent, 0))
            got['t0'] = time.thread_time_ns()
        simulator.Simulator._mark_t0 = mark
        run(node)
        got['thread'] = time.thread_time_ns() - got['t0']
        got['exchanges'] = node._round_trips.count
    try:
        _timed(spent)
        code = run_node(simulator.NODE_NAME, simulator.Simulator, run=measured, args=args,
                        lockstep=True)
    finally:
        stop(ctl)
        os.unlink(over)
    n = got.get('exchanges', 0)
    if code != 0 or n < 2:
        raise RuntimeError(f'the simulator exited {code} after {n} exchanges')
    return {'exchanges': n, 'thread_us': got['thread'] / n / 1e3,
            'parts_us': {k: round(v / n / 1e3, 1) for k, v in spent.items()}}


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--periods', type=int, default=3000, help='exchanges per run')
    parser.add_argument('--rate', type=float, default=100.0, help='control rate [Hz]')
    parser.add_argument('--runs', type=int, default=3, help='runs, each its own process')
    parser.add_argument('--one', action='store_true', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.one:  # one run, in this process (the runs below start these)
        print(json.dumps(_measure(args.periods, args.rate)))
        return 0
    # the Python way's exchange: the compiled one (nodes/sim_rcl.py) runs none of the
    # parts timed here, each a Python method
    env = dict(os.environ, PYTHONUNBUFFERED='1', RIGID_BODY_SIM_RCL_LOOP='0',
               ROS_DOMAIN_ID=os.environ.get('ROS_DOMAIN_ID', str(random.randint(101, 200))))
    load, runs = [os.getloadavg()[0]], []
    for _ in range(args.runs):
        out = subprocess.run([sys.executable, '-m', __spec__.name, '--one', '--periods',
                              str(args.periods), '--rate', str(args.rate)], env=env,
                             capture_output=True, text=True, timeout=600)
        if out.returncode != 0:
            raise RuntimeError(f'a run exited {out.returncode}:\n' + out.stderr[-2000:])
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    load.append(os.getloadavg()[0])

    def spread(values):
        return (f'{statistics.median(values):.1f} ({min(values):.1f}-{max(values):.1f})'
                if len(values) > 1 else f'{values[0]:.1f}')
    print(f'simulator thread per exchange ({args.rate:g} Hz, {runs[0]["exchanges"]} exchanges '
          f'a run, {len(runs)} runs, load {load[0]:.1f}-{load[1]:.1f}): '
          f'{spread([r["thread_us"] for r in runs])} µs')
    for label, *_ in PARTS:
        print(f'  {label:14s} {spread([r["parts_us"][label] for r in runs])} µs')
    # the loop's own: what neither run_once nor the wait spent
    print(f'  {"loop":14s} ' + spread([r['thread_us'] - r['parts_us']['run_once'] -
                                       r['parts_us']['wait'] for r in runs]) + ' µs')
    return 0


if __name__ == '__main__':
    sys.exit(main())
