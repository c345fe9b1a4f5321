"""The magnetorquers, the magnetometer and the in-process B-dot law inside the engine.

* :class:`DipoleHold`: the commanded dipole (``dipole_command``, body frame, A·m²), held
  and clipped per rod and counted by :class:`sources.CommandHold`'s own rules; it is not
  a torque: the kernels turn it into m × B at each instant (``magnetic_kernel``).
* :class:`Magnetometer`: at multiples of its period, the field in body axes (T) with a
  constant bias, white noise drawn from the scene's seed (its own stream, as the gyro's
  processes have theirs) and the rods' own dipole times ``torquer_coupling`` (NOS3 #145).
* :class:`BdotSource`: the controller's ``bdot`` mode run in process (``bdot.Bdot``) at
  the control instants, from the magnetometer's reading at that instant.
* :class:`Magnetics`: the three for one engine, and what the kernels' array needs at each
  interval: the field's line (IGRF) and the rods' dipole in the principal frame.
"""
from dataclasses import dataclass
from typing import Optional

import numpy as np

from .. import bdot
from ..physics import rotation
from ..physics.orbit import kernel as orbit_kernel
from ..sensors.noise import streams
from .sources import NEVER, CommandHold

STREAM_MAGNETOMETER = 10  # its noise stream of the seed (sensors.noise numbers 0-3)
BLOCK = 256


class DipoleHold(CommandHold):
    """A dipole command (body frame, A·m², finite) held from the instant it is set for the
    timeout, then zero; clipped per rod to ``max_dipole`` and counted (``saturated``)."""
    name = 'dipole'

    def __init__(self, max_dipole, timeout_ns: int):
        super().__init__(0.0, timeout_ns)
        self.max_torque = np.asarray(max_dipole, float)  # CommandHold clips per axis to it
        self.dipole: Optional[np.ndarray] = None

    def set(self, dipole, t_ns: int) -> None:
        super().set(dipole, t_ns)
        self.dipole, self.torque = self.torque, None

    def set_limits(self, max_torque, timeout_ns, t_ns) -> None:
        self.timeout_ns = int(timeout_ns)  # the rods' limits are read-only
        if self.dipole is not None:
            self.expiry = t_ns + self.timeout_ns

    def on_event(self, t_ns, attitude, angular_velocity):
        super().on_event(t_ns, attitude, angular_velocity)
        self.dipole = None

    def reset(self, t_ns):
        super().reset(t_ns)
        self.dipole = None


@dataclass(frozen=True, eq=False)
class MagnetometerReadings:
    """Readings (t_ns (n,), field (n, 3) T, body frame) taken during one engine call."""
    t_ns: np.ndarray
    field: np.ndarray

    def __len__(self):
        return len(self.t_ns)


