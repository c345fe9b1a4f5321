"""Samples: the state at sample instants, in the user's frames, as blocks of arrays.

A :class:`SampleBlock` holds n consecutive samples (n may be 0 or 1 in a live run, a few
thousand offline). Every front end consumes blocks: the node turns each row into
messages, the offline run into bag records and plot points, the bench into errors.
"""
from dataclasses import dataclass
import math
from functools import cached_property
from typing import Optional

import numpy as np

from ..physics import rotation
from ..physics.body import RigidBody

FIELDS = ('t_ns', 'attitude', 'angular_velocity', 'angular_momentum', 'angular_momentum_body',
          'kinetic_energy', 'torque')


@dataclass(frozen=True, eq=False)
class SampleBlock:
    """n samples. Frames: attitude (x, y, z, w) body → inertial; angular_velocity (rad/s)
    and angular_momentum_body (kg·m²/s) in the body frame; angular_momentum (kg·m²/s) in
    the inertial frame; kinetic_energy (J); torque (N·m, body frame) is the total held
    torque applied from that instant on. t_ns: sim time, integer nanoseconds. sensors:
    the gyro / star-tracker readings (``engine.sensing.SensorReadings``) taken while this
    block was produced, at their own instants; None when the scene simulates no sensor.

    It holds the principal-frame state (q principal → inertial, m) and converts it to the
    user's frames on first use of each field, so a consumer that reads only the end state
    (the bench, campaigns) pays nothing for the others."""
    t_ns: np.ndarray
    q: np.ndarray
    m: np.ndarray
    torque: np.ndarray
    body: Optional[RigidBody]
    # with wheels/CMGs: one row per sample of Actuators.row (wheel speeds, wheel momenta,
    # gimbal angles, gimbal rates, singularity measure, |h_A|); None without actuators
    actuators: Optional[np.ndarray] = None
    sensors: Optional[object] = None  # engine.sensing.SensorReadings taken meanwhile
    magnetometer: Optional[object] = None  # engine.magnetic.MagnetometerReadings, likewise
    # with magnetorquers: the rods' held dipole at each sample (n, 3), body frame, A·m²
    dipole: Optional[np.ndarray] = None

    def __len__(self):
        return len(self.t_ns)

    def __getitem__(self, key):
        """Field by name, as for a dict of arrays (``'t'`` is seconds)."""
        return self.t if key == 't' else getattr(self, key)

    @property
    def t(self) -> np.ndarray:
        """Sim time in seconds (for plots; keep t_ns for anything exact)."""
        return self.t_ns / 1e9

    @cached_property
    def attitude(self) -> np.ndarray:
        if not len(self):
            return np.zeros((0, 4))
        a = self.body.attitude_to_body(self.q)
        return a / np.linalg.norm(a, axis=-1, keepdims=True)

    @cached_property
    def angular_velocity(self) -> np.ndarray:
        if not len(self):
            return np.zeros((0, 3))
        return self.body.to_body(self.m / self.body.principal_moments)

    @cached_property
    def angular_momentum(self) -> np.ndarray:
        return rotation.rotate(self.q, self.m) if len(self) else np.zeros((0, 3))

    @cached_property
    def angular_momentum_body(self) -> np.ndarray:
        return self.body.to_body(self.m) if len(self) else np.zeros((0, 3))

    @cached_property
    def kinetic_energy(self) -> np.ndarray:
        if not len(self):
            return np.zeros(0)
        return 0.5 * np.sum(self.m * self.m / self.body.principal_moments, axis=-1)

    def values(self, i) -> list:
        """Sample i as 17 floats: attitude (4), angular_velocity (3), angular_momentum (3),
        angular_momentum_body (3), kinetic_energy, torque (3) — the fields' frames.

        A live node converts one sample at a time, where the vectorised fields cost ~90 µs
        of numpy overhead per row; short blocks are therefore converted on Python floats
        (the same formulas, equal to the fields to round-off: test_engine checks 1e-15)."""
        if len(self) > ROW_PATH_MAX or 'attitude' in self.__dict__:
            return [*self.attitude[i].tolist(), *self.angular_velocity[i].tolist(),
                    *self.angular_momentum[i].tolist(), *self.angular_momentum_body[i].tolist(),
                    float(self.kinetic_energy[i]), *self.torque[i].tolist()]
        return _row_values(self.body, self.q[i].tolist(), self.m[i].tolist(),
                           self.torque[i].tolist())

    def row(self, i):
        """Sample i as a dict of Python values. On a long block whose fields are not
        converted yet, only that sample is (an offline run reads the first and last of
        every block: converting all 1024 rows for two cost more than the physics)."""
        if len(self) > ROW_PATH_MAX and 'attitude' not in self.__dict__:
            i = range(len(self))[i]
            return self.take(slice(i, i + 1)).row(0)
        return {k: getattr(self, k)[i].tolist() for k in FIELDS}

    def take(self, index, copy=False) -> 'SampleBlock':
        """The samples at ``index`` (an index array or a slice: views of this block's
        arrays, or copies with ``copy``, which keep no reference to them)."""
        def pick(a):
            return None if a is None else a[index].copy() if copy and isinstance(
                index, slice) else a[index]
        return SampleBlock(pick(self.t_ns), pick(self.q), pick(self.m), pick(self.torque),
                           self.body, pick(self.actuators), dipole=pick(self.dipole))

    @staticmethod
    def concatenate(blocks) -> 'SampleBlock':
        blocks = [b for b in blocks if len(b)]
        if not blocks:
            return empty_block()
        if len(blocks) == 1:  # its arrays, not copies (SampleBlock's arrays are not written)
            b = blocks[0]
            return SampleBlock(b.t_ns, b.q, b.m, b.torque, b.body, b.actuators, dipole=b.dipole)
        extra, dipole = (None if getattr(blocks[0], k) is None else
                         np.concatenate([getattr(b, k) for b in blocks])
                         for k in ('actuators', 'dipole'))
        return SampleBlock(*(np.concatenate([getattr(b, k) for b in blocks])
                           for k in ('t_ns', 'q', 'm', 'torque')), blocks[0].body, extra,
                           dipole=dipole)


