"""The floor under a run's samples, measured in the same process as the run: what writing
the same sample rows and evaluating them by the cheapest means cost, with no bookkeeping.

Per sample (ns, the least of a few passes over as many rows as the run's, memory already
touched): ``store``, a compiled loop writing the block's columns (t ns, q, m, and the
torque where the run's block has it: 64 or 88 bytes); ``evaluation``, the method's sample
arithmetic alone, lanes as in the run's kernels: the exact grid's ``_lanes`` on the
scene's own solution and sample period (blocks of 2H + 1 about an anchor, the anchors
left out), dop853's dense polynomial on the run's own step (``dop853_samples``' Horner and
normalisation), or the cubic Hermite's weights and sums (``hermite_run``'s). Per
right-hand-side evaluation the samples add, ``added``: for dop853 a third of its
interpolant's build (``_build``: the 3 extra stages and F, once a step holding a
sample), else one evaluation (``rates``: the Hermite's step ends where the method does
not have them; rk4 on the free body takes them from its stages, so its samples add one
only in a law interval's last step). The floor of a
run's samples is samples × (store + evaluation) + added evaluations × added: the
samples' CPU that no bookkeeping can go below, and (1 sample/s CPU + floor) / (1 sample/s
CPU) the least sampling-overhead ratio the run could read.
"""
import math

import numpy as np

from ..engine.sample_kernel import CHUNK
from ..physics.dynamics_kernel import rates
from ..physics.exact import grid_kernel
from ..physics.exact.kernel import evaluate_into
from ..physics.integrators.dop853_dense import DIM, interpolate_lanes
from .. import physics
from ..physics import dynamics_kernel
from ..physics.exact import constants, double_double, elliptic_kernel, kernel as exact_kernel
from ..physics.integrators import dop853_dense, explicit_kernel
from ..physics.jit import depends_on, jit
from .common import cpu

REPEATS = 5  # passes of each measurement; the least is kept
BUILDS = 2000  # dop853 interpolants built per pass (~0.3 µs each)


@jit
def store(t, q, m, tau, n):
    """Rows [0, n) of the block's columns written with values of the row (``tau``: an
    empty array where the block has no torque column)."""
    torque = tau.shape[0] > 0
    for k in range(n):
        x = k * 1e-3
        t[k] = k * 10_000_000
        q[k, 0], q[k, 1], q[k, 2], q[k, 3] = x, -x, 0.5 * x, 1.0
        m[k, 0], m[k, 1], m[k, 2] = x, 2.0 * x, -x
        if torque:
            tau[k, 0], tau[k, 1], tau[k, 2] = 0.0, 0.0, 0.0


@jit
def dense(memory, n, lanes):
    """n outputs of the dop853 step whose interpolant ``memory`` holds (dop853_dense's
    layout), at n instants across it, CHUNK at a time: dop853_samples' arithmetic (its
    interpolate_lanes, then q normalised) into ``lanes`` (9 + DIM, CHUNK), no checks or
    rows. Returns the last output's q[0] (kept, so that nothing is dropped)."""
    last = 0.0
    for first in range(0, n, CHUNK):
        count = min(CHUNK, n - first)
        for k in range(count):
            lanes[0, k] = (first + k + 0.5) / n
        for k in range(count):
            lanes[1, k] = 1.0 - lanes[0, k]
        interpolate_lanes(memory, lanes, 0, 1, 2, count)
        for k in range(count):
            lanes[2 + DIM, k] = math.sqrt(lanes[2, k] * lanes[2, k] + lanes[3, k] * lanes[3, k]
                                          + lanes[4, k] * lanes[4, k] + lanes[5, k] * lanes[5, k])
        for i in range(4):
            for k in range(count):
                lanes[3 + DIM + i, k] = lanes[2 + i, k] / lanes[2 + DIM, k]
        last = lanes[3 + DIM, count - 1]
    return last


@jit
def dense_build(memory, moments, tau, model, coefficient, n):
    """n builds of the interpolant of the dop853 step ``memory`` holds (dop853_dense._build:
    its 3 extra stages and F, from the step's stages as they are): what a step holding a
    sample costs beyond the step itself. Returns F[3, 0]."""
    y, f, y_old, K, F, clock, last = dop853_dense.views(memory)
    y_stage = np.empty(DIM)
    for _ in range(n):
        dop853_dense._build(y_old, y, f, clock[1], K, F, moments, tau, model, coefficient,
                            dop853_dense.A_EXTRA, dop853_dense.D, 0.0, None, y_stage)
    return F[3, 0]


