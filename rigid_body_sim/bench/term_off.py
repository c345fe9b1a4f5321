"""A term that is off costs nothing: the free body's runs against the same scenes with an
orbit and no environment term, in one run (issue 30).

    python -m rigid_body_sim.bench.term_off [--quick] [--out DIR]

Two checks, since the cost of the free body before the orbit existed cannot be measured in
the same run as after it:

* **CPU** (``term_off.csv``): built-in scenes run offline (nothing kept) as they are and
  with ``orbit.model: kepler`` but no term on, alternately, ``REPEATS`` times each; the
  target row is the least CPU with the orbit over the least without it (the least
  disturbed run of each), its note the spread of the pairwise ratios (p10, median, p90)
  and the worst pair. A scene with an orbit and no term builds no element array (the
  dynamics' ``environment`` is None), so its loops are the free body's own.
* **Code**: each one-body loop that takes the environment (``env``) is compiled afresh
  for env None and for an element array, and its LLVM IR searched for the term's
  functions (TERM_SYMBOLS): the None specialisation must name none of them, the array one
  must (else the search proves nothing). ``dop853``'s loop (its dense output) is not
  searched here; the CPU rows cover the methods the scenes run. The section keeps the
  search's answer beside the kernels' cache for the sources it read (``compiled.
  sources_digest``): compiling ten loop versions afresh costs ~8 CPU-s, and the answer
  only changes with the sources or numba (test_term_off.py searches afresh each time).
"""
import json
import math
import os

import numpy as np

from .common import write_csv

FIELDS = ('scene', 'integrator', 'duration', 'pair', 'free_cpu_s', 'orbit_cpu_s', 'ratio',
          'steps')
# (scene, integrator, duration s full, quick): the dissipative splitting, a fixed RK4 on a
# free tumble, and the closed-form free body (auto: exact) at 100 samples/s
SCENES = (('explorer1', 'splitting2', 200.0, 20.0), ('tennis_racket', 'rk4', 100.0, 10.0),
          ('tennis_racket', None, 1000.0, 100.0))
ORBIT = ('orbit.model=kepler',)
REPEATS = {True: 3, False: 7}
REQUIRED = 1.05  # "costs nothing": within the timing's resolution
TARGET_CPU = 'a term that is off costs nothing: CPU with an orbit, no term / free body'
TARGET_CODE = 'free-body loops compiled with the term (numba IR of env None)'
TERM_SYMBOLS = ('gravity_gradient', 'eccentric_anomaly', 'radial_in_body', '_environment')


def _run(name, integrator, duration, overrides=()):
    from ..offline import simulate
    from ..scene import load
    result = simulate(load(name, overrides), duration=duration, integrator=integrator,
                      keep='none')
    return result.cpu_seconds, result.steps


def measure_cpu(quick, log=print):
    """Rows (one per pair of runs) and {scene label: (least orbit / least free, ratios)}."""
    rows, figures = [], {}
    for name, integrator, full, short in SCENES:
        duration = short if quick else full
        label = f'{name} ({integrator or "auto"})'
        _run(name, integrator, duration / 10, ORBIT)  # kernels loaded, caches warm
        free, orbit, ratios = [], [], []
        for k in range(REPEATS[quick]):
            order = ((), ORBIT) if k % 2 == 0 else (ORBIT, ())  # alternate who runs first
            got = {o: _run(name, integrator, duration, o) for o in order}
            (f_cpu, steps), (o_cpu, _) = got[()], got[ORBIT]
            free.append(f_cpu)
            orbit.append(o_cpu)
            ratios.append(o_cpu / f_cpu)
            rows.append({'scene': label, 'integrator': integrator or 'auto',
                         'duration': duration, 'pair': k, 'free_cpu_s': f_cpu,
                         'orbit_cpu_s': o_cpu, 'ratio': o_cpu / f_cpu, 'steps': steps})
        figures[label] = (min(orbit) / min(free), ratios)
        log(f'  {label}: least {min(free):.4g} s free, {min(orbit):.4g} s with an orbit '
            f'(ratio {figures[label][0]:.3f}); pairs {_spread(ratios)}')
    return rows, figures


def _spread(ratios):
    r = np.asarray(ratios, float)
    return (f'p10 {np.percentile(r, 10):.3f}, median {np.median(r):.3f}, p90 '
            f'{np.percentile(r, 90):.3f}, worst {np.max(r):.3f} (n = {len(r)})')


def _loops():
    """(name, function, arguments before env) of each one-body loop taking ``env``."""
    from ..physics.integrators import explicit_kernel, splitting_kernel
    q, m = np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.1, 0.2, 0.3])
    moments, tau = np.array([1.0, 2.0, 3.0]), np.zeros(3)
    weights, axes = np.ones(1), np.array([0, 2, 1])
    scratch = np.empty((10, 4))
    rk = (q, m, 0.01, 3, moments, tau, 0, 0.0)
    return (('splitting_run', splitting_kernel.splitting_run,
             (q, m, 0.01, 3, weights, axes, moments, tau, False, 0, 0.0, False, 0.0)),
            ('rk4_run', explicit_kernel.rk4_run, rk + (0.0,)),
            ('rk4_steps', explicit_kernel.rk4_steps, rk + (scratch, 0.0)),
            ('euler_run', explicit_kernel.euler_run, rk + (0.0,)),
            ('euler_steps', explicit_kernel.euler_steps, rk + (scratch, 0.0)))


