"""scipy on the generated scenes (bench/generated_peers.py): the peer integrates the scene's
own physics, so a ratio compares the same thing."""
import math
from dataclasses import replace

import numpy as np
import pytest

from rigid_body_sim.bench import generated, generated_peers as gp, oracle
from rigid_body_sim.physics import rotation


def _first(kind, quick=True):
    """The scene of ``kind`` that turns the least among the first 40 (the cheapest)."""
    return min((s for s in (generated.draw(generated.SEED, i, quick) for i in range(40))
                if s.kind == kind), key=lambda s: s.rotation)


@pytest.mark.parametrize('kind', ['free', 'double_bracket', 'viscous'])
def test_the_peer_at_a_tight_tolerance_is_the_reference(kind):
    """At rtol 1e-12 scipy's DOP853 lands on the reference at every sample; a peer with
    the dissipation left out (the model mis-mapped) is off by far more."""
    scene = _first(kind)
    ref = oracle.reference(scene)
    result, _ = oracle.timed(scene.scene_file())
    times = result.samples['t']
    assert times[-1] == pytest.approx(scene.duration, abs=1e-9)
    assert len(times) == len(ref.attitude)
    _, q = gp.peer_run(scene, 'DOP853', 1e-12, times)
    err = float(np.max(rotation.angle_between(q, ref.attitude)))
    assert err < 1e-6, err
    if kind != 'free':
        _, q_free = gp.peer_run(replace(scene, kind='free'), 'DOP853', 1e-12, times)
        assert float(np.max(rotation.angle_between(q_free, ref.attitude))) > 100 * err


def test_a_peer_that_cannot_meet_the_budget_is_a_lower_bound():
    """With no rtol fine enough (a budget under the ladder's reach) the sweep returns no
    rtol and the CPU of its last run, which the row reports as a lower bound."""
    scene = _first('viscous')
    ref = oracle.reference(scene)
    times = oracle.timed(scene.scene_file())[0].samples['t']
    scene = replace(scene, budget=1e-16)  # past any scene's range: the sweep's own check
    rtol, c, err = gp.peer_sweep(scene, 'RK45', ref, times, cap=0.05)
    assert rtol is None and c > 0 and err > scene.budget


@pytest.mark.parametrize('kind', ['free', 'double_bracket', 'viscous'])
def test_mujoco_at_a_small_step_is_the_reference(kind):
    """MuJoCo's RK4, read at the run's samples (the last one off the step grid where the
    duration is not a multiple of the period), lands on the reference at a small step; with
    the damping torque left out it is off by far more. The free joint's rate and torque are
    in the body frame and its quaternion is (w, x, y, z): a mix-up of either fails here."""
    from rigid_body_sim.bench import generated_mujoco as gm
    scene = _first(kind)
    ref = oracle.reference(scene)
    times = oracle.timed(scene.scene_file())[0].samples['t']
    h = 0.02 / max(float(np.linalg.norm(scene.omega)), 1.0)
    _, q = gm.run(scene, h, 'RK4', times)
    assert len(q) == len(times)
    err = float(np.max(rotation.angle_between(q, ref.attitude)))
    assert err < 1e-5, err
    if kind != 'free':
        _, q_free = gm.run(replace(scene, kind='free'), h, 'RK4', times)
        assert float(np.max(rotation.angle_between(q_free, ref.attitude))) > 100 * err


def test_the_mujoco_sweep_halves_its_step_to_the_budget():
    """The sweep returns the first step meeting the budget, its error within it; a budget
    past its reach returns no step and the last run's CPU."""
    from rigid_body_sim.bench import generated_mujoco as gm
    scene = replace(_first('free'), budget=1e-4)
    ref = oracle.reference(scene)
    times = oracle.timed(scene.scene_file())[0].samples['t']
    h, c, err = gm.sweep(scene, 'RK4', ref, times, cap=5.0)
    assert h is not None and c > 0 and err + ref.error <= scene.budget
    h2, c2, err2 = gm.sweep(replace(scene, budget=1e-16), 'RK4', ref, times, cap=0.05)
    assert h2 is None and c2 > 0 and err2 > 1e-16


def _long(kind, rotation):
    """A cheap scene of ``kind`` stretched to ``rotation`` rad at 50 samples, and a
    reference the peer cannot meet (identity): one peer run costs far past a 20 ms cap."""
    scene = _first(kind)
    span = rotation / float(np.linalg.norm(scene.omega))
    times = np.linspace(0.0, span, 50)
    ref = oracle.Reference(np.tile([0.0, 0.0, 0.0, 1.0], (len(times), 1)), 0.0, 'identity')
    return scene, ref, times