@jit
def hermite(herm, h, n, lanes):
    """n values of the cubic Hermite interpolant of the step whose ends herm (8, 4) holds
    (q0, m0, dq0, dm0, q1, m1, dq1, dm1, as sample_kernel.segment), at n instants across
    it, CHUNK at a time: hermite_run's arithmetic (explicit_kernel.hermite_lanes), q
    normalised, into ``lanes`` (17, CHUNK), no checks or rows. Returns the last q[0]."""
    last = 0.0
    for first in range(0, n, CHUNK):
        count = min(CHUNK, n - first)
        for k in range(count):
            lanes[0, k] = (first + k + 0.5) / n
        explicit_kernel.hermite_lanes(herm, h, count, lanes)
        for i in range(4):
            for c in range(count):
                lanes[13 + i, c] = lanes[5 + i, c] / lanes[12, c]
        last = lanes[13, count - 1]
    return last


@jit
def exact_lanes(c, tab, ts, n, lanes):
    """The exact grid's samples at ts[0:n] (spaced as the table's dt) by ``grid_kernel._lanes``
    alone, block by block about one anchor (its own evaluation left out: it is ~1 in 65
    samples' cost), into ``lanes`` (7, 2H + 1); where the grid does not apply (H < 2),
    ``evaluate_into`` at each. Returns the last q[0]."""
    h = (tab.shape[0] - 3) // 2
    if h < 2:
        for k in range(n):
            evaluate_into(c, ts[k], lanes[0:4, 0], lanes[4:7, 0])
        return lanes[0, 0]
    nn = c[grid_kernel.N]
    g = math.sqrt(nn * (1.0 - c[grid_kernel.KP2] + nn) * (1.0 + nn))
    cols = np.ascontiguousarray(tab.T)
    a = grid_kernel._anchor(c, ts[h])
    for first in range(0, n, 2 * h + 1):
        count = min(2 * h + 1, n - first)
        grid_kernel._lanes(c, a, cols, 1, count, g, lanes)
    return lanes[0, 0]


@jit
def rates_loop(state, moments, tau, model, coefficient, n):
    """n right-hand-side evaluations (dynamics_kernel.rates) one after another, each from
    the last's state nudged by its rates (a dependency, as a method's stages have one)."""
    x, y, z, w, m0, m1, m2 = state[0], state[1], state[2], state[3], state[4], state[5], \
        state[6]
    for _ in range(n):
        d = rates(x, y, z, w, m0, m1, m2, moments[0], moments[1], moments[2], tau[0], tau[1],
                  tau[2], model, coefficient)
        x += 1e-12 * d[0]
        y += 1e-12 * d[1]
        z += 1e-12 * d[2]
        w += 1e-12 * d[3]
        m0 += 1e-12 * d[4]
        m1 += 1e-12 * d[5]
        m2 += 1e-12 * d[6]
    return x + y + z + w + m0 + m1 + m2



# they compile in code of other files (see jit.depends_on)
for _kernel in (dense, dense_build, hermite, exact_lanes, rates_loop):
    depends_on(_kernel, dop853_dense, explicit_kernel, grid_kernel, exact_kernel,
               elliptic_kernel, double_double, constants, dynamics_kernel, physics.jit)

def _least(call, n, repeats=REPEATS):
    """Least CPU (ns) per item of ``repeats`` calls of ``call`` over n items."""
    call()  # compiled (or loaded) and its memory touched before the clock
    best = float('inf')
    for _ in range(repeats):
        t0 = cpu()
        call()
        best = min(best, cpu() - t0)
    return best / max(n, 1) * 1e9


