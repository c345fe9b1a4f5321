"""Parameters of the sensors (simulator) and of the estimator (controller); typed settings.

All are off by default: a scene that enables no sensor gets ``SensorSettings`` None and
the engine builds nothing (no events, no noise draws).
"""
from dataclasses import dataclass
import math
from typing import Mapping, Optional, Tuple

from ..param_spec import ParamSpec

NS = 1_000_000_000
FEEDBACK = ('truth', 'sensors')

SIMULATOR = (
    ParamSpec('seed', 0, 'seed of every random process of the run (sensor noise); the same '
              'seed gives the same run bit for bit', kind='int', low=0, high=2 ** 63 - 1,
              read_only=True),
    ParamSpec('sensors.gyro.enabled', False, 'simulate a 3-axis rate gyro on topic gyro '
              '(sensor_msgs/Imu, body frame)', kind='bool', read_only=True),
    ParamSpec('sensors.gyro.rate', 100.0, 'gyro sample rate (sim time; instants are '
              'multiples of the period from t = 0)', kind='float', unit='Hz', low=0.0,
              low_open=True, high=10000.0, read_only=True),
    ParamSpec('sensors.gyro.angle_random_walk', 0.0, 'angle random walk N (white rate noise, '
              'std N/sqrt(period) per reading)', kind='float', unit='rad/sqrt(s)', low=0.0,
              high=1.0, read_only=True),
    ParamSpec('sensors.gyro.bias_instability', 0.0, 'bias instability B (IEEE 952 flicker '
              'floor), modelled as a first-order Gauss-Markov bias whose Allan-deviation '
              'peak is 0.664 B', kind='float', unit='rad/s', low=0.0, high=1.0,
              read_only=True),
    ParamSpec('sensors.gyro.bias_correlation_time', 100.0, 'correlation time T_c of the '
              'Gauss-Markov bias (Allan-deviation peak near 1.89 T_c)', kind='float',
              unit='s', low=0.0, low_open=True, high=1e9, read_only=True),
    ParamSpec('sensors.gyro.rate_random_walk', 0.0, 'rate random walk K (the bias integrates '
              'white noise)', kind='float', unit='rad/s/sqrt(s)', low=0.0, high=1.0,
              read_only=True),
    ParamSpec('sensors.gyro.initial_bias', [0.0, 0.0, 0.0], 'constant turn-on bias, body '
              'frame', kind='float_array', unit='rad/s', sizes=(3,), low=-1.0, high=1.0,
              read_only=True),
    ParamSpec('sensors.star_tracker.enabled', False, 'simulate a star tracker on topic '
              'star_tracker (geometry_msgs/QuaternionStamped, body -> frame_id)', kind='bool',
              read_only=True),
    ParamSpec('sensors.star_tracker.rate', 5.0, 'star-tracker fix rate (sim time)',
              kind='float', unit='Hz', low=0.0, low_open=True, high=10000.0, read_only=True),
    ParamSpec('sensors.star_tracker.noise', [1e-4], 'attitude noise 1-sigma per body axis '
              '(small rotation applied in the body frame); one value or three', unit='rad',
              kind='float_array', sizes=(1, 3), low=0.0, high=1.0, scalar_ok=True,
              read_only=True),
    ParamSpec('sensors.star_tracker.outages', [], 'no fixes during these sim-time intervals: '
              'flat list [start1, end1, start2, end2, ...], sorted, start < end',
              kind='float_array', unit='s', low=0.0, high=1e12, read_only=True),
)

CONTROLLER = (
    ParamSpec('feedback', 'truth', 'what the law sees: truth (attitude and angular_velocity '
              'topics) or sensors (gyro and star_tracker through the estimator)',
              kind='string', choices=FEEDBACK, read_only=True),
    ParamSpec('estimator.bandwidth', 0.5, 'bandwidth w_e of the gyro/star-tracker '
              'complementary filter (critically damped error loop; at most half the star '
              'tracker rate in Hz)', kind='float', unit='rad/s', low=0.0, low_open=True,
              high=1e4, read_only=True),
)


def seconds_to_ns(seconds: float) -> int:
    return max(1, int(round(seconds * NS)))


