"""Samples written from the compiled loop (engine/closed_loop.py) into the engine's block.

The compiled path must give the very samples of the event-by-event path (bit for bit on
bodies whose principal frame is the body frame, where both evaluate the same floating-point
operations), compiled and as plain Python (NUMBA_DISABLE_JIT=1), and it must not go back
to Python per sample.
"""
import json

import numpy as np
import pytest
from jit_modes import run_both

from rigid_body_sim.engine import Engine, SampleBlock
from rigid_body_sim.offline import engine_for
from rigid_body_sim.scene import load

# (scene, overrides, --set): a law in the loop (slew, detumble), a fixed method on a
# dissipative scene (rk4, splitting4), auto, and an end off the sample grid
CASES = [('slew', {'duration': 6.0}, ['publish_rate=100.0']),
         ('detumble', {'duration': 6.0}, ['publish_rate=100.0']),
         ('explorer1', {'duration': 3.0, 'integrator': 'rk4', 'step': 1e-3},
          ['publish_rate=100.0']),
         ('explorer1', {'duration': 3.37, 'integrator': 'splitting4', 'step': 1e-3},
          ['publish_rate=7.0']),
         ('slew', {'duration': 4.37}, ['publish_rate=30.0']),
         # the methods whose loops the kernel calls besides the fixed-step ones: dop853
         # (its dense output carried between calls; restarted by the law's torques on
         # slew), splitting2_lstable (its own damping code) and exact's split steps
         ('explorer1', {'duration': 3.37, 'integrator': 'dop853'}, ['publish_rate=100.0']),
         ('slew', {'duration': 4.37, 'integrator': 'dop853'}, ['publish_rate=100.0']),
         # ~7 ms steps of dop853, 2-3 samples inside each (engine.dop853_samples: every
         # sample before the end from one loop of its steps; ~20 and ~120 steps)
         ('explorer1', {'duration': 1.0, 'integrator': 'dop853'}, ['publish_rate=300.0']),
         # ~1 s steps of dop853, 100 samples inside each (two chunks of lanes a step)
         ('tennis_racket', {'duration': 5.37, 'integrator': 'dop853'},
          ['publish_rate=100.0', 'dissipation.model=viscous', 'dissipation.coefficient=0.01']),
         ('explorer1', {'duration': 3.0, 'integrator': 'splitting2_lstable', 'step': 1e-3},
          ['publish_rate=100.0']),
         ('explorer1', {'duration': 3.0, 'integrator': 'exact', 'step': 1e-3},
          ['publish_rate=100.0']),
         ('slew', {'duration': 4.37, 'integrator': 'exact', 'step': 0.01},
          ['publish_rate=30.0'])]


def _samples(name, overrides, sets, compiled_loop):
    # landing on every sample, as the live node does: the event path's own samples
    engine = engine_for(load(name, sets), interpolate_samples=False, **overrides)
    engine._compiled_samples = compiled_loop  # the event-by-event path is the reference
    block = SampleBlock.concatenate(list(engine.run()))
    return engine, block


@pytest.mark.parametrize('name,overrides,sets', CASES)
def test_compiled_samples_are_the_event_loop_samples_bit_for_bit(name, overrides, sets):
    (py, a), (kernel, b) = (_samples(name, overrides, sets, c) for c in (False, True))
    assert len(a) == len(b) > 20
    for field in ('t_ns', 'q', 'm', 'torque'):
        np.testing.assert_array_equal(getattr(b, field), getattr(a, field), err_msg=field)
    assert py.steps == kernel.steps and py.total_evaluations == kernel.total_evaluations
    assert a.t_ns[-1] == round(overrides['duration'] * 1e9)  # the run ends at its duration
    if name in ('slew', 'detumble'):
        assert np.abs(b.torque).max() > 0.0  # the law acted inside the kernel


