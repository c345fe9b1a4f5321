"""The exact solution on a grid of times (physics/exact/grid_kernel.py): each sample from
an anchor and a table of offsets by addition theorems must agree with the direct
evaluation to round-off, and where the problem is ill-conditioned (beside the separatrix,
nearly symmetric bodies) be no further from the 40-digit reference than the direct one."""
import numpy as np
import pytest

from rigid_body_sim.bench.reference40 import Reference40, attitude_error, vector_error
from rigid_body_sim.physics.exact import TorqueFreeSolution, grid_kernel, kernel as exact_kernel


def _grid_and_direct(moments, q0, m0, t0, dt, n):
    sol = TorqueFreeSolution(moments, q0, m0)
    t = t0 + dt * np.arange(n)
    q, m = sol.at_grid(t, dt)
    qd, md = sol.at(t)
    return sol, q, m, qd, md


def _body(rng):
    q0 = rng.normal(size=4)
    return rng.uniform(0.2, 3.0, 3), q0 / np.linalg.norm(q0), \
        rng.normal(size=3) * 10 ** rng.uniform(-1, 2)


def test_grid_equals_direct_evaluation_on_seeded_bodies():
    """Generic bodies (k'² ≥ 1e-3), grids of 2^-9 … 2^-2 s from up to 1e3 s (exact binary
    times, so both paths see the same t): ≤ 1e-13 in q, ≤ 1e-14·|m| in m (measured
    1.6e-14 and 8e-16); the fast path must actually be taken on most of them."""
    rng = np.random.default_rng(20261126)
    fast = 0
    for _ in range(80):
        moments, q0, m0 = _body(rng)
        dt = 2.0 ** -int(rng.integers(2, 10))
        t0 = float(rng.integers(0, 1000))
        sol, q, m, qd, md = _grid_and_direct(moments, q0, m0, t0, dt, 300)
        if sol._row0[exact_kernel.KIND] == exact_kernel.ELLIPTIC and \
                sol._row0[exact_kernel.KP2] < 1e-3:
            continue
        fast += grid_kernel.half_width(sol._row0, dt) >= 2
        assert np.max(np.linalg.norm(q - qd, axis=1)) <= 1e-13, (moments, m0, dt)
        assert np.max(np.abs(m - md)) <= 1e-14 * np.linalg.norm(m0), (moments, m0, dt)
    assert fast >= 40


@pytest.mark.parametrize('moments, m0', [
    ((0.0023, 0.014, 0.0163), (0.0023e-3, 0.14, 0.0163e-3)),      # tennis racket, k'² 4e-9
    ((0.0023, 0.014, 0.0163), (0.0023e-2, 0.14, 0.0163e-2)),      # k'² 4e-7, chained anchors
    ((1.0, 2.0, 2.0 * (1 + 1e-3)), (0.0, 1.3, 0.8)),             # nearly symmetric, N 1e3
])
def test_ill_conditioned_bodies_are_as_close_to_the_reference_as_direct(moments, m0):
    """Where the grid and the direct evaluation differ by more than round-off, the problem
    amplifies the inputs' rounding: judge both against the 40-digit reference at the
    samples where they differ most."""
    q0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    m0 = np.array(m0) + np.array([1e-9, 0.0, 0.0])
    sol, q, m, qd, md = _grid_and_direct(moments, q0, m0, 0.0, 2.0 ** -7, 2000)
    assert grid_kernel.half_width(sol._row0, 2.0 ** -7) >= 2
    ref = Reference40(moments, q0, m0)
    g = np.linalg.norm(m0)
    for k in np.argsort(-np.linalg.norm(q - qd, axis=1) - np.max(np.abs(m - md), axis=1) / g)[:3]:
        q_ref, m_ref = ref.at(k * 2.0 ** -7)
        grid, direct = attitude_error(q[k], q_ref), attitude_error(qd[k], q_ref)
        assert grid <= 2.0 * direct + 5e-14, (k, grid, direct)
        assert vector_error(m[k], m_ref) <= 5e-14 * g, (k, vector_error(m[k], m_ref))


