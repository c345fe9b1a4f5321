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
import importlib.util
import os
from datetime import datetime, timedelta
from functools import lru_cache

import numpy as np

from . import earth

MU0_OVER_4PI = 1e-7  # T·m/A
IGRF_RADIUS = 6371.2e3  # m: the model's reference radius (not the equatorial 6378.137 km)
MODELS = ('dipole', 'igrf')


@lru_cache(maxsize=1)
def _coefficients():
    """IGRF-14's Gauss coefficients (nT), as ppigrf reads them: (g, h) by date. Read once
    per process (~0.03 CPU s a read, three reads per scene otherwise); callers only read."""
    from ppigrf import ppigrf
    return ppigrf.read_shc(ppigrf.shc_fn_igrf14)


def coefficient_file() -> str:
    """ppigrf's IGRF-14 coefficient file (``ppigrf.shc_fn_igrf14``, in its package's
    directory), found without importing ppigrf: its import loads pandas (~0.5 CPU-s),
    which a scene's epoch check does not need."""
    spec = importlib.util.find_spec('ppigrf')
    if spec is None or not spec.submodule_search_locations:  # missing: ppigrf's own error
        from ppigrf import ppigrf
        return ppigrf.shc_fn_igrf14
    return os.path.join(spec.submodule_search_locations[0], 'IGRF14.shc')


def _decimal_year(value: float) -> datetime:
    """A decimal year as ppigrf reads it (``yearfrac_to_datetime``): the fraction of the
    year's days from its 1 January, UTC."""
    year = int(value)
    leap = year % 4 == 0 and (year % 100 != 0 or year % 400 == 0)
    return earth.utc(datetime(year, 1, 1) + timedelta(days=(value - year) * (365 + leap)))


@lru_cache(maxsize=1)
def model_range():
    """(first, last) datetime (UTC) the coefficient file covers: the first and last of the
    model dates on the file's line after its parameters (the header ``read_shc`` reads,
    without the coefficients and pandas)."""
    with open(coefficient_file()) as f:
        lines = (line for line in f if not line.startswith('#'))
        next(lines)  # N_MIN, N_MAX, NTIMES, SP_ORDER, N_STEPS
        years = [float(x) for x in next(lines).split()]
    return _decimal_year(years[0]), _decimal_year(years[-1])


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


class FieldAlongOrbit:
    """The field (T, inertial frame) along ``orbit`` by ``model``, t s after ``epoch``.

    The orbit does not depend on the attitude, so B_world is a function of time alone.
    ``dipole``: the closed form, the Earth's moment taken at the epoch (its secular change,
    ~1e-4 a year, is far below a run) and turning at the sidereal rate from GMST at the
    epoch; the compiled loops evaluate the same closed form (``magnetic_kernel``).
    ``igrf``: ppigrf's values at the epoch's coefficients on a grid every ``spacing`` s,
    computed a chunk at a time as the run reaches it, and linear between them;
    :meth:`line` gives the loops that line for an engine interval. Its error against
    ppigrf at the same instants is Δ²/8·|B̈| (B turns at about twice the orbital rate):
    measured in test_magnetic.py.
    """
    CHUNK = 512  # grid points per ppigrf call

    def __init__(self, model, orbit, epoch, spacing=5.0):
        if model not in MODELS:
            raise ValueError(f'environment.magnetic_field: {model!r} is not one of {MODELS}')
        self.model, self.orbit, self.spacing = model, orbit, float(spacing)
        self.epoch = check_epoch(epoch)
        self.angle0 = float(earth.gmst(self.epoch))
        # the dipole's moment only: igrf reads its coefficients (ppigrf, pandas) when the
        # field is first evaluated, not when a scene is loaded
        self.moment = dipole_moment(self.epoch) if model == 'dipole' else None
        self._table = np.zeros((0, 3))

    def angle(self, t):
        """The Earth's rotation angle (rad) at sim time t: GMST at the epoch + ω_E t."""
        return self.angle0 + earth.EARTH_ROTATION_RATE * np.asarray(t, float)

    def positions(self, times):
        return np.array([self.orbit.state(float(t))[0] for t in np.atleast_1d(times)])

    def exact(self, times):
        """The model's own values (n, 3) at sim times (ppigrf for igrf: slow)."""
        times = np.atleast_1d(np.asarray(times, float))
        angle = self.angle(times)
        ecef = earth.eci_to_ecef(self.positions(times), angle)
        b = dipole_field(ecef, self.moment) if self.model == 'dipole' else \
            igrf_field_ecef(ecef, self.epoch)
        return earth.ecef_to_eci(b, angle)

    def _grid(self, last: int):
        """The table through grid point ``last``."""
        while len(self._table) <= last:
            first = len(self._table)
            times = self.spacing * np.arange(first, first + self.CHUNK)
            self._table = np.concatenate([self._table, self.exact(times)])

    def at(self, t: float) -> np.ndarray:
        """B (T, inertial, (3,)) at sim time t ≥ 0: exact for the dipole, the table's line
        for igrf."""
        if self.model == 'dipole':
            return self.exact(t)[0]
        x = max(0.0, float(t)) / self.spacing
        k = int(x)
        self._grid(k + 1)
        f = x - k
        return (1.0 - f) * self._table[k] + f * self._table[k + 1]

    def line(self, t0: float, t1: float):
        """(B at t0, Ḃ) of the chord over [t0, t1] through the table (igrf)."""
        b0 = self.at(t0)
        return b0, (self.at(t1) - b0) / (t1 - t0) if t1 > t0 else np.zeros(3)

    def fill(self, env, t0: float = 0.0, t1: float = 0.0):
        """The magnetic slots of the loops' array ``env`` (``orbit.kernel`` layout) for the
        interval [t0, t1], the rods' dipole slots left alone."""
        from ..orbit import kernel as k
        if self.model == 'dipole':
            env[k.MAG_MODEL] = 1.0
            env[k.MAG_MOMENT:k.MAG_MOMENT + 3] = self.moment
            env[k.MAG_ANGLE0], env[k.MAG_SPIN] = self.angle0, earth.EARTH_ROTATION_RATE
            return
        b0, rate = self.line(t0, t1)
        env[k.MAG_MODEL], env[k.MAG_T0] = 2.0, t0
        env[k.MAG_B0:k.MAG_B0 + 3] = b0
        env[k.MAG_B_RATE:k.MAG_B_RATE + 3] = rate