def test_samples_do_not_go_back_to_python_per_sample(monkeypatch):
    """At 100 samples/s the engine's Python step (``Engine._integrate``) and the Python
    control law run a handful of times per run (the first and last events), not once per
    sample."""
    from rigid_body_sim.engine.sources import ControlLaw
    calls = {'integrate': 0, 'law': 0}
    integrate, on_event = Engine._integrate, ControlLaw.on_event

    def counted_integrate(self, *args):
        calls['integrate'] += 1
        return integrate(self, *args)

    def counted_law(self, *args):
        calls['law'] += 1
        return on_event(self, *args)
    monkeypatch.setattr(Engine, '_integrate', counted_integrate)
    monkeypatch.setattr(ControlLaw, 'on_event', counted_law)
    for name, overrides in (('explorer1', {'integrator': 'rk4', 'step': 1e-3}),
                            ('slew', {}), ('explorer1', {'integrator': 'dop853'}),
                            ('explorer1', {'integrator': 'splitting2_lstable', 'step': 1e-3}),
                            ('explorer1', {'integrator': 'exact', 'step': 1e-3}),
                            ('slew', {'integrator': 'dop853'}),
                            ('slew', {'integrator': 'exact', 'step': 0.01})):
        engine = engine_for(load(name, ['publish_rate=100.0']), duration=5.0, **overrides)
        calls.update(integrate=0, law=0)
        assert sum(len(b) for b in engine.run()) == 501
        assert calls['integrate'] + calls['law'] <= 10, (name, calls)


_SCRIPT = '''
import hashlib, json, sys
import numpy as np
from rigid_body_sim.engine import SampleBlock
from rigid_body_sim.offline import engine_for
from rigid_body_sim.physics import jit as kernels
from rigid_body_sim.scene import load
out = {"compiled": kernels.COMPILED}
for name, overrides, sets in json.loads(sys.argv[1]):
    for compiled_loop in (False, True):
        # landing on every sample, as in _samples: the event path's own samples
        engine = engine_for(load(name, sets), interpolate_samples=False, **overrides)
        engine._compiled_samples = compiled_loop
        b = SampleBlock.concatenate(list(engine.run()))
        arrays = [b.t_ns, b.q, b.m, b.torque]
        out[f"{name}/{overrides}/{compiled_loop}"] = [
            hashlib.sha256(b"".join(a.tobytes() for a in arrays)).hexdigest(),
            np.concatenate([b.q[-1], b.m[-1]]).tolist(), engine.steps]
print(json.dumps(out))
'''


@pytest.mark.slow
def test_compiled_samples_in_both_jit_modes():
    """Compiled and as plain Python: in each mode the kernel's samples are the event
    loop's bit for bit, and the modes agree to round-off."""
    cases = [CASES[0], CASES[2]]
    compiled, plain = run_both(_SCRIPT, json.dumps(cases))
    assert compiled.pop('compiled') is True and plain.pop('compiled') is False
    for mode in (compiled, plain):
        for key in [k for k in mode if k.endswith('/True')]:
            assert mode[key][0] == mode[key[:-4] + 'False'][0], key
    for key, (_, state, steps) in compiled.items():
        np.testing.assert_allclose(state, plain[key][1], rtol=0, atol=1e-12, err_msg=key)
        assert steps == plain[key][2]


def test_engine_without_compiled_loop_keeps_the_event_path():
    """``compiled_loop=False`` (the reference of the tests above) runs no kernel."""
    from rigid_body_sim.engine import EngineConfig
    engine = Engine(EngineConfig.from_parameters(
        {'integrator': 'rk4', 'duration': 1.0, 'publish_rate': 10.0}), compiled_loop=False)
    assert not engine._compiled_samples
    assert sum(len(b) for b in engine.run()) == 11


def _cli_json(*args):
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-c', 'import sys; from rigid_body_sim import cli; '
                           'sys.exit(cli.main(sys.argv[1:]))', 'run', *args, '--json'],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize('scene', ['wheel_slew', 'detumble'])
