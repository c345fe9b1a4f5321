"""Timing, error metrics and references shared by the benchmark sections."""
import contextlib
import csv
import json
import math
import os
import signal
import time

import numpy as np

# the engine and the control law are imported where an engine is built (engine_for):
# the tools that import this module for report() and best_of() (lockstep, fleet, flood,
# recovery, ...) then answer --help and run their nodes without loading numba (0.35 CPU-s)
from ..physics import rotation
from ..physics.body import RigidBody

REF_RTOL = 1e-13
# generated scenes in the generalisation section (--quick, full): generated.COUNTS, here so
# that the suite's --help states them without importing the section (and numba)
GENERATED_COUNTS = {True: 20, False: 200}
EPS = np.finfo(float).eps


def report(result, out=None, name=None):
    """Print ``result`` as one JSON line (what scripts and the README quote) and, with
    ``out``, also write it to ``out/name`` (e.g. docs/bench/flood.json)."""
    print(json.dumps(result))
    if out:
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, name), 'w') as f:
            json.dump(result, f, indent=1)


def cpu():
    """Process CPU time (s): robust to other load on the machine, counts Python overhead."""
    return time.process_time()


class CpuCapReached(Exception):
    """A run stopped by :func:`cpu_limit`: the CPU it had spent bounds its cost below."""


@contextlib.contextmanager
def cpu_limit(seconds: float):
    """Raise :class:`CpuCapReached` in this (the main) thread once the process has spent
    ``seconds`` more CPU, user + system as :func:`cpu` counts it. A cap that is only
    checked between runs does not hold: one run of a Python-loop peer (scipy's solve_ivp)
    may take minutes. The interrupt lands between two bytecodes: inside solve_ivp's loop,
    in MuJoCo's Python callback or after its C call returns.

    A thread watches the clock, not a process CPU timer (ITIMER_PROF, as before): while
    one is armed, and for a tick after, Linux reads the process clock from the group's
    tick-updated sum, so :func:`cpu` moved in ticks of ~1-4 ms. A 1 ms run timed then read
    0 s (the suite's bench once divided by it) and every run timed near a cap was off by
    up to a tick. The watcher sleeps for the CPU still allowed (one thread cannot spend it
    faster), at most 0.1 s, so it wakes a few times per capped run."""
    import _thread
    import threading
    if not seconds > 0.0:
        raise CpuCapReached(f'no CPU left ({seconds:.3g} s)')
    armed = [True]

    def expire(_signum, _frame):
        if armed[0]:
            armed[0] = False
            raise CpuCapReached(f'past its cap of {seconds:.3g} CPU s')

    limit = cpu() + seconds
    done = threading.Event()

    def watch():
        while not done.wait(min(max(limit - cpu(), 1e-3), 0.1)):
            if cpu() >= limit:
                _thread.interrupt_main(signal.SIGPROF)  # runs expire() in the main thread
                return

    previous = signal.signal(signal.SIGPROF, expire)
    watcher = threading.Thread(target=watch, name='cpu_limit', daemon=True)
    watcher.start()
    try:
        yield
    finally:
        try:
            armed[0] = False  # a later interrupt is ignored: the body has ended
        finally:  # restored even if the interrupt lands on the line above
            done.set()
            watcher.join()
            signal.signal(signal.SIGPROF, previous)


def best_of(run, repeats=5) -> float:
    """The least CPU time (s) of ``repeats`` calls of ``run()``: the run least disturbed by
    the rest of the machine."""
    best = math.inf
    for _ in range(repeats):
        t0 = cpu()
        run()
        best = min(best, cpu() - t0)
    return best


def invariants(moments, m):
    m = np.asarray(m, float)
    return 0.5 * float(np.sum(m * m / moments)), float(np.linalg.norm(m))


def metrics(scene, q, m, q_ref, m_ref):
    """Attitude error (rad), ω error (rad/s), relative T and |L| error against the reference."""
    moments = np.asarray(scene.moments, float)
    t, g = invariants(moments, m)
    t_ref, g_ref = invariants(moments, m_ref)
    return {'attitude_error': float(rotation.angle_between(np.asarray(q, float), q_ref)),
            'omega_error': float(np.linalg.norm((np.asarray(m) - m_ref) / moments)),
            'energy_drift': abs(t - t_ref) / t_ref,
            'momentum_drift': abs(g - g_ref) / g_ref}


def engine_for(scene, method, h=None, **options):
    """The simulation engine on a bench scene: one sample at the end, fixed steps h (or,
    h None, one adaptive call per interval between events: the whole horizon, or each
    control period for controlled scenes), their law as the in-process control source."""
    from ..control import ControlConfig
    from ..engine import NS, ControlSettings, Engine, EngineConfig
    ns = int(round(scene.t_end * NS))
    control = None
    if scene.control is not None:
        s = scene.control
        law = ControlConfig(inertia=scene.moments, natural_frequency=s.natural_frequency,
                            damping_ratio=s.damping_ratio, gyroscopic_compensation=False)
        control = ControlSettings(law, s.mode, np.asarray(s.target, float) /
                                  np.linalg.norm(s.target), int(round(s.period * NS)))
    step = h if h is not None else (scene.control.period if scene.control else scene.t_end)
    config = EngineConfig(RigidBody.from_inertia(scene.moments), scene.dissipation,
                          scene.q0_array, np.asarray(scene.omega0, float), integrator=method,
                          step=step, sample_period_ns=ns, duration_ns=ns, max_torque=np.inf,
                          control=control, integrator_options=options)
    return Engine(config)


