"""Live figures, measured by scripts other modules own (run as subprocesses).

* simulator: ``rigid_body_sim.tools.live_simulator`` (real-time factor as fast as possible
  at 1 kHz physics / 100 Hz publishing, CPU share at real time), each run beside one of
  ``rigid_body_sim.tools.live_floor`` (what a bare rclpy publisher of the same topics
  reaches: the middleware's floor under the same load);
* recorder: ``rigid_body_sim.tools.recorder_load`` (messages/s through a real recorder, loss);
* viewer: ``rigid_body_sim.tools.viewer`` (the Foxglove viewer's CPU beside a 50 Hz simulator).
Absent modules or failures are reported as 'not measured (<reason>)', never as errors.
"""
import importlib.util
import json
import math
import re
import subprocess
import sys

from . import targets

RECORDER_RATE_HZ = 3400  # per topic; 3 topics → 10,200 messages/s offered


def _module_missing(name):
    try:
        return importlib.util.find_spec(name) is None
    except (ImportError, ValueError):
        return True


def _not_measured(mod, quick):
    """The result dict when a live measurement can't run here, else None."""
    if quick:
        return {'status': 'not measured (skipped in --quick: starts ROS processes; '
                          'run without --quick)'}
    if _module_missing(mod):
        return {'status': f'not measured ({mod} not found)'}
    return None


def _last_json(out, key=None) -> dict:
    """The last line of ``out`` that is a JSON object (holding ``key`` if given), or {}."""
    for line in reversed(out.splitlines()):
        try:
            data = json.loads(line)
        except ValueError:
            continue
        if isinstance(data, dict) and (key is None or key in data):
            return data
    return {}


RUNS = 5  # the live node's figures are the worst of five runs (issue 29: "minimum of five")


def simulator(quick, log=print, runs=RUNS):
    """The live node's figures: the worst of ``runs`` runs (the least real-time factor, the
    largest CPU share at real time and first-message time), each run's beside them."""
    mod = 'rigid_body_sim.tools.live_simulator'
    skipped = _not_measured(mod, quick)
    if skipped:
        return skipped
    each, floors = [], []
    for _ in range(runs):  # each beside a floor run, under the same load
        each.append(_simulator_once(mod))
        floors.append(_floor_once())
    ok = [r for r in each if r['status'] == 'ok']
    if not ok:
        return each[-1]
    out = dict(ok[-1])
    floors = [f for f in floors if isinstance(f, (int, float))]
    if floors:
        out['floor_real_time_factor_runs'] = floors
    for key, worst in (('real_time_factor', min), ('cpu_share_at_real_time', max),
                       ('first_message_s', max)):
        values = [r[key] for r in ok if isinstance(r.get(key), (int, float))]
        if values:
            out[key] = worst(values)
            out[f'{key}_runs'] = values
    if len(ok) < len(each):
        out['status'] = f'{len(each) - len(ok)} of {len(each)} runs failed: ' + \
            '; '.join(r['status'] for r in each if r['status'] != 'ok')
    return out


def _floor_once():
    """One run of ``tools.live_floor``: the real-time factor a bare rclpy publisher of the
    same topics reaches with the same subscriber (None if it failed)."""
    try:
        proc = subprocess.run([sys.executable, '-m', 'rigid_body_sim.tools.live_floor',
                               '--runs', '1'], capture_output=True, text=True, timeout=300)
    except subprocess.TimeoutExpired:
        return None
    runs = _last_json(proc.stdout, 'floor_real_time_factor_runs').get(
        'floor_real_time_factor_runs')
    return runs[0] if runs else None


def _simulator_once(mod):
    try:
        # 1 kHz physics as the target states: splitting2 steps every 1 ms (auto would pick the
        # exact flow and evaluate it only at publish instants)
        proc = subprocess.run([sys.executable, '-m', mod, '--integrator', 'splitting2',
                               '--subscribe'],
                              capture_output=True, text=True, timeout=600)
    except subprocess.TimeoutExpired:
        return {'status': f'not measured ({mod} timed out after 600 s)'}
    out = proc.stdout.strip()
    result = {'status': 'ok' if proc.returncode == 0 else f'exit code {proc.returncode}',
              'output': out[-2000:]}
    result.update(_last_json(out))
    # text form: "real_time_factor 0 (...): achieved RTF 37.45, CPU 75.4 % of one core" and
    # "real_time_factor 1: achieved RTF 1.00, CPU 13.7 % of one core"
    fast = re.search(r'real_time_factor 0\b[^\n]*?achieved RTF ([\d.]+)', out)
    real = re.search(r'real_time_factor 1\b[^\n]*?CPU ([\d.]+) % of one core', out)
    if fast and 'real_time_factor' not in result:
        result['real_time_factor'] = float(fast.group(1))
    if real and 'cpu_share_at_real_time' not in result:
        result['cpu_share_at_real_time'] = float(real.group(1)) / 100.0
    if proc.returncode != 0 and not out:
        result['status'] = f'not measured ({mod} failed: {proc.stderr.strip()[-300:]})'
    return result


def viewer(quick, log=print):
    """The Foxglove viewer beside a real-time simulator at 50 Hz (``tools.viewer``): its CPU
    share of a core with one client on every channel, the simulator's RTF with and without."""
    mod = 'rigid_body_sim.tools.viewer'
    skipped = _not_measured(mod, quick)
    if skipped:
        return skipped
    try:
        proc = subprocess.run([sys.executable, '-m', mod, '--seconds', '8'],
                              capture_output=True, text=True, timeout=300)
    except subprocess.TimeoutExpired:
        return {'status': f'not measured ({mod} timed out after 300 s)'}
    result = {'status': 'ok' if proc.returncode == 0 else f'exit code {proc.returncode}'}
    summary = _last_json(proc.stdout, 'viewer_cpu_share')
    result.update(summary)
    if not summary:
        result['status'] = f'not measured ({mod}: {proc.stderr.strip()[-300:]})'
    return result


