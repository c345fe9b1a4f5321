"""``rigid-body-sim bench``: work-precision, stability, long-horizon, batch and live benchmarks.

    rigid-body-sim bench [--quick] [--out DIR] [--peers]

One process run measures every section, prints tables and writes CSV + PNG files into DIR:
work_precision.csv, stability.csv, long_horizon.csv, batch.csv, sampling.csv, live.json,
exact_horizon.csv,
generated.csv (auto against each generated scene's oracle),
targets.csv, targets.md, work_precision_<scene>.png, stability.png, long_horizon.png. Times
are process CPU seconds (``time.process_time``), so they include Python overhead — ours and
scipy's alike; MuJoCo and Basilisk step in C. Modules: scenes (data), workprecision,
stability, longhorizon, batch, live, peers, exact_horizon (with reference40, the 40-digit
reference; mpmath), targets, charts.
"""
import csv
import json
import math
import os
import platform
import sys
import time

from . import batch as batch_mod
from . import compile as compile_cost
from . import (charts, exact_horizon, generated, live, longhorizon, peers, perstep, sampling,
               selection, stability, targets, workprecision)
from .common import reference
from .scenes import SCENES, SCENE_BY_NAME

BUDGETS = {True: {'ours': 0.2, 'peer': 0.2}, False: {'ours': 4.0, 'peer': 3.0}}


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
                             f'{generated.COUNTS[True]} with --quick, {generated.COUNTS[False]} '
                             'without)')
    parser.add_argument('--scenes', default='', metavar='A,B',
                        help='comma-separated subset of scenes for the work-precision section: '
                             + ', '.join(SCENE_BY_NAME))
    parser.epilog = ('CPU times are process seconds; errors are attitude angles in rad against '
                     'the reference each chart names; drifts are relative (value/initial − 1).')


def machine():
    cpu_name = platform.processor() or ''
    try:
        with open('/proc/cpuinfo') as f:
            for line in f:
                if line.startswith('model name'):
                    cpu_name = line.split(':', 1)[1].strip()
                    break
    except OSError:
        pass
    load = os.getloadavg()[0] if hasattr(os, 'getloadavg') else float('nan')
    import numpy
    import scipy
    return (f'{cpu_name}, {os.cpu_count()} cores, load {load:.1f} at start; {platform.system()} '
            f'{platform.release()}; Python {platform.python_version()}, '
            f'numpy {numpy.__version__}, scipy {scipy.__version__}')


def _write_csv(path, fields, rows):
    with open(path, 'w', newline='') as f:
        w = csv.DictWriter(f, fieldnames=fields, extrasaction='ignore')
        w.writeheader()
        for r in rows:
            w.writerow({k: (f'{v:.6g}' if isinstance(v, float) else v) for k, v in r.items()})


def _fmt(v, spec='.3g'):
    if isinstance(v, float):
        return 'nan' if math.isnan(v) else format(v, spec)
    return str(v)


def _markdown_targets(rows, machine_text, command):
    lines = [f'Measured on: {machine_text}', '', f'Regenerate: `{command}`', '',
             '| target | scene | error level (rad) | best ours (CPU s) | best peer (CPU s) '
             '| measured | required | verdict |',
             '|---|---|---|---|---|---|---|---|']
    for r in rows:
        ours = f'{r["ours_method"]} ({_fmt(r["ours_cpu_s"])})' if r['ours_method'] else '—'
        peer = f'{r["peer_method"]} ({_fmt(r["peer_cpu_s"])})' if r['peer_method'] else '—'
        verdict = r['verdict'] + (f' ({r["note"]})' if r['note'] else '')
        level = _fmt(r['level'], '.0e') if r['level'] != '' else ''
        cells = [r['target'], r['scene'], level, ours, peer, _fmt(r['measured']),
                 _fmt(r['required']), verdict]
        lines.append('| ' + ' | '.join(str(c).replace('|', '\\|') for c in cells) + ' |')
    return '\n'.join(lines) + '\n'


def run(args) -> int:
    import numpy as np
    with np.errstate(over='ignore', invalid='ignore'):  # diverging methods are data, not warnings
        return _run(args)