def propagate(scene, method, h=None, **options):
    """(q, m, engine): the principal-frame state at the scene's end (see engine_for)."""
    engine = engine_for(scene, method, h, **options)
    for _ in engine.run():
        pass
    q, m = engine.principal_state
    return q, m, engine


def timed_engine(make, repeat_below=0.05, repeats=3):
    """(min CPU seconds of the run, (q, m, engine) of the last run): ``make()`` builds a
    fresh engine outside the timed region (as MuJoCo's model is built outside its timer);
    only ``engine.run()`` is timed. Short runs are repeated, the minimum kept."""
    best, engine = np.inf, None
    for i in range(repeats):
        engine = make()
        t0 = cpu()
        for _ in engine.run():
            pass
        best = min(best, cpu() - t0)
        if best > repeat_below:
            break
    q, m = engine.principal_state
    return best, (q, m, engine)


def timed(run, repeat_below=0.05, repeats=3):
    """(min CPU seconds, result of the last run); short runs are repeated, the minimum kept."""
    best, out = np.inf, None
    for i in range(repeats):
        t0 = cpu()
        out = run()
        best = min(best, cpu() - t0)
        if best > repeat_below:
            break
    return best, out


def reference(scene):
    """(q_ref, m_ref, label, own-error estimate in rad).

    Torque-free: the exact solution (its error is cross-checked against dop853 at rtol
    1e-13). Otherwise dop853 at rtol 1e-13; its own error is estimated by the distance to
    the rtol 1e-12 solution (an upper estimate: that is the error of the looser run).
    """
    dyn = scene.dynamics
    fine = propagate(scene, 'dop853', rtol=REF_RTOL, atol=REF_RTOL * 1e-2)
    if scene.torque_free:
        from ..physics.exact import TorqueFreeSolution
        q, m = TorqueFreeSolution(dyn.moments, scene.q0_array, scene.m0).at(scene.t_end)
        check = float(rotation.angle_between(fine[0], q))
        return q, m, 'exact', check
    looser = propagate(scene, 'dop853', rtol=10 * REF_RTOL, atol=REF_RTOL * 1e-1)
    return fine[0], fine[1], 'dop853 rtol 1e-13', float(rotation.angle_between(fine[0], looser[0]))


# (IntegrationError, once re-exported here, is imported from physics by every section)
__all__ = ['cpu', 'metrics', 'propagate', 'engine_for', 'timed', 'timed_engine', 'reference',
           'invariants', 'EPS']


def write_csv(path, fields, rows):
    """Rows (dicts) as CSV with ``fields`` as columns; floats to 6 significant digits."""
    with open(path, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction='ignore')
        w.writeheader()
        for r in rows:
            w.writerow({k: (f'{v:.6g}' if isinstance(v, float) else v) for k, v in r.items()})


def replace_section(folder, name, fields, rows, t_rows, prefixes):
    """Put one section's re-run into a full run's ``folder``: its CSV ``name``, and its
    target rows (those whose target starts with one of ``prefixes``) of targets.csv and
    targets.md replaced where they stood, each note saying when and on what it was
    measured; the other sections' rows stay the full run's, and summary.md is rendered
    from the files again (``report``). Returns the summary's path."""
    from . import report, targets as targets_mod
    from .suite import _markdown_targets, machine
    stamp = f'this section re-run alone {time.strftime("%Y-%m-%d")} on {machine()}'
    t_rows = [dict(r, note=f'{r["note"]}; {stamp}' if r['note'] else stamp) for r in t_rows]
    write_csv(os.path.join(folder, name), fields, rows)

    def mine(target):
        return target.startswith(tuple(prefixes))
    path = os.path.join(folder, 'targets.csv')
    with open(path, newline='', encoding='utf-8') as f:
        old = list(csv.DictReader(f))
    at = next(i for i, r in enumerate(old) if mine(r['target']))
    kept = [r for r in old if not mine(r['target'])]
    write_csv(path, targets_mod.FIELDS, kept[:at] + t_rows + kept[at:])
    path = os.path.join(folder, 'targets.md')
    with open(path, encoding='utf-8') as f:
        lines = f.read().splitlines()
    ours = [i for i, line in enumerate(lines) if mine(line[2:])]
    if ours != list(range(ours[0], ours[-1] + 1)):
        raise ValueError(f'{path}: the section\'s rows are not one block')
    table = _markdown_targets(t_rows, '', '').splitlines()[6:]  # its rows, not the header
    with open(path, 'w', encoding='utf-8') as f:
        f.write('\n'.join(lines[:ours[0]] + table + lines[ours[-1] + 1:]) + '\n')
    return report.write(folder)


def section_main(doc, printed, update, quick=True):
    """A section run alone (``python -m rigid_body_sim.bench.<section>``): with ``--update
    DIR`` re-run into a full run's DIR (``update``, which returns the summary's path), else
    each of ``printed(quick)``'s rows as a JSON line."""
    import argparse
    import json
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    if quick:
        parser.add_argument('--quick', action='store_true')
    parser.add_argument('--update', metavar='DIR', default='',
                        help="re-run the section into a full run's DIR (e.g. docs/bench): "
                             'its CSV, its rows of targets.csv/targets.md, the summary')
    args = parser.parse_args()
    if args.update:
        print(update(args.update))
        return
    for r in printed(getattr(args, 'quick', False)):
        print(json.dumps(r))
