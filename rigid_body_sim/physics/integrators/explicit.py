"""Classical explicit Runge–Kutta methods on (q, m), kept as references and to show failure.

They integrate q as a vector in R⁴ and renormalise it after each step (common practice,
e.g. Fukushima 2008); neither |m| nor T is conserved.
"""
import numpy as np

from .base import Integrator


class _ExplicitRK(Integrator):
    def _rates(self, q, m, torque):
        self.nfev += 1
        return self.dynamics.attitude_rate(q, m), self.dynamics.momentum_rate(m, torque)

    @staticmethod
    def _normalised(q):
        return q / np.linalg.norm(q, axis=-1, keepdims=True)


class Euler(_ExplicitRK):
    """Explicit Euler: first order; |m| and T grow at every step (by h²|ṁ|² and h²/2·ṁ·(ṁ/I))."""
    name = 'euler'
    order = 1
    stability = 'unstable for free rotation at any step (amplification √(1 + (hλ)²) > 1)'

    def _step(self, q, m, h, torque, t):
        dq, dm = self._rates(q, m, torque)
        return self._normalised(q + h * dq), m + h * dm


class RK4(_ExplicitRK):
    """Classical 4th-order Runge–Kutta: energy drifts linearly in time (∝ h⁴ per unit time)."""
    name = 'rk4'
    order = 4
    stability = 'real-axis limit hλ ≈ 2.785 (stiff dissipation); imaginary-axis limit hλ = 2√2'

    def _step(self, q, m, h, torque, t):
        dq1, dm1 = self._rates(q, m, torque)
        dq2, dm2 = self._rates(q + 0.5 * h * dq1, m + 0.5 * h * dm1, torque)
        dq3, dm3 = self._rates(q + 0.5 * h * dq2, m + 0.5 * h * dm2, torque)
        dq4, dm4 = self._rates(q + h * dq3, m + h * dm3, torque)
        q_new = q + (h / 6.0) * (dq1 + 2.0 * dq2 + 2.0 * dq3 + dq4)
        m_new = m + (h / 6.0) * (dm1 + 2.0 * dm2 + 2.0 * dm3 + dm4)
        return self._normalised(q_new), m_new
