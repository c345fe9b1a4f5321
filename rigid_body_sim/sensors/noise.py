"""Gyro and star-tracker error processes in discrete time, generated in vectorised blocks.

Conventions (IEEE Std 952-1997, Allan-variance terms), for a gyro sampled every h seconds,
each reading being the body rate plus the errors below (body frame, rad/s, per axis):

* angle random walk N [rad/√s]: white rate noise, one draw per reading with standard
  deviation N/√h (the rate averaged over the sample interval). Allan variance N²/τ
  (slope −1/2 in a log–log Allan-deviation plot, σ(1 s) = N).
* rate random walk K [rad/s/√s]: the bias integrates white noise,
  b[k+1] = b[k] + K√h·w[k]. Allan variance K²τ/3 (slope +1/2, σ(3 s) = K).
* bias instability B [rad/s]: approximated by a first-order Gauss–Markov bias with
  correlation time T_c, b[k+1] = φ b[k] + σ_gm √(1 − φ²)·w[k], φ = e^(−h/T_c), whose
  stationary standard deviation σ_gm is chosen so that the peak of its Allan deviation
  equals the flicker floor √(2 ln 2 / π)·B ≈ 0.664 B of IEEE 952 (the peak lies at
  τ ≈ 1.89 T_c; see :func:`gauss_markov_sigma`). A Gauss–Markov bias is a flicker
  approximation valid around τ ~ T_c: below it the slope is +1/2, above it −1/2.
* a constant turn-on bias b₀ [rad/s].

Reproducibility: each process draws from its own stream (``numpy.random.SeedSequence(seed)``
spawned per component and axis set), so a run is the same bit for bit for a given seed,
whatever the block sizes it is generated in, and turning one process on or off does not
change the others.
"""
import math

import numpy as np

from ..physics.jit import jit
# the Gauss–Markov bias's sizing, here for the callers that import it from here
from .gauss_markov import (FLICKER_FLOOR, GM_PEAK_RATIO, GM_PEAK_X,  # noqa: F401
                           gauss_markov_avar, gauss_markov_sigma)

# streams of one seed, by component (stable numbers: never renumber)
STREAM_ARW, STREAM_GM, STREAM_RRW, STREAM_STAR = 0, 1, 2, 3
STREAM_SUN = 8  # the sun sensor (the magnetometer's: 10, engine.magnetic)


def streams(seed: int, component: int) -> np.random.Generator:
    """The generator of one noise component of a run seeded ``seed``."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), component])))


@jit
def recursion(state, phi, drive, out):
    """out[k] += b[k], then b ← φ b + drive[k], for k in order; ``state`` (3,) is b and is
    updated in place (a Gauss–Markov bias for φ < 1, a random walk for φ = 1)."""
    for k in range(drive.shape[0]):
        for i in range(3):
            out[k, i] += state[i]
            state[i] = phi * state[i] + drive[k, i]


def warm():
    recursion(np.zeros(3), 0.5, np.zeros((2, 3)), np.zeros((2, 3)))


class GyroNoise:
    """The error of a 3-axis rate gyro read every ``period`` s, generated in blocks.

    ``take(n)`` returns the next n readings' errors (n, 3), rad/s, body frame; state (the
    Gauss–Markov and random-walk biases) carries over from block to block.
    """

    def __init__(self, period: float, angle_random_walk=0.0, bias_instability=0.0,
                 correlation_time=100.0, rate_random_walk=0.0, initial_bias=(0.0, 0.0, 0.0),
                 seed: int = 0):
        self.period = float(period)
        self.arw, self.rrw = float(angle_random_walk), float(rate_random_walk)
        self.bias_instability, self.correlation_time = float(bias_instability), \
            float(correlation_time)
        self.initial_bias = np.array(initial_bias, float).reshape(3)
        self.sigma_gm = gauss_markov_sigma(self.bias_instability)
        self.phi = math.exp(-self.period / self.correlation_time)
        self._arw_rng = streams(seed, STREAM_ARW)
        self._gm_rng = streams(seed, STREAM_GM)
        self._rrw_rng = streams(seed, STREAM_RRW)
        # stationary start: the Gauss–Markov bias is drawn from its steady distribution
        self._gm = self.sigma_gm * self._gm_rng.standard_normal(3) if self.sigma_gm else \
            np.zeros(3)
        self._rw = np.zeros(3)

    @property
    def white_std(self) -> float:
        """Per-reading std of the angle-random-walk term, N/√h (rad/s)."""
        return self.arw / math.sqrt(self.period)

    @property
    def bias(self) -> np.ndarray:
        """The bias now (turn-on + Gauss–Markov + random walk), rad/s, body frame."""
        return self.initial_bias + self._gm + self._rw

    def take(self, n: int) -> np.ndarray:
        out = np.empty((n, 3))
        out[:] = self.initial_bias
        if n == 0:
            return out
        if self.arw > 0.0:
            out += self.white_std * self._arw_rng.standard_normal((n, 3))
        # reading k carries b[k]; the recursions run in order (compiled), so the sums are
        # the same whatever the block sizes
        if self.sigma_gm > 0.0:
            drive = self.sigma_gm * math.sqrt(1.0 - self.phi ** 2) * \
                self._gm_rng.standard_normal((n, 3))
            recursion(self._gm, self.phi, drive, out)
        if self.rrw > 0.0:
            steps = self.rrw * math.sqrt(self.period) * self._rrw_rng.standard_normal((n, 3))
            recursion(self._rw, 1.0, steps, out)
        return out


class StarTrackerNoise:
    """Small-angle attitude errors of a star tracker (body frame, rad, per axis 1σ); with
    ``stream`` STREAM_SUN, the sun sensor's direction errors."""

    def __init__(self, sigma, seed: int = 0, stream: int = STREAM_STAR):
        self.sigma = np.broadcast_to(np.asarray(sigma, float), (3,)).copy()
        self._rng = streams(seed, stream)

    def take(self, n: int) -> np.ndarray:
        return self.sigma * self._rng.standard_normal((n, 3))


def allan_deviation(rate, dt: float, m):
    """Overlapping Allan deviation of a rate series (n, ...) sampled every ``dt`` s at
    cluster sizes ``m`` (τ = m·dt): σ²(τ) = Σ(θ[k+2m] − 2θ[k+m] + θ[k])² / (2τ²(n − 2m + 1)),
    θ the integrated angle. Returns (τ, σ) with σ of shape (len(m), ...)."""
    rate = np.asarray(rate, float)
    theta = np.concatenate([np.zeros((1,) + rate.shape[1:]), np.cumsum(rate, axis=0) * dt])
    n = len(theta)
    m = np.asarray(m, int)
    out = []
    for k in m:
        d = theta[2 * k:] - 2.0 * theta[k:n - k] + theta[:n - 2 * k]
        out.append(np.sqrt(np.mean(d * d, axis=0) / 2.0) / (k * dt))
    return m * dt, np.array(out)
