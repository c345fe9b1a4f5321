"""Samples between steps (engine/sample_kernel.py): an offline run's steps and auto's
choice do not depend on the sample rate, and the samples keep the method's accuracy.

Before, every sample was an event the steps landed on: a step that did not divide the
sample period was shortened (rk4 at 4 ms ran 1,200 steps of 2.5 ms over 3 s at 100
samples/s, 750 at 1 sample/s), and auto chose with the sample period as its longest step
(detumble: splitting6 at 20 ms at 1 sample/s, splitting4 at 5 ms at 100).
"""
import numpy as np
import pytest

from rigid_body_sim.engine import Engine, EngineConfig, SampleBlock
from rigid_body_sim.offline import engine_for, simulate
from rigid_body_sim.physics import rotation
from rigid_body_sim.physics.exact import TorqueFreeSolution
from rigid_body_sim.scene import load

# a free tumble near the intermediate axis (tennis racket's inertia, |ω| ≈ 10 rad/s)
FREE = {'inertia': [0.0023, 0.0140, 0.0163], 'initial_angular_velocity': [0.05, 10.0, 0.05],
        'initial_attitude': [0.1, -0.2, 0.3, 0.9], 'accuracy': 1e-6}


def _run(sim, **engine):
    config = EngineConfig.from_parameters(sim)
    engine = Engine(config, **engine)
    return config, engine, SampleBlock.concatenate(list(engine.run()))


def _errors(config, block):
    """Attitude error (rad) and ω error (rad/s) of every sample against the closed form."""
    body = config.body
    exact = TorqueFreeSolution(body.principal_moments,
                               body.attitude_to_principal(config.attitude),
                               body.principal_moments * body.to_principal(
                                   config.angular_velocity))
    angle, rate = [], []
    for i, t_ns in enumerate(block.t_ns):
        q, m = exact.at(t_ns / 1e9)
        angle.append(rotation.angle_between(body.attitude_to_body(q), block.attitude[i]))
        rate.append(np.abs(block.angular_velocity[i]
                           - body.to_body(m / body.principal_moments)).max())
    return np.array(angle), np.array(rate)


@pytest.mark.parametrize('integrator,step', [('rk4', 0.004), ('splitting6', 0.004)])
def test_samples_between_steps_match_the_torque_free_solution(integrator, step):
    """At 100 samples/s the method keeps its own step (every other sample falls
    mid-step; landing on them ran 902 steps) and every sample is within the scene's
    accuracy (1e-6 rad; ω to 1e-5 rad/s) of the exact solution; an interpolated one
    within the interpolant's share of it, a tenth (1e-7 rad), of the method's own error
    at the step ends (measured: +7e-9 rad for rk4, +1.3e-8 for splitting6, as
    (hΩ)⁴/192 predicts). The run ends at its duration, 3.008 s, off the sample grid,
    with the steps of the run at 1 sample/s, whose samples are the dense run's own."""
    sim = {**FREE, 'integrator': integrator, 'step': step, 'duration': 3.008,
           'publish_rate': 100.0}
    config, dense, block = _run(sim, interpolate_samples=True)
    _, sparse, ends = _run({**sim, 'publish_rate': 1.0}, interpolate_samples=True)
    assert dense.steps == sparse.steps == round(3.008 / step)  # no step shortened
    assert len(block) == 302 and block.t_ns[-1] == 3_008_000_000
    angle, rate = _errors(config, block)
    assert angle.max() <= 1e-6 and rate.max() <= 1e-5, (angle.max(), rate.max())
    mid = block.t_ns % round(step * 1e9) != 0
    assert mid.sum() == 150 and angle[mid].max() <= angle[~mid].max() + 1e-7
    on_grid = np.isin(block.t_ns, ends.t_ns)
    assert on_grid.sum() == len(ends) == 5
    np.testing.assert_allclose(block.q[on_grid], ends.q, rtol=0, atol=1e-14)
    np.testing.assert_allclose(block.m[on_grid], ends.m, rtol=0, atol=1e-14)


def test_interpolation_is_refused_where_it_would_miss_the_accuracy():
    """rk4 at 20 ms on a 10 rad/s tumble: the cubic's error, ~(hΩ)⁴/192 ≈ 8e-5 rad, is
    far above a tenth of the 1e-6 budget, so the steps land on the samples as before
    (0.02 s steps cut to 0.01 s) and the samples are the method's own states."""
    sim = {**FREE, 'integrator': 'rk4', 'step': 0.02, 'duration': 1.0,
           'publish_rate': 100.0, 'accuracy': 1e-6}
    _, engine, block = _run(sim, interpolate_samples=True)
    assert engine.steps == 100
    _, landing, same = _run(sim, interpolate_samples=False)
    np.testing.assert_array_equal(block.q, same.q)


