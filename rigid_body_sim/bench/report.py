"""The benchmarks page's figures, rendered from a run's files (never typed by hand).

``python -m rigid_body_sim.bench.report DIR`` writes DIR/summary.md from the files in DIR:
what ``rigid-body-sim bench`` wrote (targets.csv, generated.csv, sampling.csv, batch.csv,
perstep.csv, compile.csv, exact_horizon.csv, live.json) and what the standalone tools wrote
there (soak.json, flood.json, recovery.json, fleet.json, lockstep.json,
lockstep_floor.json). The bench calls it at the end of a run; docs/benchmarks.md includes
the result, so every figure on the page comes from a file.
A file that is missing is said to be missing, not filled in.
"""
import csv
import json
import math
import os
import sys

import numpy as np

NAME = 'summary.md'


def _rows(out, name):
    path = os.path.join(out, name)
    if not os.path.exists(path):
        return None
    with open(path, newline='', encoding='utf-8') as f:
        return list(csv.DictReader(f))


def _json(out, name):
    path = os.path.join(out, name)
    if not os.path.exists(path):
        return None
    with open(path, encoding='utf-8') as f:
        return json.load(f)


def _f(v, spec='.3g'):
    try:
        x = float(v)
    except (TypeError, ValueError):
        return str(v)
    return 'nan' if math.isnan(x) else format(x, spec)


def _span(values, spec='.3g', unit=''):
    vals = [float(v) for v in values if v not in ('', None) and math.isfinite(float(v))]
    if not vals:
        return '—'
    lo, hi = min(vals), max(vals)
    return (f'{_f(lo, spec)}{unit}' if _f(lo, spec) == _f(hi, spec)
            else f'{_f(lo, spec)}–{_f(hi, spec)}{unit}')


def _spread(values):
    v = np.array([float(x) for x in values if x not in ('', None)], float)
    v = v[np.isfinite(v)]
    if not len(v):
        return 'none'
    return (f'p10 {_f(np.percentile(v, 10))}, median {_f(np.median(v))}, p90 '
            f'{_f(np.percentile(v, 90))}, worst {_f(v.max())} (n = {len(v)})')


def _missing(name):
    return [f'- `{name}`: not in this directory (not measured in the last run).']


def targets_section(out):
    rows = _rows(out, 'targets.csv')
    if rows is None:
        return _missing('targets.csv')
    verdicts = {v: sum(r['verdict'] == v for r in rows) for v in ('PASS', 'MISS', 'n/a')}
    lines = [f'- **Targets:** {verdicts["PASS"]} PASS, {verdicts["MISS"]} MISS, '
             f'{verdicts["n/a"]} n/a (the table below).',
             '- **Best peer CPU / our best CPU at the same attitude error** (target ≥ 10×; '
             'levels 1e-2 … 1e-10 rad where a peer gets there):']
    ratio = [r for r in rows if r['target'].startswith('cpu ratio')]
    for scene in dict.fromkeys(r['scene'] for r in ratio):
        rs = [r for r in ratio if r['scene'] == scene and r['verdict'] in ('PASS', 'MISS')]
        ours = ', '.join(sorted({r['ours_method'] for r in rs if r['ours_method']}))
        lines.append(f'  - {scene}: {_span([r["measured"] for r in rs], unit="×")} '
                     f'({sum(r["verdict"] == "MISS" for r in rs)} MISS; ours: {ours or "—"})')
    return lines


BASILISK = 'Basilisk CPU / ours at equal attitude error (gravity gradient)'
BASILISK_MTB = 'Basilisk CPU / ours at equal attitude error (magnetorquers)'


