"""The Earth's field, the magnetorquers and the magnetometer: their parameters and the
typed settings built from them (no ROS). See docs/physics.md#the-orbit.

A scene without ``environment.magnetic_field`` (``none``) builds nothing here.
"""
from dataclasses import dataclass
from datetime import datetime, timezone
import math
from typing import Optional, Tuple

import numpy as np

from ..param_spec import ParamSpec
from ..sensors.specs import seconds_to_ns
from ..physics.environment import magnetic_field

FIELD_MODELS = ('none',) + magnetic_field.MODELS
# the dipole without an epoch: IGRF-14's degree 1 at its base date, GMST of that instant
DEFAULT_EPOCH = datetime(2025, 1, 1, tzinfo=timezone.utc)

MAGNETIC = (
    ParamSpec('environment.magnetic_field', 'none', 'the Earth\'s magnetic field along the '
              'orbit: none, dipole (IGRF-14\'s tilted dipole at the epoch, closed form) or '
              'igrf (IGRF-14 to degree 13, ppigrf); needs orbit.model, igrf needs epoch',
              kind='string', choices=FIELD_MODELS, read_only=True,
              note='the epoch must lie in the model\'s range (1900-2030)'),
    ParamSpec('magnetorquer.max_dipole', [0.0, 0.0, 0.0], 'largest dipole of the three rods '
              'along body x, y, z (all zero: no magnetorquers); commands on dipole_command '
              'are clipped per rod and held like torque commands (command_timeout)',
              kind='float_array', unit='A*m^2', sizes=(3,), low=0.0, high=1e6,
              read_only=True, note='needs environment.magnetic_field'),
    ParamSpec('magnetometer.enabled', False, 'simulate a 3-axis magnetometer on topic '
              'magnetic_field (sensor_msgs/MagneticField, T, body frame)', kind='bool',
              read_only=True, note='needs environment.magnetic_field'),
    ParamSpec('magnetometer.rate', 10.0, 'magnetometer sample rate (sim time; instants are '
              'multiples of the period from t = 0)', kind='float', unit='Hz', low=0.0,
              low_open=True, high=10000.0, read_only=True),
    ParamSpec('magnetometer.noise', 0.0, 'white noise 1-sigma per axis and reading (drawn '
              'from seed)', kind='float', unit='T', low=0.0, high=1e-3, read_only=True),
    ParamSpec('magnetometer.bias', [0.0, 0.0, 0.0], 'constant bias, body frame', unit='T',
              kind='float_array', sizes=(3,), low=-1e-3, high=1e-3, read_only=True),
    ParamSpec('magnetometer.torquer_coupling', 0.0, 'field the rods\' own dipole adds to '
              'the reading per A*m^2 of it, same axis (NOS3 #145: a magnetometer near the '
              'torquers sees them); 0: none', kind='float', unit='T/(A*m^2)', low=-1e-3,
              high=1e-3, read_only=True),
)


@dataclass(frozen=True)
class MagnetometerSettings:
    period_ns: int
    noise: float
    bias: Tuple[float, float, float]
    coupling: float
    seed: int


@dataclass(frozen=True, eq=False)
class MagneticSettings:
    """The field along the orbit (``magnetic_field.FieldAlongOrbit``), the rods' largest
    dipoles (A·m², body x, y, z; None: no magnetorquers) and the magnetometer (or None)."""
    field: magnetic_field.FieldAlongOrbit
    max_dipole: Optional[np.ndarray] = None
    magnetometer: Optional[MagnetometerSettings] = None

    @property
    def magnetorquers(self) -> bool:
        return self.max_dipole is not None

    def torque_rate(self, moments) -> float:
        """The rods' rate scale (1/s): √(|m_max|·B_max/I_min), B_max = 65 µT (the field's
        largest at the surface), for ``auto``'s torque rate."""
        return math.sqrt(float(np.linalg.norm(self.max_dipole)) * 65e-6 / min(moments))


def magnetic_from_parameters(p, orbit, epoch) -> Optional[MagneticSettings]:
    """The settings from coerced values, None if the field is off (``none``). ``orbit``:
    the scene's (None: no orbit), ``epoch``: its datetime or None. ValueError naming the
    key and the reason."""
    model = p['environment.magnetic_field']
    rods = np.asarray(p['magnetorquer.max_dipole'], float)
    sensing = p['magnetometer.enabled']
    if model == 'none':
        if rods.any():
            raise ValueError('magnetorquer.max_dipole: the rods need a field '
                             '(environment.magnetic_field dipole or igrf)')
        if sensing:
            raise ValueError('magnetometer.enabled: a magnetometer needs a field '
                             '(environment.magnetic_field dipole or igrf)')
        return None
    if orbit is None:
        raise ValueError(f'environment.magnetic_field: {model} needs an orbit (orbit.model '
                         'kepler, j2 or sgp4)')
    if model == 'igrf' and epoch is None:
        raise ValueError('epoch: environment.magnetic_field igrf needs the UTC instant of sim '
                         'time 0 (ISO 8601, e.g. 2026-03-20T12:00:00Z)')
    try:
        field = magnetic_field.FieldAlongOrbit(model, orbit, epoch or DEFAULT_EPOCH)
    except ValueError as exc:
        raise ValueError(f'epoch: {exc}') from None
    meter = None
    if sensing:
        meter = MagnetometerSettings(seconds_to_ns(1.0 / p['magnetometer.rate']),
                                     p['magnetometer.noise'], tuple(p['magnetometer.bias']),
                                     p['magnetometer.torquer_coupling'], int(p['seed']))
    return MagneticSettings(field, rods if rods.any() else None, meter)