def test_denser_samples_change_neither_autos_choice_nor_the_steps():
    """detumble (a law at 50 Hz) at 1 and at 100 samples/s: the same method, step and
    steps (it chose splitting6 at 20 ms, then splitting4 at 5 ms), and the samples of the
    sparse run found in the dense one to round-off."""
    runs = {}
    for rate in (1.0, 100.0):
        scene = load('detumble', [f'publish_rate={rate:g}'])
        engine = engine_for(scene)  # 15 s
        result = simulate(scene, engine=engine)
        runs[rate] = (result.integrator, result.step, engine.steps, result.samples)
    (m1, h1, n1, sparse), (m100, h100, n100, dense) = runs[1.0], runs[100.0]
    assert (m1, h1, n1) == (m100, h100, n100)
    assert len(dense) == 1501 and len(sparse) == 16
    on_grid = np.isin(dense.t_ns, sparse.t_ns)
    np.testing.assert_allclose(dense.q[on_grid], sparse.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(dense.m[on_grid], sparse.m, rtol=0, atol=1e-12)


def test_a_controlled_run_between_steps_ends_at_its_duration_with_the_law_acting():
    """A 3 Hz law, rk4 at 0.1 s (4 steps per law interval), 7 samples/s, 2.55 s: the
    samples between the steps carry the held torque, the last is at 2.55 s."""
    sim = {'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.3, 0.1, 0.2],
           'integrator': 'rk4', 'step': 0.1, 'publish_rate': 7.0, 'duration': 2.55,
           'accuracy': 1e-3}
    ctl = {'mode': 'detumble', 'control_rate': 3.0, 'inertia': [1.0, 2.0, 3.0]}
    config = EngineConfig.from_parameters(sim, ctl)
    interp = Engine(config, interpolate_samples=True)
    block = SampleBlock.concatenate(list(interp.run()))
    lands = Engine(config)
    landing = SampleBlock.concatenate(list(lands.run()))
    assert block.t_ns[-1] == 2_550_000_000 and len(block) == len(landing)
    assert np.abs(block.torque).max() > 0.0
    # the landing run shortens steps to each sample; both stay within the budget
    angle = [rotation.angle_between(a, b) for a, b in zip(block.attitude, landing.attitude)]
    assert max(angle) <= 1e-3
    assert interp.steps < lands.steps  # 4 steps per law interval; more, cut to samples


_SCRIPT = """
import json, sys
import numpy as np
from rigid_body_sim.engine import Engine, EngineConfig, SampleBlock
from rigid_body_sim.physics.jit import COMPILED
sim = json.loads(sys.argv[1])
engine = Engine(EngineConfig.from_parameters(sim), interpolate_samples=True)
block = SampleBlock.concatenate(list(engine.run()))
print(json.dumps({'compiled': COMPILED, 'steps': engine.steps, 'q': block.q.tolist(),
                  'm': block.m.tolist()}))
"""


@pytest.mark.slow
def test_samples_between_steps_in_both_jit_modes():
    """The interpolating loop as plain Python (NUMBA_DISABLE_JIT=1) gives the compiled
    loop's steps and samples to round-off."""
    import json
    from jit_modes import run_both
    sim = {**FREE, 'integrator': 'rk4', 'step': 0.004, 'duration': 0.5, 'publish_rate': 100.0}
    compiled, plain = run_both(_SCRIPT, json.dumps(sim))
    assert compiled['compiled'] is True and plain['compiled'] is False
    assert compiled['steps'] == plain['steps'] == 125 and len(compiled['q']) == 51
    for k in ('q', 'm'):
        np.testing.assert_allclose(compiled[k], plain[k], rtol=0, atol=1e-12, err_msg=k)


_DIVERGING = """
import json, sys
import numpy as np
from rigid_body_sim.engine import Engine, EngineConfig, closed_loop, closed_loop_args
from rigid_body_sim.physics import IntegrationError
from rigid_body_sim.physics.jit import COMPILED
kernel, interpolated = closed_loop.closed_loop_run, []


def spy(state, ticks, *rest):
    interpolated.append(int(ticks[closed_loop.INTERPOLATE]))
    return kernel(state, ticks, *rest)


closed_loop_args.closed_loop_run = spy
out = {'compiled': COMPILED}
for name, options in (('between', {'interpolate_samples': True}),
                      ('events', {'compiled_loop': False})):
    engine = Engine(EngineConfig.from_parameters(json.loads(sys.argv[1])), **options)
    del interpolated[:]
    try:
        with np.errstate(all='ignore'):
            list(engine.run())
        out[name] = None
    except IntegrationError as exc:
        out[name] = [str(exc), engine.fault, list(interpolated)]
print(json.dumps(out))
"""


@pytest.mark.slow
def test_a_step_failing_between_samples_stops_the_run_in_both_jit_modes():
    """Euler diverging inside the interpolating loop (the whole run one call, samples
    between steps) stops the run with the event path's IntegrationError (method, step,
    the failing step's time) and a fault, compiled and as plain Python: the loop's one
    failure tail serves both ways of stepping."""
    import json
    from jit_modes import run_both
    sim = {'inertia': [1.0, 2.0, 3.0], 'initial_angular_velocity': [0.5, 3.0, 0.5],
           'integrator': 'euler', 'step': 0.5, 'publish_rate': 0.01, 'duration': 1e4,
           'accuracy': 1.0}
    compiled, plain = run_both(_DIVERGING, json.dumps(sim))
    assert compiled.pop('compiled') is True and plain.pop('compiled') is False
    for mode in (compiled, plain):
        message, fault, interpolated = mode['between']
        assert interpolated == [1]  # one call of the loop, interpolating
        assert message == mode['events'][0] and mode['events'][2] == []
        assert 'euler failed at t = 11.5 s with step h = 0.5 s' in message and fault


def _hermite_reference(herm, h, theta):
    """The cubic Hermite interpolant sample by sample, as the loop evaluated it before
    hermite_run (plain floats: the same IEEE operations in the same order)."""
    t2 = theta * theta
    t3 = t2 * theta
    a0 = 2.0 * t3 - 3.0 * t2 + 1.0
    a1 = 1.0 - a0
    b0 = (t3 - 2.0 * t2 + theta) * h
    b1 = (t3 - t2) * h
    q = [a0 * herm[0, i] + b0 * herm[2, i] + a1 * herm[4, i] + b1 * herm[6, i]
         for i in range(4)]
    norm = 0.0
    for v in q:
        norm += v * v
    norm = norm ** 0.5
    m = [a0 * herm[1, i] + b0 * herm[3, i] + a1 * herm[5, i] + b1 * herm[7, i]
         for i in range(3)]
    return [v / norm for v in q] + m


def test_a_chunk_of_samples_is_the_interpolant_sample_by_sample_bit_for_bit():
    """sample_kernel.hermite_run (the samples inside one step, a chunk at a time) gives the
    interpolant of each sample bit for bit, stops at CHUNK, at the step's end and at the
    segment's end, and reports a sample that is not finite with the rows before it."""
    from rigid_body_sim.engine import sample_kernel
    rng = np.random.default_rng(5)
    herm = rng.normal(size=(8, 4))
    h, n, span, held, period = 0.25, 4, 10**9, 1, 2 * 10**6  # step 1: [0.25, 0.5) s
    rows = 200
    t, q, m, tau = (np.zeros(rows, np.int64), np.zeros((rows, 4)), np.zeros((rows, 3)),
                    np.zeros((rows, 3)))
    torque = np.array([1.0, 2.0, 3.0])
    lanes = np.empty((13, sample_kernel.CHUNK))
    s, row, ends = 252 * 10**6, 0, []
    while True:
        written, finite = sample_kernel.hermite_run(herm, h, 0, 10**9, n, span, held, s,
                                                    period, lanes, t, q, m, tau, torque, row)
        assert finite
        if not written:
            break
        ends.append(written)
        row, s = row + written, s + written * period
    assert ends == [sample_kernel.CHUNK, 124 - sample_kernel.CHUNK]  # 0.252 … 0.498 s
    np.testing.assert_array_equal(t[:row], 252 * 10**6 + period * np.arange(row))
    expected = [_hermite_reference(herm, h, (ti * (n / span)) - 1) for ti in t[:row]]
    np.testing.assert_array_equal(np.hstack([q, m])[:row], np.array(expected))
    np.testing.assert_array_equal(tau[:row], np.tile(torque, (row, 1)))
    # the segment ends first (b_ns): only the samples before it
    assert sample_kernel.hermite_run(herm, h, 0, 260 * 10**6, n, span, held, 252 * 10**6,
                                     period, lanes, t, q, m, tau, torque, 0) == (4, True)
    herm[5, 1] = np.inf  # m's end: every interpolated m[1] is not finite
    assert sample_kernel.hermite_run(herm, h, 0, 10**9, n, span, held, 252 * 10**6, period,
                                     lanes, t, q, m, tau, torque, 0) == (0, False)