def test_cli_loads_every_kernel_before_its_clock(scene, tmp_path):
    """A fresh process: every numba kernel the run calls (the gyrostat loop of a wheel
    scene, which compiled.warm() leaves to the first call) is loaded before the clock,
    reported as the warm-up; the bag's encoding and writing are reported on their own."""
    summary = _cli_json(scene, '--duration', '2', '--no-plots', '--out', str(tmp_path))
    assert summary['kernels_loaded_during_run'] == 0
    assert summary['kernel_load_cpu_seconds'] > 0.0
    assert summary['output_cpu_seconds'] > 0.0 and summary['cpu_seconds'] > 0.0
    # without a bag, nothing to encode or write: what the command reports, not its process
    # (in this one: a second fresh interpreter cost ~1 CPU-s, issue 32)
    from cli_inprocess import run_cli
    out = run_cli('run', scene, '--duration', '2', '--no-plots', '--no-bag', '--out',
                  tmp_path / 'b', '--json')
    assert out.returncode == 0, out.stderr[-3000:]
    summary = json.loads(out.stdout.strip().splitlines()[-1])
    assert summary['output_cpu_seconds'] == 0.0 and summary['bag'] is None


@pytest.mark.slow
@pytest.mark.parametrize('rate', [1000, 10000])
def test_the_clis_run_touches_no_fresh_pages_for_its_samples(tmp_path, rate):
    """A fresh process: the pages of the run's sample arrays were touched before the clock
    (run_cli.warm_heap), as a warm process's are; without it the run of 20,001 exact
    samples took ~380 page faults in its clock, 1.5 ms against 0.8, and with a warmed
    buffer of 32 MiB (glibc's threshold: mapped apart, so unmapped when freed) the run of
    200,001 (past SINK_BATCH) took 2285, 9.6-10.1 ms against 5.9-6.3. The bag's own
    faults are not the run's (offline.simulate counts the sinks apart). The second case
    runs 14 s: 140,001 samples are past SINK_BATCH too, and its bag of 200,001 took 16 of
    the file's 45 s (issue 32)."""
    from rigid_body_sim.offline import SINK_BATCH
    duration = 20 if rate == 1000 else 14
    summary = _cli_json('tennis_racket', '--integrator', 'exact', '--duration', str(duration),
                        '--set', f'publish_rate={rate}', '--no-plots', '--out', str(tmp_path))
    assert summary['samples'] == duration * rate + 1 and summary['integrator'] == 'exact'
    assert (summary['samples'] > SINK_BATCH) == (rate == 10000)
    assert 0 <= summary['page_faults_during_run'] <= 20, summary


def test_a_runs_page_faults_leave_out_its_sinks():
    """``RunResult.page_faults`` counts the clock's: a sink that touches 8 MiB of fresh
    pages (2048 of them) each call, called inside the clock (SINK_BATCH rows reached:
    200,001 samples) and after it, adds none to those of a sink that does nothing.

    The sink maps its pages itself: 8 MiB from malloc came from the heap's top wherever an
    earlier test had raised glibc's dynamic mmap threshold past it, and the run's next
    blocks were then fresh pages above them (511 faults in a fresh clone's suite): the
    heap's history, not the count this test is about."""
    import mmap
    from rigid_body_sim.offline import OFFLINE_BLOCK, SINK_BATCH, simulate
    held = []

    def sink(block):
        pages = mmap.mmap(-1, 8 << 20)  # 8 MiB outside malloc's heap, kept: fresh each call
        np.frombuffer(pages, dtype=np.uint8)[::mmap.PAGESIZE] = 1  # every page touched
        held.append(pages)

    def run(sinks):
        return simulate(load('tennis_racket', ['publish_rate=10000']), duration=20.0,
                        integrator='exact', keep='none', sinks=sinks).page_faults
    assert 20 * 10_000 > SINK_BATCH
    alone = run([lambda block: None])  # (the first also loads the kernels in this process)
    alone = min(alone, run([lambda block: None]))
    with_sink = run([sink])
    assert len(held) >= 200_001 // OFFLINE_BLOCK and with_sink is not None  # each block
    assert 0 <= with_sink <= alone + 100, (with_sink, alone)


