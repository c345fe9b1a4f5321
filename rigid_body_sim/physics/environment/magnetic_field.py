"""The Earth's magnetic field along an orbit: a tilted dipole in closed form, or IGRF-14.

Both take positions in the inertial frame (m) and return the field there in T, in the
inertial frame; the Earth turns under the orbit by :func:`earth.gmst` from the epoch.

* ``dipole``: the degree-1 part of IGRF-14 at the epoch, as the moment
  m = (4π/μ0)·a³·(g₁¹, h₁¹, g₁⁰) (ECEF, A·m²; a = 6371.2 km, IGRF's reference radius) in
  B(r) = (μ0/4π)/r³·[3(m·r̂)r̂ − m]. |m| ≈ 7.7e22 A·m², tilted ~9.7° from the spin axis.
* ``igrf``: IGRF-14 to degree 13 by PyPI ``ppigrf`` (pure Python, the model's coefficient
  file shipped with it), in geocentric spherical components, turned into the frame here.

The model is defined from 1900 to 2030: an epoch outside is refused, naming it.
"""
from datetime import timedelta

import numpy as np

from . import earth

MU0_OVER_4PI = 1e-7  # T·m/A
IGRF_RADIUS = 6371.2e3  # m: the model's reference radius (not the equatorial 6378.137 km)
MODELS = ('dipole', 'igrf')


def _coefficients():
    """IGRF-14's Gauss coefficients (nT), as ppigrf reads them: (g, h) by date."""
    from ppigrf import ppigrf
    return ppigrf.read_shc(ppigrf.shc_fn_igrf14)


def model_range():
    """(first, last) datetime (UTC) the coefficient file covers."""
    g, _ = _coefficients()
    return (earth.utc(g.index[0].to_pydatetime()), earth.utc(g.index[-1].to_pydatetime()))


def check_epoch(epoch, duration=0.0):
    """``epoch`` as UTC datetime; ValueError naming it when the run [epoch, epoch + duration]
    leaves the model's range."""
    start = earth.utc(epoch)
    first, last = model_range()
    end = start + timedelta(seconds=float(duration))
    if start < first or end > last:
        raise ValueError(f'epoch {start.isoformat()} (+{duration:g} s): outside the IGRF-14 '
                         f'field model\'s range {first.date()} … {last.date()}')
    return start


def dipole_moment(epoch):
    """The Earth's dipole moment (A·m², ECEF) at ``epoch``: IGRF-14's degree 1, its
    coefficients interpolated linearly in time between the model's dates, as ppigrf does."""
    start = check_epoch(epoch)
    g, h = _coefficients()
    when = np.array([earth.utc(d.to_pydatetime()).timestamp() for d in g.index])
    t = start.timestamp()
    g10, g11, h11 = (np.interp(t, when, table[key].to_numpy(float))
                     for table, key in ((g, (1, 0)), (g, (1, 1)), (h, (1, 1))))
    return IGRF_RADIUS ** 3 / MU0_OVER_4PI * 1e-9 * np.array([g11, h11, g10])


def dipole_field(position, moment):
    """Field (T) of a centred dipole ``moment`` (A·m²) at ``position`` (m, …×3), both in
    one frame, in that frame: μ0/(4π r³)·[3(m·r̂)r̂ − m]."""
    r = np.asarray(position, float)
    norm = np.linalg.norm(r, axis=-1, keepdims=True)
    u = r / norm
    return MU0_OVER_4PI / norm ** 3 * (3.0 * np.sum(u * moment, axis=-1, keepdims=True) * u
                                       - moment)


def _spherical_to_ecef(position, b_r, b_theta, b_phi):
    """Field components along r̂, θ̂ (south), φ̂ (east) at ECEF ``position`` → ECEF vectors."""
    x, y, z = position[..., 0], position[..., 1], position[..., 2]
    rho = np.hypot(x, y)
    r = np.hypot(rho, z)
    cos_t, sin_t = z / r, rho / r
    cos_p, sin_p = np.where(rho > 0, x / np.where(rho > 0, rho, 1), 1.0), \
        np.where(rho > 0, y / np.where(rho > 0, rho, 1), 0.0)
    e_r = np.stack([sin_t * cos_p, sin_t * sin_p, cos_t], axis=-1)
    e_t = np.stack([cos_t * cos_p, cos_t * sin_p, -sin_t], axis=-1)
    e_p = np.stack([-sin_p, cos_p, np.zeros_like(cos_p)], axis=-1)
    return b_r[..., None] * e_r + b_theta[..., None] * e_t + b_phi[..., None] * e_p


def igrf_field_ecef(position, epoch, max_degree=13):
    """IGRF-14 (T, ECEF) at ECEF ``position`` (m, …×3) at ``epoch`` (ppigrf's synthesis)."""
    from ppigrf import igrf_gc
    start = check_epoch(epoch)
    p = np.asarray(position, float)
    r = np.linalg.norm(p, axis=-1)
    theta = np.degrees(np.arccos(np.clip(p[..., 2] / r, -1.0, 1.0)))
    phi = np.degrees(np.arctan2(p[..., 1], p[..., 0]))
    date = start.replace(tzinfo=None)  # ppigrf compares with naive UTC dates
    b_r, b_t, b_p = (np.asarray(c, float).reshape(r.shape) * 1e-9
                     for c in igrf_gc(r * 1e-3, theta, phi, date, max_degree=max_degree))
    return _spherical_to_ecef(p, b_r, b_t, b_p)


def field(model, position, epoch, t=0.0):
    """The field (T, inertial frame) at inertial ``position`` (m, …×3), ``t`` s after
    ``epoch``, by ``model`` (``dipole`` or ``igrf``)."""
    if model not in MODELS:
        raise ValueError(f'environment.magnetic_field: {model!r} is not one of {MODELS}')
    angle = earth.gmst(epoch, t)
    ecef = earth.eci_to_ecef(position, angle)
    when = earth.utc(epoch) + timedelta(seconds=float(np.max(t)))
    if model == 'dipole':
        b = dipole_field(ecef, dipole_moment(when))
    else:
        b = igrf_field_ecef(ecef, when)
    return earth.ecef_to_eci(b, angle)
