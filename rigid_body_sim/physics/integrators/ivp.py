"""scipy's adaptive DOP853 (solve_ivp) over each step: the high-accuracy reference method."""
import numpy as np
from scipy.integrate import solve_ivp

from .base import IntegrationError, Integrator


class DOP853(Integrator):
    """Dormand–Prince 8(5,3) via scipy.integrate.solve_ivp, adaptive with rtol/atol.

    Options: rtol (default 1e-10), atol (default 1e-12). Each call to ``step`` integrates
    [t, t + h] for the whole batch as one system; q is renormalised at the end of the step.
    """
    name = 'dop853'
    order = 8
    adaptive = True
    stability = 'adaptive; step shrinks under stiff dissipation (cost grows with stiffness)'

    def __init__(self, dynamics, rtol: float = 1e-10, atol: float = 1e-12):
        super().__init__(dynamics)
        if not (rtol > 0 and atol > 0):
            raise ValueError('dop853 needs rtol > 0 and atol > 0')
        self.rtol, self.atol = float(rtol), float(atol)

    def _step(self, q, m, h, torque, t):
        shape_q, shape_m = q.shape, m.shape
        nq = q.size
        dyn = self.dynamics

        def rhs(_, y):
            qq = y[:nq].reshape(shape_q)
            mm = y[nq:].reshape(shape_m)
            return np.concatenate((dyn.attitude_rate(qq, mm).ravel(),
                                   dyn.momentum_rate(mm, torque).ravel()))

        sol = solve_ivp(rhs, (0.0, h), np.concatenate((q.ravel(), m.ravel())), method='DOP853',
                        rtol=self.rtol, atol=self.atol)
        self.nfev += sol.nfev
        if not sol.success:
            raise IntegrationError(self.name, h, t, sol.message)
        y = sol.y[:, -1]
        q_new = y[:nq].reshape(shape_q)
        return q_new / np.linalg.norm(q_new, axis=-1, keepdims=True), y[nq:].reshape(shape_m)
