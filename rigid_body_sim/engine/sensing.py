"""The scene's sensors inside the engine: sampled at their own instants from the true state.

:class:`SensorSuite` is an engine source that never holds a torque: at each gyro or star
tracker instant (multiples of its period from t = 0) it reads the body state, adds the
noise (drawn in blocks from ``sensors.noise``) and keeps the reading for the front ends
(``SampleBlock.sensors``: the node publishes them, the offline run records them). When
the control law closes the loop on sensors, it also feeds the estimator, and the law
asks :meth:`observe` for the estimated state instead of the truth.

Frames: gyro readings are body-frame rates (rad/s); star-tracker fixes are quaternions
(x, y, z, w) body → inertial, the truth turned by a small body-frame noise rotation; sun
sensor readings are unit vectors to the Sun in the body frame, turned likewise, none
while the spacecraft is in the Earth's shadow (``sunlight_specs.sun_in_body``).
"""
from dataclasses import dataclass, field

import numpy as np

from ..physics import rotation
from ..sensors.estimator import AttitudeEstimator
from ..sensors.noise import STREAM_SUN, GyroNoise, StarTrackerNoise
from ..sensors.specs import SensorSettings
from .sources import NEVER
from .sunlight_specs import sun_in_body

BLOCK = 256  # noise readings drawn at a time (the draws do not depend on it)


@dataclass(frozen=True, eq=False)
class SensorReadings:
    """Readings taken during one engine call: gyro (t_ns (n,), rate (n, 3) rad/s body),
    star tracker (t_ns (m,), attitude (m, 4) x, y, z, w body → inertial) and sun sensor (t_ns
    (k,), unit vector (k, 3) body frame)."""
    gyro_t_ns: np.ndarray
    gyro: np.ndarray
    star_t_ns: np.ndarray
    star: np.ndarray
    sun_t_ns: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    sun: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __len__(self):
        return len(self.gyro_t_ns) + len(self.star_t_ns) + len(self.sun_t_ns)


def _next_multiple(t_ns: int, period: int) -> int:
    return -(-t_ns // period) * period


class SensorSuite:
    """Engine source (duck-typed like ``TorqueSource``; ``torque`` is always None)."""
    name = 'sensors'
    torque = None

    def __init__(self, settings: SensorSettings, estimator_bandwidth=None, environment=None):
        self.settings = settings
        self.environment = environment  # the orbit and epoch the sun sensor needs
        g, s = settings.gyro, settings.star_tracker
        self.sun_noise = None if settings.sun is None else StarTrackerNoise(
            settings.sun.noise, settings.seed, STREAM_SUN)
        self._sun_errors = np.zeros((0, 3))
        self.eclipse_skips = 0
        self.gyro_noise = None if g is None else GyroNoise(
            g.period, g.angle_random_walk, g.bias_instability, g.correlation_time,
            g.rate_random_walk, g.initial_bias, settings.seed)
        self.star_noise = None if s is None else StarTrackerNoise(s.noise, settings.seed)
        self.estimator = None if estimator_bandwidth is None else \
            AttitudeEstimator(estimator_bandwidth)
        self._gyro_errors = np.zeros((0, 3))
        self._star_errors = np.zeros((0, 3))
        self.outage_skips = 0
        self.reset(0)

    def reset(self, t_ns: int) -> None:
        """Readings from ``t_ns`` on; the noise streams continue (a reset is not a new run)."""
        g, s = self.settings.gyro, self.settings.star_tracker
        self._next_gyro = NEVER if g is None else _next_multiple(t_ns, g.period_ns)
        self._next_star = NEVER if s is None else _next_multiple(t_ns, s.period_ns)
        u = self.settings.sun
        self._next_sun = NEVER if u is None else _next_multiple(t_ns, u.period_ns)
        if self.estimator is not None:
            self.estimator.reset()
        self._clear()

    def _clear(self):
        self._gt, self._gv, self._st, self._sv = [], [], [], []
        self._ut, self._uv = [], []

    def next_event(self) -> int:
        return min(self._next_gyro, self._next_star, self._next_sun)

    def _take(self, which: str) -> np.ndarray:
        buf = getattr(self, which)
        if not len(buf):
            noise = self.gyro_noise if which == '_gyro_errors' else \
                self.sun_noise if which == '_sun_errors' else self.star_noise
            buf = noise.take(BLOCK)
        setattr(self, which, buf[1:])
        return buf[0]

    def on_event(self, t_ns: int, attitude, angular_velocity) -> None:
        if t_ns == self._next_sun:
            self._sun(t_ns, attitude)
        if t_ns == self._next_gyro:
            rate = np.asarray(angular_velocity, float) + self._take('_gyro_errors')
            self._gt.append(t_ns)
            self._gv.append(rate)
            if self.estimator is not None:
                self.estimator.gyro(t_ns, rate)
            self._next_gyro += self.settings.gyro.period_ns
        if t_ns == self._next_star:
            s = self.settings.star_tracker
            self._next_star += s.period_ns
            if not s.available(t_ns):
                self.outage_skips += 1
                return
            q = rotation.multiply(attitude, rotation.exp(self._take('_star_errors')))
            q = q / np.linalg.norm(q)
            self._st.append(t_ns)
            self._sv.append(q)
            if self.estimator is not None:
                self.estimator.star_tracker(t_ns, q)

    def _sun(self, t_ns: int, attitude) -> None:
        """The sun sensor's reading at t_ns, none in the shadow (counted)."""
        u = self.settings.sun
        self._next_sun += u.period_ns
        env = self.environment
        direction, lit = sun_in_body(env.epoch, env.orbit, t_ns / 1e9, attitude, u.shadow)
        if lit <= 0.0:
            self.eclipse_skips += 1
            return
        error = self._take('_sun_errors')
        if np.any(error):
            direction = rotation.rotate(rotation.exp(-error), direction)
            direction = direction / np.linalg.norm(direction)
        self._ut.append(t_ns)
        self._uv.append(direction)

    def observe(self, t_ns: int):
        """The estimated (attitude, ω) at ``t_ns`` for the law, or None before the first fix."""
        return self.estimator.estimate(t_ns)

    def drain(self):
        """The readings taken since the last call (SensorReadings), or None if none."""
        if not (self._gt or self._st or self._ut):
            return None
        out = SensorReadings(np.array(self._gt, np.int64), np.array(self._gv).reshape(-1, 3),
                             np.array(self._st, np.int64), np.array(self._sv).reshape(-1, 4),
                             np.array(self._ut, np.int64), np.array(self._uv).reshape(-1, 3))
        self._clear()
        return out


def estimator_bandwidth(control):
    """ω_e (rad/s) when the in-process law closes the loop on the sensors, else None."""
    if control is None or getattr(control, 'feedback', 'truth') != 'sensors':
        return None
    return control.estimator_bandwidth
