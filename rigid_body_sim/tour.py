"""``rigid-body-sim tour``: the five classic phenomena of free rotation, one figure each.

Runs the scenes offline (no bag) and writes a thumbnail of the figure that shows each
phenomenon into ``--out`` (docs/tour for the README). ``make tour`` runs it.
"""
import os
import shutil
import sys
import tempfile

# (phenomenon, scene, figure): the README's tour, in its order
TOUR = (
    ('tennis racket (Dzhanibekov) flips', 'tennis_racket', 'flips.png'),
    ('free precession: body and space cones', 'symmetric_top', 'precession.png'),
    ('Poinsot\'s construction', 'tennis_racket', 'poinsot.png'),
    ('Explorer 1: the major-axis rule', 'explorer1', 'nutation.png'),
    ('Chandler (free Euler) wobble of a rigid Earth', 'rigid_earth', 'precession.png'),
)
THUMB_SCALE = 0.5  # of the 100-dpi figure: 40-70 kB each (≤ 80 kB, tested)
MAX_BYTES = 80_000


def thumbnail_name(scene, figure):
    return f'{scene}_{figure}'


def add_arguments(parser):
    parser.add_argument('--out', default=os.path.join('docs', 'tour'),
                        help='directory for the thumbnails (default docs/tour)')


def run(args) -> int:
    from matplotlib import image

    from .offline import simulate
    from .plots import free_until, write_plots
    from .scene import SceneError, load
    os.makedirs(args.out, exist_ok=True)
    done = {}
    with tempfile.TemporaryDirectory() as work:
        for phenomenon, name, figure in TOUR:
            if name not in done:
                try:
                    scene = load(name)
                except SceneError as exc:
                    print(f'error: {exc}', file=sys.stderr)
                    return 2
                r = simulate(scene, keep='plot')
                s = r.samples
                out = os.path.join(work, name)
                # only the figures the tour shows: 5 of the 4 scenes' 16 (70 % of its CPU)
                write_plots(s, r.body, out, name, free_until(s.t, s.torque), scene,
                            only={f for _, n, f in TOUR if n == name})
                done[name] = out
            path = os.path.join(args.out, thumbnail_name(name, figure))
            image.thumbnail(os.path.join(done[name], figure), path, scale=THUMB_SCALE)
            size = os.path.getsize(path)
            print(f'{phenomenon}: {path} ({size // 1000} kB)')
        shutil.rmtree(work, ignore_errors=True)
    return 0