class Magnetometer:
    """Engine source (``torque`` always None); ``dipole()``: the rods' dipole now (body)."""
    name = 'magnetometer'
    torque = None

    def __init__(self, settings, field, dipole):
        self.settings, self.field, self.dipole = settings, field, dipole
        self.rng = streams(settings.seed, STREAM_MAGNETOMETER)
        self._noise = np.zeros((0, 3))
        self.latest = None  # (t_ns, reading) of the last reading
        self.reset(0)

    def reset(self, t_ns: int) -> None:
        p = self.settings.period_ns
        self._next = -(-t_ns // p) * p
        self._t, self._b = [], []

    def next_event(self) -> int:
        return self._next

    def reading(self, t: float, attitude) -> np.ndarray:
        """The field (T, body frame) the sensor reads at time t, attitude body → inertial,
        noise aside: truth + bias + coupling · the rods' dipole."""
        b = rotation.rotate(rotation.conjugate(attitude), self.field.at(t))
        s = self.settings
        b = b + np.asarray(s.bias)
        if s.coupling:
            b = b + s.coupling * self.dipole()
        return b

    def on_event(self, t_ns: int, attitude, angular_velocity) -> None:
        b = self.reading(t_ns * 1e-9, attitude)
        if self.settings.noise > 0.0:
            if not len(self._noise):
                self._noise = self.settings.noise * self.rng.standard_normal((BLOCK, 3))
            b = b + self._noise[0]
            self._noise = self._noise[1:]
        self.latest = (t_ns, b)
        self._t.append(t_ns)
        self._b.append(b)
        self._next += self.settings.period_ns

    def drain(self) -> Optional[MagnetometerReadings]:
        if not self._t:
            return None
        out = MagnetometerReadings(np.array(self._t, np.int64), np.array(self._b))
        self._t, self._b = [], []
        return out


class BdotSource:
    """The ``bdot`` mode in process: at each control instant, m = −k·Ḃ/|B|² from the
    magnetometer's readings (``bdot.Bdot``), held until the next instant."""
    name = 'bdot'
    torque = None

    def __init__(self, law: bdot.Bdot, period_ns: int, magnetometer: Magnetometer):
        self.law, self.period_ns, self.meter = law, int(period_ns), magnetometer
        self.active = lambda: True  # the engine ties it to the controller's mode
        self.reset(0)

    def reset(self, t_ns):
        self.law.reset()
        self.dipole = None
        self._next = t_ns

    def next_event(self) -> int:
        return self._next

    def on_event(self, t_ns, attitude, angular_velocity):
        self._next += self.period_ns
        if not self.active():  # the mission switched to a torque law: the rods rest
            self.dipole = None
            return
        latest = self.meter.latest
        if latest is None or latest[0] != t_ns:  # no reading at this instant
            return
        m = self.law.update(t_ns * 1e-9, latest[1])
        self.dipole = None if m is None else m


class Magnetics:
    """The scene's magnetic parts for one engine (``settings``: ``MagneticSettings``)."""

    def __init__(self, settings, body, timeout_ns: int, control=None):
        self.settings, self.body = settings, body
        self.field = settings.field
        self.hold = DipoleHold(settings.max_dipole, timeout_ns) \
            if settings.magnetorquers else None
        self.meter = None if settings.magnetometer is None else \
            Magnetometer(settings.magnetometer, self.field, self.dipole)
        self.law = None
        if control is not None and control.mode == 'bdot':
            if self.meter is None or self.hold is None:
                raise ValueError('mode: bdot needs magnetorquer.max_dipole and '
                                 'magnetometer.enabled in the simulator\'s scene')
            self.law = BdotSource(bdot.Bdot(control.bdot_gain, settings.max_dipole),
                                  control.period_ns, self.meter)
        self.sources = [s for s in (self.hold, self.meter, self.law) if s is not None]

    @property
    def compiled(self) -> bool:
        """Whether a compiled sample loop can run between this part's events: the field in
        closed form (a tabulated IGRF line is re-anchored at every interval) and only the
        held dipole acting (the magnetometer and B-dot have events of their own, in Python)."""
        return self.field.model == 'dipole' and self.meter is None and self.law is None

    def next_event(self) -> int:
        """The next instant (ns) one of the magnetic sources acts."""
        return min(s.next_event() for s in self.sources)

    def dipole(self) -> np.ndarray:
        """The rods' dipole now (body frame, A·m²): the held command plus the law's."""
        m = np.zeros(3)
        for s in (self.hold, self.law):
            if s is not None and s.dipole is not None:
                m = m + s.dipole
        return m

    def anchor(self, env, t0: float, t1: float, aligned: bool) -> bool:
        """The kernels' magnetic slots for the interval [t0, t1] (s), in place: the field's
        line (igrf) and the rods' dipole, principal frame. True if they changed (an
        adaptive method's step in progress, dop853's, is then stale)."""
        if env is None or self.hold is None:
            return False
        k = orbit_kernel
        before = env[k.MAG_MODEL:k.MAG_END].copy()
        if self.field.model != 'dipole':
            self.field.fill(env, t0, t1)
        m = self.dipole()
        env[k.MAG_DIPOLE:k.MAG_DIPOLE + 3] = m if aligned else self.body.to_principal(m)
        return not np.array_equal(before, env[k.MAG_MODEL:k.MAG_END])

    def torque(self, t: float, attitude) -> np.ndarray:
        """The rods' torque m × B_body (N·m, body frame) at time t and attitude (body →
        inertial), the held dipole: the magnetorquers' share of the environment's."""
        b = rotation.rotate(rotation.conjugate(attitude), self.field.at(t))
        return np.cross(self.dipole(), b)

    def drain(self):
        return None if self.meter is None else self.meter.drain()


__all__ = ['NEVER', 'DipoleHold', 'Magnetometer', 'MagnetometerReadings', 'BdotSource',
           'Magnetics']
