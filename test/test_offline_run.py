"""What an offline run tells its user before and after: a fixed method's predicted error
against the scene's budget, scene steps every method survives, a run record that is the
run (and runs again), a step that cannot be honoured, a run that replaces the previous."""
import hashlib
import math
import os

import numpy as np
import pytest

from rigid_body_sim import cli, offline, run_cli
from rigid_body_sim.bag.reader import iter_messages, read_info
from rigid_body_sim.engine import Engine
from rigid_body_sim.physics import INTEGRATORS
from rigid_body_sim.physics.integrators import BODY_ONLY
from rigid_body_sim.physics.integrators.stability import check_step, distortion
from rigid_body_sim.physics.auto.step_advice import advise
from rigid_body_sim.scene import SceneError, list_scenes, load

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
CONFIG = os.path.join(REPO, 'config')
SCENES = sorted(name for name, _, _ in list_scenes() if not load(name).spacecraft)  # one body


def _cli(capsys, *args):
    rc = cli.main(list(args))
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_rk4_on_explorer1_at_a_nutation_killing_step_is_warned_with_a_step_that_fits(capsys):
    """RK4 at 0.05 s: hλ ≈ 2.5i on the 50 rad/s nutation mode, |R| ≈ 0.51 per step, so the
    nutation is damped away and the body never goes flat. Its stability check passed it
    (|R| < 1); the prediction (auto's pilot) says so, too damped, with a step that fits."""
    scene = load(os.path.join(CONFIG, 'explorer1.yaml'))
    engine = offline.engine_for(scene, integrator='rk4', step=0.05, duration=600.0)
    q, m = engine.principal_state
    advice = advise('rk4', engine.dynamics, q, m, 0.05, accuracy=0.01, duration=600.0,
                    spacing=1.0)
    assert advice.far and advice.damping == pytest.approx(0.51, abs=0.01)
    assert advice.growth <= 1.0 + 1e-9          # nothing amplified: the old check's blind spot
    assert advice.meets is not None and advice.meets < 0.005
    # the step it names does meet the budget when predicted again
    again = advise('rk4', engine.dynamics, q, m, advice.meets, accuracy=0.01, duration=600.0,
                   spacing=1.0)
    assert again.predicted_error <= 0.01 and not again.far
    # the engine checks whenever it configures a fixed method; auto needs no such word
    checked = Engine(engine.config, check_method=True)
    assert [v for v, _ in checked.method_warnings] == ['warn']
    assert Engine(engine.config.replace(integrator='auto'), check_method=True) \
        .method_warnings == []
    rc, _, err = _cli(capsys, 'run', 'explorer1', '--integrator', 'rk4', '--step', '0.05',
                      '--duration', '600', '--no-bag', '--no-plots', '--json')
    assert rc == 0
    assert 'warning: rk4 at h = 0.05 s' in err and 'too damped' in err, err
    assert 'would meet it' in err


def test_euler_is_warned_as_too_amplified(capsys):
    rc, _, err = _cli(capsys, 'run', 'tennis_racket', '--integrator', 'euler', '--duration',
                      '2', '--no-bag', '--no-plots', '--json')
    assert rc == 0 and 'too amplified' in err, err


@pytest.mark.parametrize('name', SCENES)
def test_scene_steps_are_survived_by_every_fixed_method(name):
    """Every registered method at the scene's ``step`` (what a user gets with
    ``--integrator NAME``): not refused, and no mode damped or amplified by more than 1 %
    over the run by its stability function (Explorer 1's 0.05 s damped the nutation by 49 %
    per step under RK4; the Earth's one-day step was refused for RK4). Euler amplifies
    every rotation at any step: it must be flagged where it does not survive."""
    scene = load(os.path.join(CONFIG, f'{name}.yaml'))
    for method in BODY_ONLY:
        environment = scene.simulator['environment.gravity_gradient'] or \
            any(scene.simulator['magnetorquer.max_dipole'])
        if environment and not INTEGRATORS[method].environment:  # refused at load, naming it
            with pytest.raises(SceneError, match='does not integrate (environment|magnetorq)'):
                load(os.path.join(CONFIG, f'{name}.yaml'), [f'integrator={method}'])
            continue
        engine = offline.engine_for(load(os.path.join(CONFIG, f'{name}.yaml'),
                                         [f'integrator={method}']))
        if engine.actuators is not None:  # wheels / CMGs: the gyrostat method, always
            assert INTEGRATORS[engine.method].requires_actuators
            continue
        c = engine.config
        _, m = engine.principal_state
        h = engine.step_max
        steps = c.duration / h
        verdict, message = check_step(method, engine.dynamics, m, h, c.duration)
        damping, z, growth = distortion(method, engine.dynamics, m, h)
        survives = verdict == 'ok' and damping ** steps >= 0.99
        if method == 'euler':
            assert survives or verdict in ('warn', 'refuse'), (name, method)
            continue
        assert survives, (name, method, scene.simulator['step'], verdict, message, damping, z)