def per_sample(engine, samples: int) -> dict:
    """The floor's parts (ns): ``store`` and ``evaluation`` a sample, ``added`` an added
    right-hand-side evaluation (dop853: a third of its interpolant's build, whose 3
    stages they are; else one evaluation), for ``samples`` rows of the method ``engine``
    ran (its state and integrator after the run: the exact grid of its body at its sample
    period, dop853's last step; any other method the cubic Hermite)."""
    from ..physics.exact import TorqueFreeSolution
    n = max(int(samples), 2 * grid_kernel.HMAX + 1)
    q0, m0 = engine.principal_state
    moments = np.asarray(engine.dynamics.moments, float)
    method = engine.method
    torque = method != 'exact'  # the exact grid's rows go to a block without one
    t = np.empty(n, np.int64)
    q, m = np.empty((n, 4)), np.empty((n, 3))
    tau = np.empty((n if torque else 0, 3))
    out = {'store': _least(lambda: store(t, q, m, tau, n), n)}
    dt = engine.config.sample_period
    if method == 'exact':
        solution = TorqueFreeSolution(moments, q0, m0)
        ts = dt * np.arange(n)
        solution.at_grid(ts[:2 * grid_kernel.HMAX + 1], dt)  # its table at this dt
        tab, lanes = solution._grid[1], np.empty((7, 2 * grid_kernel.HMAX + 1))
        out['evaluation'] = _least(lambda: exact_lanes(solution._row0, tab, ts, n, lanes), n)
    elif method == 'dop853':
        memory = engine.integrator.loop_memory()[0].copy()
        lanes = np.empty((9 + DIM, CHUNK))
        out['evaluation'] = _least(lambda: dense(memory, n, lanes), n)
    else:
        herm = np.empty((8, 4))
        herm[0], herm[4] = q0, q0
        herm[1, :3], herm[5, :3] = m0, m0
        herm[2], herm[3], herm[6], herm[7] = 1e-3, 1e-3, 1e-3, 1e-3
        lanes = np.empty((17, CHUNK))
        out['evaluation'] = _least(lambda: hermite(herm, engine.step_max, n, lanes), n)
    state = np.concatenate([q0, m0])
    tau_p = np.zeros(3) if engine._tau_p is None else np.asarray(engine._tau_p, float)
    model = engine.integrator.loop_model() if engine.integrator is not None else 0
    coefficient = float(engine.dynamics.dissipation.coefficient)
    if method == 'dop853':  # its evaluations come 3 to an interpolant's build
        out['added'] = _least(lambda: dense_build(memory, moments, tau_p, model, coefficient,
                                                  BUILDS), BUILDS) / 3.0
    else:
        out['added'] = _least(lambda: rates_loop(state, moments, tau_p, model, coefficient, n),
                              n)
    return out


def floor_seconds(parts: dict, samples: int, evaluations: int) -> float:
    """The CPU (s) ``samples`` more samples cost at the floor, with ``evaluations`` more
    right-hand-side evaluations (:func:`per_sample`'s ``parts``, ns)."""
    return (samples * (parts['store'] + parts['evaluation'])
            + evaluations * parts['added']) * 1e-9


# The floor row's target: the samples' CPU at most twice their floor, i.e. bookkeeping
# (instants, checks, rows, calls, split step loops) at most as much again as the arithmetic
# and stores any sampler pays. Measured (20 generated scenes, 2026-11-27, load 10-14): the
# exact grid 1.3-1.6x, dop853 2.1-3.0x (dense_samples ~10 ns a sample where its arithmetic
# and rows are ~6.7; a step holding a sample ~180 ns for its interpolant's build), rk4
# under a law 4.2-5.1x (~100 ns a sample where the Hermite's two ends and sums are ~26:
# the step loop split at every sample, after the one-sample path took 138 -> 102 ns).
# Then (samples5, load 2-3): rk4 2.4-2.6x of a floor of ~7.6 ns a sample (its ends from
# its stages: ~19 ns a sample, one loop a law interval), dop853 1.8-2.7x, exact 1.1-1.5x.
# Then (dense7: dense_samples' rows a column at a time, unsigned indices): dense_samples
# ~6.7 ns a sample against the floor's dense + store ~8.2 in one micro-benchmark; scene 1
# (~150 samples a step) 1.17-1.24x; steps holding ~10 samples 2.0-2.2x (per-step costs).
# Then (engine.dop853_samples: the samples up to the next event from one loop of dop853's
# steps, no advance call and no pass of the event loop a step): scenes 14, 16, 17 (~5-12
# samples a step) 2.2-2.8x -> 1.5-1.9x, interleaved with the code before, load 2-3.
FLOOR_MAX = 2.0
# judged only where 100 samples/s adds this many samples: fewer are below the timing noise
# of two least-of-3 CPU figures (~20 µs at load), e.g. 520 samples at the floor are ~8 µs
FLOOR_SAMPLES = 5000
# and where the floor is at least this share of the 1 sample/s run's CPU: the samples'
# CPU is the difference of two CPU figures, each a few % apart from run to run at load,
# which on a floor of 2 % of the run moves the excess by 1-2 (generated scene 4, rk4 under
# a law, 6,687 samples on a 2.2 ms run: 1.98 in one run, 4.06 in the next). Such a scene's
# samples are cheap beside its physics: the sampling ratio row (<= 1.25 at the floor)
# judges it, so every scene adding FLOOR_SAMPLES is judged by one row or both.
FLOOR_SHARE = 0.1