def inspect_code(loops=None):
    """{loop: (symbols named with env None, symbols named with the term's array)}, or None
    where the loops are not compiled (NUMBA_DISABLE_JIT). ``loops``: (name, jitted
    function, arguments before env), default the engine's (``_loops``)."""
    from ..physics import jit
    if not jit.COMPILED:
        return None
    import numba
    from ..physics.orbit import KeplerOrbit, kernel as orbit_kernel
    elements = KeplerOrbit(7.0e6, 0.1, 0.9, 0.0, 0.0, 0.0).elements(0.0)
    elements[orbit_kernel.ON] = 1.0
    found = {}
    for name, loop, args in loops or _loops():
        options = {k: v for k, v in loop.targetoptions.items() if k != 'nopython'}
        fresh = numba.njit(loop.py_func, **options)  # compiled afresh, not from the disk cache
        for env in (None, elements):
            fresh(*[a.copy() if isinstance(a, np.ndarray) else a for a in args], env)
        named = []
        for signature, ir in fresh.inspect_llvm().items():
            named.append(tuple(s for s in TERM_SYMBOLS if s in ir))
            if str(signature[-1]) == 'none':
                named.insert(0, named.pop())
        found[name] = (named[0], named[1])
    return found


def inspect_code_kept():
    """:func:`inspect_code` of the engine's loops, from the answer kept for these sources
    and this numba when there is one (written here otherwise)."""
    from .. import compiled
    from ..physics import jit
    from ..physics.auto import calibration
    if not jit.COMPILED:
        return None
    path = os.path.join(calibration.cache_dir(), 'term_off_code.json')
    digest = compiled.sources_digest()
    try:
        with open(path, encoding='utf-8') as f:
            kept = json.load(f)
        if kept['sources'] == digest:
            return {name: (tuple(off), tuple(on)) for name, (off, on) in kept['found'].items()}
    except (OSError, ValueError, KeyError, TypeError):
        pass
    found = inspect_code()
    try:
        with open(path, 'w', encoding='utf-8') as f:
            json.dump({'sources': digest, 'found': found}, f)
    except OSError:
        pass  # a read-only install: searched again next time
    return found


def run(quick, log=print):
    """(rows, target rows)."""
    from . import targets
    from .. import compiled
    compiled.setup()
    rows, figures = measure_cpu(quick, log)
    t_rows = []
    for label, (ratio, ratios) in figures.items():
        t_rows.append(targets.simple(TARGET_CPU, ratio, REQUIRED, ratio <= REQUIRED,
                                     f'least of {len(ratios)} runs each; pairs '
                                     f'{_spread(ratios)}', scene=label))
    code = inspect_code_kept()
    if code is None:
        t_rows.append(targets.simple(TARGET_CODE, math.nan, 0, None,
                                     'kernels not compiled (NUMBA_DISABLE_JIT)'))
    else:
        leaks = [n for n, (off, _) in code.items() if off]
        blind = [n for n, (_, on) in code.items() if not on]
        for n, (off, on) in code.items():
            log(f'  {n}: env None names {list(off) or "none of the term"}; with the term '
                f'{list(on)}')
        t_rows.append(targets.simple(
            TARGET_CODE, float(len(leaks)), 0, not leaks and not blind,
            f'{len(code)} loops searched ({", ".join(code)}) for {", ".join(TERM_SYMBOLS)}'
            + (f'; named with env None: {", ".join(leaks)}' if leaks else '')
            + (f'; the search found nothing in the term\'s own specialisation of '
               f'{", ".join(blind)}' if blind else '')))
    return rows, t_rows


def main(argv=None):
    """Run this section alone; term_off.csv into DIR and its rows into DIR's targets."""
    import argparse
    from . import report
    parser = argparse.ArgumentParser(prog='python -m rigid_body_sim.bench.term_off',
                                     description=__doc__.split('\n\n')[0])
    parser.add_argument('--quick', action='store_true', help='shorter runs, fewer pairs')
    parser.add_argument('--out', default='out/bench', metavar='DIR',
                        help='output directory (default out/bench)')
    args = parser.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    rows, t_rows = run(args.quick)
    write_csv(os.path.join(args.out, 'term_off.csv'), FIELDS, rows)
    for r in t_rows:
        print(f'{r["verdict"]:5s} {r["target"]} {r["scene"]}: {r["measured"]:.4g} '
              f'(required {r["required"]:g}) {r["note"]}')
    report.replace_targets(args.out, (TARGET_CPU, TARGET_CODE), t_rows,
                           command='python -m rigid_body_sim.bench.term_off --out {out}',
                           after='offline run')
    print(report.write(args.out))
    return 0


if __name__ == '__main__':
    import sys
    sys.exit(main())
