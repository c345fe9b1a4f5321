"""The one interface every integrator has (cf. scipy.integrate.OdeSolver).

An integrator advances the principal-frame state (q, m) of one body or a batch
(q: (..., 4), m: (..., 3)) by a step h, with a body torque τ (principal frame) held
constant over the step (zero-order hold). Methods differ only in ``_step``.
"""
from typing import ClassVar, FrozenSet, Optional

import math

import numpy as np

from ..dynamics import Dynamics


class IntegrationError(RuntimeError):
    """The state became non-finite or a solver failed; names the method, step and time."""

    def __init__(self, integrator: str, h: float, t: float, reason: str):
        self.integrator, self.h, self.t, self.reason = integrator, h, t, reason
        super().__init__(f'{integrator} failed at t = {t:.9g} s with step h = {h:.6g} s: {reason}')


# Names of invariants a method may keep exactly (to round-off) in free rotation.
PRESERVES = ('angular_momentum_norm', 'kinetic_energy', 'unit_quaternion', 'poisson',
             'time_reversible')


class Integrator:
    """Base class. Subclasses set the class attributes and implement ``_step``.

    Attributes:
        name: registry key.
        order: classical order of accuracy (for the free rigid body).
        implicit: solves equations each step.
        adaptive: chooses its own internal steps (h is then an output interval).
        preserves: invariants kept exactly in torque-free motion (see PRESERVES).
        stability: known stability limit, in words.
        nfev: right-hand-side evaluations (or equivalent sub-flows) so far.
    """
    name: ClassVar[str] = ''
    order: ClassVar[int] = 0
    implicit: ClassVar[bool] = False
    adaptive: ClassVar[bool] = False
    preserves: ClassVar[FrozenSet[str]] = frozenset()
    stability: ClassVar[str] = ''

    def __init__(self, dynamics: Dynamics, **options):
        if options:
            raise TypeError(f'{self.name} takes no options {sorted(options)}')
        self.dynamics = dynamics
        self.nfev = 0

    def step(self, q, m, h: float, torque: Optional[np.ndarray] = None, t: float = 0.0):
        """Advance (q, m) by h seconds; returns new arrays. Raises IntegrationError."""
        if not (np.isfinite(h) and h > 0.0):
            raise IntegrationError(self.name, h, t, 'step must be finite and positive')
        q_new, m_new = self._step(np.asarray(q, float), np.asarray(m, float), float(h),
                                  None if torque is None else np.asarray(torque, float), t)
        if not (np.all(np.isfinite(m_new)) and np.all(np.isfinite(q_new))):
            raise IntegrationError(self.name, h, t,
                                   'state became non-finite (the method diverged)')
        return q_new, m_new

    def _step(self, q, m, h, torque, t):
        raise NotImplementedError

    def effective_order(self, m, h) -> int:
        """The order on this dynamics at step h for one body's momentum m (measured by the
        tests per kind of scene): :meth:`order_on` at |m|."""
        x, y, z = (float(v) for v in m)
        return self.order_on(self.dynamics, math.sqrt(x * x + y * y + z * z), h)

    @classmethod
    def order_on(cls, dynamics: Dynamics, momentum_norm: float, h: float) -> int:
        """The order on ``dynamics`` at step h for |m| = ``momentum_norm``, asked without
        an instance (``auto`` asks it per candidate and step). Methods whose order depends
        on the damping's stiffness override this."""
        return cls.order

    def run(self, q, m, h: float, n: int, torque: Optional[np.ndarray] = None, t0: float = 0.0):
        """``n`` steps of ``h`` from (q, m) at time t0; new arrays. Methods with a compiled
        loop (``integrators/*_kernel.py``) override this for one body; IntegrationError names the
        step and time where the state stopped being finite."""
        for k in range(n):
            q, m = self.step(q, m, h, torque, t0 + k * h)
        return q, m

    def _run_kernel(self, kernel, q, m, h, n, torque, t0):
        """Shared shell of the compiled loops: copies in, checks, failure with its time."""
        if not (math.isfinite(h) and h > 0.0):
            raise IntegrationError(self.name, h, t0, 'step must be finite and positive')
        q = np.array(q, dtype=float)
        m = np.array(m, dtype=float)
        tau = np.zeros(3) if torque is None else np.array(torque, dtype=float).reshape(3)
        failed = kernel(q, m, float(h), int(n), tau, torque is not None)
        if failed >= 0:
            raise IntegrationError(self.name, h, t0 + (failed + 1) * h,
                                   'state became non-finite (the method diverged)')
        return q, m

    def reset(self):
        """Forget any state carried between steps (caches, solver warm starts)."""

    def loop_spec(self):
        """(weights, split_axes) of this method's compiled one-body loop for kernels that
        drive it themselves (the engine's compiled closed loop), or None if it has none."""
        return None

    @classmethod
    def describe(cls) -> dict:
        return {'name': cls.name, 'order': cls.order, 'implicit': cls.implicit,
                'adaptive': cls.adaptive, 'preserves': sorted(cls.preserves),
                'stability': cls.stability, 'summary': (cls.__doc__ or '').strip().splitlines()[0]}
