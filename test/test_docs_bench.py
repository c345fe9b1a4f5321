"""The benchmarks page states no figure by hand: its figures are the run's files, rendered.

docs/benchmarks.md includes docs/bench/summary.md and targets.md, which the bench writes
(``bench.report``). A number in the page's own prose must be one of the run files'
numbers (at the precision the page states it); commands and code are not figures.
"""
import csv
import json
import math
import os
import re

import pytest

from rigid_body_sim.bench import report

pytestmark = pytest.mark.fast
DOCS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'docs')
RUN = os.path.join(DOCS, 'bench')
PAGE = os.path.join(DOCS, 'benchmarks.md')
INCLUDED = ('bench/summary.md', 'bench/targets.md')
NUMBER = re.compile(r'(?<![\w.])[-−]?\d[\d,]*(?:\.\d+)?(?:[eE][-−+]?\d+)?'
                    r'(?:\s*·\s*10[⁰¹²³⁴⁵⁶⁷⁸⁹⁻]+)?')
SUPERSCRIPT = str.maketrans('⁰¹²³⁴⁵⁶⁷⁸⁹⁻', '0123456789-')


def prose(text):
    """The page without its code blocks, inline code, comments, link targets and includes."""
    text = re.sub(r'```.*?```', ' ', text, flags=re.S)
    text = re.sub(r'<!--.*?-->', ' ', text, flags=re.S)
    text = re.sub(r'`[^`]*`', ' ', text)
    text = re.sub(r'\]\([^)]*\)', ']', text)           # link targets (file names, anchors)
    return re.sub(r'!\[[^\]]*\]', ' ', text)            # image alt texts


def value(token):
    t = token.replace('−', '-').replace(',', '')
    if '·' in t:
        mantissa, power = t.split('·')
        return float(mantissa) * 10.0 ** int(power.strip()[2:].translate(SUPERSCRIPT))
    return float(t)


def stated(text):
    """(token, value, significant digits) of every number the prose states."""
    out = []
    for m in NUMBER.finditer(prose(text)):
        token = m.group(0).strip()
        digits = len(re.sub(r'[^\d]', '', token.split('e')[0].split('E')[0].split('·')[0])
                     .lstrip('0')) or 1
        out.append((token, value(token), digits))
    return out


def run_numbers(folder=RUN):
    """Every number in the run's CSV, JSON and Markdown files."""
    found = set()

    def add(x):
        try:
            v = float(x)
        except (TypeError, ValueError):
            return
        if math.isfinite(v):
            found.add(v)

    for name in os.listdir(folder):
        path = os.path.join(folder, name)
        if name.endswith('.csv'):
            with open(path, newline='', encoding='utf-8') as f:
                for row in csv.DictReader(f):
                    for v in row.values():
                        add(v)
        elif name.endswith('.json'):
            with open(path, encoding='utf-8') as f:
                stack = [json.load(f)]
            while stack:
                x = stack.pop()
                if isinstance(x, dict):
                    stack.extend(x.values())
                elif isinstance(x, list):
                    stack.extend(x)
                else:
                    add(x)
        elif name.endswith('.md'):
            with open(path, encoding='utf-8') as f:
                for _, v, _ in stated(f.read()):
                    found.add(v)
    return found


def in_run(v, digits, numbers):
    """v is a run number rounded to ``digits`` significant digits (or that as a percent)."""
    def rounds_to(x):
        if x == 0 or v == 0:
            return x == v
        return float(f'{x:.{digits - 1}e}') == v
    return any(rounds_to(x) or rounds_to(100 * x) for x in numbers)


def test_the_page_includes_the_run_files_and_they_exist():
    with open(PAGE, encoding='utf-8') as f:
        text = f.read()
    for name in INCLUDED:
        assert f'```{{include}} {name}\n```' in text, name
        assert os.path.getsize(os.path.join(DOCS, name)) > 0, name


def test_the_page_states_no_number_that_is_not_in_the_run_files():
    with open(PAGE, encoding='utf-8') as f:
        text = f.read()
    numbers = run_numbers()
    typed = [token for token, v, digits in stated(text) if not in_run(v, digits, numbers)]
    assert not typed, f'benchmarks.md states figures not in docs/bench: {typed}'


def test_a_hand_typed_figure_fails_the_check():
    """The check itself: made-up figures are caught (the old page's 82,000 publishes a
    second among them), a run file's figure and code are not. (A 4-digit figure can
    match one of the run files' thousands of numbers by chance: the old page's 141.9
    runs/s matched a CPU ratio of 1.41857, as a percent; the third is given to 6.)"""
    numbers = run_numbers()
    made_up = 'The slew ran 4,417× faster, 82,000 times a second, 141.937 runs/s.'
    assert [t for t, v, d in stated(made_up) if not in_run(v, d, numbers)] == [
        '4,417', '82,000', '141.937']
    assert stated('`--minutes 60` and ```sh\nrun 12\n```') == []