def test_a_failing_dop853_reports_as_on_the_event_path():
    """dop853 failing inside the compiled loop raises the IntegrationError the event path
    raises (method, step, time, reason), and its memory starts afresh."""
    from rigid_body_sim.engine import EngineConfig
    from rigid_body_sim.physics import IntegrationError
    raised = []
    for compiled_loop in (False, True):
        engine = Engine(EngineConfig.from_parameters(
            {'integrator': 'dop853', 'duration': 1.0, 'publish_rate': 10.0,
             'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [1e160, 2e160, 1e160],
             'dissipation.model': 'viscous', 'dissipation.coefficient': 0.1}),
            compiled_loop=compiled_loop)
        with pytest.raises(IntegrationError) as exc, np.errstate(over='ignore'):
            list(engine.run())
        raised.append((exc.value.integrator, exc.value.h, exc.value.t, exc.value.reason))
        assert engine.fault and not engine.integrator._memory.any()
    assert raised[0] == raised[1] and raised[0][0] == 'dop853'


def test_an_offline_run_converts_two_rows_whatever_its_blocks(monkeypatch):
    """``offline.simulate`` converts the first and the last sample to the user's frames
    once each (each conversion of a long block's row costs ~70 µs: converting every
    block's last row was a third of a 100 samples/s run's overhead), and the last is the
    run's final sample."""
    from rigid_body_sim.offline import simulate
    calls = []
    row = SampleBlock.row

    def counted(self, i):
        if len(self) > 1:  # not the one-row block a long block's row converts through
            calls.append(i)
        return row(self, i)
    monkeypatch.setattr(SampleBlock, 'row', counted)
    scene = load('explorer1', ['publish_rate=100.0'])
    engine = engine_for(scene, duration=30.0, integrator='rk4', step=1e-3)
    engine._builder = type(engine._builder)(engine.body, 512)  # many blocks
    result = simulate(scene, engine=engine, keep='all')
    assert result.sample_count == 3001 and len(calls) == 2
    np.testing.assert_array_equal(result.final['attitude'], result.samples.attitude[-1])


# a held dipole in the closed-form field: the kernel runs between the hold's events (its
# expiry at 25 s here, mid-run); the tabulated IGRF line and the magnetometer stay on the
# event path
MAGNETIC = ['epoch=2026-03-20T12:00:00Z', 'environment.magnetic_field=dipole',
            'magnetorquer.max_dipole=[0.4, 0.4, 0.4]', 'command_timeout=25.0',
            'publish_rate=2.0', 'duration=60.0',
            'initial_angular_velocity=[0.003, -0.002, 0.004]']


def _held_dipole(method, sets, compiled_loop=None):
    engine = engine_for(load('gravity_gradient', sets), integrator=method,
                        step=None if method == 'dop853' else 0.1)
    if compiled_loop is not None:
        engine._compiled_samples = compiled_loop
    engine.apply_dipole_command(np.array([0.3, -0.2, 0.5]))  # clipped to 0.4 on z
    return engine, SampleBlock.concatenate(list(engine.run()))


@pytest.mark.parametrize('method', ['rk4', 'splitting4', 'dop853'])
def test_a_held_dipole_runs_in_the_compiled_loop_bit_for_bit(method, monkeypatch):
    (py, a), (kernel, b) = (_held_dipole(method, MAGNETIC, c) for c in (False, True))
    assert kernel._compiled_samples and len(a) == len(b) == 121
    for field in ('t_ns', 'q', 'm', 'torque', 'dipole'):
        np.testing.assert_array_equal(getattr(b, field), getattr(a, field), err_msg=field)
    assert py.steps == kernel.steps
    held = b.t_ns < 25e9
    assert np.array_equal(b.dipole[held], np.tile([0.3, -0.2, 0.4], (held.sum(), 1)))
    assert not b.dipole[~held].any()  # expired at 25 s
    # the dipole acts: the same run without it ends elsewhere
    engine = engine_for(load('gravity_gradient', MAGNETIC), integrator=method,
                        step=None if method == 'dop853' else 0.1)
    free = SampleBlock.concatenate(list(engine.run()))
    assert np.abs(free.m[-1] - b.m[-1]).max() > 1e-3 * np.abs(b.m[-1]).max()
    calls = {'integrate': 0}
    integrate = Engine._integrate

    def counted(self, *args):
        calls['integrate'] += 1
        return integrate(self, *args)
    monkeypatch.setattr(Engine, '_integrate', counted)
    _held_dipole(method, MAGNETIC)
    assert calls['integrate'] <= 6, calls  # not once per sample


