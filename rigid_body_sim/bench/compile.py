"""Compile cost of the numba kernels: cold (empty cache), warm (from the on-disk cache).

Each measurement is a fresh interpreter with its own NUMBA_CACHE_DIR, so it counts what
a user's first run (cold) and every later run (warm) pay before the first step. Run cost
is measured elsewhere (work-precision); the two are never mixed.
"""
import json
import subprocess
import sys
import tempfile

FIELDS = ('phase', 'numba_import_s', 'kernels_s', 'total_s')

_PROBE = r'''
import json, time
t0 = time.perf_counter()
import numba  # noqa: F401
t1 = time.perf_counter()
import rigid_body_sim.compiled as compiled
compiled.warm()
t2 = time.perf_counter()
print(json.dumps({"numba_import_s": t1 - t0, "kernels_s": t2 - t1, "total_s": t2 - t0}))
'''


def _probe(cache_dir):
    env = {'NUMBA_CACHE_DIR': cache_dir}
    import os
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
        for phase in ('cold', 'warm'):
            r = {'phase': phase, **_probe(cache)}
            rows.append(r)
            log(f'  {phase:4s}: numba import {r["numba_import_s"]:.2f} s, kernels '
                f'{r["kernels_s"]:.2f} s, total {r["total_s"]:.2f} s (wall)')
    return rows