def judge(slow, fast, a, b, method) -> dict:
    """A generated scene's samples against their floor: ``slow``/``fast`` the least CPU (s)
    at 1 and 100 samples/s, ``a``/``b`` their runs' counts (bench.sampling._simulate_cpu's:
    samples, evaluations, the 100/s run's engine). Returns the floor's ``parts`` (ns), its
    CPU ``floor`` (s) for the samples 100/s adds (and, but for exact, whose evaluations
    count its samples, the right-hand-side evaluations it adds), ``excess`` (the added CPU
    / the floor), ``reach`` (the sampling ratio the run would read at the floor),
    ``judged`` (enough samples, FLOOR_SAMPLES, and a floor of FLOOR_SHARE of the run at
    least) and the row's ``note``."""
    added = b['samples'] - a['samples']
    evaluations = 0 if method == 'exact' else max(0, b['evaluations'] - a['evaluations'])
    parts = per_sample(b['engine'], b['samples'])
    floor = floor_seconds(parts, added, evaluations)
    excess = (fast - slow) / floor if floor > 0 else float('inf')
    reach = (slow + floor) / slow
    note = (f'floor: store {parts["store"]:.3g} + evaluation {parts["evaluation"]:.3g} ns a '
            f'sample, {parts["added"]:.3g} ns × {evaluations} added evaluations: '
            f'{added} more samples cost {(fast - slow) * 1e3:.3g} ms over a floor of '
            f'{floor * 1e3:.3g} ms (x{excess:.3g}); at the floor the ratio would read '
            f'{reach:.3g}')
    return {'parts': parts, 'floor': floor, 'excess': excess, 'reach': reach,
            'judged': added >= FLOOR_SAMPLES and floor >= FLOOR_SHARE * slow, 'note': note}


def at_floor(floors) -> str:
    """The sampling row's note: the least ratio the worst scene could read with its samples
    at their floor (``floors``: (scene name, :func:`judge`'s dict))."""
    if not floors:
        return 'no floor measured'
    name, worst = max(floors, key=lambda f: f[1]['reach'])
    return (f'with every sample at its floor (store + evaluation, measured in this run) the '
            f'worst scene would still read {worst["reach"]:.3g} ({name})')


def targets(floors, span: str) -> list:
    """The floor's target row: the worst judged scene's samples' CPU / their floor, the
    spread and the kind of each of the worst in its note."""
    from . import targets as t
    judged = [(name, f) for name, f in floors if f['judged']]
    if not judged:
        return []
    excess = [f['excess'] for _, f in judged]
    name, worst = max(judged, key=lambda f: f[1]['excess'])
    v = np.asarray(excess)
    left = [(n, f['excess']) for n, f in floors if not f['judged']]
    others = (f'; not judged, {len(left)} scenes: ' + ', '.join(
        f'{n} x{e:.3g}' for n, e in left)) if left else ''
    return [t.simple(
        'sampling: samples\' CPU / their floor (100 samples/s)', worst['excess'], FLOOR_MAX,
        worst['excess'] <= FLOOR_MAX,
        f'median {np.median(v):.3g}, worst {v.max():.3g} ({name}) over {len(v)} generated '
        f'scenes adding >= {FLOOR_SAMPLES} samples on a floor >= {FLOOR_SHARE:.0%} of the '
        f'run{others}; floor = samples × (store + evaluation) + '
        f'added evaluations × their cost (dop853: its interpolant\'s build), in the same '
        f'run (bench/sampling_floor.py); {span}',
        scene='generated (worst)')]
