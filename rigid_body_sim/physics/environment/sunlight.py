"""The Sun's direction and the Earth's shadow.

* :func:`sun_direction`: the Astronomical Almanac's low-precision solar coordinates
  (Vallado, algorithm 29): mean longitude and anomaly, ecliptic longitude, obliquity;
  good to ~0.01° over 1950–2050. A unit vector in the inertial frame of date.
* :func:`shadow`: the fraction of the Sun's disc seen from a position, 0 in the umbra and
  1 in sunlight: ``cylindrical`` (a cylinder of the Earth's radius behind it: 0 or 1) or
  ``conical`` (umbra and penumbra cones of the Sun and the Earth; in the penumbra the
  fraction grows linearly with the apparent separation of the discs, a first-order model).
"""
import numpy as np

from . import earth

EARTH_RADIUS = 6378137.0   # m, WGS-84 equatorial
SUN_RADIUS = 6.957e8       # m (IAU 2015 nominal)
AU = 1.495978707e11        # m
SHADOW_MODELS = ('cylindrical', 'conical')


def sun_vector(epoch, t=0.0):
    """Earth → Sun vector (m, inertial frame of date) at ``t`` s after ``epoch``."""
    days = (earth.utc(epoch) - earth.J2000).total_seconds() / 86400.0 \
        + np.asarray(t, float) / 86400.0
    T = days / 36525.0
    mean_longitude = np.radians(280.460 + 36000.771 * T)
    anomaly = np.radians(357.5291092 + 35999.05034 * T)
    longitude = mean_longitude + np.radians(1.914666471 * np.sin(anomaly)
                                            + 0.019994643 * np.sin(2.0 * anomaly))
    distance = AU * (1.000140612 - 0.016708617 * np.cos(anomaly)
                     - 0.000139589 * np.cos(2.0 * anomaly))
    obliquity = np.radians(23.439291 - 0.0130042 * T)
    return np.asarray(distance)[..., None] * np.stack(
        [np.cos(longitude), np.cos(obliquity) * np.sin(longitude),
         np.sin(obliquity) * np.sin(longitude)], axis=-1)


def sun_direction(epoch, t=0.0):
    """Unit Earth → Sun vector (inertial frame of date)."""
    s = sun_vector(epoch, t)
    return s / np.linalg.norm(s, axis=-1, keepdims=True)


def shadow(position, sun, model='cylindrical'):
    """Fraction of sunlight (0 … 1) at ``position`` (m, inertial, …×3) with the Earth → Sun
    vector ``sun`` (m, same frame)."""
    if model not in SHADOW_MODELS:
        raise ValueError(f'environment.shadow: {model!r} is not one of {SHADOW_MODELS}')
    r = np.asarray(position, float)
    s = np.asarray(sun, float)
    if model == 'cylindrical':
        u = s / np.linalg.norm(s, axis=-1, keepdims=True)
        along = np.sum(r * u, axis=-1)
        across = np.linalg.norm(r - along[..., None] * u, axis=-1)
        return np.where((along < 0.0) & (across < EARTH_RADIUS), 0.0, 1.0)
    # conical: apparent radii of the Sun and the Earth seen from r, and their separation
    to_sun = s - r
    d_sun = np.linalg.norm(to_sun, axis=-1)
    d_earth = np.linalg.norm(r, axis=-1)
    a = np.arcsin(np.clip(SUN_RADIUS / d_sun, -1.0, 1.0))
    b = np.arcsin(np.clip(EARTH_RADIUS / d_earth, -1.0, 1.0))
    cos_c = np.sum(to_sun * -r, axis=-1) / (d_sun * d_earth)
    c = np.arccos(np.clip(cos_c, -1.0, 1.0))
    lit = c >= a + b                      # discs apart: full sunlight
    umbra = c <= b - a                    # the Earth's disc covers the Sun's
    fraction = np.clip((c - (b - a)) / (2.0 * a), 0.0, 1.0)
    return np.where(lit, 1.0, np.where(umbra, 0.0, fraction))
