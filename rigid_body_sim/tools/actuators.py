"""Cost per step of the gyrostat (reaction wheels, CMG pyramid) against the body alone.

``python -m rigid_body_sim.tools.actuators [--steps N]`` times, in the same run and on the
same body and step, the compiled loops the engine runs: ``splitting2`` on the body alone
with a held torque (``splitting_kernel.splitting_run``), and the gyrostat's Strang step
(``gyrostat_kernel.gyrostat_run``) with four reaction wheels and with the four-CMG
pyramid, both allocating a body torque every step (pseudo-inverse; singularity-robust
inverse). It prints µs per step and the ratios; the issue's target is ≤ 2×.
"""
from . import argument_parser
import sys

import numpy as np

from ..bench.common import best_of

# the engine and the kernels are imported where they are timed: they load numba, which
# --help does not need (0.35 CPU-s)

TARGET = 2.0
MOMENTS = np.array([4.0, 5.0, 3.0])
AXES = np.argsort(MOMENTS, kind='stable')[[0, 2, 1]]
Q0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
M0 = np.array([0.3, 0.6, 0.27])
TAU = np.array([0.01, -0.02, 0.015])
H = 1e-3


def _body(n):
    from ..physics.integrators import splitting_kernel
    weights = np.array([1.0])

    def run():
        splitting_kernel.splitting_run(Q0.copy(), M0.copy(), H, n, weights, AXES, MOMENTS, TAU,
                                       True, 0, 0.0, False, 0.0, None)
    run()
    return best_of(run)


def _gyrostat(n, **params):
    from ..engine import EngineConfig
    from ..engine.actuators import Actuators
    config = EngineConfig.from_parameters({'inertia': MOMENTS.tolist(), **params})
    act = Actuators(config.actuators, config.body)
    act.set_body_torque(TAU)

    def run():
        act.reset(M0 / MOMENTS)
        act.set_body_torque(TAU)
        act.run(Q0.copy(), M0.copy(), H, n, MOMENTS, AXES, None)
    run()
    return best_of(run)


def measure(n):
    """{name: µs per step} for the body alone, four wheels and the CMG pyramid."""
    wheels = {'actuators.wheels.axes': [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
              + [3 ** -0.5] * 3}
    cmgs = {'actuators.cmgs.cluster': 'pyramid', 'actuators.cmgs.momentum': [1.0]}
    return {'body alone (splitting2, held torque)': _body(n) / n * 1e6,
            'body + 4 reaction wheels': _gyrostat(n, **wheels) / n * 1e6,
            'body + 4-CMG pyramid': _gyrostat(n, **cmgs) / n * 1e6}


def main(argv=None):
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('--steps', type=int, default=200_000, help='steps per timing')
    args = parser.parse_args(argv)
    if args.steps < 1:
        parser.error('--steps must be >= 1')
    result = measure(args.steps)
    base = next(iter(result.values()))
    ok = True
    print(f'cost per step, {args.steps} steps, best of 5 (process CPU):')
    for name, us in result.items():
        ratio = us / base
        ok &= ratio <= TARGET
        print(f'  {name:38s} {us:8.4f} µs   ratio {ratio:5.2f} (target ≤ {TARGET:g})')
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
