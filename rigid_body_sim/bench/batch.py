"""Batch throughput: body-steps per CPU second for N bodies advanced together, one core.

Per N, three paths with h = 0.01 s on random tumbling bodies:
* splitting2 ``run``: the compiled batch loop (physics.integrators.splitting_batch_kernel),
  n steps per call — how a caller advances a batch between samples. Warmed first: compile cost is
  bench/compile.py's, never mixed into run cost.
* splitting2 ``step``: one call per step, the numpy batch path (for N = 1 the single-body
  kernel) — the path the compiled loop replaced, measured in the same run.
* exact ``step``: the closed-form flow, vectorised in numpy.
CPU time is time.process_time (robust to other load on the machine).
"""
import numpy as np

from ..physics import Dynamics, create
from .common import cpu

FIELDS = ('method', 'path', 'bodies', 'steps', 'cpu_s', 'body_steps_per_s')
H = 0.01
MAX_CALLS = 100_000


def steps_per_call(bodies):
    """Steps per ``run`` call: 100, or 10 at N = 1e6 (a call then takes ~0.5 s)."""
    return 100 if bodies <= 10_000 else 10


def _measure(advance, q, m, target):
    """Repeat ``advance`` (returns q, m, steps) for ``target`` CPU seconds: (steps, CPU s)."""
    steps, spent = 0, 0.0
    for _ in range(MAX_CALLS):
        c = cpu()
        q, m, done = advance(q, m)
        spent += cpu() - c
        steps += done
        if spent >= target:
            break
    return steps, spent


def run(quick, log=print):
    sizes = (1, 100, 10_000) if quick else (1, 100, 10_000, 1_000_000)
    target = 0.1 if quick else 1.0
    dyn = Dynamics(np.array([1.0, 2.0, 3.0]))
    rng = np.random.default_rng(1)
    rows = []
    for name, path in (('splitting2', 'run'), ('splitting2', 'step'), ('exact', 'step')):
        for n in sizes:
            m = rng.normal(size=(n, 3)) if n > 1 else rng.normal(size=3)
            q = rng.normal(size=(n, 4)) if n > 1 else rng.normal(size=4)
            q /= np.linalg.norm(q, axis=-1, keepdims=True)
            integ = create(name, dyn)
            if path == 'run':
                k = steps_per_call(n)
                integ.run(q, m, H, 1)  # warm-up: loads the compiled loop

                def advance(q, m, integ=integ, k=k):
                    return integ.run(q, m, H, k) + (k,)
            else:
                integ.step(q, m, H)  # warm-up (and anchor for exact)

                def advance(q, m, integ=integ):
                    return integ.step(q, m, H) + (1,)
            steps, spent = _measure(advance, q, m, target)
            rate = n * steps / spent
            rows.append({'method': name, 'path': path, 'bodies': n, 'steps': steps,
                         'cpu_s': spent, 'body_steps_per_s': rate})
            log(f'  batch {name} {path} N={n}: {rate:.3g} body-steps/s '
                f'({steps} steps, {spent:.2f} s CPU)')
    return rows
