"""The Earth's constants (WGS-84 / EGM-96, SI), as most attitude and orbit tools use them.

A peer using another μ moves the mean motion by ~1e-9 relative: compare at that level
only with the same constants.
"""
MU = 3.986004418e14          # m³/s², gravitational parameter
RADIUS = 6378137.0           # m, equatorial radius
J2 = 1.08262668e-3           # second zonal harmonic (unnormalised)
ROTATION_RATE = 7.2921150e-5  # rad/s, the Earth's rotation rate