def test_the_summary_is_what_the_run_files_render():
    """summary.md is rendered from its neighbours, not edited: rendering again gives it."""
    with open(os.path.join(RUN, report.NAME), encoding='utf-8') as f:
        assert f.read() == report.render(RUN)


def test_the_fleet_and_lockstep_tools_files_are_rendered(tmp_path):
    """tools.fleet and tools.lockstep write fleet.json and lockstep.json (``--out``); the
    page renders what they hold, and says nothing of a file that is not there."""
    from rigid_body_sim.bench.common import report as write_json
    assert 'Spacecraft per simulator' not in report.render(str(tmp_path))
    write_json({'command': 'python -m rigid_body_sim.tools.fleet --counts 1 100',
                'rate_hz': 10.0, 'observed': '9 topics and /tf each, all subscribed',
                'seconds': 10.0,
                'rows': [{'spacecraft': 100, 'cpu_percent_of_one_core': 35.5,
                          'achieved_real_time_factor': 0.991, 'missed_deadlines': 31}]},
               str(tmp_path), 'fleet.json')
    write_json({'command': 'python -m rigid_body_sim.tools.lockstep',
                'rows': [{'control_rate_hz': 1000.0,
                          'as_fast_as_possible': {'round_trip_wall_us': 5900,
                                                  'sim_cpu_per_period_us': 788},
                          'real_time': {'achieved_rate_hz': 318.2}}]},
               str(tmp_path), 'lockstep.json')
    text = report.render(str(tmp_path))
    assert 'N = 100: 35.5 % of a core, RTF 0.991, 31 missed deadlines' in text
    assert '1000 Hz control: round trip 5.9 ms wall' in text
    assert '788 µs per exchange' in text and '318.2 exchanges/s at real time' in text


def test_repeated_lockstep_runs_render_their_median_and_spread(tmp_path):
    """tools.lockstep --runs N: each figure is the runs' median, with their min-max, and
    the simulator's own thread's share of its CPU beside the process's."""
    from rigid_body_sim.bench.common import report as write_json
    runs = [{'round_trip_wall_us': w, 'sim_cpu_per_period_us': c,
             'sim_thread_cpu_per_period_us': t}
            for w, c, t in ((700, 410, 250), (650, 380, 240), (900, 520, 300))]
    fast = {**runs[1], 'round_trip_wall_us': 700, 'sim_cpu_per_period_us': 410,
            'sim_thread_cpu_per_period_us': 250, 'runs': runs}
    write_json({'command': 'python -m rigid_body_sim.tools.lockstep --runs 3',
                'rows': [{'control_rate_hz': 100.0, 'as_fast_as_possible': fast,
                          'real_time': {'achieved_rate_hz': 99.9}}]},
               str(tmp_path), 'lockstep.json')
    text = report.render(str(tmp_path))
    assert '410 (380-520) µs per exchange (250 (240-300) µs of it in its own thread)' in text
    assert 'median of 3 runs' in text and 'Load average' not in text
    # the machine's load beside the figures, when the run recorded it
    write_json({'command': 'python -m rigid_body_sim.tools.lockstep --runs 3',
                'rows': [{'control_rate_hz': 100.0, 'as_fast_as_possible': fast,
                          'real_time': {'achieved_rate_hz': 99.9}}],
                'load_average': [5.39, 7.0], 'cpus': 2}, str(tmp_path), 'lockstep.json')
    assert 'Load average 5.39 before, 7 after, on 2 CPUs.' in report.render(str(tmp_path))


def test_the_lockstep_floor_file_is_rendered(tmp_path):
    """tools.lockstep_floor writes lockstep_floor.json: the page gives each configuration's
    median CPU, its thread's part and the wall time, and nothing without the file."""
    from rigid_body_sim.bench.common import report as write_json
    assert 'Lockstep floor' not in report.render(str(tmp_path))
    row = {'publication_mode': 'SYNCHRONOUS', 'command_taken_as': 'bytes', 'exchanges': 20,
           'cpu_per_exchange_us': 171.5, 'cpu_per_exchange_us_runs': [160.0, 171.5, 190.0],
           'thread_cpu_per_exchange_us': 95.25, 'wall_per_exchange_us': 812.0}
    write_json({'command': 'python -m rigid_body_sim.tools.lockstep_floor', 'rows': [row]},
               str(tmp_path), 'lockstep_floor.json')
    text = report.render(str(tmp_path))
    assert ('synchronous publication, command as bytes: 172 µs CPU (95.2 µs in its own '
            'thread), 0.812 ms wall (medians of 3 runs)') in text, text
    # the transports and the loop, in a file that gives them
    row.update(transport='shm', loop='waitset')
    write_json({'command': 'python -m rigid_body_sim.tools.lockstep_floor', 'rows': [row]},
               str(tmp_path), 'lockstep_floor.json')
    assert ('synchronous publication, command as bytes, shared memory only, wait set: 172 µs '
            'CPU') in report.render(str(tmp_path))


