"""The Gauss–Markov bias's sizing for a bias instability B (IEEE 952; the conventions:
``noise``), apart from the noise's compiled recursion: a node that reports a sensor's
variances (``nodes/sensor_messages.py``) imports it at start without numba."""
import math

import numpy as np

# IEEE 952: the Allan deviation of 1/f (flicker) rate noise is flat at this multiple of B
FLICKER_FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)


def gauss_markov_avar(tau, sigma, correlation_time):
    """Allan variance of a first-order Gauss–Markov rate with stationary std ``sigma`` and
    correlation time T at averaging time τ (continuous form):
    σ²/x² (2x − 3 + 4e^(−x) − e^(−2x)), x = τ/T."""
    x = np.asarray(tau, float) / correlation_time
    return sigma ** 2 * (2.0 * x - 3.0 + 4.0 * np.exp(-x) - np.exp(-2.0 * x)) / x ** 2


def _peak():
    """(x = τ/T at the peak, peak Allan deviation / σ) of a Gauss–Markov process."""
    x = np.linspace(0.5, 5.0, 45001)
    a = gauss_markov_avar(x, 1.0, 1.0)
    i = int(np.argmax(a))
    return float(x[i]), float(math.sqrt(a[i]))


GM_PEAK_X, GM_PEAK_RATIO = _peak()  # ≈ 1.89, ≈ 0.6184


def gauss_markov_sigma(bias_instability: float) -> float:
    """Stationary std of the Gauss–Markov bias whose Allan-deviation peak equals the IEEE
    952 flicker floor 0.664 B of ``bias_instability`` B (rad/s)."""
    return FLICKER_FLOOR * bias_instability / GM_PEAK_RATIO