def recorder(quick, log=print):
    mod = 'rigid_body_sim.tools.recorder_load'
    skipped = _not_measured(mod, quick)
    if skipped:
        return skipped
    cmd = [sys.executable, '-m', mod, '--rate', str(RECORDER_RATE_HZ), '--duration', '10']
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    except subprocess.TimeoutExpired:
        return {'status': 'not measured (loadtest timed out after 300 s)'}
    out = proc.stdout
    m_pub = re.search(r'published (\d+) messages in ([\d.]+) s \((\d+) msg/s', out)
    m_rec = re.search(r'recorded (\d+) \((\d+) msg/s\), lost (-?\d+)', out)
    if not (m_pub and m_rec):
        return {'status': f'not measured (loadtest output not understood; exit {proc.returncode}: '
                          f'{(proc.stderr or out).strip()[-300:]})'}
    return {'status': 'ok', 'command': ' '.join(cmd[1:]),
            'offered_msgs_per_s': RECORDER_RATE_HZ * 3,
            'published': int(m_pub.group(1)), 'published_msgs_per_s': int(m_pub.group(3)),
            'recorded': int(m_rec.group(1)), 'recorded_msgs_per_s': int(m_rec.group(2)),
            'lost': int(m_rec.group(3))}


def targets_from(live_res):
    """The targets rows for the three live measurements (not measured: verdict None)."""
    rows = []
    sim = live_res['simulator']
    for key, req, better in (('real_time_factor', 100.0, 'ge'),
                             ('cpu_share_at_real_time', 0.05, 'le'),
                             ('first_message_s', 2.0, 'le')):
        val = sim.get(key)
        if isinstance(val, (int, float)):
            ok = val >= req if better == 'ge' else val <= req
            runs = sim.get(f'{key}_runs')
            note = f'worst of {len(runs)} runs: ' + ', '.join(f'{v:.3g}' for v in runs) \
                if runs else ''
            if key == 'real_time_factor' and sim.get('subscriber'):  # what it delivered to
                note += f'; every state topic taken by {sim["subscriber"]}'
            floors = sim.get('floor_real_time_factor_runs')
            if key == 'real_time_factor' and floors:
                note += ('; a bare rclpy publisher of the same topics with the same QoS and '
                         'subscriber (tools.live_floor), beside each run: '
                         + ', '.join(f'{v:.3g}' for v in floors))
            rows.append(targets.simple(f'live simulator {key}', float(val), req, ok, note))
        else:
            rows.append(targets.simple(f'live simulator {key}', math.nan, req, None,
                                       sim['status']))
    rss = sim.get('rss_mb')
    rows.append(targets.simple('live simulator memory (RSS of a warm node, MB)',
                               float(rss) if isinstance(rss, (int, float)) else math.nan,
                               math.nan, None, 'reported, no target'))
    rec = live_res['recorder']
    if rec['status'] == 'ok':
        ok = rec['recorded_msgs_per_s'] >= 10_000 and rec['lost'] == 0
        rows.append(targets.simple(
            'recorder messages/s with zero loss', float(rec['recorded_msgs_per_s']), 1e4, ok,
            f'lost {rec["lost"]}; publisher achieved {rec["published_msgs_per_s"]} msg/s '
            f'of {rec["offered_msgs_per_s"]} offered'))
    else:
        rows.append(targets.simple('recorder messages/s with zero loss', math.nan, 1e4, None,
                                   rec['status']))
    view = live_res['viewer']
    if view['status'] == 'ok':
        rows.append(targets.simple(
            'live viewer CPU share of a core at 50 Hz', view['viewer_cpu_share'], 0.05,
            view['viewer_cpu_share'] <= 0.05, view['viewer_phase']))
        ratio = view['simulator_rtf_with_viewer'] / view['simulator_rtf_alone']
        rows.append(targets.simple(
            'live simulator RTF with the viewer / alone', ratio, 0.99, ratio >= 0.99,
            f'{view["simulator_rtf_with_viewer"]:.4f} / {view["simulator_rtf_alone"]:.4f}'))
    else:
        rows.append(targets.simple('live viewer CPU share of a core at 50 Hz', math.nan,
                                   0.05, None, view['status']))
    return rows


def update(folder, log=print):
    """Re-run this section into a full run's ``folder``: live.json and the section's target
    rows in targets.csv / targets.md (where they stood), then summary.md."""
    import os
    from . import report
    res = {'simulator': simulator(False, log), 'recorder': recorder(False, log),
           'viewer': viewer(False, log)}
    with open(os.path.join(folder, 'live.json'), 'w') as f:
        json.dump(res, f, indent=1)
    t_rows = targets_from(res)
    for r in t_rows:
        log(f'  {r["verdict"]:5s} {r["target"]}: {r["measured"]:.4g} (required '
            f'{r["required"]:g}) {r["note"]}')
    report.replace_targets(folder, tuple(r['target'] for r in t_rows), t_rows,
                           command='python -m rigid_body_sim.bench.live --update {out}',
                           after='live')
    return report.write(folder)


if __name__ == '__main__':
    import argparse
    parser = argparse.ArgumentParser(prog='python -m rigid_body_sim.bench.live',
                                     description=__doc__.splitlines()[0])
    parser.add_argument('--update', metavar='DIR', required=True,
                        help='re-run the section into a full run\'s DIR (e.g. docs/bench): '
                             'live.json, its rows of targets.csv/targets.md, the summary')
    print(update(parser.parse_args().update))
