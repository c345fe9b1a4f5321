"""A step holding one sample at most (the sample period at least the step, as rk4 or
splitting under a law at 100 samples/s): sample_kernel.segment writes its sample with
``_hermite_one``, in numbers, where ``hermite_run``'s counting loop and one-lane loops
cost a quarter of the sample. The values must stay hermite_run's, bit for bit."""
import numpy as np
import pytest

from test_sample_interpolation import _hermite_reference

pytestmark = pytest.mark.fast


def _rows(n):
    return (np.zeros(n, np.int64), np.zeros((n, 4)), np.zeros((n, 3)), np.zeros((n, 3)))


@pytest.mark.parametrize('seed', range(4))
def test_one_sample_is_hermite_runs_bit_for_bit(seed):
    """Random ends and instants inside step 1 of four: the row (t, q, m, torque) that
    _hermite_one writes is hermite_run's own for that sample alone, and the interpolant
    sample by sample (the reference of test_sample_interpolation)."""
    from rigid_body_sim.engine import sample_kernel
    rng = np.random.default_rng(seed)
    h, n, span, held = 0.25, 4, 10**9, 1  # step 1: [0.25, 0.5) s
    torque = rng.normal(size=3)
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    for _ in range(50):
        herm = rng.normal(size=(8, 4))
        s = int(rng.integers(250 * 10**6 + 1, 500 * 10**6))
        theta = s * (n / span) - 1  # segment's θ for s (its x − j)
        one, run = _rows(1), _rows(1)
        assert sample_kernel._hermite_one(herm, h, theta, s, one[1], one[2], one[0], one[3],
                                          torque, 0) == (1, True)
        # a period of the step: the next sample is in the next step, so hermite_run
        # writes this one alone
        assert sample_kernel.hermite_run(herm, h, 0, 10**9, n, span, held, s, span // n,
                                         lanes, *run, torque, 0) == (1, True)
        for a, b in zip(one, run):
            np.testing.assert_array_equal(a, b)
        # the reference's pow(x, 0.5) may differ from sqrt by an ulp
        np.testing.assert_array_max_ulp(np.hstack([one[1][0], one[2][0]]),
                                        _hermite_reference(herm, h, theta), maxulp=1)
        assert one[0][0] == s


@pytest.mark.parametrize('where', [(5, 1), (0, 2), (4, 0)])
def test_a_sample_not_finite_writes_no_row(where):
    """A non-finite end (m's, or q's: its norm) makes the sample not finite: no row is
    counted and segment reports it (-2), as hermite_run does."""
    from rigid_body_sim.engine import sample_kernel
    herm = np.random.default_rng(1).normal(size=(8, 4))
    herm[where] = np.nan
    rows = _rows(1)
    assert sample_kernel._hermite_one(herm, 0.25, 0.3, 7, rows[1], rows[2], rows[0],
                                      rows[3], np.zeros(3), 0) == (0, False)
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    assert sample_kernel.hermite_run(herm, 0.25, 0, 10**9, 4, 10**9, 1, 325 * 10**6,
                                     250 * 10**6, lanes, *_rows(1), np.zeros(3), 0) \
        == (0, False)


def test_a_segment_with_one_sample_a_step_gives_the_steps_interpolants():
    """segment at a sample period longer than the step (rk4, a torque held): every row is
    the Hermite interpolant of its step's two ends (the rk4 states and their rates, from
    the same steps taken one by one here) that hermite_run gives, bit for bit."""
    from rigid_body_sim.engine import sample_kernel
    from rigid_body_sim.physics.integrators import explicit_kernel
    moments = np.array([0.98, 2.67, 2.9])
    q0 = np.array([0.1, 0.2, 0.3, 0.927])
    q0 /= np.linalg.norm(q0)
    m0, tau = np.array([1.0, 0.5, -0.7]), np.array([1e-3, -2e-3, 5e-4])
    a_ns, b_ns, n, period, first = 0, 43_364_117, 11, 10_000_000, 3_000_000
    h = (b_ns - a_ns) / (n * 1e9)
    q, m = q0.copy(), m0.copy()
    t, qs, ms, taus = _rows(8)
    failed, evals, rows = sample_kernel.segment(
        sample_kernel.RK4, q, m, a_ns, b_ns, n, first, period, np.zeros(1),
        np.zeros(1, np.int64), moments, tau, tau, True, 0, 0.0, False, np.empty((10, 4)),
        np.empty(4), np.empty(3), None, np.empty((8, 4)),
        np.empty((sample_kernel.LANES, sample_kernel.CHUNK)), t, qs, ms, taus, 0)
    # the steps' 4 evaluations each, and the end of the last step (it holds 43 ms) once
    assert (failed, rows) == (-1, 5) and evals == 4 * n + 1
    # the steps one by one, their ends kept
    ends, qq, mm = [], q0.copy(), m0.copy()
    for k in range(n + 1):
        herm = np.empty((8, 4))
        explicit_kernel.rk4_free_end(qq, mm, moments, tau, 0, 0.0, herm, 0)
        ends.append(herm[:4].copy())
        if k < n:
            explicit_kernel.rk4_free_steps(qq, mm, h, 1, moments, tau, 0, 0.0)
    np.testing.assert_array_equal(q, qq)  # the state advanced by whole steps only
    np.testing.assert_array_equal(m, mm)
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    for r in range(rows):
        s = first + r * period
        j = int(np.floor((s - a_ns) * (n / (b_ns - a_ns))))
        herm, one = np.vstack([ends[j], ends[j + 1]]), _rows(1)
        assert sample_kernel.hermite_run(herm, h, a_ns, b_ns, n, b_ns - a_ns, j, s, period,
                                         lanes, *one, tau, 0) == (1, True)
        for a, b in zip((t, qs, ms, taus), one):
            np.testing.assert_array_equal(a[r], b[0])