def test_rk4_at_explorer1s_scene_step_goes_flat():
    """The physics at the scene's fixed-method step: RK4 ends in the flat spin about the major
    axis, T = |L|²/(2 I_max) (at 0.05 s it ended at 79 J, still about the minor axis)."""
    scene = load(os.path.join(CONFIG, 'explorer1.yaml'), ['integrator=rk4'])
    result = offline.simulate(scene, keep='none')
    L = np.linalg.norm(result.initial['angular_momentum'])
    flat = L * L / (2 * max(scene.simulator['inertia']))
    assert result.final['kinetic_energy'] == pytest.approx(flat, rel=1e-3)


def _messages(bag):
    """(topic, log time, message) of every message; compared as messages: rclpy's
    serialiser leaves alignment padding uninitialised, so equal messages differ in bytes."""
    from rclpy.serialization import deserialize_message
    from rigid_body_sim.bag.schema import message_class
    return [(m.topic, m.log_time_ns, deserialize_message(m.data, message_class(m.type)))
            for m in iter_messages(bag)]


@pytest.mark.parametrize('extra', [[], ['--integrator', 'rk4']])
def test_run_record_is_the_run_and_runs_again(tmp_path, capsys, extra):
    """The bag's run configuration holds the effective parameters (CLI overrides, not the
    scene's), the method, step and reason that ran, and the scene's name and content hash;
    running its record alone gives the same messages."""
    out = tmp_path / 'a'
    rc, _, err = _cli(capsys, 'run', 'explorer1', '--duration', '5', '--accuracy', '1e-4',
                      '--step', '0.01', '--out', str(out), '--no-plots', *extra)
    assert rc == 0, err
    record = read_info(str(out / 'bag')).run_configuration
    p = record['simulator_parameters']
    assert (p['duration'], p['accuracy'], p['step']) == (5.0, 1e-4, 0.01)
    assert p['integrator'] == ('rk4' if extra else 'auto')
    assert record['integrator'] == ('rk4' if extra else
                                    offline.engine_for(load('explorer1'), duration=5.0,
                                                       accuracy=1e-4).method)
    assert record['integrator'] != 'auto' and record['step'] > 0
    assert record['reason'].startswith('set by' if extra else 'auto:')
    assert record['scene'] == 'explorer1'
    with open(os.path.join(CONFIG, 'explorer1.yaml'), 'rb') as f:
        assert record['scene_sha256'] == hashlib.sha256(f.read()).hexdigest()
    again = tmp_path / 'b'
    scene = offline.scene_from_record(record)
    sink = offline.BagSink(scene, str(again), {}, scene.simulator)
    result = offline.simulate(scene, sinks=[sink], keep='none')
    sink.finish(result)
    sink.close()
    assert (result.integrator, result.step) == (record['integrator'], record['step'])
    first, second = _messages(str(out / 'bag')), _messages(str(again))
    assert len(first) == 6 * 9 and first == second


