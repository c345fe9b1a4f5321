"""The simulation engine (rigid_body_sim.engine): ROS-free, exact time, one trajectory.

Physics oracles: the closed-form torque-free solution at the exact elapsed time, and the
same engine driven by the offline run and by the benchmark harness.
"""
import os
import subprocess
import sys

import numpy as np
import pytest

from rigid_body_sim.engine import Engine, EngineConfig, SampleBlock
from rigid_body_sim.physics import rotation
from rigid_body_sim.physics.exact import TorqueFreeSolution

pytestmark = pytest.mark.fast  # make check

CLI = os.path.join(os.path.dirname(sys.executable), 'rigid-body-sim')
ROS_MODULES = ('rclpy', 'builtin_interfaces', 'geometry_msgs', 'std_msgs', 'nav_msgs',
               'diagnostic_msgs', 'rosgraph_msgs', 'std_srvs', 'rcl_interfaces')


@pytest.mark.slow
def test_scene_engine_and_offline_run_need_no_ros():
    """With rclpy and every message package made unimportable, every scene loads and runs
    offline (no bag, no plots)."""
    block = '; '.join(f'sys.modules[{m!r}] = None' for m in ROS_MODULES)
    code = (f'import sys; {block}\n'
            'import rigid_body_sim.scene as S, rigid_body_sim.engine, '
            'rigid_body_sim.offline as O\n'
            'for name, _, _ in S.list_scenes():\n'
            '    scene = S.load(name)\n'
            '    if scene.spacecraft: continue  # several spacecraft: live only\n'
            '    r = O.simulate(scene, duration=2 / scene.simulator["publish_rate"], '
            'keep="none")\n'
            '    assert r.sample_count == 3, name\n'
            'print("ok", len(S.list_scenes()))\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.startswith('ok ') and int(out.stdout.split()[1]) >= 7


def test_stepped_exact_stays_exact_over_a_million_samples():
    """`exact` named explicitly with a step 10x smaller than the sample period: 1e6 samples
    of 0.01 s; every sample time is an exact multiple of the period and the attitude at
    N·h equals the closed form evaluated at N·h to 1e-12 rad."""
    config = EngineConfig.from_parameters({
        'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.05, 1.0, 0.02],
        'initial_attitude': [0.1, -0.2, 0.3, 0.9], 'integrator': 'exact', 'step': 0.001,
        'publish_rate': 100.0, 'duration': 1e4})
    engine = Engine(config)
    period = config.sample_period_ns
    assert period == 10_000_000
    count, last = 0, None
    for block in engine.run():
        assert np.all(block.t_ns == (count + np.arange(len(block))) * period)
        count += len(block)
        last = block
    assert count == 1_000_001
    body = config.body
    solution = TorqueFreeSolution(body.principal_moments, body.attitude_to_principal(
        config.attitude), body.principal_moments * body.to_principal(config.angular_velocity))
    q, m = solution.at(1e6 * 0.01)
    q_body = body.attitude_to_body(q)
    assert rotation.angle_between(q_body, last.attitude[-1]) <= 1e-12
    np.testing.assert_allclose(last.angular_velocity[-1], body.to_body(m / body.principal_moments),
                               rtol=0, atol=1e-12)
    assert engine.steps == 0  # evaluated, never stepped


@pytest.mark.parametrize('integrator', ['exact', 'rk4'])
def test_a_run_ends_at_its_duration_whatever_the_sample_period(integrator):
    """1.37 s at 1 sample/s: samples at 0 and 1 s, then the final state at 1.37 s (it
    stopped at 1.0 s), equal to the closed form there."""
    sim = {'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.3, 1.1, 0.2],
           'initial_attitude': [0.1, -0.2, 0.3, 0.9], 'integrator': integrator,
           'step': 0.001, 'publish_rate': 1.0, 'duration': 1.37}
    config = EngineConfig.from_parameters(sim)
    block = SampleBlock.concatenate(list(Engine(config).run()))
    assert block.t_ns.tolist() == [0, 1_000_000_000, 1_370_000_000]
    body = config.body
    q, m = TorqueFreeSolution(body.principal_moments, body.attitude_to_principal(
        config.attitude), body.principal_moments * body.to_principal(config.angular_velocity)
    ).at(1.37)
    tol = 1e-12 if integrator == 'exact' else 1e-9
    assert rotation.angle_between(body.attitude_to_body(q), block.attitude[-1]) <= tol
    np.testing.assert_allclose(block.angular_velocity[-1],
                               body.to_body(m / body.principal_moments), rtol=0, atol=tol)


def test_a_controlled_run_ends_at_its_duration():
    """The compiled closed loop too: 2.55 s at 2 samples/s under a 3 Hz law ends with a
    sample at 2.55 s, after the one at 2.5 s."""
    sim = {'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.3, 0.1, 0.2],
           'integrator': 'rk4', 'step': 0.01, 'publish_rate': 2.0, 'duration': 2.55}
    ctl = {'mode': 'detumble', 'control_rate': 3.0, 'inertia': [1.0, 2.0, 3.0]}
    t = np.concatenate([b.t_ns for b in Engine(EngineConfig.from_parameters(sim, ctl)).run()])
    assert t[-1] == 2_550_000_000 and t[-2] == 2_500_000_000


def test_sim_time_is_integer_nanoseconds_and_events_split_steps():
    """A 30 Hz sample rate (period 33,333,333 ns) with a 20 Hz control law: samples land on
    multiples of the period (and the last at the end, 3 s), control updates on multiples of
    50 ms, steps never straddle either, and the torque column changes only at control
    instants."""
    sim = {'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.3, 0.1, 0.2],
           'integrator': 'rk4', 'step': 0.01, 'publish_rate': 30.0, 'duration': 3.0}
    ctl = {'mode': 'detumble', 'control_rate': 20.0, 'inertia': [1.0, 2.0, 3.0]}
    engine = Engine(EngineConfig.from_parameters(sim, ctl))
    blocks = list(engine.run())
    t = np.concatenate([b.t_ns for b in blocks])
    tau = np.concatenate([b.torque for b in blocks])
    assert np.all(t[:-1] % 33_333_333 == 0) and t[-2] == 90 * 33_333_333
    assert t[-1] == 3_000_000_000
    changes = t[1:][np.any(np.diff(tau, axis=0) != 0.0, axis=1)]
    # a sample shows the torque held since the latest control instant at or before it
    held_since = (t // 50_000_000) * 50_000_000
    assert len(changes) > 10 and np.all(np.diff(held_since[np.isin(t, changes)]) > 0)
    # control instants (60) + samples (100) + end, each span split into <= 10 ms steps
    assert engine.steps >= 160


def test_offline_run_and_benchmark_give_the_same_trajectory():
    """One engine behind both: the bench harness on a bench scene and the offline run on a
    params file with the same body, state, dissipation, method and step agree to 1e-12."""
    from rigid_body_sim.bench.common import propagate
    from rigid_body_sim.bench.scenes import SCENE_BY_NAME
    from rigid_body_sim.offline import simulate
    from rigid_body_sim.scene import SceneFile
    from rigid_body_sim.param_spec import coerce_all
    from rigid_body_sim.engine import specs
    bench = SCENE_BY_NAME['dissipation']
    params = coerce_all(specs.SIMULATOR, {
        'inertia': list(bench.moments), 'initial_attitude': list(bench.q0),
        'initial_angular_velocity': list(bench.omega0), 'dissipation.model': 'double_bracket',
        'dissipation.coefficient': bench.dissipation.coefficient, 'integrator': 'splitting4',
        'step': 0.005, 'publish_rate': 20.0, 'duration': bench.t_end})
    offline = simulate(SceneFile('x', '', 'inline', params))
    q, m, engine = propagate(bench, 'splitting4', 0.005)
    assert offline.steps == engine.steps == int(bench.t_end / 0.005)
    np.testing.assert_allclose(offline.samples.attitude[-1], q / np.linalg.norm(q), rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(offline.samples.angular_momentum_body[-1], m, rtol=0, atol=1e-12)


def _peak_rss_kb(duration):
    code = ('import resource, rigid_body_sim.offline as O, rigid_body_sim.scene as S\n'
            f'r = O.simulate(S.load("tennis_racket"), duration={duration}, keep="plot")\n'
            'print(r.sample_count, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    n, kb = map(int, out.stdout.split())
    return n, kb


@pytest.mark.slow
def test_offline_memory_does_not_grow_with_the_run():
    """Peak RSS of an offline run is the same (within 8 MB) for 1e4 and 1e6 samples: the
    samples stream through, only a bounded plot series is kept."""
    n_small, small = _peak_rss_kb(100.0)
    n_large, large = _peak_rss_kb(1e4)
    assert n_small == 10_001 and n_large == 1_000_001
    assert large - small < 8 * 1024, (small, large)


@pytest.mark.slow
def test_run_json_reports_selection_cpu_and_sample_count(tmp_path):
    import json
    # 300 s: long enough that a pilot round fits in the selection's 10 % of the run, and
    # that exact's a-priori bound (2·Δβ, the damping's turning) is over the budget
    out = subprocess.run([CLI, 'run', 'explorer1', '--duration', '300', '--json', '--no-plots',
                          '--out', str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout)
    assert summary['samples'] == 301 and summary['selection_cpu_seconds'] > 0.0
    # the planned cost of choosing (the a-priori pass and the pilot) is at most 10 % of the
    # run the model predicts; load only adds to the CPU measured, so it stays below the run
    assert 0.0 < summary['selection_planned_cpu_seconds'] < summary['cpu_seconds']
    from rigid_body_sim.physics.auto import CANDIDATES
    assert summary['integrator'] in [c.name for c in CANDIDATES]
    assert summary['pilot_steps'] > 0  # dissipation, no torque: auto ran its pilot
    assert summary['evaluations'] >= summary['steps'] > 0


def test_evaluations_count_what_each_method_did():
    """``evaluations`` counts right-hand sides, where ``steps`` counts steps (outputs for
    DOP853): RK4 four per step; DOP853 twelve per natural step, far more than its outputs."""
    from rigid_body_sim.offline import simulate
    from rigid_body_sim.scene import load
    scene = load('explorer1')
    rk4 = simulate(scene, duration=5.0, integrator='rk4', step=0.01)
    assert rk4.steps == 500 and rk4.evaluations == 4 * 500
    dop = simulate(scene, duration=5.0, integrator='dop853', step=0.05)  # 100 outputs
    assert dop.evaluations > 10 * dop.steps


def _closed_loop_pair(sim, ctl):
    """The same controlled run event by event (Python) and in the compiled closed loop."""
    out = []
    for compiled in (False, True):
        engine = Engine(EngineConfig.from_parameters(sim, ctl), compiled_loop=compiled)
        blocks = list(engine.run())
        out.append((engine, SampleBlock.concatenate(blocks)))
    return out


@pytest.mark.parametrize('method', ['splitting4', 'rk4', 'euler'])
def test_compiled_closed_loop_is_the_event_by_event_loop(method):
    """A full-tensor body (principal frame ≠ body frame) with double-bracket damping,
    detumbled after a free phase, switched to slew by the mission's exit rate, torque
    clipped per axis by the simulator: every sample of the compiled closed loop equals the
    event-by-event path's to 1e-12, with the same step count and mission switch."""
    inertia = [2.0, 0.1, 0.05, 0.1, 3.0, 0.2, 0.05, 0.2, 4.0]
    sim = {'inertia': inertia, 'initial_angular_velocity': [0.4, -0.3, 0.5],
           'initial_attitude': [0.1, -0.2, 0.3, 0.9], 'dissipation.model': 'double_bracket',
           'dissipation.coefficient': 0.05, 'integrator': method, 'step': 0.01,
           'publish_rate': 7.0, 'duration': 30.0, 'max_torque': 0.3}
    ctl = {'inertia': inertia, 'mode': 'detumble', 'control_rate': 30.0,
           'natural_frequency': 0.6, 'target_attitude': [0.0, 0.6, 0.0, 0.8],
           'mission.free_time': 2.0, 'mission.detumble_exit_rate': 0.05, 'max_torque': 0.5}
    (py, a), (compiled, b) = _closed_loop_pair(sim, ctl)
    assert len(a) == len(b) == 211  # 30 s at 1/7 s: samples 0 … 209, then the end, 30 s
    np.testing.assert_array_equal(a.t_ns, b.t_ns)
    for field in ('attitude', 'angular_velocity', 'angular_momentum', 'torque'):
        np.testing.assert_allclose(getattr(b, field), getattr(a, field), rtol=0, atol=1e-12)
    assert py.steps == compiled.steps and py.integrator.nfev == compiled.integrator.nfev
    assert py._law.controller.mode == compiled._law.controller.mode == 'slew'
    # the free phase had no torque, the clip bounded it afterwards, and the slew ended near
    free = a.t < 2.0
    assert np.all(b.torque[free] == 0.0) and np.abs(b.torque).max() <= 0.3
    assert np.any(np.abs(b.torque[~free]).max(axis=1) > 0.1)


def test_compiled_closed_loop_reports_divergence():
    """Euler at a step far past its limit diverges inside the compiled loop: the same
    IntegrationError (method, step, time) as everywhere, and the engine stops at a fault."""
    from rigid_body_sim.physics import IntegrationError
    sim = {'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [300.0, 1e3, 20.0],
           'integrator': 'euler', 'step': 0.5, 'publish_rate': 0.1, 'duration': 1e4}
    ctl = {'mode': 'detumble', 'control_rate': 1.0, 'max_torque': 1e-3}
    engine = Engine(EngineConfig.from_parameters(sim, ctl))
    with pytest.raises(IntegrationError, match=r'euler failed at t = .* h = 0\.5'):
        list(engine.run())
    assert engine.fault


def test_set_state_continues_from_the_new_state_at_the_same_time():
    """set_state mid-run: sim time stays, and the run from there is the run of a fresh
    engine started in that state (torque-free exact flow, evaluated from the new anchor)."""
    params = {'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.05, 1.0, 0.02],
              'integrator': 'exact', 'publish_rate': 10.0, 'duration': 4.0}
    engine = Engine(EngineConfig.from_parameters(params))
    first = SampleBlock.concatenate(engine.run(2_000_000_000))
    q_new, w_new = [0.0, 0.6, 0.0, 0.8], [0.3, -0.2, 0.9]
    engine.set_state(q_new, w_new)
    assert engine.t_ns == first.t_ns[-1] == 2_000_000_000
    rest = SampleBlock.concatenate(engine.run())
    fresh = Engine(EngineConfig.from_parameters(dict(
        params, initial_attitude=q_new, initial_angular_velocity=w_new, duration=2.0)))
    expected = SampleBlock.concatenate(fresh.run())
    np.testing.assert_allclose(rest.attitude, expected.attitude[1:], rtol=0, atol=1e-13)
    np.testing.assert_allclose(rest.angular_velocity, expected.angular_velocity[1:], rtol=0,
                               atol=1e-13)
    with pytest.raises(ValueError, match='not finite'):
        engine.set_state(q_new, [np.nan, 0.0, 0.0])


def test_row_values_equal_the_vectorised_fields_for_a_rotated_body():
    """SampleBlock.values converts short blocks on Python floats (the live node's path) and
    long ones from the vectorised fields; both must agree to round-off (1e-15 relative),
    also for a full inertia tensor whose principal axes are not the body axes."""
    from scipy.spatial.transform import Rotation

    from rigid_body_sim.physics.body import RigidBody
    rng = np.random.default_rng(3)
    axes = Rotation.from_quat(rng.normal(size=4)).as_matrix()
    inertia = axes @ np.diag([1.0, 2.0, 2.5]) @ axes.T
    body = RigidBody.from_inertia(inertia.ravel().tolist())
    assert not np.allclose(body.principal_axes, np.eye(3))
    n = 3
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    block = SampleBlock(np.arange(n, dtype=np.int64), q, rng.normal(size=(n, 3)),
                        rng.normal(size=(n, 3)), body)
    rows = [block.values(i) for i in range(n)]          # row path (short block)
    assert 'attitude' not in block.__dict__
    whole = block.take(slice(None))
    fields = np.column_stack([whole.attitude, whole.angular_velocity, whole.angular_momentum,
                              whole.angular_momentum_body, whole.kinetic_energy, whole.torque])
    assert np.allclose(np.array(rows), fields, rtol=1e-15, atol=1e-15)
    assert whole.values(1) == fields[1].tolist()         # fields path once they exist


def test_only_the_engine_writes_its_state():
    """The engine's other modules get a State record and give one back: none of them
    touches the Engine's private attributes or writes its time, counters or fault, and the
    compiled closed loop takes a few typed groups, not dozens of positional parameters."""
    import inspect
    import re
    from rigid_body_sim import engine as package
    from rigid_body_sim.engine import closed_loop
    folder = os.path.dirname(package.__file__)
    for name in sorted(os.listdir(folder)):
        if not name.endswith('.py') or name == 'core.py':
            continue
        with open(os.path.join(folder, name)) as f:
            src = f.read()
        assert not re.search(r'\bengine\._\w', src), name
        assert not re.search(r'\bengine\.(t_ns|steps|fault|finished)\s*[+-]?=(?!=)', src), name
    kernel = closed_loop.closed_loop_run
    params = inspect.signature(getattr(kernel, 'py_func', kernel)).parameters
    # (the environment's array also apart from the body's group: numba types the inlined
    # loops' `env is None` branches away only for an argument)
    assert len(params) <= 9, list(params)


def test_advancing_to_a_lockstep_instant_calls_the_compiled_loop_once(monkeypatch):
    """An external command held, the engine advanced to the next control instant (what
    a lockstep exchange asks of it): one call of the compiled loop, which writes that
    instant's sample; before, a second call followed to find no event up to the instant."""
    from rigid_body_sim.engine import closed_loop_args
    from rigid_body_sim.scene import load
    scene = load(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
                              'config', 'slew.yaml'),
                 ['integrator=splitting4', 'duration=1.0', 'publish_rate=50.0'])
    period = 20_000_000
    calls = []
    advance = closed_loop_args.advance
    monkeypatch.setattr(closed_loop_args, 'advance',
                        lambda *a: (calls.append(a[4]), advance(*a))[1])
    stepped = Engine(EngineConfig.from_parameters(scene.simulator), blocking_selection=False)
    assert len(stepped.advance(0)) == 1
    for k in range(1, 10):
        stepped.apply_command((0.0, 0.0, 1e-3 * k))
        del calls[:]
        block = stepped.advance(k * period)
        assert len(block) == 1 and stepped.t_ns == k * period and calls == [k * period]


def _lockstep_pair(sim, ctl=None):
    """The same engine with the compiled loop (its arguments packed once, reused) and
    event by event (nothing packed)."""
    config = EngineConfig.from_parameters(sim, ctl)
    return [Engine(config, blocking_selection=False, compiled_loop=compiled)
            for compiled in (True, False)]


def _same_samples(engines, until_ns):
    a, b = (e.advance(until_ns) for e in engines)
    assert len(a) == len(b) > 0 and engines[0].t_ns == engines[1].t_ns
    np.testing.assert_array_equal(a.t_ns, b.t_ns)
    for field in ('q', 'm', 'torque'):
        np.testing.assert_allclose(getattr(a, field), getattr(b, field), rtol=0, atol=1e-12,
                                   err_msg=field)


def test_the_compiled_loops_arguments_packed_once_follow_every_change():
    """The compiled loop's arguments are packed once per engine and reused from call to
    call (a lockstep exchange is a call): what changed between calls reaches the loop.
    Driven call by call through commands (held, then another), a new step and
    dissipation (a new integrator and dynamics), a new torque clip and target for the
    law, and a reset to a new inertia (a new body and controller), each engine's
    samples are those of the event-by-event path (which packs nothing) to 1e-12; while
    nothing changes the packed groups are the same objects."""
    sim = {'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.3, -0.2, 0.4],
           'integrator': 'rk4', 'step': 0.005, 'publish_rate': 50.0, 'duration': 0.0}
    period = 20_000_000
    held = _lockstep_pair(sim)
    _same_samples(held, 0)
    packing = held[0]._loop_args
    for k in range(1, 6):
        for e in held:
            e.apply_command((1e-3 * k, 0.0, -2e-3 * k))
        _same_samples(held, k * period)
    assert held[0]._loop_args is packing
    groups = (packing.method(held[0].integrator),
              packing.body(held[0].dynamics, held[0].body), packing.ticks, packing.out)
    for e in held:
        e.reconfigure(EngineConfig.from_parameters(
            {**sim, 'step': 0.002, 'dissipation.model': 'viscous',
             'dissipation.coefficient': 0.3}))
        e.apply_command((0.0, 5e-3, 0.0))
    _same_samples(held, 6 * period)
    assert packing.method(held[0].integrator) is not groups[0]
    assert packing.body(held[0].dynamics, held[0].body) is not groups[1]
    assert packing.ticks is groups[2] and packing.out is groups[3]

    ctl = {'inertia': [1.0, 2.0, 3.0], 'mode': 'slew', 'control_rate': 50.0,
           'max_torque': 0.05}
    controlled = _lockstep_pair({**sim, 'max_torque': 0.05}, ctl)
    _same_samples(controlled, 0)
    for k in range(1, 4):
        _same_samples(controlled, k * period)
    law = controlled[0]._loop_args.law(controlled[0]._law.controller)
    _same_samples(controlled, 4 * period)
    assert controlled[0]._loop_args.law(controlled[0]._law.controller) is law
    for e in controlled:  # a new target for the law's controller
        e._law.controller.set_target((0.0, 0.6, 0.0, 0.8))
    _same_samples(controlled, 6 * period)
    for e in controlled:  # a tighter clip: the law's torque now saturates
        e.reconfigure(EngineConfig.from_parameters({**sim, 'max_torque': 1e-4}, ctl))
    _same_samples(controlled, 9 * period)
    assert np.abs(controlled[0].torque).max() == pytest.approx(1e-4)
    bigger = {**ctl, 'inertia': [2.0, 5.0, 7.0]}
    for e in controlled:  # a new body for the simulator and the law's model
        e.reconfigure(EngineConfig.from_parameters(
            {**sim, 'inertia': [2.0, 5.0, 7.0], 'max_torque': 0.05}, bigger))
        e.reset()
    for k in range(10, 13):
        _same_samples(controlled, k * period)
    assert controlled[0]._loop_args.law(controlled[0]._law.controller) is not law


def test_the_engines_records_are_immutable_tuples():
    """State and Stretch (the records the engine hands its modules and takes back, three
    per lockstep exchange) are named tuples: immutable as the frozen dataclasses they were,
    made in a third of the time (a frozen dataclass sets each field through
    object.__setattr__: 1.1 µs a record)."""
    import dataclasses
    from rigid_body_sim.engine.state import State, Stretch
    state = State(np.zeros(4), np.zeros(3), 0, 10, None, None, False)
    done = Stretch(state, 1, 2, 3)
    assert isinstance(state, tuple) and isinstance(done, tuple)
    assert not dataclasses.is_dataclass(state) and not dataclasses.is_dataclass(done)
    assert done.error is None and done.full is False and done.state.next_sample == 10
    with pytest.raises(AttributeError):
        state.t_ns = 5