def test_igrf_and_the_magnetometer_keep_the_event_path():
    for extra in (['environment.magnetic_field=igrf'], ['magnetometer.enabled=true']):
        engine, block = _held_dipole('rk4', MAGNETIC + extra)
        assert not engine._compiled_samples and len(block) == 121


def _blocks(scene, block_size=None, **overrides):
    """The run's blocks, each with a copy of its arrays taken as it was yielded."""
    engine = engine_for(scene, **overrides)
    if block_size is not None:
        engine._builder = type(engine._builder)(engine.body, block_size)
    out = []
    for b in engine.run():
        out.append((b, [getattr(b, k).copy() for k in ('t_ns', 'q', 'm', 'torque')]))
    return out


@pytest.mark.parametrize('name,overrides', [
    ('tennis_racket', {'duration': 3.0}),  # exact: the grid written by _free_samples
    ('explorer1', {'duration': 1.37, 'integrator': 'rk4', 'step': 1e-3}),  # compiled loop
    ('slew', {'duration': 2.0})])  # the law in the loop
def test_blocks_taken_without_copies_are_never_written_again(name, overrides):
    """A block that takes the builder's arrays (BlockBuilder.block) keeps its samples
    while the run goes on (the builder writes into fresh arrays); the run sized to its
    samples gives the samples of the former fixed 16,384-sample block bit for bit, and of
    any other cut into blocks bit for bit too (the compiled loop) or to round-off (exact:
    each block's grid has its own anchors)."""
    from rigid_body_sim.offline import OFFLINE_BLOCK
    scene = load(name, ['publish_rate=100.0'])
    runs = {size: _blocks(scene, size, **overrides) for size in (None, OFFLINE_BLOCK, 7, 64)}
    one = runs[None]
    assert len(one) == 1  # an offline engine's block holds the whole (short) run
    for size, blocks in runs.items():
        assert size in (None, OFFLINE_BLOCK) or len(blocks) > 2
        for b, copies in blocks:
            for k, c in zip(('t_ns', 'q', 'm', 'torque'), copies):
                np.testing.assert_array_equal(getattr(b, k), c, err_msg=f'{size} {k}')
        whole = SampleBlock.concatenate([b for b, _ in blocks])
        exact = size in (None, OFFLINE_BLOCK) or name != 'tennis_racket'
        for k in ('t_ns', 'q', 'm', 'torque'):
            np.testing.assert_allclose(getattr(whole, k), getattr(one[0][0], k), rtol=0,
                                       atol=0 if exact else 1e-13, err_msg=f'{size} {k}')


def test_an_offline_run_keeps_its_samples_without_copying_them():
    """``simulate(keep='all')`` of a run that fits one block returns that block's arrays,
    which are the engine's own: copying every sample twice (the block, then the result)
    cost ~30 ns a sample, as much as the exact solution's grid. A short block (a live
    node's few samples) is copied, so that it does not hold the builder's capacity."""
    from rigid_body_sim.engine.samples import BlockBuilder
    from rigid_body_sim.offline import simulate
    scene = load('tennis_racket', ['publish_rate=100.0'])
    engine = engine_for(scene, duration=3.0)
    seen = []
    result = simulate(scene, engine=engine, sinks=[seen.append], keep='all')
    assert len(seen) == 1 and result.sample_count == len(seen[0]) == 301
    for k in ('t_ns', 'q', 'm', 'torque'):
        assert np.shares_memory(getattr(result.samples, k), getattr(seen[0], k)), k
    assert engine._builder.capacity == 301  # sized to the run: t = 0 .. 3 s
    builder = BlockBuilder(engine.body, 1024)
    builder.add(0, np.array([0.0, 0.0, 0.0, 1.0]), np.ones(3), None)
    short = builder.block()
    assert short.q.base is None and len(short) == 1