def basilisk_section(out):
    """Basilisk's rows (bench/basilisk_gg.py, basilisk_mtb_sweep.py): the ratio per scene
    and what it reached."""
    rows = _rows(out, 'targets.csv') or []
    lines = []
    for target, name, what in ((BASILISK, 'basilisk.csv', 'gravity gradient'),
                               (BASILISK_MTB, 'basilisk_mtb.csv', 'magnetorquers')):
        ratio = [r for r in rows if r['target'] == target]
        runs = _rows(out, name)
        if not ratio or runs is None:
            if target == BASILISK:
                return _missing(name if runs is None else 'its rows in targets.csv')
            continue  # a run from before the magnetorquer comparison
        lines.append(f'- **Basilisk CPU / our CPU at the same attitude error** ({what}; '
                     'target ≥ 10× at every level Basilisk reaches):')
        for scene in dict.fromkeys(r['scene'] for r in ratio):
            rs = [r for r in ratio if r['scene'] == scene and r['verdict'] in ('PASS', 'MISS')]
            peer = [r for r in runs if r['scene'] == scene and r['family'] == 'peer'
                    and r['status'] == 'ok']
            best = min(peer, key=lambda r: float(r['attitude_error'])) if peer else None
            reach = (f'; Basilisk reaches {_f(best["attitude_error"])} rad at best '
                     f'({best["method"]}, its orbit {_f(best["orbit_error"])} rad off ours)'
                     if best else '')
            lines.append(f'  - {scene}: {_span([r["measured"] for r in rs], unit="×")} '
                         f'({sum(r["verdict"] == "MISS" for r in rs)} MISS of {len(rs)} '
                         f'levels{reach}).')
    return lines


def replace_targets(out, target, new_rows,
                    command='python -m rigid_body_sim.bench.basilisk_gg --out {out}',
                    after='cpu ratio'):
    """Put ``new_rows`` in place of ``target``'s rows (a name, or a tuple of names) in
    out/targets.csv and targets.md (where they were, else after the last row whose target
    starts with ``after``: the work-precision rows by default),
    every other row as it was: a section run alone (``python -m
    rigid_body_sim.bench.basilisk_gg``) updates a full run's tables, with a line saying
    which command (``command``, {out}: the directory) measured its rows, and where."""
    from . import targets
    from .suite import _markdown_targets, machine
    from .common import write_csv
    names = (target,) if isinstance(target, str) else tuple(target)
    old = _rows(out, 'targets.csv') or []
    kept = [r for r in old if r['target'] not in names]
    was = next((i for i, r in enumerate(old) if r['target'] in names), None)
    at = was if was is not None else max(
        (i + 1 for i, r in enumerate(kept) if r['target'].startswith(after)), default=0)
    write_csv(os.path.join(out, 'targets.csv'), targets.FIELDS,
              kept[:at] + list(new_rows) + kept[at:])
    path = os.path.join(out, 'targets.md')
    if os.path.exists(path):
        with open(path, encoding='utf-8') as f:
            lines = f.read().rstrip('\n').split('\n')
    else:
        lines = _markdown_targets([], machine(), 'rigid-body-sim bench').rstrip('\n').split('\n')
    note = 'Rows ' + ', '.join(f'"{n}"' for n in names) + ':'
    drop = {i for i, line in enumerate(lines) if line.startswith(note)}
    drop |= {i + 1 for i in drop}  # the blank line after the note
    mine_at = next((i for i, line in enumerate(lines)
                    if any(line.startswith(f'| {n} |') for n in names)), None)
    if mine_at is not None:
        mine_at -= sum(1 for i in drop if i < mine_at)
    lines = [line for i, line in enumerate(lines)
             if i not in drop and not any(line.startswith(f'| {n} |') for n in names)]
    mine = _markdown_targets(new_rows, '', '').rstrip('\n').split('\n')[6:]
    table = [i for i, line in enumerate(lines) if line.startswith(('|---', f'| {after}'))]
    at = mine_at if mine_at is not None else table[-1] + 1 if table else len(lines)
    lines[at:at] = mine
    lines[4:4] = [f'{note} `{command.format(out=out)}` on: {machine()}', '']
    with open(path, 'w', encoding='utf-8') as f:
        f.write('\n'.join(lines) + '\n')


def generated_section(out):
    rows = _rows(out, 'generated.csv')
    if rows is None:
        return _missing('generated.csv')
    orbit = [r for r in rows if r['kind'] == 'gravity_gradient']
    body = [r for r in rows if r['kind'] != 'gravity_gradient']
    return (_generated_lines('Generated scenes', body) if body else []) + \
        (_generated_lines('Generated orbit scenes (gravity gradient)', orbit) if orbit else [])


