"""Sensor error processes (rigid_body_sim.sensors): Allan-variance slopes and levels against
the parameters (IEEE Std 952 conventions), reproducibility, and the estimator's claims.

Allan deviations are overlapping estimates over 2^20 readings × 3 axes (pooled), so the
statistical error of σ² at cluster size m is about sqrt(m / (n·3)) relative for white noise
and larger for the random walks at long τ; the stated tolerances sit at 3-4 such errors.
"""
import math

import numpy as np
import pytest

from rigid_body_sim.physics import rotation
from rigid_body_sim.sensors import noise as N
from rigid_body_sim.sensors.estimator import AttitudeEstimator

pytestmark = pytest.mark.fast  # make check

H = 0.01          # s: 100 Hz gyro
COUNT = 1 << 20   # readings (~2.9 h of data)


def pooled_adev(rate, m):
    """Allan deviation pooled over the axes (mean of the variances)."""
    tau, sigma = N.allan_deviation(rate, H, m)
    return tau, np.sqrt(np.mean(sigma ** 2, axis=1))


def slope(tau, sigma):
    return float(np.polyfit(np.log(tau), np.log(sigma), 1)[0])


@pytest.mark.slow  # Allan statistics on long series: make test
def test_angle_random_walk_allan_slope_minus_half_and_level_n():
    """White rate noise of ARW N: slope −1/2 ± 0.02 over τ = 0.1…100 s, σ(τ) = N/√τ
    within 3 % at every τ (σ(1 s) = N)."""
    arw = 2.0e-4
    g = N.GyroNoise(H, angle_random_walk=arw, seed=7)
    rate = g.take(COUNT)
    tau, sigma = pooled_adev(rate, np.unique(np.logspace(1, 4, 13).astype(int)))
    assert abs(slope(tau, sigma) + 0.5) < 0.02
    np.testing.assert_allclose(sigma, arw / np.sqrt(tau), rtol=0.03)
    assert np.std(rate) == pytest.approx(arw / math.sqrt(H), rel=0.01)


@pytest.mark.slow  # Allan statistics on long series: make test
def test_rate_random_walk_allan_slope_plus_half_and_level_k():
    """Bias random walk of RRW K: slope +1/2 ± 0.06 over τ = 1…300 s, σ(τ) = K·√(τ/3)
    within 15 % (RRW's Allan estimate has few independent clusters at long τ)."""
    rrw = 3.0e-6
    g = N.GyroNoise(H, rate_random_walk=rrw, seed=11)
    rate = g.take(COUNT)
    tau, sigma = pooled_adev(rate, np.unique(np.logspace(2, 4.5, 11).astype(int)))
    assert abs(slope(tau, sigma) - 0.5) < 0.06
    np.testing.assert_allclose(sigma, rrw * np.sqrt(tau / 3.0), rtol=0.15)


@pytest.mark.slow  # Allan statistics on long series: make test
def test_bias_instability_gauss_markov_peak_is_the_flicker_floor():
    """Gauss–Markov bias for B with T_c = 10 s: the Allan deviation follows the closed form
    within 12 % at τ = 1…100 s, peaks near 1.89 T_c at 0.664 B (within 8 %), and its
    stationary std is the σ_gm the model states."""
    b, tc = 1.0e-5, 10.0
    g = N.GyroNoise(H, bias_instability=b, correlation_time=tc, seed=3)
    rate = g.take(COUNT)
    m = np.unique(np.logspace(2, 4, 21).astype(int))
    tau, sigma = pooled_adev(rate, m)
    model = np.sqrt(N.gauss_markov_avar(tau, g.sigma_gm, tc))
    np.testing.assert_allclose(sigma, model, rtol=0.12)
    assert N.GM_PEAK_X == pytest.approx(1.89, abs=0.01)
    near = np.argmin(abs(tau - N.GM_PEAK_X * tc))
    assert sigma[near] == pytest.approx(N.FLICKER_FLOOR * b, rel=0.08)
    assert N.FLICKER_FLOOR == pytest.approx(0.6643, abs=1e-4)
    assert np.std(rate) == pytest.approx(g.sigma_gm, rel=0.1)


@pytest.mark.slow  # Allan statistics on long series: make test
def test_combined_processes_add_in_allan_variance():
    """ARW + RRW + turn-on bias together: the Allan variance is the sum N²/τ + K²τ/3 (the
    constant bias adds nothing) within 8 %, and its minimum lies between the two slopes."""
    arw, rrw = 1.0e-4, 1.0e-6
    g = N.GyroNoise(H, angle_random_walk=arw, rate_random_walk=rrw,
                    initial_bias=(0.01, -0.02, 0.03), seed=5)
    tau, sigma = pooled_adev(g.take(COUNT), np.unique(np.logspace(1, 4, 13).astype(int)))
    np.testing.assert_allclose(sigma ** 2, arw ** 2 / tau + rrw ** 2 * tau / 3.0, rtol=0.08)


