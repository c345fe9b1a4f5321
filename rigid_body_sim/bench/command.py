"""``rigid-body-sim bench``'s arguments, without the suite: its sections load numba, which
``--help`` does not need (0.35 CPU-s); :func:`run` imports the suite (:mod:`.suite`)."""
from . import peers
from .common import GENERATED_COUNTS
from .scenes import SCENE_BY_NAME


def add_arguments(parser):
    parser.add_argument('--quick', action='store_true',
                        help='shortened run (< 2 min on 2 cores; used by the test suite)')
    parser.add_argument('--out', default='out/bench', metavar='DIR',
                        help='output directory (default out/bench)')
    parser.add_argument('--peers', action='store_true',
                        help='also measure MuJoCo and Basilisk if installed '
                             f'({peers.INSTALL_HINT})')
    parser.add_argument('--generated', type=int, default=None, metavar='N',
                        help='generated scenes in the generalisation section (default '
                             f'{GENERATED_COUNTS[True]} with --quick, {GENERATED_COUNTS[False]} '
                             'without)')
    parser.add_argument('--scenes', default='', metavar='A,B',
                        help='comma-separated subset of scenes for the work-precision section: '
                             + ', '.join(SCENE_BY_NAME))
    parser.epilog = ('CPU times are process seconds; errors are attitude angles in rad against '
                     'the reference each chart names; drifts are relative (value/initial − 1).')


def run(args) -> int:
    from . import suite
    return suite.run(args)