def test_a_torque_free_exact_run_writes_no_torque_column(monkeypatch):
    """An exact torque-free stretch (Engine._free_samples) writes t, q and m only: its
    rows' torque is zeros, 24 of a sample's 88 bytes, which a one-shot run paid in page
    faults and writes. Every reader still gets an (n, 3) array of zeros; a builder whose
    torque column exists (a torque written before, a block copied out of it) gets zeros
    written over its old rows; rows added later keep their torque beside the free ones."""
    from rigid_body_sim.engine.samples import BlockBuilder
    from rigid_body_sim.offline import simulate
    made = []
    torque = BlockBuilder._torque
    monkeypatch.setattr(BlockBuilder, '_torque', lambda self: made.append(1) or torque(self))
    scene = load('tennis_racket', ['publish_rate=100.0'])
    result = simulate(scene, engine=engine_for(scene, duration=3.0), keep='all')
    assert result.integrator == 'exact' and result.sample_count == 301 and not made
    t = result.samples.torque
    assert t.shape == (301, 3) and t.dtype == np.float64 and not t.any()
    assert t.flags.c_contiguous and t.flags.writeable
    assert result.samples.values(300)[-3:] == [0.0, 0.0, 0.0]
    builder = BlockBuilder(result.samples.body, 1024)
    q, m = np.array([0.0, 0.0, 0.0, 1.0]), np.ones(3)
    builder.add(0, q, m, np.array([1.0, 2.0, 3.0]))  # the column now exists, row 0 written
    builder.block()  # copied out (short): the builder keeps its arrays, row 0's torque too
    t_col, q_col, m_col, tau_col = builder.free_columns(2)
    assert tau_col is not None and np.shares_memory(tau_col, builder._tau)
    fresh = BlockBuilder(result.samples.body, 1024)
    assert fresh.free_columns(2)[3] is None
    for b in (builder, fresh):  # as _free_samples: two free rows, then one with a torque
        t_col, q_col, m_col, tau_col = b.free_columns(2)
        t_col[:], q_col[:], m_col[:] = [0, 1], q, m
        if tau_col is not None:
            tau_col[:] = 0.0
        b.n = 2
        b.add(2, q, m, np.array([4.0, 5.0, 6.0]))
        np.testing.assert_array_equal(b.block().torque, [[0, 0, 0], [0, 0, 0], [4, 5, 6]])


def test_a_run_keeping_every_sample_takes_them_as_one_block():
    """A run longer than OFFLINE_BLOCK samples that keeps them all (keep='all': the bench,
    in-process users) fills one block and returns its arrays: concatenating blocks of
    16,384 copied every sample again (~45 ns a sample at 100 samples/s, 8x → 5x of the
    physics on slow generated scenes). Streamed runs keep their bounded blocks."""
    from rigid_body_sim.offline import OFFLINE_BLOCK, simulate
    scene = load('tennis_racket', ['publish_rate=100.0'])
    seen = []
    result = simulate(scene, engine=engine_for(scene, duration=200.0), sinks=[seen.append],
                      keep='all')
    assert result.sample_count == 20_001 > OFFLINE_BLOCK and len(seen) == 1
    assert np.shares_memory(result.samples.q, seen[0].q)
    seen = []
    simulate(scene, engine=engine_for(scene, duration=200.0), sinks=[seen.append],
             keep='plot')
    assert [len(b) for b in seen] == [OFFLINE_BLOCK, 20_001 - OFFLINE_BLOCK]


_DOP853_CALLS = '''
import json
from rigid_body_sim.offline import engine_for
from rigid_body_sim.physics.integrators import dop853_dense
from rigid_body_sim.scene import load
calls = [0]
advance = dop853_dense.advance
def counted(*args):
    calls[0] += 1
    return advance(*args)
dop853_dense.advance = counted
engine = engine_for(load('tennis_racket', ['publish_rate=100.0', 'dissipation.model=viscous',
                                           'dissipation.coefficient=0.01']),
                    duration=5.0, integrator='dop853')
samples = sum(len(b) for b in engine.run())
print(json.dumps({'samples': samples, 'calls': calls[0], 'steps': engine.steps}))
'''


def test_dop853_samples_inside_a_step_do_not_call_its_advance():
    """A dop853 sample inside the step in progress is interpolated inside the compiled
    loop (dop853_dense._interpolated, inlined): calling dop853_dense.advance for it cost
    ~150 ns of the ~200 ns a sample cost (its arrays' reference counts). Counted as plain
    Python (NUMBA_DISABLE_JIT=1), where the loop calls the module's function."""
    import os
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-c', _DOP853_CALLS], capture_output=True,
                          text=True, env=dict(os.environ, NUMBA_DISABLE_JIT='1'), timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out['samples'] == 501
    assert 0 < out['calls'] < 50, out  # ~1 s steps: the steps' calls, not the samples'


