"""Gyro-propagated attitude corrected by a star tracker: a multiplicative complementary filter.

Frames: quaternions (x, y, z, w) rotate body-frame vectors into the inertial frame; gyro
rates and bias are in the body frame (rad/s); corrections are small rotations in the body
frame (right multiplication).

Propagation: between readings the attitude turns at the last gyro reading minus the bias
estimate, held constant (q̂ ← q̂ ⊗ exp((g − b̂)·Δt)). Correction at a star-tracker fix
q_m: the residual δθ = 2·vec(q̂* ⊗ q_m) (sign with w ≥ 0), then

    q̂ ← q̂ ⊗ exp(k₁ δθ),  b̂ ← b̂ − k₂ δθ,   k₁ = 2 ω_e T,  k₂ = ω_e² T,

T the time since the previous fix, capped at 1/(2 ω_e) so that k₁ ≤ 1 after an outage.
Per axis, with e = θ̂ − θ and β = b − b̂, the continuous equivalent is ė = β − 2ω_e e,
β̇ = −ω_e² e: s² + 2ω_e s + ω_e², a critically damped error loop of bandwidth ω_e
(``estimator.bandwidth``). It removes a constant or slowly wandering gyro bias and
low-pass filters the star tracker's noise; the rate fed to the controller is g − b̂.
"""
from typing import Optional

import numpy as np

from ..physics import rotation

NS = 1_000_000_000


class AttitudeEstimator:
    """The filter above. ``estimate(t_ns)`` is (attitude, ω) at ``t_ns`` or None before the
    first fix and the first gyro reading."""

    def __init__(self, bandwidth: float):
        if not (np.isfinite(bandwidth) and bandwidth > 0.0):
            raise ValueError(f'estimator.bandwidth must be finite and > 0 rad/s, got '
                             f'{bandwidth}')
        self.bandwidth = float(bandwidth)
        self.reset()

    def reset(self):
        self.q: Optional[np.ndarray] = None
        self.bias = np.zeros(3)
        self._g: Optional[np.ndarray] = None   # last gyro reading (body, rad/s)
        self._t: Optional[int] = None         # time of q̂ (ns)
        self._fix_t: Optional[int] = None     # time of the last star-tracker fix (ns)
        self.fixes = 0
        self.readings = 0

    def _propagate_to(self, t_ns: int):
        if self.q is None or self._g is None or t_ns <= self._t:
            if self.q is not None and self._t is None:
                self._t = t_ns
            return
        dt = (t_ns - self._t) / NS
        q = rotation.multiply(self.q, rotation.exp((self._g - self.bias) * dt))
        self.q = q / np.linalg.norm(q)
        self._t = t_ns

    def gyro(self, t_ns: int, rate) -> None:
        """A gyro reading (body frame, rad/s) taken at ``t_ns``."""
        self._propagate_to(t_ns)
        self._g = np.array(rate, float).reshape(3)
        self.readings += 1
        if self.q is not None and self._t is None:
            self._t = t_ns

    def star_tracker(self, t_ns: int, attitude) -> None:
        """A star-tracker fix (x, y, z, w), body → inertial, taken at ``t_ns``."""
        q_m = np.array(attitude, float).reshape(4)
        q_m = q_m / np.linalg.norm(q_m)
        self.fixes += 1
        if self.q is None:  # the first fix initialises the attitude
            self.q, self._t, self._fix_t = q_m, t_ns, t_ns
            return
        self._propagate_to(t_ns)
        d = rotation.multiply(rotation.conjugate(self.q), q_m)
        if d[3] < 0.0:
            d = -d
        residual = 2.0 * d[:3]
        w = self.bandwidth
        period = min((t_ns - self._fix_t) / NS, 0.5 / w)
        self._fix_t = t_ns
        q = rotation.multiply(self.q, rotation.exp(2.0 * w * period * residual))
        self.q = q / np.linalg.norm(q)
        self.bias = self.bias - w * w * period * residual

    def estimate(self, t_ns: int):
        """(attitude (x, y, z, w) body → inertial, ω body frame rad/s) at ``t_ns``, or None."""
        if self.q is None or self._g is None:
            return None
        self._propagate_to(t_ns)
        return self.q.copy(), self._g - self.bias