def _run(args) -> int:
    quick = bool(args.quick)
    out = charts.ensure_dir(args.out)
    command = 'rigid-body-sim bench' + (' --quick' if quick else '') + \
        (' --peers' if args.peers else '') + f' --out {args.out}'
    machine_text = machine()
    wall0, cpu0 = time.monotonic(), time.process_time()

    def log(msg):
        print(msg, flush=True)

    log(f'rigid-body-sim bench ({"quick" if quick else "full"}) — {machine_text}')
    log('CPU times are process CPU seconds and include Python overhead (ours and scipy run '
        'Python code per step or per RHS call; MuJoCo and Basilisk step in C).')
    peer_methods = peers.scipy_methods()
    peer_notes = ['scipy solve_ivp RK45/DOP853']
    if args.peers:
        extra, notes = peers.optional_methods()
        peer_methods.update(extra)
        peer_notes += notes
        missing = [n for n in notes if 'not installed' in n]
        if missing:
            log(f'peers: {"; ".join(missing)}. '
                f'Install the optional peers with:  {peers.INSTALL_HINT}')
    log('peers: ' + ', '.join(peer_notes))

    scenes = SCENES
    if getattr(args, 'scenes', ''):
        wanted = [s.strip() for s in args.scenes.split(',') if s.strip()]
        unknown = [s for s in wanted if s not in SCENE_BY_NAME]
        if unknown:
            print(f'unknown scene(s) {unknown}; choose from {list(SCENE_BY_NAME)}',
                  file=sys.stderr)
            return 2
        scenes = tuple(SCENE_BY_NAME[s] for s in wanted)

    # 1. work-precision
    log('\n== 1. work-precision ==')
    wp_rows, refs = [], {}
    budget = BUDGETS[quick]
    for scene in scenes:
        c = time.process_time()
        ref = reference(scene)
        refs[scene.name] = ref
        log(f'{scene.name}: {scene.description}; reference {ref[2]}'
            + (f' (dop853 rtol 1e-13 differs from it by {ref[3]:.2g} rad)' if ref[2] == 'exact'
               else f' (own error estimate {ref[3]:.2g} rad)')
            + f' [{time.process_time() - c:.1f} s]')
        scale = 1.0 if quick else scene.budget_scale
        wp_rows += workprecision.sweep_ours(scene, ref, budget['ours'] * scale, quick, log)
        wp_rows += workprecision.sweep_peers(scene, peer_methods, ref, budget['peer'] * scale,
                                             quick, log)
    _write_csv(os.path.join(out, 'work_precision.csv'), workprecision.FIELDS, wp_rows)
    _print_wp(wp_rows, scenes, log)

    # 2. stability
    log('\n== 2. stability where methods fail ==')
    st_rows = stability.run(quick, log)
    _write_csv(os.path.join(out, 'stability.csv'), stability.FIELDS, st_rows)
    for scene, method, text in stability.summary(st_rows):
        log(f'  {scene:18s} {method:18s} {text}')

    # 3. long horizon
    log('\n== 3. long horizon (generic tumble) ==')
    lh_rows, periods = longhorizon.run(quick, log)
    _write_csv(os.path.join(out, 'long_horizon.csv'), longhorizon.FIELDS, lh_rows)

    # 4. batch
    log('\n== 4. batch throughput ==')
    b_rows = batch_mod.run(quick, log)
    _write_csv(os.path.join(out, 'batch.csv'), batch_mod.FIELDS, b_rows)

    # 4b. per step and end to end
    log('\n== 4b. cost per step (one body) and per offline sample ==')
    ps_rows, ps_fig = perstep.run(quick, log)
    _write_csv(os.path.join(out, 'perstep.csv'), perstep.FIELDS, ps_rows)

    # 4c. what samples and the CLI add to a run
    log('\n== 4c. sampling and CLI overhead (samples kept; the CLI in a fresh process) ==')
    sm_rows, sm_targets = sampling.run(quick, log)
    _write_csv(os.path.join(out, 'sampling.csv'), sampling.FIELDS, sm_rows)

    # 5. live
    log('\n== 5. live ==')
    live_res = {'simulator': live.simulator(quick, log), 'recorder': live.recorder(quick, log),
                'viewer': live.viewer(quick, log)}
    for k, v in live_res.items():
        log(f'  live {k}: ' + (v['status'] if v['status'] != 'ok' else
                               json.dumps({a: b for a, b in v.items() if a != 'output'})))
    with open(os.path.join(out, 'live.json'), 'w') as f:
        json.dump(live_res, f, indent=1)

    # 6. model selection on the built-in scenes
    log('\n== 6. model selection (integrator: auto) ==')
    sel_rows, sel_targets = selection.run(quick, log)
    _write_csv(os.path.join(out, 'selection.csv'), selection.FIELDS, sel_rows)

    # 6b. auto on seeded generated scenes against each scene's oracle
    log(f'\n== 6b. generalisation: auto on generated scenes (seed {generated.SEED}) ==')
    gen_rows, gen_targets, _ = generated.run(quick, log, count=args.generated)
    _write_csv(os.path.join(out, 'generated.csv'), generated.FIELDS, gen_rows)
    sel_targets = sel_targets + gen_targets

    # 7. compile cost of the kernels (never mixed into run cost)
    log('\n== 7. compile cost (numba kernels) ==')
    c_rows = compile_cost.run(quick, log)
    if c_rows:
        _write_csv(os.path.join(out, 'compile.csv'), compile_cost.FIELDS, c_rows)

    # 8. exact against the 40-digit reference at 1e3 s and 1e6 s, every torque-free scene
    log('\n== 8. exact at long horizons (40-digit reference) ==')
    eh_rows, eh_targets = exact_horizon.run(quick, log)
    if eh_rows:
        _write_csv(os.path.join(out, 'exact_horizon.csv'), exact_horizon.FIELDS, eh_rows)

    # targets
    log('\n== targets ==')
    t_rows = targets.work_precision(wp_rows, scenes) + sel_targets + eh_targets
    split = [r for r in st_rows if r['method'].startswith('splitting') and r['status'] == 'ok']
    if split:
        worst = max(split, key=lambda r: r['max_momentum_drift'])
        t_rows.append(targets.simple(
            'splitting* |L| drift at any step (stability sweep)',
            worst['max_momentum_drift'], 1e-12, worst['max_momentum_drift'] <= 1e-12,
            f'worst: {worst["method"]} on {worst["scene"]} at x = {worst["x"]:g}'))
    big = [r for r in b_rows if r['bodies'] == 1_000_000]
    if big:
        best = max(big, key=lambda r: r['body_steps_per_s'])
        ok = best['body_steps_per_s'] >= 1e7
        t_rows.append(targets.simple(
            'batch body-steps/s at N = 1e6 (one core)', best['body_steps_per_s'], 1e7, ok,
            f'{best["method"]}.{best["path"]}()'
            + ('' if ok else f'; short by {1e7 / best["body_steps_per_s"]:.3g}x')))
    else:
        t_rows.append(targets.simple('batch body-steps/s at N = 1e6 (one core)', math.nan, 1e7,
                                     None, 'not measured in --quick (N ≤ 1e4)'))
    t_rows += perstep.targets_from(ps_fig, quick)
    t_rows += sm_targets
    sim = live_res['simulator']
    for key, req, better in (('real_time_factor', 100.0, 'ge'),
                             ('cpu_share_at_real_time', 0.05, 'le'),
                             ('first_message_s', 2.0, 'le')):
        val = sim.get(key)
        if isinstance(val, (int, float)):
            ok = val >= req if better == 'ge' else val <= req
            t_rows.append(targets.simple(f'live simulator {key}', float(val), req, ok))
        else:
            t_rows.append(targets.simple(f'live simulator {key}', math.nan, req, None,
                                         sim['status']))
    rss = sim.get('rss_mb')
    t_rows.append(targets.simple('live simulator memory (RSS of a warm node, MB)',
                                 float(rss) if isinstance(rss, (int, float)) else math.nan,
                                 math.nan, None, 'reported, no target'))
    rec = live_res['recorder']
    if rec['status'] == 'ok':
        ok = rec['recorded_msgs_per_s'] >= 10_000 and rec['lost'] == 0
        t_rows.append(targets.simple(
            'recorder messages/s with zero loss', float(rec['recorded_msgs_per_s']), 1e4, ok,
            f'lost {rec["lost"]}; publisher achieved {rec["published_msgs_per_s"]} msg/s '
            f'of {rec["offered_msgs_per_s"]} offered'))
    else:
        t_rows.append(targets.simple('recorder messages/s with zero loss', math.nan, 1e4, None,
                                     rec['status']))
    view = live_res['viewer']
    if view['status'] == 'ok':
        t_rows.append(targets.simple(
            'live viewer CPU share of a core at 50 Hz', view['viewer_cpu_share'], 0.05,
            view['viewer_cpu_share'] <= 0.05, view['viewer_phase']))
        ratio = view['simulator_rtf_with_viewer'] / view['simulator_rtf_alone']
        t_rows.append(targets.simple(
            'live simulator RTF with the viewer / alone', ratio, 0.99, ratio >= 0.99,
            f'{view["simulator_rtf_with_viewer"]:.4f} / {view["simulator_rtf_alone"]:.4f}'))
    else:
        t_rows.append(targets.simple('live viewer CPU share of a core at 50 Hz', math.nan,
                                     0.05, None, view['status']))
    warm = [r for r in c_rows if r['phase'] == 'warm']
    t_rows.append(targets.simple(
        'kernels ready from the cache (warm start, s)', warm[0]['total_s'] if warm else math.nan,
        2.0, warm[0]['total_s'] <= 2.0 if warm else None,
        (f'cold compile {c_rows[0]["total_s"]:.1f} s' if warm else 'not measured in --quick')))
    _write_csv(os.path.join(out, 'targets.csv'), targets.FIELDS, t_rows)
    with open(os.path.join(out, 'targets.md'), 'w') as f:
        f.write(_markdown_targets(t_rows, machine_text, command))
    for r in t_rows:
        lvl = f'{r["level"]:.0e}' if r['level'] != '' else ''
        log(f'  {r["verdict"]:5s} {r["target"][:48]:48s} {r["scene"]:18s} {lvl:6s} '
            f'measured {_fmt(r["measured"])}'
            f' (required {_fmt(r["required"])}) {r["ours_method"]} vs {r["peer_method"]} '
            f'{r["note"]}')

    # charts
    try:
        for scene in scenes:
            charts.work_precision(wp_rows, scene,
                                  os.path.join(out, f'work_precision_{scene.name}.png'),
                                  machine_text, refs[scene.name][2])
        charts.stability(st_rows, os.path.join(out, 'stability.png'))
        charts.long_horizon(lh_rows, os.path.join(out, 'long_horizon.png'))
    except Exception as exc:  # noqa: BLE001 - charts are a convenience; the CSVs carry the data
        log(f'charts not written: {type(exc).__name__}: {exc}')
    log(f'\nwrote {out}/ (CSV, PNG, targets.md) in {time.monotonic() - wall0:.0f} s wall, '
        f'{time.process_time() - cpu0:.0f} s CPU (this process). Regenerate: {command}')
    return 0


