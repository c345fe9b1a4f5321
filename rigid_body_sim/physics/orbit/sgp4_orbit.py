"""SGP4 from a two-line element set, with PyPI ``sgp4`` (Vallado's code).

SGP4 works in TEME (the true equator, mean equinox of date), in km and km/s; here TEME is
taken as the scene's inertial frame (``world``), in m and m/s. Sim time 0 is the scene's
``epoch`` (the TLE's own epoch when none is given). Each call returns SGP4's error code:
a non-zero one (decay, eccentricity out of range, …) raises :class:`OrbitError` with the
time and SGP4's message, so a run stops cleanly there.

The compiled loops need the orbit inside a step: :meth:`Sgp4Orbit.elements` gives the
osculating two-body conic through SGP4's state at an instant, which the engine rebuilds
at each interval between events (``anchored``). Over an interval Δt its position differs
from SGP4's by about ½·a_J2·Δt² (a_J2 ≈ 0.015 m/s² in low orbit): 1e-9 of r at Δt = 1 s,
far below the gravity-gradient torque's other errors.
"""
import math
from datetime import datetime, timedelta, timezone

import numpy as np
from sgp4.api import SGP4_ERRORS, Satrec, WGS72

from .orbit import Orbit, OrbitError, osculating_elements

SECONDS_PER_DAY = 86400.0
_J2000 = datetime(2000, 1, 1, 12, tzinfo=timezone.utc)
JD_J2000 = 2451545.0
MU_WGS72 = 398600.8e9  # m³/s², the gravity model TLEs are fitted with


def tle_problem(lines) -> str:
    """Why ``lines`` are not a usable two-line element set ('' if they are): two lines of
    69 characters, numbered 1 and 2, one satellite, checksums right."""
    if len(lines) != 2:
        return f'needs exactly two lines, got {len(lines)}'
    for k, line in enumerate(lines, start=1):
        if len(line) != 69:
            return f'line {k} has {len(line)} characters, a TLE line has 69'
        if not line.startswith(f'{k} '):
            return f'line {k} must start with "{k} "'
        digits = sum(int(c) for c in line[:68] if c.isdigit()) + line[:68].count('-')
        if not line[68].isdigit() or digits % 10 != int(line[68]):
            return f'line {k} checksum: the last digit is {line[68]!r}, the line sums to ' \
                   f'{digits % 10}'
    if lines[0][2:7] != lines[1][2:7]:
        return f'the lines name different satellites ({lines[0][2:7]!r}, {lines[1][2:7]!r})'
    return ''


def julian_date(moment: datetime):
    """(whole part, fraction) of the Julian date of a UTC datetime, as sgp4 takes it."""
    days = (moment - _J2000).total_seconds() / SECONDS_PER_DAY
    whole = math.floor(days)
    return JD_J2000 + whole, days - whole


class Sgp4Orbit(Orbit):
    """SGP4 from ``lines`` (the two TLE lines); ``epoch``: the UTC datetime of sim time 0
    (None: the TLE's epoch). ValueError naming the reason if the set is malformed or SGP4
    refuses it at t = 0."""
    name = 'sgp4'
    anchored = True

    def __init__(self, lines, epoch=None):
        lines = [str(line).rstrip('\r\n') for line in lines]
        problem = tle_problem(lines)
        if problem:
            raise ValueError(problem)
        self.lines = lines
        self.sat = Satrec.twoline2rv(lines[0], lines[1], WGS72)
        if self.sat.error:
            raise ValueError(f'SGP4 refuses the set: {SGP4_ERRORS.get(self.sat.error, "")} '
                             f'(error {self.sat.error})')
        if epoch is None:
            self.jd0, self.fr0 = self.sat.jdsatepoch, self.sat.jdsatepochF
        else:
            self.jd0, self.fr0 = julian_date(epoch)
        self.mu = MU_WGS72  # SGP4's own μ for its osculating conics
        try:
            self.state(0.0)
        except OrbitError as exc:
            raise ValueError(f'SGP4 fails at the epoch: {exc.reason}') from None

    @property
    def epoch(self) -> datetime:
        """The UTC instant of sim time 0 (the TLE's epoch; the field and the Sun need it)."""
        return _J2000 + timedelta(days=(self.jd0 - JD_J2000) + self.fr0)

    @property
    def mean_motion(self) -> float:
        return float(self.sat.no_kozai) / 60.0  # rad/min → rad/s

    @property
    def perigee_radius(self) -> float:
        """m, from the TLE's mean elements (SGP4's a in Earth radii)."""
        return float(self.sat.a * self.sat.radiusearthkm * 1e3 * (1.0 - self.sat.ecco))

    @property
    def eccentricity(self) -> float:
        """The TLE's mean eccentricity."""
        return float(self.sat.ecco)

    def state(self, t: float):
        """(r m, v m/s) at sim time t; OrbitError with SGP4's code if it fails."""
        fr = self.fr0 + float(t) / SECONDS_PER_DAY
        whole = math.floor(fr)
        code, r, v = self.sat.sgp4(self.jd0 + whole, fr - whole)
        if code != 0:
            raise OrbitError(t, f'SGP4 error {code}: {SGP4_ERRORS.get(code, "unknown")}')
        return np.array(r) * 1e3, np.array(v) * 1e3

    def elements(self, t: float = 0.0) -> np.ndarray:
        r, v = self.state(t)
        return osculating_elements(r, v, self.mu, float(t))