def test_the_process_clock_keeps_its_resolution_under_a_cpu_limit():
    """Inside a cap, CPU is still read to the µs: consecutive reads of cpu() ~0.5 µs
    apart differ. Under a process CPU timer (ITIMER_PROF, the cap's first form) Linux read
    the clock from a tick-updated sum: most reads repeated and a 1 ms run of the suite's
    bench read 0 s (ZeroDivisionError in generated_peers)."""
    from rigid_body_sim.bench.common import cpu, cpu_limit
    with cpu_limit(10.0):
        reads = [cpu() for _ in range(20_000)]
    repeats = sum(a == b for a, b in zip(reads, reads[1:]))
    assert repeats < 200, repeats  # 1 %; a tick-granular clock repeats in ~99 %


def test_the_cpu_limit_stops_a_python_loop_and_restores_the_signal():
    import signal
    from rigid_body_sim.bench.common import CpuCapReached, cpu_limit
    before = signal.getsignal(signal.SIGPROF)
    with pytest.raises(CpuCapReached), cpu_limit(0.02):
        while True:
            sum(range(1000))
    assert signal.getsignal(signal.SIGPROF) is before
    assert signal.getitimer(signal.ITIMER_PROF) == (0.0, 0.0)
    with cpu_limit(10.0):  # a body that ends in time is left alone
        sum(range(1000))


def test_the_scipy_cap_stops_its_first_run(monkeypatch):
    """The sweep's cap held only between runs: a first run of minutes ran to its end (scene
    172 of the full run, > 18 CPU-min). Now a run is stopped at the cap: no run finishes
    (error inf), and the CPU it had spent is the peer's lower bound. (A fine rtol first:
    a coarse one takes a few big, wrong steps, too cheap to reach any cap.)"""
    monkeypatch.setattr(gp, 'RTOLS', (1e-10,))
    scene, ref, times = _long('viscous', 1e3)
    rtol, bound, err = gp.peer_sweep(scene, 'RK45', ref, times, cap=0.02)
    assert rtol is None and err == np.inf and bound > 0


def test_the_mujoco_cap_stops_its_first_run():
    from rigid_body_sim.bench import generated_mujoco as gm
    scene, ref, times = _long('viscous', 3e4)
    h, bound, err = gm.sweep(scene, 'RK4', ref, times, cap=0.02)
    assert h is None and err == np.inf and bound > 0


def test_mujoco_is_imported_before_any_runs_cap():
    """A scene measured alone (``--from N --count N+1``) imported MuJoCo inside its first
    run's CPU cap; the import (~0.1 CPU-s) was stopped by it and failed ("initialization
    failed"), each rung then counted as a diverged run, and the row lost MuJoCo. In a
    fresh interpreter, every cap of ``runs`` now starts with MuJoCo loaded."""
    import subprocess
    import sys
    code = (
        'import contextlib, sys\n'
        'from rigid_body_sim.bench import generated_mujoco as gm\n'
        'import test_bench_generated_peers as t\n'
        'seen, limit = [], gm.cpu_limit\n'
        '@contextlib.contextmanager\n'
        'def watched(seconds):\n'
        '    seen.append("mujoco" in sys.modules)\n'
        '    with limit(seconds):\n'
        '        yield\n'
        'gm.cpu_limit = watched\n'
        'scene, ref, times = t._long("viscous", 1e3)\n'
        'assert "mujoco" not in sys.modules\n'
        'gm.runs(scene, ref, times, cap=0.02)\n'
        'print(len(seen), all(seen))\n')
    here = __import__('os').path.dirname(__file__)
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=here, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    count, loaded = out.stdout.split()
    assert int(count) >= 2 and loaded == 'True', out.stdout


def test_a_peer_stops_where_it_cannot_beat_a_cheaper_one(monkeypatch):
    """Given the CPU of a peer that met the budget (``beat``), a sweep stops there: its
    bound is at least that CPU, and the row stays the cheaper peer's."""
    monkeypatch.setattr(gp, 'RTOLS', (1e-11,))
    scene, ref, times = _long('viscous', 1e3)
    rtol, bound, err = gp.peer_sweep(scene, 'DOP853', ref, times, cap=10.0, beat=0.02)
    assert rtol is None and bound >= 0.02


def test_a_peer_capped_below_the_cheapest_met_makes_the_row_a_lower_bound():
    row = {'scene': 's'}
    met = ('scipy_dop853', 1e-6, 2.0, 1e-7)
    ok = gp._row_of(row, [met, ('scipy_rk45', None, 3.0, 0.1)], 0.01)
    assert ok['status'] == 'ok' and ok['peer'] == 'scipy_dop853' and ok['ratio'] == 200.0
    low = gp._row_of(row, [met, ('mujoco_rk4', None, 0.5, 0.1)], 0.01)
    assert low['status'].startswith('lower bound') and low['peer'] == 'mujoco_rk4'
    assert low['ratio'] == 50.0
    none = gp._row_of(row, [('scipy_dop853', None, 4.0, 0.1), ('scipy_rk45', None, 3.0, 1)],
                      0.01)
    assert none['status'].startswith('lower bound') and none['peer_cpu_s'] == 3.0