_DENSE_CALLS = """
import json
from rigid_body_sim.offline import engine_for
from rigid_body_sim.engine import dop853_samples
from rigid_body_sim.physics.integrators import dop853_dense
from rigid_body_sim.scene import load
calls = {'_interpolated': 0, 'advance': 0, 'sampled_steps': 0}
def counted(module, name):
    function = getattr(module, name)
    def call(*args):
        calls[name] += 1
        return function(*args)
    setattr(module, name, call)
counted(dop853_dense, '_interpolated')
counted(dop853_dense, 'advance')
counted(dop853_samples, 'sampled_steps')
engine = engine_for(load('tennis_racket', ['publish_rate=100.0', 'dissipation.model=viscous',
                                           'dissipation.coefficient=0.01']),
                    duration=5.0, integrator='dop853')
samples = sum(len(b) for b in engine.run())
print(json.dumps({'samples': samples, **calls}))
"""


def test_dop853_samples_are_one_loop_not_one_call_each():
    """dop853's samples come from one loop of its steps (engine.dop853_samples), not a
    call of dop853_dense.advance or _interpolated each: the call's checks and the event
    loop's work around it cost ~65 of a sample's ~95 ns; then an advance call and a
    pass of the event loop a step cost 2.2-2.4x the samples' floor at ~5-12 samples a
    step. Counted as plain Python, where the loop calls the modules' functions."""
    import os
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-c', _DENSE_CALLS], capture_output=True,
                          text=True, env=dict(os.environ, NUMBA_DISABLE_JIT='1'), timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out['samples'] == 501
    # the run's first output (no step in progress yet) and the end's; a call of the loop
    # a block (before: advance where a step ends, ~5; before that one a sample, 500)
    assert 0 < out['advance'] <= 3 and out['_interpolated'] <= 2 * out['advance'], out
    assert 0 < out['sampled_steps'] <= 3, out


def test_the_free_bodys_rk4_steps_and_hermite_ends_are_the_out_of_line_ones_bit_for_bit():
    """A sample between rk4 steps runs the step loop twice and the Hermite end twice; for
    the free body (env None) the loop inlines versions whose stages are numbers
    (explicit_kernel.rk4_free_steps, rk4_free_end): the views of the scratch cost a
    reference-count round trip each, per call. They are inlined
    (``inline='always'``) and give rk4_steps' and _end's numbers to the bit, on random
    bodies, torques, each damping model, and a step that fails (the same step, the same
    state left). test_compiled_samples_are_the_event_loop_samples_bit_for_bit compares the
    whole loop's samples with the event path's."""
    from rigid_body_sim.engine import sample_kernel
    from rigid_body_sim.physics.integrators import explicit_kernel
    from rigid_body_sim.physics.jit import COMPILED
    assert COMPILED, 'this interpreter runs the kernels as plain Python'
    for kernel in (explicit_kernel.rk4_free_steps, explicit_kernel.rk4_free_end):
        assert kernel.targetoptions.get('inline') == 'always'
    rng = np.random.default_rng(20261127)
    for trial in range(60):
        model = trial % 3
        moments = rng.uniform(0.5, 3.0, 3)
        q0 = rng.normal(size=4)
        q0 /= np.linalg.norm(q0)
        m0 = rng.normal(size=3) * rng.uniform(0.1, 5.0)
        tau = rng.normal(size=3) * 0.1 if trial % 2 else np.zeros(3)
        h, n, coefficient = rng.uniform(1e-3, 0.05), int(rng.integers(1, 40)), 0.05
        if trial == 59:  # it overflows within a few steps: both stop at the same one
            m0, h, n = np.array([1e150, -3e150, 2e150]), 1.0, 30
        q1, m1, q2, m2 = q0.copy(), m0.copy(), q0.copy(), m0.copy()
        failed = explicit_kernel.rk4_steps(q1, m1, h, n, moments, tau, model, coefficient,
                                           np.empty((10, 4)), 0.0, None)
        assert explicit_kernel.rk4_free_steps(q2, m2, h, n, moments, tau, model,
                                              coefficient) == failed
        assert (failed >= 0) == (trial == 59)
        assert np.array_equal(q1, q2, equal_nan=True) and np.array_equal(m1, m2, equal_nan=True)
        herm1, herm2 = np.full((8, 4), 7.0), np.full((8, 4), 7.0)
        sample_kernel._end(q0, m0, moments, tau, model, coefficient, 0.0, None, herm1, 4)
        sample_kernel._free_end(q0, m0, moments, tau, model, coefficient, herm2, 4)
        assert np.array_equal(herm1, herm2)  # the other end and the unused cells untouched


