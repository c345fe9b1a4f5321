"""Compile cost of the numba kernels: cold (empty cache), warm (from the on-disk cache).

Each measurement is a fresh interpreter with its own NUMBA_CACHE_DIR, so it counts what
a user's first run (cold) and every later run (warm) pay before the first step. Run cost
is measured elsewhere (work-precision); the two are never mixed. The warm start is measured
in three fresh interpreters and the fastest is kept, as timeit does: on a shared machine the
slower ones measure the other processes; the slowest is reported beside it, with the CPU.

    python -m rigid_body_sim.bench.compile [--update docs/bench]
"""
import json
import math
import os
import subprocess
import sys
import tempfile

FIELDS = ('phase', 'numba_import_s', 'kernels_s', 'total_s', 'cpu_s', 'slowest_total_s', 'load')
WARM_REPEATS = 3

_PROBE = r'''
import json, resource, time
t0 = time.perf_counter()
import numba  # noqa: F401
t1 = time.perf_counter()
import rigid_body_sim.compiled as compiled
compiled.warm()
t2 = time.perf_counter()
ru = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"numba_import_s": t1 - t0, "kernels_s": t2 - t1, "total_s": t2 - t0,
                  "cpu_s": ru.ru_utime + ru.ru_stime}))
'''


def _probe(cache_dir):
    env = {'NUMBA_CACHE_DIR': cache_dir}
    out = subprocess.run([sys.executable, '-c', _PROBE], env={**os.environ, **env},
                         capture_output=True, text=True, timeout=900)
    if out.returncode != 0:
        raise RuntimeError(out.stderr[-2000:])
    return json.loads(out.stdout)


def run(quick, log=print):
    """[cold, warm] rows; in --quick, not measured (a cold compile takes ~10–30 s)."""
    if quick:
        log('  compile cost: not measured in --quick (cold compile takes 10–30 s)')
        return []
    rows = []
    with tempfile.TemporaryDirectory(prefix='rbs_numba_cache_') as cache:
        for phase, repeats in (('cold', 1), ('warm', WARM_REPEATS)):
            probes = sorted((_probe(cache) for _ in range(repeats)), key=lambda p: p['total_s'])
            r = {'phase': phase, **probes[0], 'slowest_total_s': probes[-1]['total_s'],
                 'load': os.getloadavg()[0]}
            rows.append(r)
            log(f'  {phase:4s}: numba import {r["numba_import_s"]:.2f} s, kernels '
                f'{r["kernels_s"]:.2f} s, total {r["total_s"]:.2f} s wall '
                f'(slowest of {repeats}: {r["slowest_total_s"]:.2f} s), {r["cpu_s"]:.2f} s CPU')
    return rows


WARM_TARGET_S = 2.0


def targets(rows):
    """The warm-start target row from ``run``'s rows (none measured in --quick).

    Judged on the CPU seconds of the fastest warm start: loading cached kernels waits on
    no I/O (no major faults, a handful of voluntary switches), so on an idle core its wall
    time is its CPU time, while on a shared machine the wall time measures the load. The
    wall time and the load are in the note."""
    from . import targets as targets_mod
    name = 'kernels ready from the cache (warm start, CPU s)'
    warm = [r for r in rows if r['phase'] == 'warm']
    if not warm:
        return [targets_mod.simple(name, math.nan, WARM_TARGET_S, None,
                                   'not measured in --quick')]
    w = warm[0]
    cpu = float(w['cpu_s'])
    return [targets_mod.simple(
        name, cpu, WARM_TARGET_S, cpu <= WARM_TARGET_S,
        f'fastest of {WARM_REPEATS} fresh interpreters: wall {float(w["total_s"]):.2f} s '
        f'(slowest {float(w["slowest_total_s"]):.2f} s) at load {float(w["load"]):.1f}; '
        f'cold compile {float(rows[0]["total_s"]):.1f} s wall')]


def update(folder, log=print):
    """Re-run this section into a full run's ``folder`` (:func:`.common.replace_section`)."""
    from .common import replace_section
    rows = run(False, log)
    return replace_section(folder, 'compile.csv', FIELDS, rows, targets(rows),
                           ('kernels ready from the cache',))


if __name__ == '__main__':
    from .common import section_main
    section_main(__doc__, run, update, quick=False)
