"""Euler's equations in the principal frame, with commanded torque and dissipation.

State: attitude quaternion q (principal→inertial, x y z w) and body angular momentum m
(principal frame, kg·m²/s). With Ω = m / I:

    dm/dt = m × Ω + τ + dissipation,        dq/dt = ½ q ⊗ (Ω, 0).

Angular momentum (not ω) is the state because |m| is the Casimir of the Lie–Poisson
structure that the splitting integrators keep exactly.
"""
from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import dynamics_kernel, rotation
from .dissipation import Dissipation
from .orbit import kernel as orbit_kernel


@dataclass(frozen=True, eq=False)
class Dynamics:
    """Right-hand side and invariants for principal moments ``moments`` (3,), kg·m².

    ``inverse_moment_spread`` = 1/I_min − 1/I_max (1/(kg·m²)), set from the moments: the
    scale of the dissipation's stiffness and of its path from the minor to the major axis.

    ``environment``: the orbit's element array (``orbit.kernel`` layout) whose torques act
    (the gravity gradient with environment[ON] = 1, the facets' SRP and drag); None: the
    free body (the loops are then compiled without the term). The methods that integrate
    it read it from here and see it changed in place (an SGP4 orbit re-anchored at each
    interval)."""
    moments: np.ndarray
    dissipation: Dissipation = Dissipation()
    environment: Optional[np.ndarray] = None

    def __post_init__(self):
        moments = np.asarray(self.moments, float).reshape(3)
        object.__setattr__(self, 'moments', moments)
        # as floats: asked per step size by auto's selection, where numpy's reductions on
        # three numbers cost more than the rest of the question
        i_min, i_max = float(moments.min()), float(moments.max())
        object.__setattr__(self, 'inverse_moment_spread', 1.0 / i_min - 1.0 / i_max)
        object.__setattr__(self, '_inverse_min', 1.0 / i_min)

    @property
    def gravity_gradient(self) -> bool:
        """Whether the gravity-gradient torque acts (an orbit with the term switched on)."""
        return self.environment is not None and bool(self.environment[orbit_kernel.ON] != 0)

    @property
    def magnetorquers(self) -> bool:
        """Whether the magnetorquers' m × B acts (``environment.magnetic_kernel``)."""
        return self.environment is not None and \
            bool(self.environment[orbit_kernel.MAG_MODEL] != 0)

    @property
    def solar_radiation_pressure(self) -> bool:
        """Whether the facets' solar radiation pressure acts (``environment.facets_kernel``)."""
        return self.environment is not None and \
            bool(self.environment[orbit_kernel.SRP_ON] != 0)

    @property
    def drag(self) -> bool:
        """Whether the facets' aerodynamic drag acts (``environment.facets_kernel``)."""
        return self.environment is not None and \
            bool(self.environment[orbit_kernel.DRAG_ON] != 0)

    @property
    def environment_active(self) -> bool:
        """Whether any environment torque is in the model (the methods that do not
        integrate them refuse, and the free body's closed form does not apply)."""
        return self.gravity_gradient or self.magnetorquers or \
            self.solar_radiation_pressure or self.drag

    @property
    def environment_terms(self) -> str:
        """The scene keys of the environment's torques in the model, for messages."""
        return ' and '.join(k for k, on in (
            ('environment.gravity_gradient', self.gravity_gradient),
            ('magnetorquer.max_dipole', self.magnetorquers),
            ('environment.solar_radiation_pressure', self.solar_radiation_pressure),
            ('environment.drag', self.drag)) if on)

    def environment_torque(self, q, t: float):
        """The environment's torque at attitude q (principal → inertial) and time t,
        principal frame, N·m (zeros for the free body)."""
        if self.environment is None:
            return np.zeros(3)
        return np.array(dynamics_kernel.environment_torque(
            np.asarray(q, float), float(t), self.environment, self.moments))

    def angular_velocity(self, m):
        """Ω = m / I, principal frame, rad/s."""
        return m / self.moments

    def dissipation_rate(self, m):
        """dm/dt due to dissipation alone (principal frame)."""
        d = self.dissipation
        if not d.active:
            return np.zeros_like(m)
        omega = m / self.moments
        if d.model == 'double_bracket':
            return d.coefficient * rotation.cross(m, rotation.cross(m, omega))
        return -d.coefficient * omega  # viscous

    def momentum_rate(self, m, torque=None):
        """dm/dt = m × Ω + τ + dissipation (principal frame)."""
        dm = rotation.cross(m, m / self.moments)
        if torque is not None:
            dm = dm + torque
        if self.dissipation.active:
            dm = dm + self.dissipation_rate(m)
        return dm

    def attitude_rate(self, q, m):
        """dq/dt = ½ q ⊗ (Ω, 0)."""
        omega_quat = np.zeros(m.shape[:-1] + (4,))
        omega_quat[..., :3] = m / self.moments
        return 0.5 * rotation.multiply(q, omega_quat)

    def kinetic_energy(self, m):
        """T = ½ m·Ω, J."""
        return 0.5 * np.sum(m * m / self.moments, axis=-1)

    @staticmethod
    def momentum_norm(m):
        """|m| = |L|, kg·m²/s."""
        return np.linalg.norm(m, axis=-1)

    def dissipation_stiffness(self, momentum_norm):
        """Largest decay rate of the linearised dissipation, 1/s (0 without dissipation).

        double bracket at the major axis: α|L|²(1/I_min − 1/I_max); viscous: c/I_min.
        An explicit method with real-axis stability limit s needs h ≤ s / this.
        """
        d = self.dissipation
        if not d.active:
            return 0.0
        if d.model == 'double_bracket':
            return d.coefficient * momentum_norm ** 2 * self.inverse_moment_spread
        return d.coefficient * self._inverse_min