def _generated_lines(title, rows):
    judged = [r for r in rows if r['status'] in ('ok', 'auto missed')]
    ok = [r for r in judged if r['status'] == 'ok' and r['cpu_ratio']]
    infeasible = [r for r in rows if r['status'] == 'infeasible']
    seeds = sorted({r['scene'][3:].rsplit('-', 1)[0] for r in rows})
    kinds = {k: sum(r['kind'] == k for r in rows) for k in dict.fromkeys(r['kind'] for r in rows)}
    return [f'- **{title}** (seed {", ".join(seeds)}; {len(rows)} scenes: '
            + ', '.join(f'{n} {k}' for k, n in kinds.items()) + '):',
            f'  - judged {len(judged)}, undecided '
            f'{sum(r["status"].startswith("undecided") for r in rows)}, failed '
            f'{sum(r["status"] in ("auto failed", "no reference") for r in rows)}; auto missed '
            f'its budget on {sum(r["status"] == "auto missed" for r in rows)};',
            *([f'  - infeasible (no fixed choice of the registry met the budget, and auto '
               f'said it cannot): {len(infeasible)}'
               + (f', auto error / budget there '
                  f'{_spread([r["error_ratio"] for r in infeasible])}' if infeasible else '')
               + ';'] if 'auto_predicted_error' in rows[0] else []),  # runs that classify
            f'  - auto error / budget: {_spread([r["error_ratio"] for r in judged])};',
            f'  - auto CPU / oracle CPU where auto met its budget: '
            f'{_spread([r["cpu_ratio"] for r in ok])};',
            '  - oracle: ' + ', '.join(f'{m} {n}' for m, n in _count(
                r['oracle_method'] for r in rows if r['oracle_method'])) + '; auto chose: '
            + ', '.join(f'{m} {n}' for m, n in _count(
                r['auto_method'] for r in rows if r['auto_method'])) + '.']


def _count(items):
    items = list(items)
    return sorted(((m, items.count(m)) for m in set(items)), key=lambda x: (-x[1], x[0]))


def sampling_section(out):
    rows = _rows(out, 'sampling.csv')
    if rows is None:
        return _missing('sampling.csv')
    lines = []
    for what, a, b in (('sampling overhead', '1 sample/s', '100 samples/s'),
                       ('CLI overhead', 'in-process warm', 'the CLI\'s cpu_seconds')):
        rs = [r for r in rows if r['what'] == what]
        own = [r for r in rs if not r['scene'].startswith('gen')]
        gen = [r for r in rs if r['scene'].startswith('gen')]
        lines.append(f'- **{what.capitalize()}** ({b} / {a}; CPU): '
                     + '; '.join(f'{r["scene"]} {_f(r["ratio"])}× ({_f(r["cpu_a_s"])} → '
                                 f'{_f(r["cpu_b_s"])} s)' for r in own) + '.')
        if gen:
            lines.append(f'  - generated scenes: {_spread([r["ratio"] for r in gen])}.')
    return lines


def machine_section(out):
    lines = []
    batch = _rows(out, 'batch.csv')
    if batch:
        top = max(int(float(r['bodies'])) for r in batch)
        best = max((r for r in batch if int(float(r['bodies'])) == top),
                   key=lambda r: float(r['body_steps_per_s']))
        lines.append(f'- **Batch:** {_f(best["body_steps_per_s"])} body-steps/s at N = '
                     f'{best["bodies"]}, the largest measured ({best["method"]}.'
                     f'{best["path"]}()).')
    per = _rows(out, 'perstep.csv')
    if per:
        lines.append('- **Per step and per sample:** ' + '; '.join(
            f'{r["what"]} ({r["method"]}) {_f(r["us_per_unit"])} µs a {r["unit"]}'
            for r in per) + '.')
    comp = _rows(out, 'compile.csv')
    if comp:
        lines.append('- **Kernels:** ' + ', '.join(f'{r["phase"]} {_f(r["total_s"])} s'
                                                   for r in comp) + '.')
    eh = _rows(out, 'exact_horizon.csv')
    if eh:
        lines.append('- **exact against the 40-digit reference:** ' + '; '.join(
            f'at t = {_f(t)} s ≤ {_f(max(float(r["attitude_error"]) for r in eh if r["t"] == t))}'
            f' rad' for t in dict.fromkeys(r['t'] for r in eh)) + '.')
    return lines or _missing('batch.csv, perstep.csv, compile.csv, exact_horizon.csv')