def test_blocks_and_seeds_are_reproducible_bit_for_bit():
    """The same seed gives the same errors whatever the block sizes; another seed differs;
    turning the random walk on does not change the white-noise draws."""
    kw = dict(angle_random_walk=1e-3, bias_instability=1e-4, correlation_time=5.0,
              rate_random_walk=1e-5, initial_bias=(1e-3, 0.0, -1e-3))
    whole = N.GyroNoise(H, seed=42, **kw).take(1000)
    g = N.GyroNoise(H, seed=42, **kw)
    parts = np.concatenate([g.take(n) for n in (1, 0, 299, 256, 444)])
    assert np.array_equal(whole, parts)
    assert not np.array_equal(whole, N.GyroNoise(H, seed=43, **kw).take(1000))
    white = N.GyroNoise(H, angle_random_walk=1e-3, seed=42).take(500)
    both = N.GyroNoise(H, angle_random_walk=1e-3, rate_random_walk=1e-5, seed=42).take(500)
    walk = N.GyroNoise(H, rate_random_walk=1e-5, seed=42).take(500)
    np.testing.assert_allclose(both, white + walk, rtol=0, atol=1e-15)
    st = N.StarTrackerNoise([1e-4, 1e-4, 5e-4], seed=42)
    assert np.array_equal(st.take(10), N.StarTrackerNoise([1e-4, 1e-4, 5e-4], 42).take(10))


def spin(rate, t):
    """Attitude at time t of a body turning at a constant body rate from identity."""
    return rotation.exp(np.asarray(rate) * t)


def test_estimator_learns_a_constant_bias_and_converges():
    """Noise-free readings, gyro bias b = (2, −1, 0.5) mrad/s, body turning at a constant
    rate: after 60 s (30 time constants of ω_e = 0.5 rad/s) the bias estimate equals b to
    1e-9 rad/s and the attitude estimate the truth to 1e-9 rad; the first fix initialises
    the attitude exactly."""
    w, b = np.array([0.01, -0.02, 0.005]), np.array([2e-3, -1e-3, 5e-4])
    est = AttitudeEstimator(0.5)
    assert est.estimate(0) is None
    ns = 1_000_000_000
    for k in range(0, 6001):  # 100 Hz gyro, 5 Hz star tracker
        t = k * 10_000_000
        est.gyro(t, w + b)
        if k == 0:
            assert est.estimate(t) is None  # gyro alone: no attitude yet
        if k % 20 == 0:
            est.star_tracker(t, spin(w, t / ns))
            if k == 0:
                assert rotation.angle_between(est.estimate(t)[0], spin(w, 0.0)) == 0.0
    q, rate = est.estimate(6000 * 10_000_000)
    np.testing.assert_allclose(est.bias, b, atol=1e-9)
    np.testing.assert_allclose(rate, w, atol=1e-9)
    assert rotation.angle_between(q, spin(w, 60.0)) < 1e-9


def test_estimator_error_loop_is_critically_damped_at_its_bandwidth():
    """A bias step seen only by the filter: the per-axis error follows s² + 2ω_e s + ω_e²
    (the documented loop), i.e. the attitude error after the step peaks at
    β/ω_e · e^(−1) at t = 1/ω_e (within 3 %, from the discrete updates at 50 Hz)."""
    we, beta = 0.2, 1e-3
    est = AttitudeEstimator(we)
    est.star_tracker(0, [0, 0, 0, 1.0])
    errs = []
    for k in range(1, 3001):  # body at rest; star tracker and gyro at 50 Hz
        t = k * 20_000_000
        est.gyro(t, [beta, 0.0, 0.0])
        est.star_tracker(t, [0, 0, 0, 1.0])
        errs.append(2.0 * est.estimate(t)[0][0])
    errs = np.array(errs)
    i = int(np.argmax(errs))
    assert errs[i] == pytest.approx(beta / we * math.exp(-1.0), rel=0.03)
    assert (i + 1) * 0.02 == pytest.approx(1.0 / we, rel=0.03)
    assert est.bias[0] == pytest.approx(beta, rel=1e-3)  # 12 time constants: 13·e^(−12)


@pytest.mark.parametrize('value', [0.0, -1.0, float('nan'), float('inf')])
def test_estimator_rejects_bad_bandwidth(value):
    with pytest.raises(ValueError, match='estimator.bandwidth'):
        AttitudeEstimator(value)
