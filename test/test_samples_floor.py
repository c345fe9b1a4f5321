"""bench/sampling_floor.py: the floor under a run's samples evaluates what the run's own
kernels evaluate (so its CPU is the arithmetic's, not a stand-in's), and the rows it
writes follow from the measured parts. Nothing here is timed: the parts are scripted."""
import numpy as np
import pytest

from rigid_body_sim.bench import sampling_floor
from test_sample_interpolation import _hermite_reference

pytestmark = pytest.mark.fast


def test_the_dense_floor_is_dop853s_interpolant_bit_for_bit():
    """dense() on a memory holding a step's interpolant gives, at each of its instants,
    dop853_dense._interpolate's output (the raw 7 values), and q normalised."""
    from rigid_body_sim.engine.sample_kernel import CHUNK
    from rigid_body_sim.physics.integrators import dop853_dense as d
    rng = np.random.default_rng(3)
    memory = np.zeros(d.MEMORY)
    memory[d._Y_OLD:d._K] = rng.normal(size=d.DIM)
    memory[d._FF:d._CLOCK] = rng.normal(size=d.POWER * d.DIM)
    n = 10
    lanes = np.empty((9 + d.DIM, CHUNK))
    last = sampling_floor.dense(memory, n, lanes)
    F = memory[d._FF:d._CLOCK].reshape(d.POWER, d.DIM)
    out = np.empty(d.DIM)
    for k in range(n):
        d._interpolate(memory[d._Y_OLD:d._K], F, (k + 0.5) / n, out)
        np.testing.assert_array_equal(lanes[2:2 + d.DIM, k], out)
        np.testing.assert_array_equal(lanes[3 + d.DIM:7 + d.DIM, k],
                                      out[:4] / np.sqrt(np.sum(out[:4] ** 2)))
    assert last == lanes[3 + d.DIM, n - 1]


def test_the_exact_floor_is_the_grids_own_samples():
    """exact_lanes() over one block of 2H + 1 samples gives at_grid's q and m bit for bit
    (the same anchor and table): the floor's evaluation is the grid's."""
    from rigid_body_sim.physics.exact import TorqueFreeSolution, grid_kernel
    sol = TorqueFreeSolution((1.0, 2.0, 3.0), (0.1, -0.2, 0.3, 0.927), (0.05, 0.08, 0.03))
    dt = 0.01
    n = 2 * grid_kernel.HMAX + 1
    ts = 3.0 + dt * np.arange(n)
    q, m = sol.at_grid(ts, dt)
    assert (sol._grid[1].shape[0] - 3) // 2 == grid_kernel.HMAX  # the grid applies
    lanes = np.empty((7, n))
    sampling_floor.exact_lanes(sol._row0, sol._grid[1], ts, n, lanes)
    np.testing.assert_array_equal(lanes[:4].T, q)
    np.testing.assert_array_equal(lanes[4:].T, m)


def test_the_hermite_floor_is_the_interpolant_bit_for_bit():
    rng = np.random.default_rng(4)
    herm, h, n = rng.normal(size=(8, 4)), 0.02, 7
    lanes = np.empty((17, 64))
    sampling_floor.hermite(herm, h, n, lanes)
    for k in range(n):
        expected = _hermite_reference(herm, h, (k + 0.5) / n)
        raw = lanes[5:12, k]
        np.testing.assert_array_equal(raw[4:], expected[4:])  # m
        # q normalised (the reference's pow(x, 0.5) may differ from sqrt by an ulp)
        np.testing.assert_array_max_ulp(lanes[13:17, k], np.array(expected[:4]), maxulp=1)


PARTS = {'store': 2.0, 'evaluation': 10.0, 'added': 10.0}


@pytest.mark.parametrize('method,evaluations', [('exact', 0), ('dop853', 9), ('rk4', 9)])
def test_the_floor_counts_the_added_samples_and_evaluations(monkeypatch, method, evaluations):
    """floor = added samples × (store + evaluation) + added evaluations × added; exact's
    evaluations count its samples, so they add none; the ratio at the floor and the excess
    follow; a scene adding fewer than FLOOR_SAMPLES samples is not judged."""
    monkeypatch.setattr(sampling_floor, 'per_sample', lambda engine, samples: PARTS)
    a = {'samples': 301, 'evaluations': 1000}
    b = {'samples': 30001, 'evaluations': 1009, 'engine': None}
    got = sampling_floor.judge(1e-3, 2e-3, a, b, method)
    floor = (29700 * 12.0 + evaluations * 10.0) * 1e-9
    assert got['floor'] == pytest.approx(floor)
    assert got['excess'] == pytest.approx(1e-3 / floor)
    assert got['reach'] == pytest.approx((1e-3 + floor) / 1e-3)
    assert got['judged'] and f'{evaluations} added evaluations' in got['note']
    few = sampling_floor.judge(1e-3, 2e-3, a, {**b, 'samples': 301 + 4999}, method)
    assert not few['judged']
    # a floor under FLOOR_SHARE of the 1 sample/s run: its excess is within the noise
    slow = floor / sampling_floor.FLOOR_SHARE
    assert sampling_floor.judge(slow * 0.99, slow * 2, a, b, method)['judged']
    assert not sampling_floor.judge(slow * 1.01, slow * 2, a, b, method)['judged']


def test_the_floor_row_judges_the_worst_scene_with_enough_samples():
    floors = [('g-1', {'excess': 1.2, 'reach': 2.7, 'judged': True}),
              ('g-2', {'excess': 9.0, 'reach': 1.1, 'judged': False}),  # too few samples
              ('g-3', {'excess': 3.0, 'reach': 1.2, 'judged': True})]
    (row,) = sampling_floor.targets(floors, 'runs cut to 300 s')
    assert row['measured'] == 3.0 and 'g-3' in row['note'] and 'over 2 generated' in row['note']
    assert 'not judged, 1 scenes: g-2 x9' in row['note']  # said, not hidden
    assert row['verdict'] == 'MISS'
    assert 'would still read 2.7 (g-1)' in sampling_floor.at_floor(floors)
    assert sampling_floor.targets(floors[1:2], '') == []


@pytest.mark.slow  # compiles the floor's kernels in a fresh clone
@pytest.mark.parametrize('integrator,step', [('exact', None), ('dop853', None),
                                             ('rk4', 2e-3)])
def test_each_methods_floor_is_measured_from_its_own_run(integrator, step):
    """per_sample on a finished run of each kind (tennis racket, 100 samples/s) gives a
    positive, finite store, evaluation and added-evaluation cost, the floor in seconds
    then positive for the samples a run adds."""
    from rigid_body_sim.offline import engine_for, simulate
    from rigid_body_sim.scene import load
    scene = load('tennis_racket', ['publish_rate=100.0'])
    engine = engine_for(scene, duration=2.0, integrator=integrator, step=step)
    result = simulate(scene, engine=engine)
    assert engine.method == integrator
    parts = sampling_floor.per_sample(engine, result.sample_count)
    assert set(parts) == {'store', 'evaluation', 'added'}
    assert all(np.isfinite(v) and v > 0 for v in parts.values()), parts
    assert sampling_floor.floor_seconds(parts, result.sample_count, 30) > 0
