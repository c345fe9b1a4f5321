"""Sunlight and drag: their parameters (the facet model, SRP, drag, the sun sensor) and the
typed settings built from them (no ROS). Each term enters only when the scene names it;
``environment_specs`` joins them to the orbit. See docs/physics.md#the-orbit.
"""
from dataclasses import dataclass
import math
from typing import Optional

import numpy as np

from ..param_spec import ParamSpec
from ..physics.environment import earth, facets as facet_model, sunlight
from ..physics.orbit import MU, layout as orbit_layout

DRAG_MODELS = ('none', 'exponential', 'nrlmsis')
SHADOW_CODES = {'cylindrical': 0.0, 'conical': 1.0}
FIT_STEP = 1000.0   # m: the height step of NRLMSIS's local scale-height fit

SUNLIGHT = (
    ParamSpec('environment.solar_radiation_pressure', False, 'the solar radiation pressure '
              'torque on the facets (facets.*), zero in the Earth\'s shadow (needs '
              'orbit.model and epoch)', kind='bool', read_only=True),
    ParamSpec('environment.drag', 'none', 'the aerodynamic drag torque on the facets '
              '(facets.*): none, exponential (Vallado\'s table, height above the ellipsoid) '
              'or nrlmsis (NRLMSIS 2.1 via pymsis, with environment.f107 and '
              'environment.ap; needs epoch)', kind='string', choices=DRAG_MODELS,
              false_is='none', read_only=True),
    ParamSpec('environment.shadow', 'conical', 'the Earth\'s shadow for SRP and the sun '
              'sensor: cylindrical (0 or 1) or conical (umbra and penumbra)', kind='string',
              choices=tuple(SHADOW_CODES), read_only=True),
    ParamSpec('environment.f107', 150.0, 'NRLMSIS: the F10.7 solar flux of the day before '
              'and its 81-day average (no space-weather file is read)', kind='float',
              unit='sfu', low=0.0, low_open=True, high=1000.0, read_only=True),
    ParamSpec('environment.ap', 4.0, 'NRLMSIS: the daily geomagnetic Ap index', kind='float',
              low=0.0, high=400.0, read_only=True),
    ParamSpec('facets.areas', [], 'area of each flat facet (box and panels)', unit='m^2',
              kind='float_array', low=0.0, low_open=True, high=1e4, read_only=True),
    ParamSpec('facets.normals', [], 'outward normal of each facet, body axes (3 values per '
              'facet; normalised)', kind='float_array', read_only=True),
    ParamSpec('facets.centres', [], 'centre of pressure of each facet relative to the centre '
              'of mass, body axes (3 values per facet)', unit='m', kind='float_array',
              low=-1e3, high=1e3, read_only=True),
    ParamSpec('facets.specular', [0.0], 'specular reflectivity rho_s, one value or one per '
              'facet (absorbed: 1 - rho_s - rho_d)', kind='float_array', low=0.0, high=1.0,
              scalar_ok=True, read_only=True),
    ParamSpec('facets.diffuse', [0.0], 'diffuse reflectivity rho_d, one value or one per '
              'facet', kind='float_array', low=0.0, high=1.0, scalar_ok=True, read_only=True),
    ParamSpec('facets.drag_coefficient', [2.2], 'drag coefficient C_D, one value or one per '
              'facet', kind='float_array', low=0.0, high=10.0, scalar_ok=True,
              read_only=True),
    ParamSpec('sun_sensor.enabled', False, 'simulate a sun sensor on topic sun_direction '
              '(geometry_msgs/Vector3Stamped, unit vector to the Sun in the body frame; no '
              'message in the Earth\'s shadow); needs orbit.model and epoch', kind='bool',
              read_only=True),
    ParamSpec('sun_sensor.rate', 1.0, 'sun sensor sample rate (sim time; instants are '
              'multiples of the period from t = 0)', kind='float', unit='Hz', low=0.0,
              low_open=True, high=1000.0, read_only=True),
    ParamSpec('sun_sensor.noise', [0.0], 'direction noise 1-sigma per body axis (a small '
              'rotation in the body frame, seeded by seed); one value or three', unit='rad',
              kind='float_array', sizes=(1, 3), low=0.0, high=1.0, scalar_ok=True,
              read_only=True),
)


