"""``rigid-body-sim campaign SCENE``: a Monte Carlo campaign on Dask (see the package doc)."""
import json
import math
import os
import signal
import sys

MAX_SEED = 2 ** 63 - 1


def add_arguments(parser):
    from ..cli import number
    from ..offline import add_set_argument
    from .dispersions import POLICIES
    parser.add_argument('scene', help='built-in scene name or a params file')
    parser.add_argument('--disperse', action='append', default=[], metavar='KEY=DIST:SPREAD',
                        help='disperse a scene parameter (repeatable): normal:SIGMA or '
                             'uniform:HALFWIDTH, a trailing %% relative to the scene\'s value, '
                             'per component: --disperse inertia=uniform:5%% '
                             '--disperse initial_angular_velocity=normal:0.2')
    parser.add_argument('--dispersions', metavar='FILE',
                        help='YAML file: dispersions: {KEY: DIST:SPREAD}, optional runs, seed')
    parser.add_argument('--runs', type=number(1, 1e9, integer=True),
                        help='number of runs (default: the file\'s, else 100)')
    parser.add_argument('--seed', type=number(0, MAX_SEED, integer=True),
                        help='campaign seed S; run k draws from SeedSequence(S, spawn_key=(k,)) '
                             '(default: the file\'s, else 0)')
    parser.add_argument('--scheduler', metavar='ADDRESS',
                        help='an existing Dask scheduler (tcp://HOST:8786); default: a local '
                             'cluster, one worker process per core, for this campaign only')
    parser.add_argument('--workers', type=number(1, 4096, integer=True),
                        help='worker processes of the local cluster (default: one per core)')
    parser.add_argument('--chunk', type=number(1, 1e6, integer=True),
                        help='runs per Dask task (default: automatic, at most 32)')
    parser.add_argument('--out', help='output directory (default: out/campaign-<scene>)')
    parser.add_argument('--resume', action='store_true',
                        help='run only the runs missing from --out (same campaign)')
    parser.add_argument('--overwrite', action='store_true',
                        help='delete the campaign already in --out and start again')
    parser.add_argument('--rerun', type=number(0, 1e12, integer=True), metavar='K',
                        help='run K alone here, print its row as JSON and compare it with the '
                             'stored row if --out holds one (exit 1 if they differ)')
    parser.add_argument('--unphysical', choices=POLICIES, default='redraw',
                        help='a refused draw (e.g. inertia violating the triangle inequality):'
                             ' redraw it (counted) or reject the run (a failed row)')
    parser.add_argument('--pointing-tolerance', type=number(0, math.pi, low_open=True),
                        default=0.01, help='settling: pointing error at or below, rad')
    parser.add_argument('--rate-tolerance', type=number(0, 1e9, low_open=True),
                        default=0.01, help='detumbled: |ω| at or below, rad/s')
    parser.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    add_set_argument(parser)
    parser.add_argument('--namespace', default='/', metavar='NS',
                        help='the nodes\' namespace, for params files whose sections name it')


def _spec(args):
    from ..scene import load
    from . import dispersions as disp
    from .runner import CampaignSpec
    scene = load(args.scene, args.set, args.namespace)
    found, extra = disp.load_file(args.dispersions) if args.dispersions else ([], {})
    found += [disp.parse(t) for t in args.disperse]
    disp.check_keys(scene, found, args.namespace)
    runs = args.runs or extra.get('runs') or 100
    seed = args.seed if args.seed is not None else extra.get('seed', 0)
    return CampaignSpec.create(scene, found, seed, runs, policy=args.unphysical,
                               pointing_tolerance=args.pointing_tolerance,
                               rate_tolerance=args.rate_tolerance)


