"""Pointing on sensors against its prediction, for a scene with a gyro and a star tracker.

``python -m rigid_body_sim.tools.pointing SCENE [--run] [--settle S] [--set KEY=VALUE]``

Prints the linearised closed loop's RMS pointing error per body axis
(``sensors.prediction``) and, with ``--run``, the RMS an offline run of the scene shows
after ``settle`` seconds.
"""
import sys

import numpy as np

from .. import offline, scene as S


def main(argv=None) -> int:
    """Print the predicted RMS pointing error per body axis of a scene (and, with --run,
    the RMS a run of it shows after ``settle`` s)."""
    from . import argument_parser
    parser = argument_parser(__spec__, __doc__)
    parser.add_argument('scene')
    parser.add_argument('--run', action='store_true', help='also run the scene and compare')
    parser.add_argument('--settle', type=float, default=100.0, help='s ignored at the start')
    offline.add_set_argument(parser)
    args = parser.parse_args(argv)
    # after the arguments: these load numba, which --help does not need (0.35 CPU-s)
    from ..sensors.plots import pointing_error
    from ..sensors.prediction import pointing_variance
    try:
        scene = S.load(args.scene, args.set)
        sim, ctl = scene.simulator, scene.controller
        rms = np.sqrt(pointing_variance(sim, ctl, duration=sim['duration'], settle=args.settle))
    except (ValueError, KeyError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    def fmt(x):
        return '[' + ', '.join(f'{v:.3e}' for v in x) + ']'
    print(f'predicted RMS pointing error per body axis: {fmt(rms)} rad')
    if args.run:
        result = offline.simulate(scene, keep='all')
        s = result.samples
        err = pointing_error(s, ctl['target_attitude'])[s.t >= args.settle]
        measured = np.sqrt(np.mean(err ** 2, axis=0))
        print(f'measured  RMS pointing error per body axis: '
              f'{fmt(measured)} rad (ratio '
              f'{np.array2string(measured / rms, precision=3)}, seed {sim["seed"]})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