def test_auto_runs_the_free_phase_in_the_compiled_loop(monkeypatch):
    """With ``auto`` the law's free phase (no torque by the mission) runs in the compiled
    loop: the event loop evaluates the law only around the first instant that may give a
    torque (where auto chooses again), not at each of the ~850 free instants at 50 Hz (the
    default scene cost 12x the cheapest fixed choice that way). The free phase's samples
    are the torque-free motion: within the scene's budget (1e-4 rad) of the exact solution."""
    from rigid_body_sim.engine.sources import ControlLaw
    from rigid_body_sim.offline import simulate
    calls = []
    on_event = ControlLaw.on_event

    def counted(self, t_ns, *args):
        calls.append(t_ns)
        return on_event(self, t_ns, *args)
    scene = load('default')
    free = scene.controller['mission.free_time']
    monkeypatch.setattr(ControlLaw, 'on_event', counted)
    run = simulate(scene, engine=engine_for(scene, duration=free + 1.0), keep='all')
    in_free = [t for t in calls if t / 1e9 < free - 0.1]
    assert run.integrator != 'exact' and len(in_free) <= 3, (run.integrator, len(in_free))
    assert any(t / 1e9 >= free for t in calls)  # the law's first torque: the event loop's
    monkeypatch.setattr(ControlLaw, 'on_event', on_event)
    exact = simulate(scene, engine=engine_for(scene, duration=free - 0.5,
                                              integrator='exact'), keep='all')
    n = len(exact.samples)
    a, b = run.samples.attitude[:n], exact.samples.attitude[:n]
    assert np.allclose(run.samples.t[:n], exact.samples.t)
    angle = 2 * np.arcsin(np.minimum(1.0, np.linalg.norm(
        a[:, :3] * b[:, 3:] - b[:, :3] * a[:, 3:] + np.cross(b[:, :3], a[:, :3]), axis=1)))
    assert angle.max() < 1e-4, angle.max()
    # and the samples of a run that evaluates the law at every free instant
    monkeypatch.setattr(ControlLaw, 'skip_free_instants', lambda self: None)
    every = simulate(scene, engine=engine_for(scene, duration=free - 0.5), keep='all')
    # (the exact flow's grid between law instants: the same solution to round-off)
    n = len(every.samples)
    assert np.abs(every.samples.attitude - run.samples.attitude[:n]).max() < 1e-13
    assert np.abs(every.samples.angular_momentum
                  - run.samples.angular_momentum[:n]).max() < 1e-13 * np.abs(
                      every.samples.angular_momentum).max()


def test_the_loop_writes_its_failure_record_in_one_place():
    """Every way the compiled loop stops on a failure (a fixed step interpolating or not,
    dop853, a non-finite sample) writes ``out`` through one function
    (``closed_loop._stopped``), and a failed fixed step's tail is written once for both
    ways of stepping: before, five copies of the record, two of the tail."""
    import inspect
    from rigid_body_sim.engine import closed_loop
    kernel = closed_loop.closed_loop_run
    src = inspect.getsource(getattr(kernel, 'py_func', kernel))
    assert src.count('out[5] =') == 1  # the run's normal end
    assert src.count('_stopped(') == 5 and src.count('if failed >= 0') == 1
    assert 'out[9]' not in src and 'out[10]' not in src  # dop853's too: _stopped's