def _jsonable(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None if math.isnan(v) else str(v)
    if isinstance(v, list):
        return [_jsonable(x) for x in v]
    return v


def _same(a, b) -> bool:
    """Equal, floats bit for bit (NaN included)."""
    import numpy as np
    if isinstance(a, list) or isinstance(b, list):
        return isinstance(a, list) and isinstance(b, list) and len(a) == len(b) and all(
            _same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return a is not None and b is not None and \
            np.float64(a).tobytes() == np.float64(b).tobytes()
    return a == b


def rerun(spec, k, out) -> int:
    """Run k here; print its row; compare with the stored row (bit for bit, but CPU time)."""
    from . import store
    from .runner import run_one
    row = run_one(spec, k)
    print(json.dumps({key: _jsonable(v) for key, v in row.items()}))
    table = store.read(out)
    if table is None:
        return 0
    keys = _config_diff(out, spec)
    if keys:
        print(f'{out} holds a campaign that differs from this command in: {", ".join(keys)}; '
              'not compared', file=sys.stderr)
        return 0
    import pyarrow.compute as pc
    stored = table.filter(pc.equal(table.column('run_id'), k)).to_pylist()
    if not stored:
        print(f'run {k} is not in {store.runs_dir(out)}', file=sys.stderr)
        return 0
    diff = [key for key, v in stored[0].items() if key != 'cpu_time'
            and not _same(v, row.get(key))]
    if diff:
        print(f'run {k} differs from the stored row in: {", ".join(diff)}', file=sys.stderr)
        return 1
    print(f'run {k}: identical to the stored row (CPU time aside)', file=sys.stderr)
    return 0


def _config_diff(out, spec):
    """The keys in which the campaign stored in ``out`` differs from ``spec`` (empty if
    the same campaign; every key if none is stored)."""
    from . import store
    stored = (store.read_config(out) or {}).get('config') or {}
    mine = json.loads(json.dumps(spec.identity(), default=str))
    return sorted(k for k in mine if stored.get(k) != mine[k])


def _meta(spec, scheduler):
    from .store import versions
    return {'config': spec.identity(), 'runs': spec.runs, 'columns': list(spec.columns),
            'scheduler': scheduler or 'local', 'versions': versions()}


def run(args) -> int:
    from ..scene import SceneError
    from . import store
    try:
        spec = _spec(args)
    except (SceneError, ValueError) as exc:
        print(f'error: {exc}', file=sys.stderr)
        return 2
    out = args.out or os.path.join('out', f'campaign-{spec.scene.name}')
    if args.rerun is not None:
        return rerun(spec, int(args.rerun), out)
    have = store.existing_ids(out)
    if have and args.overwrite:
        store.remove(out)
        have = set()
    elif have and not args.resume:
        print(f'error: {out} holds a campaign ({len(have)} runs); --resume to finish it or '
              '--overwrite to start again', file=sys.stderr)
        return 2
    elif have:
        keys = _config_diff(out, spec)
        if keys:
            print(f'error: {out} holds a different campaign (differs in: '
                  f'{", ".join(keys)}); use another --out', file=sys.stderr)
            return 2
    todo = [k for k in range(spec.runs) if k not in have]
    try:
        rows = store.RunStore(out, spec.columns, _meta(spec, args.scheduler))
    except OSError as exc:
        print(f'error: {out}: cannot write the campaign: {exc}', file=sys.stderr)
        return 2
    done = _drive(args, spec, todo, rows, out)
    if done is not None:
        return done
    return _finish(args, spec, out, len(todo))


def _drive(args, spec, todo, rows, out):
    """Run ``todo``; None when finished, else the exit code (interrupted, cluster error)."""
    from .runner import Cluster, execute
    from tqdm import tqdm
    bar = None
    cluster = None
    failures = 0
    # SIGTERM stops as Ctrl-C does: finished rows are written, the cluster shut down
    old_term = signal.signal(signal.SIGTERM, _interrupt)
    try:
        if todo:
            cluster = Cluster(args.scheduler, args.workers)
            bar = tqdm(total=len(todo), unit='run', disable=args.no_progress or None,
                       file=sys.stderr, dynamic_ncols=True)

            def on_rows(new):
                nonlocal failures
                rows.add(new)
                failures += sum(r['status'] != 'ok' for r in new)
                bar.set_postfix(failed=failures, refresh=False)
                bar.update(len(new))
            execute(cluster, spec, todo, on_rows, args.chunk)
    except KeyboardInterrupt:
        rows.close()
        if bar is not None:
            bar.close()
        print(f'\ninterrupted: {len(store_ids(out))} of {spec.runs} runs kept in '
              f'{out}/runs; --resume runs the rest', file=sys.stderr)
        _close_quietly(cluster)
        return 130
    except OSError as exc:  # no scheduler at the address, a full disk, ...
        print(f'error: {exc}', file=sys.stderr)
        try:
            rows.close()
        except OSError:
            pass
        _close_quietly(cluster)
        return 2
    finally:
        signal.signal(signal.SIGTERM, old_term)
    rows.close()
    if bar is not None:
        bar.close()
    _close_quietly(cluster)
    return None


def _interrupt(signum, frame):
    raise KeyboardInterrupt


def store_ids(out):
    from .store import existing_ids
    return existing_ids(out)


def _close_quietly(cluster):
    if cluster is None:
        return
    try:
        cluster.close()
    except (Exception, KeyboardInterrupt):  # noqa: BLE001 — shutting down anyway
        pass


def _finish(args, spec, out, ran) -> int:
    from . import report, store
    table = store.read(out)
    if table is None:
        print('no runs', file=sys.stderr)
        return 0
    s = report.summary(table, spec.columns)
    print(f'{spec.scene.name}: {ran} runs now, {s["runs"]} in {store.runs_dir(out)}')
    print(report.format_summary(s))
    with open(os.path.join(out, 'summary.json'), 'w', encoding='utf-8') as f:
        json.dump(s, f, indent=1)
    if not args.no_plots:
        for p in report.write_plots(table, spec.columns, os.path.join(out, 'plots')):
            print(f'  plot: {os.path.abspath(p)}')
    return 0
