"""engine.dop853_samples.sampled_steps (dop853's samples up to the next event, from one
loop of its natural steps) against dop853_dense.advance called once an output, as the
event loop calls it: the same rows, state, evaluations and memory, bit for bit, where the
samples span many steps, a step holds more than a chunk of them, the rows start past the
block's first, a new torque restarts the integration, the run ends at a law instant off
the sample grid, and an output is not finite; and nothing written where it declines."""
import math

import numpy as np
import pytest

pytestmark = pytest.mark.fast

MOMENTS = np.array([1.0, 2.0, 3.0])
MODEL, COEFFICIENT, RTOL, ATOL = 1, 0.01, 1e-6, 1e-8
H_MAX = 0.25  # an output step longer than this is split (closed_loop's n, h)


def _split(span_ns):
    """closed_loop_run's split of an output step: (n, h·n)."""
    n = max(1, int(math.ceil(span_ns / (H_MAX * 1e9) - 1e-9)))
    return n, span_ns / (n * 1e9) * n


def _started(m0, tau):
    """(q, m, memory) after dop853's first output (1 ms), as the loop's first call."""
    from rigid_body_sim.physics.integrators import dop853_dense
    q = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    m = np.array(m0, float)
    memory = np.zeros(dop853_dense.MEMORY)
    dop853_dense.advance(q, m, 1e-3, tau, memory, MOMENTS, MODEL, COEFFICIENT, RTOL, ATOL,
                         0.0, None)
    return q, m, memory


def _advanced(q, m, tau, memory, t_ns, instants):
    """advance once an instant (the event loop): [(status, q, m)], evaluations, the
    failure's instant (ns) as closed_loop reports it or None."""
    from rigid_body_sim.physics.integrators import dop853_dense, dop853_kernel
    outputs, evals = [], 0
    for instant in instants:
        n, span = _split(instant - t_ns)
        status, reached, _, e = dop853_dense.advance(q, m, span, tau, memory, MOMENTS, MODEL,
                                                     COEFFICIENT, RTOL, ATOL, t_ns / 1e9, None)
        evals += e
        if status != dop853_kernel.OK:
            return outputs, evals, t_ns + int(reached * 1e9)
        outputs.append((n, np.concatenate([q, m])))
        t_ns = instant
    return outputs, evals, None


def _sampled(q, m, tau, torque_body, memory, t_ns, s, period_ns, end_ns, to_end, row, room):
    from rigid_body_sim.engine import dop853_samples, sample_kernel
    size = row + room + 3
    t, qo, mo, to = (np.full(size, -1, np.int64), np.full((size, 4), 7.0),
                     np.full((size, 3), 7.0), np.full((size, 3), 7.0))
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    n_first, hn_first = _split(s - t_ns)
    n_p, _ = _split(period_ns)
    h_p = period_ns / (n_p * 1e9)
    result = dop853_samples.sampled_steps(
        q, m, tau, torque_body, memory, MOMENTS, MODEL, COEFFICIENT, RTOL, ATOL, None, t_ns,
        end_ns, to_end, s, period_ns, hn_first, n_first, h_p, n_p, H_MAX, t, qo, mo, to, row,
        room, lanes)
    return result, (t, qo, mo, to)


@pytest.mark.parametrize('case', ['slow body, 100 a step', 'fast body, many steps',
                                  'new torque, end at a law instant', 'poisoned'])
