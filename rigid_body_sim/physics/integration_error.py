"""IntegrationError alone, without the integrators: a node that names it (to catch it)
imports it at start without numba (~0.4 CPU-s), which a run refused for its parameters,
``--help`` and the node's construction before its engine never need."""


class IntegrationError(RuntimeError):
    """The state became non-finite or a solver failed; names the method, step and time."""

    def __init__(self, integrator: str, h: float, t: float, reason: str):
        self.integrator, self.h, self.t, self.reason = integrator, h, t, reason
        super().__init__(f'{integrator} failed at t = {t:.9g} s with step h = {h:.6g} s: {reason}')