def live_section(out):
    lines = []
    live = _json(out, 'live.json')
    if live:
        s, r, v = live.get('simulator', {}), live.get('recorder', {}), live.get('viewer', {})
        if s.get('status') == 'ok':
            lines.append(f'- **Live simulator:** {_f(s["real_time_factor"])}× real time as '
                         f'fast as possible, {_f(100 * s["cpu_share_at_real_time"], ".2g")} % '
                         f'of a core at real time, first message {_f(s["first_message_s"])} s'
                         f', RSS {_f(s["rss_mb"])} MB.')
        if r.get('status') == 'ok':
            lines.append(f'- **Recorder:** {_f(r["recorded_msgs_per_s"])} messages/s, '
                         f'{r["lost"]} lost.')
        if v.get('status') == 'ok':
            lines.append(f'- **Foxglove viewer** ({v["viewer_phase"]}): '
                         f'{_f(100 * v["viewer_cpu_share"], ".2g")} % of a core; simulator '
                         f'RTF {_f(v["simulator_rtf_alone"], ".4f")} alone, '
                         f'{_f(v["simulator_rtf_with_viewer"], ".4f")} with it.')
    soak = _json(out, 'soak.json')
    if soak:
        lines.append(f'- **Soak** (`{soak["command"]}`): {_f(soak["minutes"])} min; RSS '
                     'growth per hour ' + ', '.join(
                         f'{k} {_f(v)} MB' for k, v in soak['rss_growth_mb_per_hour'].items())
                     + f'; RTF {_span(soak["rtf_range"], ".4g")}; '
                     f'{soak["missed_deadlines"]} missed deadlines; '
                     f'{soak["attitude_recorded"]} attitude samples, {soak["attitude_lost"]} '
                     'lost.')
    flood = _json(out, 'flood.json')
    if flood:
        lines.append(f'- **Flood** (`{flood["command"]}`): RTF {_span(flood["rtf_during"], ".4g")}'
                     f'; {flood["samples_published"]} samples published of '
                     f'{flood["samples_due"]} due; rejected ' + ', '.join(
                         f'{k} {n}' for k, n in flood['rejected'].items())
                     + f'; RSS {_f(flood["rss_mb_before"])} → {_f(flood["rss_mb_after"])} MB;'
                     f' zero torque within {_f(flood["zero_torque_reported_within_s"])} s.')
    rec = _json(out, 'recovery.json')
    if rec:
        lines.append(f'- **Crashed peers** (`{rec["command"]}`): controller killed → zero '
                     f'torque after {_f(rec["controller_killed_to_zero_torque_reported_s"])} s,'
                     f' restarted → control after {_f(rec["controller_restarted_to_control_s"])}'
                     f' s; simulator killed → zero command after '
                     f'{_f(rec["simulator_killed_to_zero_command_s"])} s, restarted → control '
                     f'after {_f(rec["simulator_restarted_to_control_s"])} s.')
    fleet = _json(out, 'fleet.json')
    if fleet:
        lines.append(f'- **Spacecraft per simulator process** (`{fleet["command"]}`; '
                     f'{fleet["observed"]}, {_f(fleet["rate_hz"])} Hz): ' + '; '.join(
                         f'N = {r["spacecraft"]}: {_f(r["cpu_percent_of_one_core"])} % of a '
                         f'core, RTF {_f(r["achieved_real_time_factor"], ".4g")}, '
                         f'{r["missed_deadlines"]} missed deadlines' for r in fleet['rows'])
                     + '.')
    step = _json(out, 'lockstep.json')
    if step:
        fast = [r['as_fast_as_possible'] for r in step['rows']]
        lines.append(f'- **Lockstep** (`{step["command"]}`): ' + '; '.join(
            f'{_f(r["control_rate_hz"], "g")} Hz control: round trip '
            f'{_f(f["round_trip_wall_us"] / 1000)} ms wall, simulator CPU '
            f'{_runs_figure(f, "sim_cpu_per_period_us")} µs per exchange '
            f'({_runs_figure(f, "sim_thread_cpu_per_period_us")} µs of it in its own '
            'thread) as fast as possible; '
            f'{_f(r["real_time"]["achieved_rate_hz"], ".4g")} exchanges/s at real time'
            for r, f in zip(step['rows'], fast)) + '.' + (
            f' Each figure is the median of {len(fast[0]["runs"])} runs (min-max in '
            'brackets).' if 'runs' in fast[0] else '') + (
            f' Load average {_f(step["load_average"][0])} before, '
            f'{_f(step["load_average"][1])} after, on {step["cpus"]} CPUs.'
            if 'load_average' in step else ''))
    floor = _json(out, 'lockstep_floor.json')
    if floor:
        lines.append(f'- **Lockstep floor** (`{floor["command"]}`): a bare rclpy node that '
                     'publishes the one odometry message the lockstep controller answers and '
                     'takes its command, nothing else, per exchange: ' + '; '.join(
                         f'{r["publication_mode"].lower()} publication, command as '
                         f'{r["command_taken_as"]}{_floor_options(r)}: '
                         f'{_f(r["cpu_per_exchange_us"])} µs CPU '
                         f'({_f(r["thread_cpu_per_exchange_us"])} µs in its own thread), '
                         f'{_f(r["wall_per_exchange_us"] / 1000)} ms wall'
                         for r in floor['rows']) + ' (medians of '
                     f'{len(floor["rows"][0]["cpu_per_exchange_us_runs"])} runs).')
    return lines or _missing('live.json, soak.json, flood.json, recovery.json')


