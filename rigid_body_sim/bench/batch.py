"""Batch throughput: body-steps per CPU second for N bodies stepped together (vectorised)."""
import numpy as np

from ..physics import Dynamics, create
from .common import cpu

FIELDS = ('method', 'bodies', 'steps', 'cpu_s', 'body_steps_per_s')


def run(quick, log=print):
    sizes = (1, 100, 10_000) if quick else (1, 100, 10_000, 1_000_000)
    dyn = Dynamics(np.array([1.0, 2.0, 3.0]))
    rng = np.random.default_rng(1)
    rows = []
    for name in ('splitting2', 'exact'):
        for n in sizes:
            m = rng.normal(size=(n, 3)) if n > 1 else rng.normal(size=3)
            q = rng.normal(size=(n, 4)) if n > 1 else rng.normal(size=4)
            q /= np.linalg.norm(q, axis=-1, keepdims=True)
            integ = create(name, dyn)
            integ.step(q, m, 0.01)  # warm-up (and anchor for exact)
            target = 0.1 if quick else 1.0
            steps, spent = 0, 0.0
            best = np.inf
            while spent < target and steps < 100_000:
                c = cpu()
                q, m = integ.step(q, m, 0.01)
                dt = cpu() - c
                spent += dt
                steps += 1
                best = min(best, dt)
            rate = n * steps / spent
            rows.append({'method': name, 'bodies': n, 'steps': steps, 'cpu_s': spent,
                         'body_steps_per_s': rate})
            log(f'  batch {name} N={n}: {rate:.3g} body-steps/s '
                f'({steps} steps, {spent:.2f} s CPU)')
    return rows
