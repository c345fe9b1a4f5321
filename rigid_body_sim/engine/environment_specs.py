"""The orbit and the environment's torques: their parameters and the typed settings built
from them (no ROS). Keys as orbit tools name them; see docs/physics.md#the-orbit.

A scene without ``orbit.model`` (``none``) builds nothing here: the free body of today.
"""
from dataclasses import dataclass
from datetime import datetime, timezone
import math
from typing import Optional

import numpy as np

from ..param_spec import ParamSpec
from ..physics import orbit as orbit_models
from ..physics import rotation
from ..physics.orbit import frames, layout as orbit_layout
from .magnetic_specs import MAGNETIC, MagneticSettings, magnetic_from_parameters
from .sunlight_specs import SUNLIGHT, Sunlight, sunlight_from_parameters

ENVIRONMENT = (
    ParamSpec('orbit.model', 'none', 'the orbit: none (no orbit, no environment), kepler '
              '(two-body), j2 (two-body with J2\'s secular drift of node, periapsis and mean '
              'anomaly) or sgp4 (from orbit.tle)', kind='string', choices=orbit_models.MODELS,
              read_only=True),
    ParamSpec('orbit.semi_major_axis', 7.0e6, 'semi-major axis at sim time 0 (kepler, j2)',
              kind='float', unit='m', low=0.0, low_open=True, read_only=True,
              note='the perigee a(1 - e) must lie above the Earth\'s surface'),
    ParamSpec('orbit.eccentricity', 0.0, 'eccentricity (kepler, j2)', kind='float', low=0.0,
              high=1.0, high_open=True, read_only=True),
    ParamSpec('orbit.inclination', 0.0, 'inclination to the world frame\'s x-y plane (kepler, '
              'j2)', kind='float', unit='rad', low=0.0, high=math.pi, read_only=True),
    ParamSpec('orbit.raan', 0.0, 'right ascension of the ascending node (kepler, j2)',
              kind='float', unit='rad', read_only=True),
    ParamSpec('orbit.argument_of_periapsis', 0.0, 'argument of periapsis (kepler, j2)',
              kind='float', unit='rad', read_only=True),
    ParamSpec('orbit.true_anomaly', 0.0, 'true anomaly at sim time 0 (kepler, j2)',
              kind='float', unit='rad', read_only=True),
    ParamSpec('orbit.tle', [''], 'two-line element set (the two lines) for sgp4; TEME is '
              'taken as the world frame', kind='string_array', read_only=True),
    ParamSpec('epoch', '', 'UTC instant of sim time 0, ISO 8601 (2026-03-20T12:00:00Z); '
              'empty: the TLE\'s epoch with sgp4, unused otherwise', kind='string',
              read_only=True),
    ParamSpec('orbit.frame_id', 'lvlh', 'the orbit frame\'s tf name (LVLH; the simulator '
              'node publishes frame_id -> it and the orbit topic with it)', kind='string',
              read_only=True),
    ParamSpec('initial_attitude_frame', 'world', 'frame of initial_attitude and '
              'initial_angular_velocity: world (inertial), or lvlh: the orbit frame at sim '
              'time 0 (x along the velocity, z to nadir), the rate relative to it',
              kind='string', choices=('world', 'lvlh'), read_only=True,
              note='lvlh needs orbit.model'),
    ParamSpec('environment.gravity_gradient', False, 'the gravity-gradient torque 3 mu/r^3 '
              'c x (I c) along the orbit (needs orbit.model)', kind='bool', read_only=True),
) + MAGNETIC + SUNLIGHT  # magnetic: the field, the magnetorquers, the magnetometer
# (magnetic_specs); sunlight, drag, the facets and the sun sensor (sunlight_specs)


