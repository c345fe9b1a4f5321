"""Cost of evaluating the torque-free solution: compiled kernel against the numpy path.

Both are measured side by side in one run (ratios, not absolute times, are what carry
between machines)::

    python -m rigid_body_sim.tools.exact_eval [--quick]

Per regime (elliptic A, separatrix, symmetric, steady spin): µs for one body at one time
(``at(t)``, what the engine's events call) and per time for 1e5 times (``at(ts)``, the
engine's runs of samples), for ``at`` (exact_kernel) and ``at_numpy``, and the
construction of a TorqueFreeSolution. Best of five repetitions each.
"""
import time

import numpy as np

BODIES = (('A', (1.0, 2.0, 3.0), (0.3, 0.5, 0.9)),
          ('separatrix', (2.0, 3.0, 6.0), (1.0, 0.5, 1.0)),
          ('symmetric', (2.0, 2.0, 3.0), (0.3, 0.4, 1.0)),
          ('steady_spin', (1.0, 2.0, 3.0), (0.0, 0.0, 2.0)))
FIELDS = ('regime', 'one_compiled_us', 'one_numpy_us', 'many_compiled_us', 'many_numpy_us',
          'construction_us')


def _best(f, n, repeats=5):
    """Best per-call wall time (µs) of n calls, over ``repeats`` batches."""
    best = float('inf')
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(n):
            f()
        best = min(best, (time.perf_counter() - t0) / n)
    return best * 1e6


def run(quick=False, log=print):
    from ..physics.exact import TorqueFreeSolution
    n_times = 10_000 if quick else 100_000
    q0 = np.array([0.1, 0.2, 0.3, 0.9]) / np.linalg.norm([0.1, 0.2, 0.3, 0.9])
    ts = np.linspace(0.0, 1e4, n_times)
    rows = []
    for regime, moments, m0 in BODIES:
        sol = TorqueFreeSolution(moments, q0, m0)
        sol.at(1.0), sol.at(ts[:10]), sol.at_numpy(ts[:10])          # compile / load, anchor
        row = {'regime': regime,
               'one_compiled_us': _best(lambda: sol.at(12.345), 2000),
               'one_numpy_us': _best(lambda: sol.at_numpy(12.345), 200),
               'many_compiled_us': _best(lambda: sol.at(ts), 1) / n_times,
               'many_numpy_us': _best(lambda: sol.at_numpy(ts), 1) / n_times,
               'construction_us': _best(lambda: TorqueFreeSolution(moments, q0, m0), 100)}
        rows.append(row)
        one, one_np = row['one_compiled_us'], row['one_numpy_us']
        many, many_np = row['many_compiled_us'], row['many_numpy_us']
        log(f'  {regime:11s} one time: {one:6.2f} µs compiled, {one_np:6.1f} µs numpy '
            f'({one_np / one:.0f}×); {n_times:g} times: {many:.3f} vs {many_np:.3f} µs each '
            f'({many_np / many:.1f}×); construction {row["construction_us"]:.0f} µs')
    return rows


if __name__ == '__main__':
    from . import argument_parser
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--quick', action='store_true', help='fewer repetitions')
    run(quick=parser.parse_args().quick)