@dataclass(frozen=True, eq=False)
class Sunlight:
    """The facet terms of a scene: SRP (bool), drag model, shadow model, the facets, the
    epoch (UTC datetime) and NRLMSIS's space weather (f107, ap)."""
    srp: bool
    drag: str
    shadow: str
    facets: facet_model.FacetModel
    epoch: object
    f107: float = 150.0
    ap: float = 4.0

    @property
    def terms(self):
        return (('solar radiation pressure',) if self.srp else ()) + \
            ((f'drag ({self.drag})',) if self.drag != 'none' else ())

    @property
    def anchored(self) -> bool:
        """NRLMSIS's local fit is re-made at each interval between events."""
        return self.drag == 'nrlmsis'

    def torque_rate(self, moments, orbit) -> float:
        """The facets' rate scale (1/s) for ``auto``'s torque rate: √(τ_max/I_min), τ_max
        a bound of SRP's and drag's torque, Σ|c_i|·|F_i| with |F_i| ≤ 2·P·A_i (a mirror at
        normal incidence) for SRP and ½ρv²·C_D·A_i for drag, ρ the exponential table's
        at the perigee's height above the equator (its least) and v the escape speed
        there plus the atmosphere's co-rotation (bounds of the speed relative to the air).
        NRLMSIS's density is not looked up here: the table's stands for it."""
        f = self.facets
        arm = np.linalg.norm(f.centres, axis=1) * f.areas
        force = 0.0
        if self.srp:
            force += 2.0 * facet_model.SOLAR_PRESSURE
        torque = force * float(np.sum(arm))
        if self.drag != 'none':
            r = orbit.perigee_radius
            rho = facet_model.exponential_density(r - facet_model.EARTH_RADIUS)
            v = math.sqrt(2.0 * MU / r) + earth.EARTH_ROTATION_RATE * r
            torque += 0.5 * rho * v * v * float(np.sum(arm * f.drag_coefficient))
        return math.sqrt(torque / min(moments))

    def fill(self, env: np.ndarray, orbit, t: float, to_frame=None) -> np.ndarray:
        """``env`` (the orbit's elements near t) with the terms' slots set and the facets
        appended (in the loops' frame by ``to_frame``)."""
        env[orbit_layout.SRP_ON] = 1.0 if self.srp else 0.0
        env[orbit_layout.DRAG_ON] = 1.0 if self.drag != 'none' else 0.0
        env[orbit_layout.SHADOW] = SHADOW_CODES[self.shadow]
        env[orbit_layout.SUN_L0], env[orbit_layout.SUN_G0], env[orbit_layout.SUN_EPS] = \
            sun_angles(self.epoch)
        env[orbit_layout.N_FACETS] = len(self.facets)
        if self.drag == 'exponential':
            env[orbit_layout.DENSITY] = 1.0
        elif self.drag == 'nrlmsis':
            env[orbit_layout.DENSITY] = 2.0
            r, _ = orbit.state(t)
            env[orbit_layout.RHO_REF], env[orbit_layout.H_REF], \
                env[orbit_layout.SCALE_HEIGHT] = self.msis_fit(r, t)
        return np.concatenate([env, self.facets.packed(to_frame)])

    def msis_fit(self, r, t: float):
        """(ρ kg/m³, height m, scale height m) of NRLMSIS at position r and sim time t: the
        density there and its local scale height −Δh/Δln ρ over FIT_STEP upwards."""
        h = facet_model.height(r)
        lower = msis_density(self.epoch, t, r, 0.0, self.f107, self.ap)
        upper = msis_density(self.epoch, t, r, FIT_STEP, self.f107, self.ap)
        return lower, h, FIT_STEP / math.log(lower / upper)


def sun_angles(epoch):
    """(mean longitude, mean anomaly, obliquity), rad, of the almanac's formula
    (``sunlight.sun_vector``) at ``epoch``: what the loops advance in time."""
    days = (earth.utc(epoch) - earth.J2000).total_seconds() / 86400.0
    T = days / 36525.0
    return (math.radians(280.460 + 36000.771 * T), math.radians(357.5291092 + 35999.05034 * T),
            math.radians(23.439291 - 0.0130042 * T))


def msis_density(epoch, t: float, r, up: float, f107: float, ap: float) -> float:
    """NRLMSIS 2.1's total mass density (kg/m³) at inertial position r raised by ``up`` m,
    ``t`` s after ``epoch``. F10.7 and Ap are passed, so pymsis reads no space-weather
    file (it would download one otherwise)."""
    from pymsis import msis   # imported on use: only scenes with drag: nrlmsis load it
    ecef = earth.eci_to_ecef(np.asarray(r, float), earth.gmst(epoch, t))
    lon = math.degrees(math.atan2(ecef[1], ecef[0]))
    lat = math.degrees(math.asin(ecef[2] / np.linalg.norm(ecef)))
    moment = np.datetime64(earth.utc(epoch).replace(tzinfo=None)) + \
        np.timedelta64(int(round(t * 1e6)), 'us')
    out = msis.calculate(moment, lon, lat, (facet_model.height(r) + up) / 1e3,
                         f107s=[f107], f107as=[f107], aps=[[ap] * 7], version=2.1)
    return float(np.asarray(out).reshape(-1)[0])


def sunlight_from_parameters(p, model: str, epoch) -> Optional[Sunlight]:
    """The facet terms from coerced parameters, None if neither is named. ValueError naming
    the key: a term needs an orbit, an epoch and facets."""
    srp, drag = p['environment.solar_radiation_pressure'], p['environment.drag']
    if p['sun_sensor.enabled']:
        _needs('sun_sensor.enabled', model, epoch)
    if not srp and drag == 'none':
        return None
    key = 'environment.solar_radiation_pressure' if srp else 'environment.drag'
    _needs(key, model, epoch if srp or drag == 'nrlmsis' else True)
    if not p['facets.areas']:
        raise ValueError(f'{key}: needs a facet model (facets.areas, facets.normals, '
                         'facets.centres)')
    facets = facet_model.FacetModel.build(
        p['facets.areas'], p['facets.normals'], p['facets.centres'], p['facets.specular'],
        p['facets.diffuse'], p['facets.drag_coefficient'])
    return Sunlight(srp, drag, p['environment.shadow'], facets, epoch, p['environment.f107'],
                    p['environment.ap'])


def _needs(key: str, model: str, epoch):
    if model == 'none':
        raise ValueError(f'{key}: needs an orbit (orbit.model kepler, j2 or sgp4)')
    if epoch is None:
        raise ValueError(f'{key}: needs an epoch (epoch: the UTC instant of sim time 0, '
                         'ISO 8601) for the Sun\'s direction')


def sun_in_body(epoch, orbit, t: float, attitude, shadow: str):
    """(unit vector to the Sun in the body frame of ``attitude`` (body → inertial), lit
    fraction) at sim time t: what the sun sensor reads before its noise."""
    from ..physics import rotation
    r, _ = orbit.state(t)
    s = sunlight.sun_vector(epoch, t)
    lit = float(sunlight.shadow(r, s, shadow))
    to_sun = s - r
    u = rotation.rotate(rotation.conjugate(np.asarray(attitude, float)),
                        to_sun / np.linalg.norm(to_sun))
    return u, lit