@dataclass(frozen=True, eq=False)
class EnvironmentSettings:
    """The orbit (None: none) and which environment torques act (``sunlight``: SRP and
    drag on the facets, None if neither)."""
    orbit: Optional['orbit_models.Orbit'] = None
    gravity_gradient: bool = False
    epoch: Optional[datetime] = None
    magnetic: Optional[MagneticSettings] = None  # the field, rods, magnetometer (or None)
    sunlight: Optional[Sunlight] = None

    @property
    def magnetorquers(self) -> bool:
        return self.magnetic is not None and self.magnetic.magnetorquers

    @property
    def terms(self):
        """Names of the environment's torques in the model (for ``auto``'s reason)."""
        return tuple(name for name, on in (('gravity gradient', self.gravity_gradient),
                                           ('magnetorquers', self.magnetorquers)) if on) + \
            (() if self.sunlight is None else self.sunlight.terms)

    @property
    def anchored(self) -> bool:
        """Whether the kernels' array is re-made at each interval between events (SGP4's
        osculating conic, NRLMSIS's local density fit)."""
        return bool(self.terms) and (self.orbit.anchored or (
            self.sunlight is not None and self.sunlight.anchored))

    def elements(self, t: float, to_frame=None):
        """The kernels' element array (``physics.orbit.kernel``) near sim time t with the
        environment's torques switched on, None if none acts (the free body). The rods'
        dipole is zero here: the engine writes the held one (``engine.magnetic``);
        ``to_frame`` maps the facets' body-axes vectors to the loops' (principal) frame."""
        if not self.terms:
            return None
        elements = self.orbit.elements(t)
        elements[orbit_layout.ON] = 1.0 if self.gravity_gradient else 0.0
        if self.magnetorquers:
            self.magnetic.field.fill(elements, t, t)
        if self.sunlight is not None:  # may append the facets: after the fixed slots
            elements = self.sunlight.fill(elements, self.orbit, t, to_frame)
        return elements

    @property
    def periodic_forcing(self) -> bool:
        """Whether the gravity gradient varies periodically along the orbit (a
        non-circular one): a forced libration, whose error ``auto`` cannot bound a priori
        (``physics.auto.selection``, ``forced``)."""
        return self.gravity_gradient and self.orbit.eccentricity > 0.0

    def gravity_gradient_rate(self, moments) -> float:
        """The gravity gradient's rate scale (1/s) at perigee: √(3μ/r³ · (I_max − I_min)/
        I_min), the fastest libration it can drive (``auto``'s torque rate)."""
        r = self.orbit.perigee_radius
        return math.sqrt(3.0 * orbit_models.MU / r ** 3 * (max(moments) - min(moments))
                         / min(moments))


def parse_epoch(text: str) -> Optional[datetime]:
    """The UTC datetime of an ISO 8601 text (Z or an offset; none: UTC); None if empty.
    ValueError naming ``epoch`` otherwise."""
    if not text:
        return None
    try:
        moment = datetime.fromisoformat(text.strip().replace('Z', '+00:00'))
    except ValueError:
        raise ValueError(f'epoch {text!r} is not an ISO 8601 date and time '
                         '(e.g. 2026-03-20T12:00:00Z)') from None
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=timezone.utc)
    return moment.astimezone(timezone.utc)


def initial_state_in_world(settings: Optional[EnvironmentSettings], frame: str, attitude,
                           angular_velocity):
    """(attitude body → world, ω body) from an initial state given in ``frame``: for lvlh,
    the attitude relative to the orbit frame at t = 0 and the rate relative to it (so
    zeros hold the body fixed in LVLH). ValueError naming the key without an orbit."""
    if frame == 'world':
        return attitude, angular_velocity
    if settings is None:
        raise ValueError('initial_attitude_frame: lvlh needs an orbit (orbit.model kepler, '
                         'j2 or sgp4)')
    r, v = settings.orbit.state(0.0)
    body = rotation.multiply(frames.lvlh_attitude(r, v), rotation.validated(attitude))
    w = np.asarray(angular_velocity, float) + rotation.rotate(rotation.conjugate(body),
                                                              frames.lvlh_rate(r, v))
    return body, w


def environment_from_parameters(p) -> Optional[EnvironmentSettings]:
    """The settings from coerced parameter values, None for the free body (orbit.model
    none, no environment torque). ValueError naming the key and the reason."""
    model, gg = p['orbit.model'], p['environment.gravity_gradient']
    epoch = parse_epoch(p['epoch'])
    if model == 'none':
        if gg:
            raise ValueError('environment.gravity_gradient: needs an orbit (orbit.model '
                             'kepler, j2 or sgp4)')
        magnetic_from_parameters(p, None, epoch)  # refuses a field without an orbit
        sunlight_from_parameters(p, model, epoch)  # refuses a term without an orbit
        return None
    if model == 'sgp4':
        lines = [line for line in p['orbit.tle'] if line.strip()]
        if not lines:
            raise ValueError('orbit.tle: orbit.model sgp4 needs the two lines of a TLE')
        try:
            orbit = orbit_models.from_tle(lines, epoch)
        except ValueError as exc:
            raise ValueError(f'orbit.tle: {exc}') from None
        epoch = epoch or orbit.epoch
        return EnvironmentSettings(orbit, gg, epoch, magnetic_from_parameters(p, orbit, epoch),
                                   sunlight_from_parameters(p, model, epoch))
    a, e = p['orbit.semi_major_axis'], p['orbit.eccentricity']
    if a * (1.0 - e) <= orbit_models.RADIUS:
        raise ValueError(f'orbit.semi_major_axis: the perigee a(1 - e) = '
                         f'{a * (1.0 - e) / 1e3:.6g} km is below the Earth\'s surface '
                         f'(R = {orbit_models.RADIUS / 1e3:.6g} km)')
    cls = orbit_models.J2Orbit if model == 'j2' else orbit_models.KeplerOrbit
    orbit = cls(a, e, p['orbit.inclination'], p['orbit.raan'],
                p['orbit.argument_of_periapsis'], p['orbit.true_anomaly'])
    return EnvironmentSettings(orbit, gg, epoch, magnetic_from_parameters(p, orbit, epoch),
                               sunlight_from_parameters(p, model, epoch))