def test_sampled_steps_are_advance_called_once_an_output(case):
    """From row 3 of a block, with a body-frame torque in the rows: the rows are the
    calls' outputs at s, s + p, … (the torque on each), the rows before 3 and after the
    last untouched; the state, the step count, the evaluations and the memory as the
    calls leave them. A torque other than the memory's restarts the integration as
    advance restarts it; ``to_end``: the output at a law instant off the grid after the
    last sample, into the state and not into a row. Poisoned, two of F's coefficients of
    m[0] near the largest double make the interpolant overflow past x ≈ 0.8 of the step:
    both stop at the same output, with the same failure and instant."""
    from rigid_body_sim.physics.integrators import dop853_dense, dop853_kernel
    fast = case == 'fast body, many steps'
    tau = np.zeros(3)
    q, m, memory = _started([9.0, -20.0, 15.0] if fast else [0.03, 0.05, -0.04], tau)
    if case == 'poisoned':  # F's rows 6 and 5 (the Horner's first two terms), m[0]
        f, power, dim = dop853_dense._FF, dop853_dense.POWER, dop853_dense.DIM
        memory[f + (power - 1) * dim + 4] = 1e308
        memory[f + (power - 2) * dim + 4] = 1e308
    if case.startswith('new torque'):
        tau = np.array([0.02, -0.01, 0.005])
    t_ns, period_ns = 10**6, 10**6 if not fast else 7 * 10**6
    s = t_ns + (3 * 10**5 if fast else period_ns)  # the first sample off the period
    end_ns = s + (400 if fast else 250) * period_ns + 123_457
    to_end = case.startswith('new torque')
    instants = list(range(s, end_ns, period_ns))
    room, row = len(instants) + 2, 3
    reference = memory.copy()
    expected, evals, failed_at = _advanced(q.copy(), m.copy(), tau, reference, t_ns,
                                           instants + ([end_ns] if to_end else []))
    last_output = expected.pop() if to_end else None
    torque_body = np.array([0.25, -0.5, 1e-3])
    (written, steps, e, status, t_failed, reached, h), (t, qo, mo, to) = _sampled(
        q, m, tau, torque_body, memory, t_ns, s, period_ns, end_ns, to_end, row, room)
    assert written == len(expected) and e == evals
    rows = slice(row, row + written)
    np.testing.assert_array_equal(np.hstack([qo, mo])[rows], [o for _, o in expected])
    np.testing.assert_array_equal(t[rows], instants[:written])
    np.testing.assert_array_equal(to[rows], np.tile(torque_body, (written, 1)))
    for column in (qo, mo, to):
        assert (column[:row] == 7.0).all() and (column[row + written:] == 7.0).all()
    assert (t[:row] == -1).all() and (t[row + written:] == -1).all()
    if case == 'poisoned':
        assert status == dop853_kernel.NON_FINITE and 10 < written < 0.9 * len(instants)
        assert t_failed + int(reached * 1e9) == failed_at == instants[written]
        return
    assert status == dop853_kernel.OK and failed_at is None
    assert steps == sum(n for n, _ in expected) + (last_output[0] if to_end else 0)
    state = last_output[1] if to_end else expected[-1][1]
    np.testing.assert_array_equal(np.concatenate([q, m]), state)
    np.testing.assert_array_equal(memory, reference)
    assert (h > 0.0) == to_end  # the end's own h: its output was made
    # tens of steps (12 evaluations each), or ~100 samples in one step (two chunks)
    assert (evals > 300) == fast, evals


@pytest.mark.parametrize('bad', ['row', 'q columns', 'torque columns', 'state', 'cold'])
def test_sampled_steps_declines_what_is_not_its_own(bad):
    """A negative row, a block whose rows are not (q 4, m 3, torque 3) wide, a state other
    than the memory's last output, or a memory with no step in progress: no row, no
    state and no memory written (0: the caller's advance takes the output)."""
    from rigid_body_sim.engine import dop853_samples, sample_kernel
    tau = np.zeros(3)
    q, m, memory = _started([0.03, 0.05, -0.04], tau)
    if bad == 'state':
        m[0] += 1e-12
    if bad == 'cold':
        memory[:] = 0.0
    before, state = memory.copy(), np.concatenate([q, m])
    n = 20
    t, qo, mo, to = (np.zeros(n, np.int64), np.zeros((n, 5 if bad == 'q columns' else 4)),
                     np.zeros((n, 3)), np.zeros((n, 4 if bad == 'torque columns' else 3)))
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    span = 1e-3
    written = dop853_samples.sampled_steps(
        q, m, tau, tau, memory, MOMENTS, MODEL, COEFFICIENT, RTOL, ATOL, None, 10**6,
        10**8, True, 2 * 10**6, 10**6, span, 1, span, 1, H_MAX, t, qo, mo, to,
        -1 if bad == 'row' else 0, 5, lanes)[0]
    assert written == 0
    np.testing.assert_array_equal(memory, before)
    np.testing.assert_array_equal(np.concatenate([q, m]), state)
    assert not t.any() and not qo.any() and not mo.any() and not to.any()
