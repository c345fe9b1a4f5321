"""sample_kernel.dense_samples (dop853's samples inside its step in progress, a chunk of
lanes at a time) against dop853_dense._interpolated called once a sample: the same rows,
state and memory, bit for bit, where the rows start past the block's first and a chunk's
output is not finite; and nothing written where the rows are not its own."""
import numpy as np
import pytest

pytestmark = pytest.mark.fast

PERIOD_NS = 10**6  # 1 ms samples: ~100 of them in the ~0.1 s step, across two chunks


def _step():
    """(q, m, torque, memory) after one output of a slow body's dop853 run: its step in
    progress holds ~100 samples of PERIOD_NS."""
    from rigid_body_sim.physics.integrators import dop853_dense
    moments, tau = np.array([1.0, 2.0, 3.0]), np.zeros(3)
    q = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    m = np.array([0.03, 0.05, -0.04])
    memory = np.zeros(dop853_dense.MEMORY)
    dop853_dense.advance(q, m, PERIOD_NS / 1e9, tau, memory, moments, 1, 0.01, 1e-6, 1e-8,
                         0.0, None)
    return q, m, tau, memory


def _calls(q, m, tau, memory):
    """The outputs of calling _interpolated once a sample until it declines: (q, m) each."""
    from rigid_body_sim.physics.integrators import dop853_dense
    out = []
    while dop853_dense._interpolated(q, m, PERIOD_NS / 1e9, tau, memory):
        out.append(np.concatenate([q, m]))
    return out


def _dense(q, m, tau, memory, row, room, torque_body):
    from rigid_body_sim.engine import sample_kernel
    n = row + room
    t, qo, mo, to = (np.full(n, -1, np.int64), np.full((n, 4), 7.0), np.full((n, 3), 7.0),
                     np.full((n, 3), 7.0))
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    span = PERIOD_NS / 1e9
    written = sample_kernel.dense_samples(q, m, tau, memory, span, span, room, 5 * PERIOD_NS,
                                          PERIOD_NS, t, qo, mo, to, torque_body, row, lanes)
    return written, t, qo, mo, to


@pytest.mark.parametrize('poisoned', [False, True])
def test_dense_samples_are_the_calls_from_any_row_and_stop_where_an_output_is_not_finite(
        poisoned):
    """From row 3 of a block, with a torque in the rows: the rows are the calls' outputs
    (t from the first instant on, the torque on each), the rows before 3 and after the
    last untouched. Poisoned, two of F's coefficients of m[0] near the largest double make
    the interpolant overflow past x ≈ 0.8 of the step (1e308·x + 1e308): both stop at the
    same output (in the second chunk), the rows before it written, the memory (the
    failing output's raw value included) as the calls leave it."""
    from rigid_body_sim.engine import sample_kernel
    from rigid_body_sim.physics.integrators import dop853_dense
    q, m, tau, memory = _step()
    whole = len(_calls(q.copy(), m.copy(), tau, memory.copy()))
    if poisoned:  # F's rows 6 and 5 (the Horner's first two terms), component 4 (m[0])
        f, power, dim = dop853_dense._FF, dop853_dense.POWER, dop853_dense.DIM
        memory[f + (power - 1) * dim + 4] = 1e308
        memory[f + (power - 2) * dim + 4] = 1e308
    slow = memory.copy()
    expected = _calls(q.copy(), m.copy(), tau, slow)
    assert len(expected) > sample_kernel.CHUNK + 5
    room, row = len(expected) + 10, 3
    torque_body = np.array([0.25, -0.5, 1e-3])
    written, t, qo, mo, to = _dense(q.copy(), m.copy(), tau, memory, row, room, torque_body)
    assert written == len(expected)
    rows = slice(row, row + written)
    np.testing.assert_array_equal(np.hstack([qo, mo])[rows], np.array(expected))
    np.testing.assert_array_equal(t[rows], 5 * PERIOD_NS + PERIOD_NS * np.arange(written))
    np.testing.assert_array_equal(to[rows], np.tile(torque_body, (written, 1)))
    np.testing.assert_array_equal(memory, slow)
    for column in (qo, mo, to):
        assert (column[:row] == 7.0).all() and (column[row + written:] == 7.0).all()
    assert (t[:row] == -1).all() and (t[row + written:] == -1).all()
    if poisoned:  # the failing output's raw m[0] is kept, as the call leaves it
        raw = memory[dop853_dense._LAST + 10 + 4]
        assert not np.isfinite(raw) and written < 0.9 * whole
    else:
        assert written == whole


@pytest.mark.parametrize('bad', ['row', 'q columns', 'torque columns'])
def test_dense_samples_write_nothing_where_the_rows_are_not_its_own(bad):
    """A negative row, or a block whose rows are not (q 4, m 3, torque 3) wide: no row and
    no memory written (0: the caller's usual path, which checks them, takes the samples)."""
    from rigid_body_sim.engine import sample_kernel
    q, m, tau, memory = _step()
    before = memory.copy()
    n = 20
    t, qo, mo, to = (np.zeros(n, np.int64), np.zeros((n, 5 if bad == 'q columns' else 4)),
                     np.zeros((n, 3)), np.zeros((n, 4 if bad == 'torque columns' else 3)))
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    span = PERIOD_NS / 1e9
    row = -1 if bad == 'row' else 0
    assert sample_kernel.dense_samples(q, m, tau, memory, span, span, 5, 0, PERIOD_NS, t, qo,
                                       mo, to, tau, row, lanes) == 0
    np.testing.assert_array_equal(memory, before)
    assert not t.any() and not qo.any() and not mo.any() and not to.any()
    # the same arguments but the rows' own: it writes
    if bad != 'row':
        t, qo, mo, to = np.zeros(n, np.int64), np.zeros((n, 4)), np.zeros((n, 3)), \
            np.zeros((n, 3))
    assert sample_kernel.dense_samples(q, m, tau, memory, span, span, 5, 0, PERIOD_NS, t, qo,
                                       mo, to, tau, 0, lanes) == 5
