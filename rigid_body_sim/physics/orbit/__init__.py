"""The orbit, a function of time (no ROS): two-body, J2 secular drift, SGP4 from a TLE,
and the kernels' view of it (``kernel``: the element array, the gravity-gradient torque).
"""
from ...lazy_exports import lazy_exports
from .constants import J2, MU, RADIUS, ROTATION_RATE

# The orbits are imported on first use: they evaluate through the compiled kernel (numba),
# which the specs that check a scene's orbit keys and --help never run.
_HOME = {name: 'orbit' for name in ('J2Orbit', 'KeplerOrbit', 'Orbit', 'OrbitError',
                                    'osculating_elements')}
__getattr__, __dir__ = lazy_exports(__name__, globals(), _HOME)

MODELS = ('none', 'kepler', 'j2', 'sgp4')


def from_tle(lines, epoch=None):
    """An :class:`sgp4_orbit.Sgp4Orbit` (imported here on use: the sgp4 package loads only
    for scenes that name it)."""
    from .sgp4_orbit import Sgp4Orbit
    return Sgp4Orbit(lines, epoch)


__all__ = ['J2', 'MU', 'RADIUS', 'ROTATION_RATE', 'MODELS', 'J2Orbit', 'KeplerOrbit',
           'Orbit', 'OrbitError', 'osculating_elements', 'from_tle']
