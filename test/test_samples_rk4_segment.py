"""rk4 on the free body (engine/sample_steps.py): one loop over the interval's steps whose
first stages are the Hermite's derivatives at the step ends, a step holding no sample, one,
a few (written one by one) or many (in lanes, CHUNK at a time). The rows must stay the
interpolants of the steps taken one by one (their ends' rates evaluated apart), bit for
bit, the state the steps' own, and the evaluations only the steps' (4 each) plus one where
the interval's last step holds a sample."""
import numpy as np
import pytest

pytestmark = pytest.mark.fast

MOMENTS = np.array([0.98, 2.67, 2.9])


def _rows(n):
    return (np.zeros(n, np.int64), np.zeros((n, 4)), np.zeros((n, 3)), np.zeros((n, 3)))


def _state():
    q0 = np.array([0.1, 0.2, 0.3, 0.927])
    return q0 / np.linalg.norm(q0), np.array([1.0, 0.5, -0.7])


def _reference(q0, m0, tau, a_ns, b_ns, n, first, period, model, coefficient):
    """The steps one by one (rk4_free_steps), each end's rates apart (rk4_free_end), and
    each sample before b_ns as segment places it: on a step's end (within ON_STEP) that
    end's state, else hermite_run on its step's two ends. Returns (rows, q, m, whether
    the last step holds a sample)."""
    from rigid_body_sim.engine import sample_kernel
    from rigid_body_sim.physics.integrators import explicit_kernel
    h = (b_ns - a_ns) / (n * 1e9)
    ends, q, m = [], q0.copy(), m0.copy()
    for k in range(n + 1):
        herm = np.empty((8, 4))
        explicit_kernel.rk4_free_end(q, m, MOMENTS, tau, model, coefficient, herm, 0)
        ends.append(herm[:4].copy())
        if k < n:
            explicit_kernel.rk4_free_steps(q, m, h, 1, MOMENTS, tau, model, coefficient)
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    rows, s, span, last = [], first, b_ns - a_ns, False
    while s < b_ns:
        x = (s - a_ns) * (n / span)
        j = int(np.floor(x))
        theta = x - j
        one = _rows(1)
        if theta > 1 - sample_kernel.ON_STEP or theta < sample_kernel.ON_STEP:
            j += theta > 0.5
            one[0][0], one[1][0], one[2][0], one[3][0] = s, ends[j][0], ends[j][1, :3], tau
        else:
            herm, last = np.vstack([ends[j], ends[j + 1]]), j == n - 1
            # this sample alone (the next a span on, past b_ns)
            assert sample_kernel.hermite_run(herm, h, a_ns, b_ns, n, span, j, s, span,
                                             lanes, *one, tau, 0) == (1, True)
        rows.append(one)
        s += period
    return rows, q, m, last


def _segment(q, m, tau, a_ns, b_ns, n, first, period, model, coefficient, room=400):
    from rigid_body_sim.engine import sample_kernel
    out = _rows(room)
    got = sample_kernel.segment(
        sample_kernel.RK4, q, m, a_ns, b_ns, n, first, period, np.zeros(1),
        np.zeros(1, np.int64), MOMENTS, tau, tau, True, model, coefficient, False,
        np.empty((10, 4)), np.empty(4), np.empty(3), None, np.empty((8, 4)),
        np.empty((sample_kernel.LANES, sample_kernel.CHUNK)), *out, 0)
    return got, out


# (a_ns, b_ns, n, first sample, period, dissipation model, coefficient): samples inside
# steps, one on a step's end (3 of 12 steps of 10 ms: 30 ms), one in the last step, one at
# the interval's start, a period of exactly the step, the double bracket and viscous models
CASES = [(0, 43_364_117, 11, 3_000_000, 10_000_000, 0, 0.0),
         (0, 120_000_000, 12, 30_000_000, 25_000_000, 0, 0.0),
         (5_000_000, 105_000_000, 20, 5_000_000, 7_000_000, 1, 0.05),
         (0, 100_000_000, 25, 2_000_000, 4_000_000, 2, 0.3),
         (1_000_000_000, 1_100_000_000, 7, 1_099_999_999, 50_000_000, 0, 0.0),
         # a few samples a step (one by one), 16 and 17 (in lanes: LANES_MIN), 100 a step
         # (CHUNK, then the rest), the last step's samples one by one after the lanes
         (0, 480_000_000, 4, 1_000_000, 10_000_000, 1, 0.05),
         (0, 330_000_000, 2, 5_000_000, 10_000_000, 0, 0.0),
         (0, 1_990_000_000, 2, 3_000_000, 10_000_000, 2, 0.3),
         (0, 357_000_000, 21, 1_000_000, 1_000_000, 0, 0.0)]


@pytest.mark.parametrize('a_ns,b_ns,n,first,period,model,coefficient', CASES)
def test_the_rows_are_the_interpolants_of_the_steps_one_by_one(a_ns, b_ns, n, first, period,
                                                               model, coefficient):
    """Each row bit for bit the reference's (t, q, m, torque), the state after the n
    steps the steps' own, no row more, and 4 evaluations a step (+1: last step held)."""
    q0, m0 = _state()
    tau = np.array([1e-3, -2e-3, 5e-4])
    rows, q_ref, m_ref, last = _reference(q0, m0, tau, a_ns, b_ns, n, first, period, model,
                                    coefficient)
    q, m = q0.copy(), m0.copy()
    (failed, evals, written), out = _segment(q, m, tau, a_ns, b_ns, n, first, period, model,
                                             coefficient)
    assert failed == -1 and written == len(rows) > 0
    np.testing.assert_array_equal(q, q_ref)  # the state advanced by whole steps only
    np.testing.assert_array_equal(m, m_ref)
    for r, one in enumerate(rows):
        for a, b, name in zip(out, one, ('t', 'q', 'm', 'torque')):
            np.testing.assert_array_equal(a[r], b[0], err_msg=f'row {r} {name}')
    # no row past the ones written
    assert not out[0][written:].any()
    # the steps' own evaluations, and one for a sample inside the last step
    assert evals == 4 * n + int(last)


def test_the_ends_of_a_step_holding_a_sample_cost_no_evaluation():
    """11 steps, 5 samples inside 5 of them: the loop evaluates 4 a step and the last
    step's end once (44 + 1), where evaluating both ends of each held step apart cost 10
    more (segment before this loop: 4·11 + 2·5)."""
    q, m = _state()
    tau = np.zeros(3)
    (failed, evals, rows), _ = _segment(q, m, tau, 0, 43_364_117, 11, 3_000_000, 10_000_000,
                                        0, 0.0)
    assert (failed, rows, evals) == (-1, 5, 45)


@pytest.mark.parametrize('period', [10_000_000, 1_000_000])
def test_a_step_failing_stops_the_interval_with_its_index(period):
    """A non-finite state at step 0 (an infinite torque): the loop reports step 0 of the
    interval failing, no row written, the state left non-finite, as rk4_free_steps; with
    a sample a step at most (rk4_free_segment) and with several (rk4_free_samples)."""
    q, m = _state()
    tau = np.array([np.inf, 0.0, 0.0])
    with np.errstate(all='ignore'):
        (failed, evals, rows), out = _segment(q, m, tau, 0, 40_000_000, 4, 5_000_000,
                                              period, 0, 0.0)
    assert (failed, rows) == (0, 0) and not np.isfinite(m).all()
