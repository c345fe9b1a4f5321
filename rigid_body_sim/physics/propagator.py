"""Propagate a rigid body in the user's body frame with any registered integrator.

The user's frame is the body frame of the inertia they gave; dynamics run in the
principal frame and every input/output here is converted at the boundary.
"""
from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import rotation
from .body import RigidBody
from .dynamics import Dissipation, Dynamics
from .integrators import create


@dataclass(frozen=True)
class State:
    """A body's state at time t.

    attitude: quaternion (x, y, z, w) rotating body-frame vectors into the inertial frame.
    angular_velocity: ω in the body frame, rad/s.
    """
    t: float
    attitude: np.ndarray
    angular_velocity: np.ndarray


def validated_state(attitude, angular_velocity):
    """Normalised attitude and ω as float arrays; ValueError on NaN/Inf/zero quaternion."""
    q = rotation.validated(attitude, 'attitude')
    w = np.asarray(angular_velocity, float)
    if w.shape[-1] != 3:
        raise ValueError(f'angular velocity must have 3 components, got shape {w.shape}')
    if not np.all(np.isfinite(w)):
        raise ValueError(f'angular velocity is not finite: {w.tolist()}')
    return q, w


class Propagator:
    """One body (or a batch with shared inertia) advanced by a named integrator.

    Example::

        body = RigidBody.from_inertia([1.0, 2.0, 3.0])
        p = Propagator(body, attitude=[0, 0, 0, 1], angular_velocity=[0.01, 1.0, 0.0])
        p.advance(10.0, step=0.01)
        p.kinetic_energy, p.angular_momentum_inertial
    """

    def __init__(self, body: RigidBody, attitude=(0.0, 0.0, 0.0, 1.0),
                 angular_velocity=(0.0, 0.0, 0.0),
                 dissipation: Dissipation = Dissipation(), integrator: str = 'splitting2',
                 t: float = 0.0, **options):
        self.body = body
        self.dynamics = Dynamics(body.principal_moments, dissipation)
        self.integrator = create(integrator, self.dynamics, **options)
        self.set_state(attitude, angular_velocity, t)

    # --- state in the user's frames -------------------------------------------------
    def set_state(self, attitude, angular_velocity, t: float = 0.0):
        q, w = validated_state(attitude, angular_velocity)
        self.t = float(t)
        self._q = self.body.attitude_to_principal(q)
        self._m = self.body.principal_moments * self.body.to_principal(w)
        self.integrator.reset()

    @property
    def state(self) -> State:
        return State(self.t, self.attitude, self.angular_velocity)

    @property
    def attitude(self):
        """Quaternion (x, y, z, w), body→inertial."""
        return self.body.attitude_to_body(self._q)

    @property
    def angular_velocity(self):
        """ω, body frame, rad/s."""
        return self.body.to_body(self._m / self.body.principal_moments)

    @property
    def angular_momentum_body(self):
        """L = I ω, body frame, kg·m²/s."""
        return self.body.to_body(self._m)

    @property
    def angular_momentum_inertial(self):
        """L in the inertial frame, kg·m²/s (constant without external torque)."""
        return rotation.rotate(self._q, self._m)

    @property
    def kinetic_energy(self):
        """T = ½ ω·Iω, J."""
        return self.dynamics.kinetic_energy(self._m)

    @property
    def angular_momentum_norm(self):
        return np.linalg.norm(self._m, axis=-1)

    @property
    def principal_state(self):
        """(q principal→inertial, m principal frame) — what the integrators advance."""
        return self._q.copy(), self._m.copy()

    # --- stepping -------------------------------------------------------------------
    def set_integrator(self, name: str, **options):
        """Switch method; the state carries over unchanged."""
        self.integrator = create(name, self.dynamics, **options)

    def step(self, h: float, torque_body: Optional[np.ndarray] = None):
        """One step of h seconds with a body-frame torque (N·m) held constant over it."""
        torque = None if torque_body is None else self.body.to_principal(torque_body)
        self._q, self._m = self.integrator.step(self._q, self._m, h, torque, self.t)
        self.t += h

    def advance(self, duration: float, step: float, torque_body=None):
        """Advance by ``duration`` with steps of at most ``step`` (the last one lands exactly)."""
        n = max(1, int(np.ceil(duration / step - 1e-9)))
        h = duration / n
        for _ in range(n):
            self.step(h, torque_body)


def poinsot(moments, m):
    """Poinsot's construction for principal moments and body momentum m (principal frame).

    Returns the polhode point ω on the energy ellipsoid ω·Iω = 2T, the invariable-plane
    normal L̂ (body frame), its distance 2T/|L| from the centre (since L·ω = 2T), and T, |L|.
    """
    moments = np.asarray(moments, float)
    m = np.asarray(m, float)
    omega = m / moments
    two_t = np.sum(m * omega, axis=-1)
    norm = np.linalg.norm(m, axis=-1)
    return {'polhode_point': omega, 'invariable_plane_normal': m / norm[..., None],
            'invariable_plane_distance': two_t / norm, 'kinetic_energy': 0.5 * two_t,
            'angular_momentum_norm': norm}
