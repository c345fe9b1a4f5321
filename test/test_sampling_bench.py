"""bench/sampling.py's measurement: the CLI's runs alternated with the in-process ones, and
the page faults said of the least run (the machine's load and malloc's reuse of pages, not
the code, moved the rows). Scripted clocks: nothing here is timed."""
import itertools
from types import SimpleNamespace

import pytest

from rigid_body_sim.bench import sampling

pytestmark = pytest.mark.fast


@pytest.mark.parametrize('repeats,cli_repeats', [(3, 3), (5, 2), (2, 4)])
def test_cli_runs_alternate_with_in_process_runs(monkeypatch, repeats, cli_repeats):
    """Each CLI run follows in-process runs (two, the second warm), so both minima come
    from one stretch of load; every run of each kind is made and the least is kept."""
    calls, inproc, cli = [], iter([5e-3, 3e-3, 4e-3, 6e-3, 2.5e-3]), iter([9, 7, 8, 6])

    def simulate_cpu(scene, duration, rate, overrides, n, counts=None):
        calls.append(('in', n))
        return next(inproc)

    def cli_cpu(target, duration, n):
        calls.append(('cli', n))
        return (next(cli) * 1e-3, 0.01, 0, 0)
    monkeypatch.setattr(sampling, '_simulate_cpu', simulate_cpu)
    monkeypatch.setattr(sampling, '_cli_cpu', cli_cpu)
    best_in, (best_cli, output, loaded, faults) = sampling._cli_and_inprocess(
        'slew', 'slew', 1.0, 50.0, repeats, cli_repeats)
    rounds = max(repeats, cli_repeats)
    expected = [c for i in range(rounds)
                for c in [('in', 2)] + ([('cli', 1)] if i < cli_repeats else [])]
    assert calls == expected
    assert best_in == min([5e-3, 3e-3, 4e-3, 6e-3, 2.5e-3][:rounds])
    assert best_cli == min([9, 7, 8, 6][:cli_repeats]) * 1e-3 and output == 0.01


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
