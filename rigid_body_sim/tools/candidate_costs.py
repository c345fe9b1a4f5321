"""Per-step costs in ``auto``'s model against the compiled loops, measured here.

The table is ``physics.auto.model.CANDIDATES``; the loops run free and with weak
double-bracket damping.

``python -m rigid_body_sim.tools.candidate_costs``

Only the ratios between methods steer ``auto``, so the table is checked by its ratios to
``splitting2`` torque-free: a row whose measured ratio is off the table's by more than 1.5×
is flagged (recalibrate the table from the measured µs). Explorer 1's body and state at
h = 0.01 s (hΩ = 0.63): the damping is weak, inside the compositions, one substep
outside them. ``auto`` itself uses the costs calibrated on the machine where a calibration
is current (``physics.auto.calibration``, written by ``python -m rigid_body_sim.compiled``),
these constants otherwise; the last line says which.
"""
from . import argument_parser
import json
import sys

import numpy as np

from ..bench.common import best_of

# physics and auto's model are imported where they are used: they load numba, which
# --help does not need (0.35 CPU-s)

MOMENTS = (0.04, 0.2, 0.2)   # Explorer 1, kg·m²
M0 = np.array([2.5132741228718345, 0.04386936299713697, 0.0])  # its initial momentum
Q0 = np.array([0.0, 0.0, 0.0, 1.0])
ALPHA = 1.0678e-05            # s/(kg·m²), Explorer 1: weak at this step
STEP, STEPS = 0.01, 200_000


def table_cost(candidate, damped):
    """µs per step the model assumes (splitting2 with damping: its substeps, one here)."""
    from ..physics.auto.model import DAMP_SUBSTEP
    if damped and candidate.name == 'splitting2':
        return candidate.cost[0] + 2 * DAMP_SUBSTEP
    return candidate.cost[1 if damped else 0]


def run(steps=STEPS, log=print):
    from ..physics import Dissipation, Dynamics, create
    from ..physics.auto.calibration import ADAPTIVE_EVALS, REPEATS
    from ..physics.auto.model import CANDIDATES
    rows = []
    for damped in (False, True):
        dyn = Dynamics(np.array(MOMENTS), Dissipation('double_bracket', ALPHA) if damped
                       else Dissipation())
        for c in CANDIDATES:
            if c.name == 'exact':
                continue  # its cost is 5× higher on a triaxial body: calibration.EXACT_MOMENTS
            integ = create(c.name, dyn)
            integ.run(Q0, M0, STEP, 10)  # compiled (or loaded) before timing
            nfev = integ.nfev
            cpu = best_of(lambda: integ.run(Q0, M0, STEP, steps), REPEATS)
            # an adaptive method's cost is per its own step (``calibration.measure``)
            taken = max(1.0, (integ.nfev - nfev) / (REPEATS * ADAPTIVE_EVALS)) if c.adaptive \
                else steps
            rows.append({'method': c.name, 'damped': damped, 'measured_us': 1e6 * cpu / taken,
                         'table_us': table_cost(c, damped)})
    base = next(r for r in rows if r['method'] == 'splitting2' and not r['damped'])
    for r in rows:
        r['measured_ratio'] = r['measured_us'] / base['measured_us']
        r['table_ratio'] = r['table_us'] / base['table_us']
        off = r['table_ratio'] / r['measured_ratio']
        r['ok'] = 1 / 1.5 <= off <= 1.5
        log(f'{r["method"]:20s} {"damped" if r["damped"] else "free":6s} measured '
            f'{r["measured_us"]:.3f} µs (×{r["measured_ratio"]:.2f}), table '
            f'{r["table_us"]:.3f} µs (×{r["table_ratio"]:.2f})' + ('' if r['ok'] else
                                                                   '  ← recalibrate'))
    return rows


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--steps', type=int, default=STEPS, help='steps per timing')
    args = parser.parse_args(argv)
    rows = run(args.steps)
    from ..physics.auto.calibration import current
    print(f'auto uses: {current().source}')
    print(json.dumps({'all_within_1.5x': all(r['ok'] for r in rows)}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
