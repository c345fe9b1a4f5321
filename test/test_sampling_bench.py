"""bench/sampling.py's measurement: the CLI's runs alternated with the in-process ones, and
the page faults said of the least run (the machine's load and malloc's reuse of pages, not
the code, moved the rows). Scripted clocks: nothing here is timed."""
import itertools
from types import SimpleNamespace

import pytest

from rigid_body_sim.bench import sampling

pytestmark = pytest.mark.fast


@pytest.mark.parametrize('repeats', [1, 3, 5])
def test_cli_runs_alternate_with_in_process_runs(monkeypatch, repeats):
    """Each CLI run follows in-process runs (two, the second warm), so both minima come
    from one stretch of load, and both are minima over as many turns (a CLI's least of 3
    against in-process's least of 7 read noise as overhead); the least of each is kept."""
    calls, inproc, cli = [], iter([5e-3, 3e-3, 4e-3, 6e-3, 2.5e-3]), iter([9, 7, 8, 6, 8.5])

    def simulate_cpu(scene, duration, rate, overrides, n, counts=None):
        calls.append(('in', n))
        return next(inproc)

    def cli_cpu(target, duration, n):
        calls.append(('cli', n))
        return (next(cli) * 1e-3, 0.01, 0, 0)
    monkeypatch.setattr(sampling, '_simulate_cpu', simulate_cpu)
    monkeypatch.setattr(sampling, '_cli_cpu', cli_cpu)
    best_in, (best_cli, output, loaded, faults) = sampling._cli_and_inprocess(
        'slew', 'slew', 1.0, 50.0, repeats)
    assert calls == [('in', 2), ('cli', 1)] * repeats
    assert best_in == min([5e-3, 3e-3, 4e-3, 6e-3, 2.5e-3][:repeats])
    assert best_cli == min([9, 7, 8, 6, 8.5][:repeats]) * 1e-3 and output == 0.01


def test_the_faults_said_are_the_least_runs_and_the_most_of_any(monkeypatch):
    """counts['faults'] = [faults in the clock of the least-CPU run, most of any run]: the
    least run here (2 ms) is one that faulted 100 times, the most is 613."""
    spent = iter([3e-3, 2e-3, 4e-3])          # CPU of each run: the second is the least
    faults = iter([0, 613, 613, 713, 713, 713])  # before/after each run: 613, 100, 0
    clock = itertools.count()

    def fake_cpu():                            # 0 at each run's start, its CPU at the end
        return 0.0 if next(clock) % 2 == 0 else next(spent)
    engine = SimpleNamespace(selection_cpu=0.0, total_evaluations=12)
    result = SimpleNamespace(selection_cpu_seconds=0.0, sample_count=30001)
    monkeypatch.setattr(sampling, 'cpu', fake_cpu)
    monkeypatch.setattr('rigid_body_sim.offline._faults', lambda: next(faults))
    monkeypatch.setattr('rigid_body_sim.offline.engine_for', lambda scene, **k: engine)
    monkeypatch.setattr('rigid_body_sim.offline.simulate', lambda scene, **k: result)
    counts = {}
    best = sampling._simulate_cpu('slew', 300.0, 100.0, {}, 3, counts)
    assert best == 2e-3
    assert counts == {'evaluations': 12, 'samples': 30001, 'faults': [100, 613],
                      'engine': engine}


def test_the_two_rates_alternate_and_each_keeps_its_least_run(monkeypatch):
    """A generated scene's 1/s and 100/s runs alternate, so that both minima come from one
    stretch of the machine's load; each rate keeps its least run and that run's faults."""
    calls = []
    spent = {1.0: iter([5e-3, 3e-3, 4e-3]), 100.0: iter([9e-3, 8e-3, 9.5e-3])}
    faults = {1.0: iter([0, 7, 1]), 100.0: iter([600, 0, 900])}

    def simulate_cpu(scene, duration, rate, overrides, n, counts=None):
        calls.append((rate, n))
        counts.update(samples=int(rate) * 300, faults=[next(faults[rate])] * 2)
        return next(spent[rate])
    monkeypatch.setattr(sampling, '_simulate_cpu', simulate_cpu)
    a, b = {}, {}
    assert sampling._alternated('slew', 300.0, {}, 3, a, b) == (3e-3, 8e-3)
    assert calls == [(1.0, 1), (100.0, 1)] * 3
    assert a['faults'] == [7, 7] and b['faults'] == [0, 900]
    assert a['samples'] == 300 and b['samples'] == 30000


def _floor(reach):
    return {'reach': reach}


@pytest.mark.parametrize('reaches,verdict,measured', [
    ((1.1, 3.1, 1.2), 'PASS', 1.4),   # the exact free body past reach: not judged
    ((1.1, 1.2, 1.2), 'MISS', 2.9),   # every scene in reach: the worst of all
    ((2.0, 3.1, 1.9), 'n/a', 2.9),    # none in reach: the worst of all, no verdict
])
def test_the_generated_sampling_row_judges_scenes_whose_floor_leaves_it_in_reach(
        reaches, verdict, measured):
    """1.5 is judged on scenes whose ratio at the samples' floor is at most 1.25 (samples
    at twice their floor would then read 1.5); the note keeps the spread of all scenes."""
    assert sampling.reachable() == pytest.approx(1.25)
    ratios = [1.3, 2.9, 1.4]
    floors = [(f'gen-{i}', _floor(r)) for i, r in enumerate(reaches)]
    row = sampling._reachable_row(ratios, floors, 'runs cut to 300 s')
    assert row['verdict'] == verdict and row['measured'] == measured
    assert 'over all: p10' in row['note'] and 'worst 2.9 over 3' in row['note']
    assert '(gen-1) reading' in row['note']
