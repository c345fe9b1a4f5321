"""The rotating Earth: the rotation angle (GMST) and the inertial ↔ Earth-fixed rotation.

Frames. ``world`` (inertial) is taken as the Earth-centred inertial frame of date (z along
the spin axis, x towards the vernal equinox), and ECEF rotates from it about z by the
Greenwich mean sidereal time: r_ecef = R_z(θ_GMST)ᵀ r_eci. Precession, nutation and polar
motion (arc-seconds) are far below what the field or the Sun's direction need here.
"""
from datetime import datetime, timezone

import numpy as np

J2000 = datetime(2000, 1, 1, 12, 0, 0, tzinfo=timezone.utc)
EARTH_ROTATION_RATE = 7.2921158553e-5  # rad/s, sidereal (WGS-84: 7.292115e-5)


def utc(epoch) -> datetime:
    """``epoch`` (ISO 8601 text or datetime) as an aware UTC datetime; ValueError naming it."""
    if isinstance(epoch, str):
        try:
            epoch = datetime.fromisoformat(epoch.replace('Z', '+00:00'))
        except ValueError:
            raise ValueError(f'epoch {epoch!r} is not an ISO 8601 date and time '
                             '(e.g. 2026-03-20T14:46:00Z)') from None
    if not isinstance(epoch, datetime):
        raise ValueError(f'epoch must be ISO 8601 text or a datetime, got {epoch!r}')
    if epoch.tzinfo is None:
        epoch = epoch.replace(tzinfo=timezone.utc)
    return epoch.astimezone(timezone.utc)


def gmst(epoch, t=0.0):
    """Greenwich mean sidereal time (rad, in [0, 2π)) at ``t`` s after ``epoch`` (UTC taken
    as UT1: |UT1 − UTC| < 0.9 s moves it by < 4e-5 rad). IAU-1982 (Vallado, eq. 3-47)."""
    days = (utc(epoch) - J2000).total_seconds() / 86400.0 + np.asarray(t, float) / 86400.0
    T = days / 36525.0
    seconds = (67310.54841 + (876600.0 * 3600.0 + 8640184.812866) * T
               + 0.093104 * T * T - 6.2e-6 * T * T * T)
    return np.mod(np.radians(seconds / 240.0), 2.0 * np.pi)


def eci_to_ecef(vectors, angle):
    """Vectors (…, 3) in the inertial frame, resolved in ECEF at rotation angle(s) ``angle``."""
    v = np.asarray(vectors, float)
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * v[..., 0] + s * v[..., 1], -s * v[..., 0] + c * v[..., 1],
                     v[..., 2]], axis=-1)


def ecef_to_eci(vectors, angle):
    """The inverse of :func:`eci_to_ecef`."""
    return eci_to_ecef(vectors, -np.asarray(angle, float))