def _print_wp(rows, scenes, log):
    log('\nbest attitude error reached per method (CPU s for it; nfev):')
    for scene in scenes:
        log(f'  {scene.name}')
        for method in dict.fromkeys(r['method'] for r in rows if r['scene'] == scene.name):
            rs = [r for r in rows
                  if r['scene'] == scene.name and r['method'] == method and r['status'] == 'ok']
            fails = [r for r in rows
                     if r['scene'] == scene.name and r['method'] == method and r['status'] != 'ok']
            if not rs:
                log(f'    {method:20s} no successful run ({fails[0]["status"] if fails else "-"})')
                continue
            b = min(rs, key=lambda r: (r['attitude_error'], r['cpu_s']))
            cheapest = min(rs, key=lambda r: r['cpu_s'])
            log(f'    {method:20s} best {b["attitude_error"]:9.2e} rad in {b["cpu_s"]:8.3g} s '
                f'({b["kind"]}={b["param"]:.3g}, nfev {b["nfev"]}); '
                f'cheapest {cheapest["cpu_s"]:.3g} s -> '
                f'{cheapest["attitude_error"]:.2e} rad; |L| drift {b["momentum_drift"]:.1e}, '
                f'T {b["energy_drift"]:.1e}'
                + (f'; {len(fails)} failed run(s)' if fails else ''))