def test_other_kinds_and_coarse_grids_are_evaluated_directly():
    """Closed-form bodies, the separatrix, bodies symmetric to 1e-9 (N outside
    [NMIN, NMAX]) and a grid
    too coarse for two offsets per anchor take the direct path: the same numbers as at()."""
    q0 = np.array([0.0, 0.0, 0.0, 1.0])
    for moments, m0, dt in (((1.0, 1.0, 2.0), (0.3, 0.1, 1.0), 0.01),      # symmetric
                            ((1.0, 2.0, 2.0 * (1 + 3e-11)), (1e-9, 1.3, 0.8), 0.01),  # N 3e10
                            ((1.0, 1.0 + 1e-9, 2.0), (0.3, 0.1, 1.0), 0.01),  # N 5e-10
                            ((2.0, 3.0, 6.0), (1.0, 0.5, 1.0), 0.01),      # separatrix
                            ((1.0, 2.0, 3.0), (0.1, 1.0, 0.2), 5.0)):      # coarse grid
        sol = TorqueFreeSolution(moments, q0, m0)
        q, m = sol.at_grid(dt * np.arange(50), dt)
        qd, md = sol.at(dt * np.arange(50))
        assert np.array_equal(q, qd) and np.array_equal(m, md), moments


def test_engine_samples_match_direct_evaluation():
    """The engine's free ``exact`` samples (tennis racket, 100 samples/s) come from the grid
    and equal the direct evaluation at the sample instants."""
    from rigid_body_sim import scene
    from rigid_body_sim.engine import Engine, EngineConfig
    config = EngineConfig.from_parameters({**scene.load('tennis_racket').simulator,
                                           'publish_rate': 100.0, 'duration': 5.0,
                                           'integrator': 'exact'})
    engine = Engine(config)
    sol = TorqueFreeSolution(engine.dynamics.moments, engine._q, engine._m)
    blocks = list(engine.run())
    t_ns = np.concatenate([b.t_ns for b in blocks])
    q = np.concatenate([b.q for b in blocks])
    assert len(t_ns) == 501
    qd, _ = sol.at(t_ns / 1e9)
    assert np.max(np.linalg.norm(q - qd, axis=1)) <= 1e-12


def test_bad_grid_is_refused():
    sol = TorqueFreeSolution((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), (0.1, 1.0, 0.2))
    with pytest.raises(ValueError, match='dt > 0'):
        sol.at_grid(np.arange(10.0), 0.0)
    with pytest.raises(ValueError, match=r'out must be \(10, 4\)'):
        sol.at_grid(np.arange(10.0), 0.1, out=(np.empty((9, 4)), np.empty((10, 3))))
    with pytest.raises(ValueError, match='one body'):
        TorqueFreeSolution((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0),
                           ((0.1, 1.0, 0.2), (0.2, 0.1, 1.0))).at_grid(np.arange(10.0), 0.1)


@pytest.mark.slow
def test_the_grid_runs_several_samples_to_an_instruction():
    """The grid's samples go through one branch-free loop over contiguous lanes
    (``grid_kernel._lanes``), which the compiler vectorises: its machine code takes packed
    square roots and divisions (several samples at once; ~26 ns a sample, where the loop
    of one sample after another with its stores between cost ~62 ns and took only scalar
    ones). Compiled afresh (the disk cache's code cannot be inspected)."""
    import re
    from numba import njit
    sol = TorqueFreeSolution((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), (0.1, 1.0, 0.2))
    sol.at_grid(0.5 + 0.01 * np.arange(200), 0.01)
    c, tab = sol._row0, sol._grid[1]
    lanes = njit(error_model='numpy')(grid_kernel._lanes.py_func)
    h = (tab.shape[0] - 3) // 2
    out = np.empty((7, 2 * h + 1))
    lanes(c, grid_kernel._anchor(c, 1.0), np.ascontiguousarray(tab.T), 0, 2 * h + 1, 1.0, out)
    asm = lanes.inspect_asm(lanes.signatures[0])
    packed = re.compile(r'\bv?(sqrt|div)pd\b|\bf(sqrt|div)\s+v\d+\.2d')
    assert {m.group(1) or m.group(2) for m in packed.finditer(asm)} == {'sqrt', 'div'}, \
        'no packed square root or division: the samples run one by one'
