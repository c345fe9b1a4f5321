"""The benchmark suite's command (``rigid-body-sim bench``): the run of every section
(:mod:`.sections`); its arguments are :mod:`.command`'s. See the package's docstring."""
import math
import os
import platform
import sys
import time

from . import charts, generated, peers, report, sections, targets  # noqa: F401 - suite.generated
from .command import add_arguments  # noqa: F401 - the command's arguments, re-exported
from .common import write_csv
from .scenes import SCENES, SCENE_BY_NAME


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
        (' --peers' if args.peers else '') + \
        (f' --generated {args.generated}' if args.generated is not None else '') + \
        f' --out {args.out}'
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

    run = sections.Run(quick=quick, out=out, scenes=scenes, peer_methods=peer_methods,
                       generated_count=args.generated, log=log)
    for section in sections.SECTIONS:
        log(f'\n== {section.title} ==')
        run.results[section.name] = section.run(run)

    log('\n== targets ==')
    t_rows = [row for name in sections.TARGET_ORDER
              for row in sections.SECTION_BY_NAME[name].targets(run)]
    write_csv(os.path.join(out, 'targets.csv'), targets.FIELDS, t_rows)
    with open(os.path.join(out, 'targets.md'), 'w') as f:
        f.write(_markdown_targets(t_rows, machine_text, command))
    for r in t_rows:
        lvl = f'{r["level"]:.0e}' if r['level'] != '' else ''
        log(f'  {r["verdict"]:5s} {r["target"][:48]:48s} {r["scene"]:18s} {lvl:6s} '
            f'measured {_fmt(r["measured"])}'
            f' (required {_fmt(r["required"])}) {r["ours_method"]} vs {r["peer_method"]} '
            f'{r["note"]}')

    try:
        for scene in scenes:
            charts.work_precision(run.results['work_precision'], scene,
                                  os.path.join(out, f'work_precision_{scene.name}.png'),
                                  machine_text, run.refs[scene.name][2])
        charts.stability(run.results['stability'], os.path.join(out, 'stability.png'))
        charts.long_horizon(run.results['long_horizon'], os.path.join(out, 'long_horizon.png'))
    except Exception as exc:  # noqa: BLE001 - charts are a convenience; the CSVs carry the data
        log(f'charts not written: {type(exc).__name__}: {exc}')
    report.write(out)  # the benchmarks page's figures, from the files just written
    log(f'\nwrote {out}/ (CSV, PNG, targets.md, summary.md) in '
        f'{time.monotonic() - wall0:.0f} s wall, {time.process_time() - cpu0:.0f} s CPU '
        f'(this process). Regenerate: {command}')
    return 0
