"""Samples: the state at sample instants, in the user's frames, as blocks of arrays.

A :class:`SampleBlock` holds n consecutive samples (n may be 0 or 1 in a live run, a few
thousand offline). Every front end consumes blocks: the node turns each row into
messages, the offline run into bag records and plot points, the bench into errors.
"""
from dataclasses import dataclass

import numpy as np

from ..physics import rotation
from ..physics.body import RigidBody

FIELDS = ('t_ns', 'attitude', 'angular_velocity', 'angular_momentum', 'angular_momentum_body',
          'kinetic_energy', 'torque')


@dataclass(frozen=True)
class SampleBlock:
    """n samples. Frames: attitude (x, y, z, w) body → inertial; angular_velocity (rad/s)
    and angular_momentum_body (kg·m²/s) in the body frame; angular_momentum (kg·m²/s) in
    the inertial frame; kinetic_energy (J); torque (N·m, body frame) is the total held
    torque applied from that instant on. t_ns: sim time, integer nanoseconds."""
    t_ns: np.ndarray
    attitude: np.ndarray
    angular_velocity: np.ndarray
    angular_momentum: np.ndarray
    angular_momentum_body: np.ndarray
    kinetic_energy: np.ndarray
    torque: np.ndarray

    def __len__(self):
        return len(self.t_ns)

    def __getitem__(self, key):
        """Field by name, as for a dict of arrays (``'t'`` is seconds)."""
        return self.t if key == 't' else getattr(self, key)

    @property
    def t(self) -> np.ndarray:
        """Sim time in seconds (for plots; keep t_ns for anything exact)."""
        return self.t_ns / 1e9

    def row(self, i):
        """Sample i as a dict of Python values."""
        return {k: getattr(self, k)[i].tolist() for k in FIELDS}

    @staticmethod
    def concatenate(blocks) -> 'SampleBlock':
        blocks = list(blocks)
        if not blocks:
            return empty_block()
        return SampleBlock(*(np.concatenate([getattr(b, k) for b in blocks]) for k in FIELDS))


def empty_block() -> SampleBlock:
    return SampleBlock(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros((0, 3)),
                       np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))


class BlockBuilder:
    """Collects principal-frame states (q, m) at sample instants; ``block()`` converts them
    to the user's frames in one vectorised pass."""

    def __init__(self, body: RigidBody, capacity: int = 1024):
        self.body = body
        self.capacity = capacity
        self._t = np.empty(capacity, np.int64)
        self._q = np.empty((capacity, 4))
        self._m = np.empty((capacity, 3))
        self._tau = np.empty((capacity, 3))
        self.n = 0

    @property
    def full(self) -> bool:
        return self.n >= self.capacity

    def add(self, t_ns, q, m, torque_body):
        i = self.n
        self._t[i], self._q[i], self._m[i] = t_ns, q, m
        self._tau[i] = 0.0 if torque_body is None else torque_body
        self.n += 1

    def add_many(self, t_ns, q, m):
        """Torque-free rows (e.g. the exact flow evaluated at many instants)."""
        k = len(t_ns)
        s = slice(self.n, self.n + k)
        self._t[s], self._q[s], self._m[s], self._tau[s] = t_ns, q, m, 0.0
        self.n += k

    def block(self) -> SampleBlock:
        n, body = self.n, self.body
        q, m = self._q[:n], self._m[:n]
        moments = body.principal_moments
        attitude = body.attitude_to_body(q)
        attitude /= np.linalg.norm(attitude, axis=-1, keepdims=True)
        out = SampleBlock(self._t[:n].copy(), attitude, body.to_body(m / moments),
                          rotation.rotate(q, m), body.to_body(m),
                          0.5 * np.sum(m * m / moments, axis=-1), self._tau[:n].copy())
        self.n = 0
        return out