def test_a_step_longer_than_the_sample_period_is_refused_with_the_reason(tmp_path, capsys):
    """--step 0.5 at 100 samples/s ran at 0.01 s without a word: refused, saying why and
    how; with one sample per 0.5 s it is honoured."""
    rc, _, err = _cli(capsys, 'run', 'tennis_racket', '--integrator', 'rk4', '--step', '0.5',
                      '--out', str(tmp_path), '--json')
    assert rc == 2
    assert 'longer than the sample period 0.01 s' in err and 'publish_rate=2' in err, err
    assert not os.listdir(tmp_path)  # refused before writing anything
    rc, out, err = _cli(capsys, 'run', 'tennis_racket', '--integrator', 'splitting2',
                        '--step', '0.5', '--set', 'publish_rate=2', '--duration', '2',
                        '--no-bag', '--no-plots', '--json')
    assert rc == 0, err
    import json
    summary = json.loads(out)
    assert summary['step'] == 0.5 and summary['steps'] == 4


def test_a_run_says_it_replaces_the_previous_one_and_leaves_none_of_its_figures(tmp_path,
                                                                               capsys):
    """Same --out twice: the second run says it replaces the first; the first's Poinsot
    figure (a free tumble) does not stay beside a run that has no free phase."""
    out = str(tmp_path / 'run')
    rc, _, err = _cli(capsys, 'run', 'tennis_racket', '--duration', '1', '--out', out,
                      '--json')
    assert rc == 0 and 'replacing' not in err
    assert os.path.isfile(os.path.join(out, 'poinsot.png'))
    with open(os.path.join(out, 'notes.txt'), 'w') as f:  # not the run's: left alone
        f.write('mine')
    rc, _, err = _cli(capsys, 'run', 'detumble', '--duration', '1', '--out', out, '--json')
    assert rc == 0
    assert f'replacing the previous run in {out}' in err, err
    assert not os.path.exists(os.path.join(out, 'poinsot.png'))
    assert os.path.isfile(os.path.join(out, 'control.png'))
    assert os.path.isfile(os.path.join(out, 'notes.txt'))
    assert read_info(os.path.join(out, 'bag')).run_configuration['scene'] == 'detumble'
    assert math.isfinite(read_info(os.path.join(out, 'bag')).duration_s)


def test_the_cli_warms_the_run_right_before_its_clock(tmp_path, capsys, monkeypatch):
    """What runs last before the clock is the run's own warm-up (a few sample periods of
    the same engine configuration), after the bag's set-up: set up after the warm-up, the
    bag evicted the caches the run's code was warm in, which a 0.25 ms run paid again in
    its cpu_seconds (1.5-2.4x the same run in-process). The warm-up is reported with the
    kernels' loading, outside cpu_seconds."""
    events = []
    warm, sink, simulate = run_cli.rehearse, run_cli.BagSink.__init__, run_cli.simulate
    monkeypatch.setattr(run_cli, 'rehearse', lambda *a: (events.append('warm'), warm(*a))[1])
    monkeypatch.setattr(run_cli.BagSink, '__init__', lambda self, *a, **k: (
        events.append('bag'), sink(self, *a, **k))[1])
    monkeypatch.setattr(run_cli, 'simulate', lambda *a, **k: (
        events.append('clock'), simulate(*a, **k))[1])
    rc, _, err = _cli(capsys, 'run', 'slew', '--duration', '2', '--out', str(tmp_path),
                      '--no-plots')
    assert rc == 0, err
    assert events[-3:] == ['bag', 'warm', 'clock'], events



@pytest.mark.parametrize('flags,keep', [(('--no-plots',), 'none'), ((), 'plot')])
def test_the_cli_rehearses_its_run_through_the_runs_own_code(tmp_path, capsys, monkeypatch,
                                                              flags, keep):
    """Last before the clock, ``offline.simulate`` runs the first periods of a fresh engine
    of the same configuration, keeping what the run keeps, without the bag: the Python that
    handles the run's blocks (first and last rows converted, the plot series) first ran
    inside the clock otherwise, 1.2-1.3x a 0.3 ms run's in-process CPU."""
    events = []
    rehearsal, clock = offline.simulate, run_cli.simulate
    monkeypatch.setattr(offline, 'simulate', lambda scene, **k: (
        events.append(('rehearsal', k['keep'], k['until_ns'], k['engine'])),
        rehearsal(scene, **k))[1])
    monkeypatch.setattr(run_cli, 'simulate', lambda scene, **k: (
        events.append(('clock', k['keep'], None, k['engine'])), clock(scene, **k))[1])
    rc, _, err = _cli(capsys, 'run', 'slew', '--duration', '2', '--out', str(tmp_path),
                      *flags)
    assert rc == 0, err
    (what, kept, until, copy), (last, run_keep, _, engine) = events[-2:]
    assert (what, last) == ('rehearsal', 'clock') and kept == run_keep == keep
    assert copy is not engine and copy.config == engine.config
    assert 0 < until < engine.end_ns  # its first periods, not the run

