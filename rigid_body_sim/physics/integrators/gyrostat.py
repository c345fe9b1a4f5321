"""The gyrostat Strang splitting: a body carrying reaction wheels and CMGs (order 2).

The method of every scene with actuators (``gyrostat_kernel`` holds its compiled loop and
the scheme). It advances the body's (q, m) together with the actuators' own state (wheel
momenta, gimbal angles), which an *actuators* object owns and passes to the loop:
``actuators.run(q, m, h, n, moments, split_axes, tau_ext_p)`` advancing (q, m) and its
own state in place (``engine.actuators.Actuators``). So it cannot run without one, nor
with dissipation (the loop has none): ``requires_actuators`` says so to the sites that
iterate the registry (choices, benchmarks, tests), which skip it where it cannot run.
"""
import numpy as np

from . import gyrostat_kernel
from .base import IntegrationError, Integrator


class GyrostatStrang(Integrator):
    """Gyrostat Strang splitting (wheels/CMGs): actuator kicks around exact axis rotations."""
    name = 'gyrostat_strang'
    order = 2
    # torque-free and with a held external torque; no dissipation (the loop has none)
    orders = {'torque_free': 2, 'double_bracket': None, 'viscous': None, 'torque': 2}
    stages = 1
    requires_actuators = True
    kernel_modules = (gyrostat_kernel,)
    environment = True  # the gravity gradient joins the external kicks (gyrostat_kernel)
    preserves = frozenset({'angular_momentum_norm', 'unit_quaternion'})
    stability = 'no step-size limit for free rotation (every sub-flow is a rotation)'

    def __init__(self, dynamics, actuators=None):
        super().__init__(dynamics)
        if actuators is None:
            raise ValueError(f'{self.name} needs the scene\'s actuators (actuators.wheels / '
                             'actuators.cmgs): it advances them with the body')
        if dynamics.dissipation.active:
            raise ValueError(f'{self.name} has no dissipation; set dissipation.model to none '
                             'with actuators')
        self.actuators = actuators
        # outer, middle, inner axis of the composition, as the body's splittings order them
        # (splitting.py _ORDER: smallest, largest, intermediate)
        self._split_axes = np.argsort(dynamics.moments, kind='stable')[[0, 2, 1]]

    def _kernel(self, q, m, h, n, tau, has_tau, t0=0.0):
        failed = self.actuators.run(q, m, h, n, self.dynamics.moments, self._split_axes,
                                    tau if has_tau else None, t0, self.dynamics.environment)
        self.nfev += n if failed < 0 else failed + 1
        return failed

    def run(self, q, m, h, n, torque=None, t0=0.0):
        """``n`` steps of the body with its actuators (one body only)."""
        if np.ndim(q) != 1 or np.ndim(m) != 1:
            raise IntegrationError(self.name, h, t0, 'one body only (its actuators are one '
                                   'set)')
        return self._run_kernel(self._kernel, q, m, h, n, torque, t0)

    def _step(self, q, m, h, torque, t):
        return self.run(q, m, h, 1, torque, t)
