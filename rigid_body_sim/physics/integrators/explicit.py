"""Classical explicit Runge–Kutta methods on (q, m), kept as references and to show failure.

They integrate q as a vector in R⁴ and renormalise it after each step (common practice,
e.g. Fukushima 2008); neither |m| nor T is conserved.
"""
import numpy as np

from .. import dynamics_kernel
from . import explicit_kernel
from .base import Candidate, Integrator, same_order


class _ExplicitRK(Integrator):
    def _rates(self, q, m, torque):
        self.nfev += 1
        return self.dynamics.attitude_rate(q, m), self.dynamics.momentum_rate(m, torque)

    @staticmethod
    def _normalised(q):
        return q / np.linalg.norm(q, axis=-1, keepdims=True)

    _kernel_loop = None        # compiled loop in explicit_kernel
    stages = 1                 # evaluations per step
    kernel_modules = (explicit_kernel,)

    def __init__(self, dynamics, **options):
        super().__init__(dynamics, **options)
        d = dynamics.dissipation
        self._model = dynamics_kernel.MODEL_CODES[d.model] if d.active else 0
        self._coefficient = d.coefficient
        self._moments = np.array(dynamics.moments, dtype=float)

    def _kernel(self, q, m, h, n, tau, has_tau, t0=0.0):
        failed = type(self)._kernel_loop(q, m, h, n, self._moments, tau, self._model,
                                         self._coefficient, t0, self.dynamics.environment)
        self.nfev += self.stages * (n if failed < 0 else failed + 1)
        return failed

    def loop_spec(self):
        return np.ones(1), np.array([0, 2, 1])  # unused by the Runge–Kutta loops

    environment = True  # a term of the right-hand side (explicit_kernel)
    environment_evaluations = 1  # one per stage (Euler; RK4 states its 4)

    def run(self, q, m, h, n, torque=None, t0=0.0):
        if np.ndim(q) != 1 or np.ndim(m) != 1:
            self._one_body_only(q, t0)
            return super().run(q, m, h, n, torque, t0)
        return self._run_kernel(self._kernel, q, m, h, n, torque, t0)

    def step(self, q, m, h, torque=None, t=0.0):
        """As Integrator.step; with the environment's torques, one body's step runs the
        compiled loop (the numpy rates have no attitude or time to evaluate them at)."""
        if self.dynamics.environment_active:
            self._one_body_only(q, t)
            return self._run_kernel(self._kernel, q, m, h, 1, torque, t)
        return super().step(q, m, h, torque, t)


class Euler(_ExplicitRK):
    """Explicit Euler: first order; |m| and T grow at every step (by h²|ṁ|² and h²/2·ṁ·(ṁ/I))."""
    name = 'euler'
    order = 1
    orders = same_order(1)
    loop_code = 2
    amplification = staticmethod(lambda z: 1.0 + z)
    stability = 'unstable for free rotation at any step (amplification √(1 + (hλ)²) > 1)'
    _kernel_loop = staticmethod(explicit_kernel.euler_run)

    def _step(self, q, m, h, torque, t):
        dq, dm = self._rates(q, m, torque)
        return self._normalised(q + h * dq), m + h * dm


class RK4(_ExplicitRK):
    """Classical 4th-order Runge–Kutta: energy drifts linearly in time (∝ h⁴ per unit time)."""
    name = 'rk4'
    order = 4
    orders = same_order(4)
    loop_code = 1
    amplification = staticmethod(lambda z: 1.0 + z + z * z / 2.0 + z ** 3 / 6.0 + z ** 4 / 24.0)
    # under a control law (Candidate.torque), from 12 generated detumble scenes (seeds 7 and
    # 20261126: 120–1.8·10⁵ rad, hΩ 0.003–0.5, against dop853 at rtol 1e-15): the largest
    # E/((hΩ)⁴·ΩT) 8.3e-5 on short runs, the largest E/((hΩ)⁵·(ΩT)²) 5.5e-7 on long ones
    # (there the error fell 2⁵× a halving of h: the energy drift), each set 3× above
    auto = Candidate((0.047, 0.056), 1.2e-3, growth='drift', stability=2.5, geometric=False,
                     rounding='random', torque=(2.5e-4, 1.7e-6))
    stability = 'real-axis limit hλ ≈ 2.785 (stiff dissipation); imaginary-axis limit hλ = 2√2'
    _kernel_loop = staticmethod(explicit_kernel.rk4_run)
    stages = 4
    environment_evaluations = 4

    def _step(self, q, m, h, torque, t):
        dq1, dm1 = self._rates(q, m, torque)
        dq2, dm2 = self._rates(q + 0.5 * h * dq1, m + 0.5 * h * dm1, torque)
        dq3, dm3 = self._rates(q + 0.5 * h * dq2, m + 0.5 * h * dm2, torque)
        dq4, dm4 = self._rates(q + h * dq3, m + h * dm3, torque)
        q_new = q + (h / 6.0) * (dq1 + 2.0 * dq2 + 2.0 * dq3 + dq4)
        m_new = m + (h / 6.0) * (dm1 + 2.0 * dm2 + 2.0 * dm3 + dm4)
        return self._normalised(q_new), m_new
