"""The exact torque-free flow as an integrator, split with torque and dissipation.

Torque-free: the closed-form solution (``physics.exact``) is anchored at a state and
evaluated at the elapsed time, so stepping adds no error however long the run. When the
caller feeds back the state this integrator returned, the anchor is kept and only the
elapsed time advances: the result is the solution at t, not a chain of rounded steps.
With torque or dissipation the step is the symmetric splitting of ``splitting2`` with the
exact free flow in place of the axis rotations (order 2 in the coupling).
"""
import math

import numpy as np

from ..exact import TorqueFreeSolution, build as exact_build
from .. import exact
from . import exact_flow_kernel
from .base import Candidate
from .splitting import Splitting2


class Exact(Splitting2):
    """Closed-form torque-free solution (Jacobi elliptic functions, Carlson integrals).

    No stepping error without torque or dissipation; order 2 splitting with them.
    """
    name = 'exact'
    order = 0  # exact when torque-free; see docstring
    orders = {'torque_free': None, 'double_bracket': 2, 'viscous': 2, 'torque': 2}
    stages = 0.0  # a closed form at each step: no repeated rotation to round
    loop_code = 4  # its split steps (exact_flow_kernel); torque-free, the engine evaluates it
    # with dissipation or torque each step builds a closed form from its state in its
    # compiled loop: 1.6–1.8 µs on a triaxial body in the classes' units (11–12× splitting2's
    # free step; a symmetric body ~0.25; calibrated on a triaxial one). The earlier 18 µs
    # was the Python step's. Its pilot keeps hΩ ≤ 2 like the others, though it rotates
    # exactly: at steps that are multiples of the precession period its splitting error
    # aliases (Explorer 1: exact at h = 1 s and 0.5 s agree to 1e-6 and are 0.025 rad off
    # after 690 s), which step doubling cannot see; on a symmetric body auto bounds that a
    # priori (auto.selection: at most the damping's turning Δβ, at any step)
    auto = Candidate((1.7, 1.8), math.inf, coupled_only=True)
    kernel_modules = (exact, exact_flow_kernel)
    environment = False  # its split steps kick with the held torque only
    preserves = frozenset({'angular_momentum_norm', 'kinetic_energy', 'unit_quaternion', 'poisson',
                           'time_reversible'})
    stability = 'none: evaluated at any t without stepping'

    def __init__(self, dynamics):
        super().__init__(dynamics)
        self._moments = np.ascontiguousarray(dynamics.moments, dtype=float)
        self._q_out, self._m_out = np.empty(4), np.empty(3)  # the compiled flow's output
        self.reset()

    @classmethod
    def order_on(cls, dynamics, momentum_norm, h) -> int:
        """2: the order of its splitting with torque or dissipation (measured by the tests).
        Without either it has no stepping error, and ``auto`` never steps it then."""
        return 2

    def run(self, q, m, h, n, torque=None, t0=0.0):
        """Torque-free: step by step from the anchor (each step a closed-form evaluation).
        With torque or dissipation, one body runs the split steps' compiled loop
        (``exact_flow_kernel``: the sub-flows of :meth:`_step`, equal to round-off)."""
        coupled = torque is not None or self.dynamics.dissipation.active
        if coupled and np.ndim(q) == 1 and np.ndim(m) == 1:
            self._last = None
            return self._run_kernel(self._kernel, q, m, h, n, torque, t0)
        for k in range(n):
            q, m = self.step(q, m, h, torque, t0 + k * h)
        return q, m

    def _kernel(self, q, m, h, n, tau, has_tau, t0=0.0):
        failed, evals = exact_flow_kernel.exact_steps(q, m, h, n, self._moments, tau, has_tau,
                                                      self._model, self._coefficient,
                                                      self._q_out, self._m_out)
        self.nfev += evals
        return failed

    def reset(self):
        self._solution = None
        self._elapsed = 0.0
        self._last = None

    def _free(self, q, m, h):
        last = self._last
        anchored = (self._solution is not None and last is not None
                    and np.array_equal(q, last[0]) and np.array_equal(m, last[1]))
        if not anchored:
            self._solution = TorqueFreeSolution(self.dynamics.moments, q, m)
            self._elapsed = 0.0
        self._elapsed += h
        q_new, m_new = self._solution.at(self._elapsed)
        self._last = (q_new, m_new)
        self.nfev += 1
        return q_new, m_new

    def _flow(self, q, m, h):
        """The free flow for h from (q, m), a new solution each time: for one body a
        compiled one-shot (:func:`..exact.build.flow`, ~1 µs instead of a TorqueFreeSolution's
        ~300 µs of numpy set-up); a non-finite state gives NaN, which step() reports."""
        if q.ndim > 1 or m.ndim > 1:
            return TorqueFreeSolution(self.dynamics.moments, q, m).at(h)
        q_out, m_out = np.full(4, np.nan), np.full(3, np.nan)
        norm = math.sqrt(q @ q)
        if math.isfinite(norm) and norm > 0.0 and np.all(np.isfinite(m)):
            exact_build.flow(self._moments, q / norm, np.asarray(m, float), h, q_out, m_out)
        return q_out, m_out

    def _step(self, q, m, h, torque, t):
        if torque is None and not self.dynamics.dissipation.active:
            return self._free(q, m, h)
        self._last = None
        m = self._dissipate(m, 0.5 * h)
        if torque is not None:
            m = m + (0.5 * h) * torque
        q, m = self._flow(q, m, h)
        self.nfev += 1
        if torque is not None:
            m = m + (0.5 * h) * torque
        m = self._dissipate(m, 0.5 * h)
        return q, m
