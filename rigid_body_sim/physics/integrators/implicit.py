"""Implicit midpoint rule: conserves every quadratic invariant (|m|², T) of free rotation.

m₁ = m₀ + h F(x), x = (m₀ + m₁)/2, solved by Newton's method on x with the exact
Jacobian. The attitude equation is linear given Ω(x), so its midpoint step is the Cayley
transform of ½[Ω]: the quaternion norm is kept exactly, no renormalising.
"""
import numpy as np

from .. import dynamics_kernel, rotation
from . import implicit_kernel
from .base import Candidate, IntegrationError, Integrator, same_order

_EPS = np.finfo(float).eps


def _skew(v):
    """[v]×, batched: (..., 3) -> (..., 3, 3)."""
    z = np.zeros(v.shape[:-1])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return np.stack((np.stack((z, -w, y), -1),
                     np.stack((w, z, -x), -1),
                     np.stack((-y, x, z), -1)), -2)


class ImplicitMidpoint(Integrator):
    """Implicit midpoint (Gauss–Legendre, 1 stage): order 2, A-stable, keeps T and |m| exactly.

    Options: max_iterations (default 30). Newton (damped, exact Jacobian) that does not
    converge is retried on halved steps; failing at h/16 too raises IntegrationError.
    """
    name = 'implicit_midpoint'
    order = 2
    orders = same_order(2)
    stages = 1
    auto = Candidate((0.12, 0.17), 0.025, stiff_only=True, geometric=False)
    kernel_modules = (implicit_kernel,)
    implicit = True
    preserves = frozenset({'angular_momentum_norm', 'kinetic_energy', 'unit_quaternion',
                           'time_reversible'})
    stability = ('A-stable; damped Newton, a failed solve retried on halved steps '
                 '(seen to converge up to h·|Ω| = 1000)')

    def __init__(self, dynamics, max_iterations: int = 30):
        super().__init__(dynamics)
        self.max_iterations = int(max_iterations)
        d = dynamics.dissipation
        self._model = dynamics_kernel.MODEL_CODES[d.model] if d.active else 0
        self._coefficient = d.coefficient
        self._moments = np.array(dynamics.moments, dtype=float)

    def run(self, q, m, h, n, torque=None, t0=0.0):
        """One body: the compiled loop (physics.implicit_kernel); a batch: the numpy path.
        Both retry a failed Newton solve on halved steps and report a failure at h/16
        with the sub-step's size and start time."""
        if np.ndim(q) != 1 or np.ndim(m) != 1:
            return super().run(q, m, h, n, torque, t0)
        if not (np.isfinite(h) and h > 0.0):
            raise IntegrationError(self.name, h, t0, 'step must be finite and positive')
        q = np.array(q, dtype=float)
        m = np.array(m, dtype=float)
        tau = np.zeros(3) if torque is None else np.array(torque, dtype=float).reshape(3)
        failed, status, level, pos, evals = implicit_kernel.implicit_midpoint_run(
            q, m, float(h), int(n), self._moments, tau, self._model, self._coefficient,
            self.max_iterations)
        self.nfev += evals
        if failed >= 0:
            t = t0 + failed * h  # the start of the failing step, as Integrator.run has it
            reason = implicit_kernel.REASONS[status].format(self.max_iterations)
            if status == implicit_kernel.NON_FINITE:
                raise IntegrationError(self.name, h, t, reason)
            raise IntegrationError(self.name, h * 0.5 ** level,
                                   implicit_kernel.substep_time(t, h, level, pos), reason)
        return q, m

    def _jacobian(self, x):
        """dF/dm at x for F(m) = m×Ω + τ + dissipation."""
        dyn = self.dynamics
        inv_i = 1.0 / dyn.moments
        omega = x * inv_i
        j_cross = -_skew(omega) + _skew(x) * inv_i  # d(m×Ω)/dm
        d = dyn.dissipation
        if d.active and d.model == 'double_bracket':
            c = rotation.cross(x, omega)
            j_cross = j_cross + d.coefficient * (-_skew(c) + _skew(x) @ j_cross)
        elif d.active:  # viscous: −c Ω
            j_cross = j_cross - d.coefficient * np.diag(inv_i)
        return j_cross

    def _step(self, q, m, h, torque, t, depth=0):
        """One midpoint step; a failed Newton solve is retried as two half steps (≤ 4 levels).

        Composing midpoint steps keeps symmetry and both quadratic invariants; only when
        h/16 also fails is the step reported as failed.
        """
        try:
            return self._midpoint(q, m, h, torque, t)
        except IntegrationError:
            if depth >= 4:
                raise
            q, m = self._step(q, m, 0.5 * h, torque, t, depth + 1)
            return self._step(q, m, 0.5 * h, torque, t + 0.5 * h, depth + 1)

    def _midpoint(self, q, m, h, torque, t):
        dyn = self.dynamics
        # Start from m, not an explicit predictor: under stiff dissipation the explicit
        # guess overshoots far outside Newton's basin. Backtracking keeps each update
        # from increasing the residual (damped Newton).
        x = m.copy()
        residual = x - m - 0.5 * h * dyn.momentum_rate(x, torque)
        self.nfev += 1
        eye = np.eye(3)
        for _ in range(self.max_iterations):
            jac = eye - 0.5 * h * self._jacobian(x)
            dx = np.linalg.solve(jac, residual[..., None])[..., 0]
            norm0 = np.linalg.norm(residual)
            lam = 1.0
            while True:
                x_try = x - lam * dx
                r_try = x_try - m - 0.5 * h * dyn.momentum_rate(x_try, torque)
                self.nfev += 1
                if np.linalg.norm(r_try) <= norm0 or lam < 1e-3 or not np.all(np.isfinite(r_try)):
                    break
                lam *= 0.5
            x, residual = x_try, r_try
            if not np.all(np.isfinite(x)):
                break
            if np.all(np.abs(lam * dx) <= 4.0 * _EPS * np.max(np.abs(x), axis=-1, keepdims=True)):
                break
        else:
            raise IntegrationError(self.name, h, t,
                                   'Newton iteration did not converge in '
                                   f'{self.max_iterations} iterations')
        if not np.all(np.isfinite(x)):
            raise IntegrationError(self.name, h, t, 'Newton iteration diverged')
        m_new = 2.0 * x - m
        # Cayley step for q' = ½ q ⊗ Ω with Ω frozen at the midpoint: (1 − h/2 A)⁻¹(1 + h/2 A).
        # Right-multiplication by the pure quaternion Ω is a rotation of R⁴, so the
        # Cayley transform equals right-multiplication by a unit quaternion:
        half = 0.25 * h * (x / dyn.moments)
        denom = 1.0 + np.sum(half * half, axis=-1, keepdims=True)
        cayley = np.concatenate((2.0 * half, 1.0 - np.sum(half * half, axis=-1, keepdims=True)),
                                -1) / denom
        return rotation.multiply(q, cayley), m_new