def test_where_auto_missed_the_budget_too_no_lower_bound_is_claimed():
    """A scene that auto could not meet (float64 cannot: auto says so) and no peer met is
    infeasible, with no ratio; one a peer met is auto's miss, and the target row fails."""
    row = {'scene': 's'}
    capped = [('scipy_dop853', None, 4.0, 0.1), ('scipy_rk45', None, 3.0, 1)]
    gone = gp._row_of(row, capped, 0.01, auto_met=False)
    assert gone['status'] == gp.INFEASIBLE and 'ratio' not in gone
    met = ('scipy_dop853', 1e-6, 2.0, 1e-7)
    lost = gp._row_of(row, [met] + capped, 0.01, auto_met=False)
    assert lost['status'].startswith('auto missed') and lost['ratio'] == 200.0
    ok = dict(gp._row_of({'scene': 'a'}, [met], 1e-3), peer_cpu_s=2.0)
    target = gp.summary_target([ok, dict(gone, scene='b')], 1)
    assert target['verdict'] == 'PASS' and '1 infeasible' in target['note']
    target = gp.summary_target([ok, dict(lost, scene='c')], 1)
    assert target['verdict'] == 'MISS' and 'a peer met it: c' in target['note']


def test_a_run_stopped_half_way_resumes_from_its_rows(tmp_path):
    """A share of the run (--from) writes only its rows; the whole run with --resume takes
    the rows already measured as they are (scene 0's row here is one no run would write)
    and measures only the scenes missing."""
    import csv
    import shutil
    out = tmp_path / 'bench'
    shutil.copytree('docs/bench', out)
    rows = tmp_path / 'rows.csv'
    assert gp.main(['--quick', '--count', '2', '--from', '1', '--rows', str(rows),
                    '--out', str(out)]) == 0
    share = list(csv.DictReader(rows.open()))
    assert [r['scene'] for r in share] == [generated.draw(generated.SEED, 1, True).name]
    before = (out / 'generated_peers.csv').read_text()
    assert before == open('docs/bench/generated_peers.csv').read()  # a share writes no section
    first = generated.draw(generated.SEED, 0, True)
    made = {'scene': first.name, 'kind': first.kind, 'budget': first.budget,
            'rotation': first.rotation, 'status': 'not measured: written by the test'}
    with rows.open('a', newline='') as f:
        csv.DictWriter(f, fieldnames=gp.FIELDS, extrasaction='ignore').writerow(made)
    assert gp.main(['--quick', '--count', '2', '--rows', str(rows), '--resume',
                    '--out', str(out)]) == 0
    written = list(csv.DictReader((out / 'generated_peers.csv').open()))
    assert [r['scene'] for r in written] == [first.name, share[0]['scene']]
    assert written[0]['status'] == made['status'] and written[1] == share[0]


def test_a_peer_whose_every_setting_missed_bounds_nothing():
    """A sweep that ran every rung and missed returns an infinite bound (no finer setting
    exists to meet the budget at some CPU); such a peer sets no lower bound, and a scene
    where every peer is so has no ratio."""
    from types import SimpleNamespace
    from rigid_body_sim.bench import generated_mujoco as gm
    scene = SimpleNamespace(budget=1e-9)
    ref = SimpleNamespace(attitude=np.array([[0.0, 0.0, 0.0, 1.0]]), error=0.0)
    off = np.array([[0.0, 0.0, np.sin(0.05), np.cos(0.05)]])  # 0.1 rad from the reference
    rung, bound, err = gm.ladder(scene, ref, (1, 2, 3), lambda r: (1e-4, off), cap=10.0)
    assert rung is None and bound == math.inf and err == pytest.approx(0.1)
    row = {'scene': 's'}
    gone = gp._row_of(row, [('bsk_rkf78', None, math.inf, 0.1),
                            ('scipy_dop853', None, math.inf, 0.2)], 0.01)
    assert gone['status'] == gp.NO_SETTING and 'ratio' not in gone
    # where auto missed too, the scene is infeasible, not one that auto met
    assert gp._row_of(row, [('bsk_rkf78', None, math.inf, 0.1)], 0.01,
                      auto_met=False)['status'] == gp.INFEASIBLE
    capped = gp._row_of(row, [('bsk_rkf78', None, math.inf, 0.1),
                              ('scipy_dop853', None, 3.0, 0.2)], 0.01)
    assert capped['status'].startswith('lower bound') and capped['peer'] == 'scipy_dop853'
    met = gp._row_of(row, [('bsk_rkf78', None, math.inf, 0.1),
                           ('scipy_dop853', 1e-8, 2.0, 1e-10)], 0.01)
    assert met['status'] == 'ok' and met['ratio'] == 200.0
    target = gp.summary_target([dict(met, peer_cpu_s=2.0), dict(gone, scene='b')], 1)
    assert '1 where auto met it and no peer did at any setting' in target['note']