def _floor_options(row) -> str:
    """A lockstep floor row's transports and loop, when it says (older files do not)."""
    if 'loop' not in row:
        return ''
    return (f', {"shared memory only" if row["transport"] == "shm" else "default transports"}, '
            f'{"wait set" if row["loop"] == "waitset" else "events executor"}')


def _runs_figure(row, key) -> str:
    """A lockstep figure: its value, with the runs' min-max when it was repeated."""
    values = [r.get(key) for r in row.get('runs', [row])]
    if None in values:
        return 'not recorded'
    if len(values) == 1:
        return _f(values[0])
    return f'{_f(row[key])} ({_f(min(values))}-{_f(max(values))})'


SECTIONS = (('Speed against accuracy', targets_section),
            ('Against Basilisk on the gravity-gradient scenes', basilisk_section),
            ('auto on generated scenes', generated_section),
            ('What a user\'s run adds', sampling_section),
            ('Throughput, per-step cost, kernels, long horizons', machine_section),
            ('Live nodes and standalone tools', live_section))


def render(out) -> str:
    head = ''
    md = os.path.join(out, 'targets.md')
    if os.path.exists(md):
        with open(md, encoding='utf-8') as f:
            head = f.readline().strip()
    lines = ['<!-- written by `python -m rigid_body_sim.bench.report` from the files beside '
             'it: do not edit -->', '', head or 'Machine: not recorded (no targets.md).', '']
    for title, section in SECTIONS:
        lines += [f'### {title}', ''] + section(out) + ['']
    return '\n'.join(lines)


def write(out) -> str:
    path = os.path.join(out, NAME)
    with open(path, 'w', encoding='utf-8') as f:
        f.write(render(out))
    return path


def main(argv=None):
    import argparse
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('dir', nargs='?', default='docs/bench', help='a run\'s directory')
    args = parser.parse_args(argv)
    print(write(args.dir))
    return 0


if __name__ == '__main__':
    sys.exit(main())