# A fresh CLI process that reports, when the clock starts, which of the functions a run
# calls once are quickened (CPython 3.11: RESUME_QUICK, at a code object's 8th call)
_QUICKENED_AT_CLOCK = '''
import dis, json, sys
from rigid_body_sim import cli, offline, run_cli
from rigid_body_sim.engine import Engine
seen, clock = {}, run_cli.simulate
def at_clock(*a, **k):
    for f in (offline.simulate, offline._end_rows, Engine.run, Engine.advance):
        seen[f.__qualname__] = any(i.opname == 'RESUME_QUICK'
                                   for i in dis.get_instructions(f, adaptive=True))
    return clock(*a, **k)
run_cli.simulate = at_clock
rc = cli.main(['run', 'slew', '--duration', '2', '--no-plots', '--no-bag', '--json', '--out',
               sys.argv[1]])
print(json.dumps({'rc': rc, 'quick': seen}))
'''


@pytest.mark.slow
def test_the_clis_rehearsals_leave_the_runs_python_quickened(tmp_path):
    """The per-run Python (offline.simulate, its end rows) runs once a run; CPython 3.11
    quickens a function at its 8th call. With 3 rehearsals those two were still plain
    bytecode when the clock started, and a 0.2 ms run read 1.2-1.5x its warm in-process
    CPU (generated scene 18: 214-325 µs against 165-190); with REHEARSALS (10) they are
    quickened, 176-280 µs."""
    import json
    import subprocess
    import sys
    assert sys.version_info[:2] == (3, 11), 'RESUME_QUICK is 3.11\'s: check the new rule'
    proc = subprocess.run([sys.executable, '-c', _QUICKENED_AT_CLOCK, str(tmp_path)],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out['rc'] == 0 and out['quick'] and all(out['quick'].values()), out


# One fresh process imports what the CLI's process imports before its main (cli, numba)
# and forks a child a case: each child runs the CLI, then lists the package's modules whose
# kernels hold a compiled version (loaded from the cache or compiled): what the run loaded.
# Nothing is loaded before the fork (no kernel called), so each child starts as a fresh
# CLI process does, without its interpreter's start-up (~0.7 CPU-s a case, issue 32).
_RUN_AND_LIST = '''
import json, os, sys, traceback
from numba.core.registry import CPUDispatcher
from rigid_body_sim import cli
codes = []
for argv, out in json.load(sys.stdin):
    sys.stdout.flush(); sys.stderr.flush()
    pid = os.fork()
    if pid == 0:
        status = 1
        try:
            os.dup2(os.open(out, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), 1)
            code = cli.main(argv)
            print(json.dumps({'code': code, 'loaded': sorted(
                name for name, module in list(sys.modules.items())
                if name.startswith('rigid_body_sim') and module is not None
                and any(isinstance(v, CPUDispatcher) and v.signatures
                        for v in vars(module).values()))}))
            status = 0
        except BaseException:
            traceback.print_exc()
        finally:
            sys.stdout.flush(); sys.stderr.flush()
            os._exit(status)
    codes.append(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))
print(json.dumps(codes))
'''
CLI_CASES = [('tennis_racket', '1'), ('slew', '1'), ('explorer1', '1'), ('explorer1', '50'),
             ('explorer1_orbit', '1')]
_CLI_RUNS = {}


def cli_run_and_list(case, tmp_path_factory):
    """(exit status, stdout) of the case's CLI run in a fresh process (see _RUN_AND_LIST):
    the first call runs every case's, in one process (loadfile keeps this file on one
    worker)."""
    import json
    import subprocess
    import sys
    if case not in _CLI_RUNS:
        jobs = []
        for scene, duration in CLI_CASES:
            tmp = tmp_path_factory.mktemp('cli_run')
            jobs.append((['run', scene, '--json', '--duration', duration, '--no-bag',
                          '--no-plots', '--out', str(tmp)], str(tmp / 'stdout.txt')))
        proc = subprocess.run([sys.executable, '-c', _RUN_AND_LIST], input=json.dumps(jobs),
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, proc.stderr[-3000:]
        for c, code, (_, out) in zip(CLI_CASES, json.loads(proc.stdout), jobs):
            with open(out) as f:
                _CLI_RUNS[c] = code, f.read(), proc.stderr
    return _CLI_RUNS[case]


@pytest.mark.parametrize('scene, duration', CLI_CASES)
def test_the_cli_loads_the_kernels_its_run_uses_and_no_others(scene, duration,
                                                               tmp_path_factory):
    """Free tumble, a slew whose law's torque makes auto choose again, a dissipative scene
    (auto's pilot), the same over 50 s (auto takes exact a priori: its split steps' loop
    with the engine's read-only arrays, 11 ms of a 0.3 ms run when loaded in the clock), an
    orbit: no kernel is loaded after the clock starts (each one the warm-up missed would
    be), and the kernels of methods the scene cannot use are not loaded at all (loading
    all 19 cost every run ~0.15 CPU-s)."""
    import json
    code, stdout, stderr = cli_run_and_list((scene, duration), tmp_path_factory)
    assert code == 0, stderr[-3000:]
    summary, listing = (json.loads(line) for line in stdout.strip().splitlines()[-2:])
    assert listing['code'] == 0
    assert summary['kernels_loaded_during_run'] == 0, (summary['integrator'], listing)
    assert 'rigid_body_sim.physics.integrators.gyrostat_kernel' not in listing['loaded'], \
        listing  # wheels and CMGs only


def _decimated_by_index_arrays(sizes, limit):
    """The plot series' samples as Decimated chose them before it took slices: each block
    by an index array, then every other of all kept when past the limit (once an add)."""
    seen, stride, kept = 0, 1, np.zeros(0, np.int64)
    for n in sizes:
        t = seen + np.arange(n)
        kept = np.concatenate([kept, t[t % stride == 0]])
        seen += n
        if len(kept) > limit:
            kept, stride = kept[::2], stride * 2
    return kept


@pytest.mark.parametrize('sizes', [[16384, 13617], [30001], [1] * 50 + [7, 300, 64],
                                   [5000] * 9 + [3, 1, 20_000, 999]])
def test_the_plot_series_keeps_every_stride_th_sample_in_copies(sizes, monkeypatch):
    """offline.Decimated keeps the samples it kept with index arrays (every stride-th of
    the stream, the stride doubling once an add past the limit), now as slices copied
    out of each block (1.9 ms more than the run's 0.8 at 30,001 samples; now ~0.4), and
    holds no block it was given."""
    from rigid_body_sim.engine import SampleBlock
    taken, take = [], SampleBlock.take
    monkeypatch.setattr(SampleBlock, 'take', lambda self, index, copy=False: (
        taken.append(type(index)), take(self, index, copy))[1])
    limit, seen, given = 1000, 0, []
    series = offline.Decimated(limit)
    for n in sizes:
        t = seen + np.arange(n, dtype=np.int64)
        block = SampleBlock(t, np.zeros((n, 4)) + t[:, None], np.zeros((n, 3)) + t[:, None],
                            np.zeros((n, 3)), None)
        given.append(block)
        series.add(block)
        seen += n
    out = series.block()
    expected = _decimated_by_index_arrays(sizes, limit)
    np.testing.assert_array_equal(out.t_ns, expected)
    np.testing.assert_array_equal(out.q[:, 2], expected)
    assert series.count == len(expected)
    assert taken and set(taken) == {slice}  # no index array (numpy's gather: the cost)
    for b in series.blocks:
        for a in (b.t_ns, b.q, b.m, b.torque):
            assert not any(np.shares_memory(a, g.t_ns) or np.shares_memory(a, g.q) or
                           np.shares_memory(a, g.m) or np.shares_memory(a, g.torque)
                           for g in given)