def parse_outages(values, name='sensors.star_tracker.outages') -> Tuple[Tuple[int, int], ...]:
    """[(start_ns, end_ns)] from the flat list; ValueError naming ``name`` if malformed."""
    values = [float(v) for v in values]
    if len(values) % 2:
        raise ValueError(f'{name} needs pairs [start, end, ...], got {len(values)} values')
    out = []
    for i in range(0, len(values), 2):
        start, end = values[i], values[i + 1]
        if not (math.isfinite(start) and math.isfinite(end) and 0.0 <= start < end):
            raise ValueError(f'{name}: interval {i // 2} [{start:g}, {end:g}] must be finite '
                             'with 0 <= start < end')
        if out and start * NS < out[-1][1]:
            raise ValueError(f'{name}: interval {i // 2} starts at {start:g} s, before the '
                             'previous one ends (sort them, no overlap)')
        out.append((int(round(start * NS)), int(round(end * NS))))
    return tuple(out)


@dataclass(frozen=True)
class GyroSettings:
    period_ns: int
    angle_random_walk: float
    bias_instability: float
    correlation_time: float
    rate_random_walk: float
    initial_bias: Tuple[float, float, float]

    @property
    def period(self) -> float:
        return self.period_ns / NS


@dataclass(frozen=True)
class StarTrackerSettings:
    period_ns: int
    noise: Tuple[float, float, float]
    outages: Tuple[Tuple[int, int], ...]

    def available(self, t_ns: int) -> bool:
        """False during an outage [start, end)."""
        return not any(a <= t_ns < b for a, b in self.outages)


@dataclass(frozen=True)
class SunSensorSettings:
    """The sun sensor (``sun_sensor.*``, specs in ``engine/sunlight_specs``): its period,
    noise (rad, per body axis) and the shadow model that hides the Sun."""
    period_ns: int
    noise: Tuple[float, float, float]
    shadow: str = 'conical'


@dataclass(frozen=True)
class SensorSettings:
    """The simulated sensors of a scene (None in the engine config when all are off)."""
    seed: int
    gyro: Optional[GyroSettings]
    star_tracker: Optional[StarTrackerSettings]
    sun: Optional[SunSensorSettings] = None

    @classmethod
    def from_parameters(cls, p: Mapping) -> Optional['SensorSettings']:
        """From the simulator's coerced values; None when no sensor is enabled."""
        gyro = star = None
        if p['sensors.gyro.enabled']:
            gyro = GyroSettings(seconds_to_ns(1.0 / p['sensors.gyro.rate']),
                                p['sensors.gyro.angle_random_walk'],
                                p['sensors.gyro.bias_instability'],
                                p['sensors.gyro.bias_correlation_time'],
                                p['sensors.gyro.rate_random_walk'],
                                tuple(p['sensors.gyro.initial_bias']))
        if p['sensors.star_tracker.enabled']:
            noise = list(p['sensors.star_tracker.noise'])
            star = StarTrackerSettings(seconds_to_ns(1.0 / p['sensors.star_tracker.rate']),
                                       tuple(noise * 3 if len(noise) == 1 else noise),
                                       parse_outages(p['sensors.star_tracker.outages']))
        else:
            parse_outages(p['sensors.star_tracker.outages'])  # malformed is an error anyway
        sun = None
        if p.get('sun_sensor.enabled'):
            noise = list(p['sun_sensor.noise'])
            sun = SunSensorSettings(seconds_to_ns(1.0 / p['sun_sensor.rate']),
                                    tuple(noise * 3 if len(noise) == 1 else noise),
                                    p['environment.shadow'])
        if gyro is None and star is None and sun is None:
            return None
        return cls(int(p['seed']), gyro, star, sun)


def check_feedback(sensors: Optional[SensorSettings], feedback: str, bandwidth: float):
    """ValueError naming the parameter if the controller's ``feedback: sensors`` cannot
    work with the simulator's sensors."""
    if feedback != 'sensors':
        return
    if sensors is None or sensors.gyro is None or sensors.star_tracker is None:
        raise ValueError('feedback: sensors needs sensors.gyro.enabled and '
                         'sensors.star_tracker.enabled on the simulator')
    rate = NS / sensors.star_tracker.period_ns
    if bandwidth > rate / 2.0:
        raise ValueError(f'estimator.bandwidth = {bandwidth:g} rad/s is too high for a '
                         f'{rate:g} Hz star tracker: must be <= {rate / 2.0:g} (rate / 2)')