def test_the_sampling_section_re_run_alone_replaces_its_own_rows(tmp_path, monkeypatch):
    """``bench.sampling --update DIR``: the section's rows of targets.csv and targets.md are
    replaced where they stood, each note saying it was re-run alone; every other row and
    line stays the full run's, and the summary is rendered from the files again."""
    import shutil
    from rigid_body_sim.bench import sampling, targets
    folder = tmp_path / 'bench'
    shutil.copytree(RUN, folder)
    rows = [{'what': 'sampling overhead', 'scene': 'slew', 'duration': 15.0, 'rate_a': 1.0,
             'cpu_a_s': 0.001, 'rate_b': 100.0, 'cpu_b_s': 0.00123, 'ratio': 1.23, 'note': ''}]
    new = [targets.simple('sampling overhead: 100 samples/s / 1 sample/s (CPU)', 1.23, 1.5,
                          True, '15 s, samples kept in-process', scene='slew'),
           targets.simple('CLI overhead: rigid-body-sim run cpu_seconds / in-process', 0.97,
                          1.2, True, '15 s', scene='slew')]
    monkeypatch.setattr(sampling, 'run', lambda quick, log=print: (rows, [dict(r) for r in new]))
    sampling.update(str(folder), log=lambda *a: None)

    def lines(name):
        with open(os.path.join(name), encoding='utf-8') as f:
            return f.read().splitlines()
    # the section's rows: the floor's too (bench.sampling_floor), which this run has not
    mine = ('| sampling overhead', '| CLI overhead', "| sampling: samples' CPU",
            'sampling overhead', 'CLI overhead', "sampling: samples' CPU")
    before, after = lines(os.path.join(RUN, 'targets.md')), lines(folder / 'targets.md')
    assert [x for x in before if not x.startswith(mine)] == \
        [x for x in after if not x.startswith(mine)]
    ours = [x for x in after if x.startswith(mine)]
    assert len(ours) == 2 and all('re-run alone' in x for x in ours)
    assert ours[0].startswith('| sampling overhead') and '| 1.23 |' in ours[0]
    before, after = lines(os.path.join(RUN, 'targets.csv')), lines(folder / 'targets.csv')
    assert [x for x in before if not x.startswith(mine)] == \
        [x for x in after if not x.startswith(mine)]
    assert after.index(next(x for x in after if x.startswith(mine))) == \
        before.index(next(x for x in before if x.startswith(mine)))
    assert lines(folder / 'summary.md') == report.render(str(folder)).splitlines()
    assert 'slew 1.23×' in '\n'.join(lines(folder / 'summary.md'))


def test_the_perstep_section_re_run_alone_replaces_its_own_rows(tmp_path, monkeypatch):
    """``bench.perstep --update DIR``: its block of targets (per step, per sample and the
    MuJoCo ratios, one row per dynamics when MuJoCo is installed) replaces the old block
    where it stood; every other row stays the full run's."""
    import shutil
    from rigid_body_sim.bench import perstep
    folder = tmp_path / 'bench'
    shutil.copytree(RUN, folder)
    fig = {'free': 0.1, 'damped': 0.25, 'mujoco_euler': 1.5, 'offline_exact': 0.2,
           'offline_dissipative': 0.3}
    monkeypatch.setattr(perstep, 'run', lambda quick, log=print: ([], dict(fig)))
    perstep.update(str(folder), log=lambda *a: None)
    mine = ('| splitting2 µs per step', '| offline run µs per', '| MuJoCo Euler step')

    def lines(name):
        with open(name, encoding='utf-8') as f:
            return f.read().splitlines()
    before, after = lines(os.path.join(RUN, 'targets.md')), lines(folder / 'targets.md')
    assert [x for x in before if not x.startswith(mine)] == \
        [x for x in after if not x.startswith(mine)]
    ours = [i for i, x in enumerate(after) if x.startswith(mine)]
    assert ours == list(range(ours[0], ours[0] + 6)), 'one block'
    assert ours[0] == next(i for i, x in enumerate(before) if x.startswith(mine))
    damped = after[ours[-1]]
    assert damped.startswith('| MuJoCo Euler step / splitting2 step (damped)') and \
        '| 6 | 4 | PASS' in damped, damped


def test_the_generated_suite_read_back_from_its_csv_gives_its_targets():
    """``bench.generated --update DIR --from-csv FILE`` judges the rows a run wrote: read
    back from the full run's generated.csv, they give that run's target rows."""
    from rigid_body_sim.bench import generated
    rows = generated.read_rows(os.path.join(RUN, 'generated.csv'))
    t_rows, _ = generated.targets_for(rows)
    with open(os.path.join(RUN, 'targets.csv'), newline='', encoding='utf-8') as f:
        written = [r for r in csv.DictReader(f) if r['target'].startswith('generated:')]
    assert [r['target'] for r in t_rows] == [r['target'] for r in written]
    for ours, theirs in zip(t_rows, written):
        assert float(theirs['measured']) == pytest.approx(ours['measured'], rel=1e-5)
        assert theirs['verdict'] == ours['verdict']