ROW_PATH_MAX = 4  # blocks up to this length convert row by row on floats (SampleBlock.values)


def _row_values(body: RigidBody, q, m, torque) -> list:
    """SampleBlock.values for one principal-frame state (q principal → inertial, m), with
    the formulas of rotation.multiply, rotation.rotate and RigidBody.to_body."""
    qx, qy, qz, qw = q
    px, py, pz, pw = body.principal_to_body.tolist()
    cx, cy, cz, cw = -px, -py, -pz, pw                   # a = q ⊗ conj(p): body attitude
    ax = qw * cx + qx * cw + qy * cz - qz * cy
    ay = qw * cy - qx * cz + qy * cw + qz * cx
    az = qw * cz + qx * cy - qy * cx + qz * cw
    aw = qw * cw - qx * cx - qy * cy - qz * cz
    n = math.sqrt(ax * ax + ay * ay + az * az + aw * aw)
    ix, iy, iz = body.principal_moments.tolist()
    m0, m1, m2 = m
    w0, w1, w2 = m0 / ix, m1 / iy, m2 / iz
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = body.principal_axes.tolist()
    tx, ty, tz = 2 * (qy * m2 - qz * m1), 2 * (qz * m0 - qx * m2), 2 * (qx * m1 - qy * m0)
    return [ax / n, ay / n, az / n, aw / n,                # L = m + qw t + u × t, t = 2 u × m
            r00 * w0 + r01 * w1 + r02 * w2, r10 * w0 + r11 * w1 + r12 * w2,
            r20 * w0 + r21 * w1 + r22 * w2,
            m0 + qw * tx + (qy * tz - qz * ty), m1 + qw * ty + (qz * tx - qx * tz),
            m2 + qw * tz + (qx * ty - qy * tx),
            r00 * m0 + r01 * m1 + r02 * m2, r10 * m0 + r11 * m1 + r12 * m2,
            r20 * m0 + r21 * m1 + r22 * m2,
            0.5 * (m0 * m0 / ix + m1 * m1 / iy + m2 * m2 / iz), *torque]


def empty_block() -> SampleBlock:
    return SampleBlock(np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros((0, 3)),
                       np.zeros((0, 3)), None)


class BlockBuilder:
    """Collects principal-frame states (q, m) at sample instants; ``block()`` converts them
    to the user's frames in one vectorised pass.

    A block at least half of ``capacity`` long takes the builder's arrays themselves (views
    of its filled rows) instead of copies, and the builder allocates fresh ones when it is
    written to again: an offline run sized to its samples (``capacity`` = their count)
    then copies none, where two copies of every sample (the block's, then the result's
    concatenation) cost ~30 ns a sample, as much as the exact solution's own. A short block
    (a live node's one sample) is copied, so that it does not hold the whole capacity.

    The torque column is allocated on the first row that needs it (``add`` with a torque,
    ``columns``): rows without (``add`` of None, ``free_columns``) are zeros, 24 of a sample's
    88 bytes, which a one-shot run otherwise pays in page faults (~27 % of them) and
    writes; a block without it gets a fresh zero array (calloc: untouched until read)."""

    def __init__(self, body: RigidBody, capacity: int = 1024):
        self.body = body
        self.capacity = capacity
        self._t = None  # the arrays, allocated on the first write (_allocate)
        self._extra = None  # actuator rows, allocated on the first one
        self._dipole = None  # the rods' dipole per row, allocated on the first one
        self._columns = None  # (the arrays' t, cap, the views columns() gave for them)
        self.n = 0

    def _allocate(self):
        c = self.capacity
        self._t, self._q = np.empty(c, np.int64), np.empty((c, 4))
        self._m, self._tau = np.empty((c, 3)), None  # (the torque: _torque)

    def _torque(self):
        """The torque column, allocated now if it was not, its rows so far zeros."""
        if self._tau is None:
            self._tau = np.empty((self.capacity, 3))
            self._tau[:self.n] = 0.0
        return self._tau

    @property
    def full(self) -> bool:
        return self.n >= self.capacity

    def add(self, t_ns, q, m, torque_body, extra=None, dipole=None):
        if self._t is None:
            self._allocate()
        i = self.n
        self._t[i], self._q[i], self._m[i] = t_ns, q, m
        if torque_body is not None or self._tau is not None:  # (None: a zero row)
            self._torque()[i] = 0.0 if torque_body is None else torque_body
        if extra is not None:
            if self._extra is None or self._extra.shape[1] != len(extra):
                self._extra = np.zeros((self.capacity, len(extra)))
            self._extra[i] = extra
        if dipole is not None:
            if self._dipole is None:
                self._dipole = np.zeros((self.capacity, 3))
            self._dipole[i] = dipole
        self.n += 1

    def fill_dipole(self, start: int, dipole) -> None:
        """Rows [start, n) written by a compiled loop held ``dipole`` (body frame, A·m²)."""
        if self._dipole is None:
            self._dipole = np.zeros((self.capacity, 3))
        self._dipole[start:self.n] = dipole

    def columns(self, cap: int):
        """(t ns, q, m, τ body) of rows [0, cap), views that a compiled loop fills from row
        ``n`` on (the caller then counts the rows it wrote into ``n``). The same views
        while the arrays and ``cap`` are (a lockstep exchange asks for them at every call:
        four slices, 0.5 µs)."""
        if self._t is None:
            self._allocate()
        key = self._columns
        if key is None or key[0] is not self._t or key[1] != cap:
            key = self._columns = (self._t, cap, (self._t[:cap], self._q[:cap],
                                                  self._m[:cap], self._torque()[:cap]))
        return key[2]

    def free_columns(self, cap: int):
        """(t ns, q, m) of rows [0, cap) for rows whose torque is zero (a torque-free
        stretch), and the torque column's rows if it has one (else None: they are zeros)."""
        if self._t is None:
            self._allocate()
        tau = None if self._tau is None else self._tau[:cap]
        return self._t[:cap], self._q[:cap], self._m[:cap], tau

    def block(self) -> SampleBlock:
        n = self.n
        if self._t is None:
            self._allocate()
        handover = n > 0 and 2 * n >= self.capacity  # the arrays themselves (see the class)

        def rows(a):
            return None if a is None else a[:n] if handover else a[:n].copy()
        torque = np.zeros((n, 3)) if self._tau is None else rows(self._tau)
        out = SampleBlock(rows(self._t), rows(self._q), rows(self._m), torque,
                          self.body, rows(self._extra), dipole=rows(self._dipole))
        if handover:
            self._t = self._tau = self._extra = self._dipole = None
        self.n = 0
        return out
