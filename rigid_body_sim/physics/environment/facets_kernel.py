"""The facet model's torques as the compiled loops see them: solar radiation pressure with
the Earth's shadow, and aerodynamic drag, read from the orbit's element array ``env``
(``orbit.kernel``: slots SRP_ON … N_FACETS, then the facets) at attitude q and time t.

Both depend on the attitude and the time, never on ω: the splittings apply them as kicks
at fixed attitude, the Runge–Kutta methods and dop853 as a term of the right-hand side
(``dynamics_kernel.environment_torque``). The slow inputs are exact functions of time
here, not held per interval:

* the Sun: the Astronomical Almanac's low-precision formula (``sunlight.sun_vector``) is
  evaluated at each instant from the mean longitude and anomaly at t = 0 and their rates;
  only the obliquity is held at the epoch's value (it moves 6e-9 rad a day), so the
  direction is that formula's (~0.01°) for runs of any length;
* the shadow: cylindrical or conical, from the position at the instant (an eclipse's
  entry and exit fall inside steps: a step that crosses one sees the torque switch there,
  an error of the order of the step times the SRP torque, once per boundary);
* the density: the exponential table at the height of the instant, or NRLMSIS through a
  local exponential fit ρ_ref·exp(−(h − h_ref)/H) that the engine re-makes at each
  interval (``environment_specs``): the height's variation is followed exactly within
  the interval, the horizontal variation (local time, latitude) is held at the
  interval's midpoint.

Facet values are in the loops' frame (principal axes). Plain numerical Python compiled
by ``jit``; ``facets`` is the numpy reference.
"""
import math

import numpy as np

from ..jit import jit
from ..orbit import kernel as orbit_kernel
from ..orbit.kernel import (DENSITY, DRAG_ON, H_REF, N_FACETS, RHO_REF, SCALE_HEIGHT, SHADOW,
                            SIZE, SRP_ON, SUN_EPS, SUN_G0, SUN_L0)
from .facets import EARTH_RADIUS, EXPONENTIAL_TABLE, FACET_SIZE, FLATTENING, SOLAR_PRESSURE
from .sunlight import AU, SUN_RADIUS

EARTH_ROTATION_RATE = 7.2921158553e-5  # rad/s (earth.EARTH_ROTATION_RATE): the atmosphere
CENTURY = 36525.0 * 86400.0            # s
L_RATE = math.radians(36000.771) / CENTURY        # mean longitude, rad/s
G_RATE = math.radians(35999.05034) / CENTURY      # mean anomaly, rad/s
C1 = math.radians(1.914666471)
C2 = math.radians(0.019994643)
TABLE_H = np.ascontiguousarray(EXPONENTIAL_TABLE[:, 0])
TABLE_RHO = np.ascontiguousarray(EXPONENTIAL_TABLE[:, 1])
TABLE_SCALE = np.ascontiguousarray(EXPONENTIAL_TABLE[:, 2])


@jit
def sun(env, t):
    """(unit Earth → Sun vector x, y, z inertial, distance m) at time t."""
    g = env[SUN_G0] + G_RATE * t
    lam = env[SUN_L0] + L_RATE * t + C1 * math.sin(g) + C2 * math.sin(2.0 * g)
    d = AU * (1.000140612 - 0.016708617 * math.cos(g) - 0.000139589 * math.cos(2.0 * g))
    eps = env[SUN_EPS]
    return math.cos(lam), math.cos(eps) * math.sin(lam), math.sin(eps) * math.sin(lam), d


@jit
def shadow(x, y, z, sx, sy, sz, d, model):
    """The lit fraction (0 … 1) at (x, y, z) with the unit Sun vector and distance d:
    ``sunlight.shadow``'s cylindrical (model 0) or conical (1) shadow."""
    along = x * sx + y * sy + z * sz
    if model == 0.0:
        if along >= 0.0:
            return 1.0
        cx = x - along * sx
        cy = y - along * sy
        cz = z - along * sz
        return 0.0 if cx * cx + cy * cy + cz * cz < EARTH_RADIUS * EARTH_RADIUS else 1.0
    tx = d * sx - x
    ty = d * sy - y
    tz = d * sz - z
    d_sun = math.sqrt(tx * tx + ty * ty + tz * tz)
    d_earth = math.sqrt(x * x + y * y + z * z)
    a = math.asin(min(1.0, SUN_RADIUS / d_sun))
    b = math.asin(min(1.0, EARTH_RADIUS / d_earth))
    cos_c = -(tx * x + ty * y + tz * z) / (d_sun * d_earth)
    c = math.acos(max(-1.0, min(1.0, cos_c)))
    if c >= a + b:
        return 1.0
    if c <= b - a:
        return 0.0
    return max(0.0, min(1.0, (c - (b - a)) / (2.0 * a)))


@jit
def density(env, x, y, z):
    """ρ (kg/m³) at the inertial position: the exponential table (DENSITY 1) or the
    interval's local fit (2), at the height above the ellipsoid (``facets.height``)."""
    r = math.sqrt(x * x + y * y + z * z)
    sin_lat = z / r
    h = r - EARTH_RADIUS * (1.0 - FLATTENING * sin_lat * sin_lat)
    if env[DENSITY] == 2.0:
        return env[RHO_REF] * math.exp(-(h - env[H_REF]) / env[SCALE_HEIGHT])
    i = 0
    while i + 1 < TABLE_H.shape[0] and TABLE_H[i + 1] <= h:
        i += 1
    return TABLE_RHO[i] * math.exp(-(h - TABLE_H[i]) / TABLE_SCALE[i])


@jit
def _to_frame(q, ux, uy, uz):
    """q⁻¹ u q: an inertial vector in the frame of q (q normalised here: the RK stages)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    s = 1.0 / (x * x + y * y + z * z + w * w)
    return ((1.0 - 2.0 * s * (y * y + z * z)) * ux + 2.0 * s * (x * y + w * z) * uy
            + 2.0 * s * (x * z - w * y) * uz,
            2.0 * s * (x * y - w * z) * ux + (1.0 - 2.0 * s * (x * x + z * z)) * uy
            + 2.0 * s * (y * z + w * x) * uz,
            2.0 * s * (x * z + w * y) * ux + 2.0 * s * (y * z - w * x) * uy
            + (1.0 - 2.0 * s * (x * x + y * y)) * uz)


@jit
def facets_torque(q, t, env):
    """τ = Σ r_cp × F of the terms switched on (SRP, drag), frame of q, N·m."""
    x, y, z, vx, vy, vz = orbit_kernel.position_velocity(env, t)
    n = int(env[N_FACETS])
    tx = 0.0
    ty = 0.0
    tz = 0.0
    if env[SRP_ON] != 0.0:
        sx, sy, sz, d = sun(env, t)
        lit = shadow(x, y, z, sx, sy, sz, d, env[SHADOW])
        if lit > 0.0:
            ex = d * sx - x   # spacecraft → Sun (the parallax counts at 1e-5 rad)
            ey = d * sy - y
            ez = d * sz - z
            dist = math.sqrt(ex * ex + ey * ey + ez * ez)
            p = lit * SOLAR_PRESSURE * (AU / dist) * (AU / dist)
            ux, uy, uz = _to_frame(q, ex / dist, ey / dist, ez / dist)
            for k in range(n):
                j = SIZE + k * FACET_SIZE
                cos = env[j + 1] * ux + env[j + 2] * uy + env[j + 3] * uz
                if cos > 0.0:
                    rs = env[j + 7]
                    a = -p * env[j] * cos
                    bu = a * (1.0 - rs)
                    bn = a * (2.0 * rs * cos + (2.0 / 3.0) * env[j + 8])
                    fx = bu * ux + bn * env[j + 1]
                    fy = bu * uy + bn * env[j + 2]
                    fz = bu * uz + bn * env[j + 3]
                    tx += env[j + 5] * fz - env[j + 6] * fy
                    ty += env[j + 6] * fx - env[j + 4] * fz
                    tz += env[j + 4] * fy - env[j + 5] * fx
    if env[DRAG_ON] != 0.0:
        rho = density(env, x, y, z)
        wx = vx + EARTH_ROTATION_RATE * y   # v − ω_E × r: the atmosphere turns with the Earth
        wy = vy - EARTH_ROTATION_RATE * x
        speed = math.sqrt(wx * wx + wy * wy + vz * vz)
        ux, uy, uz = _to_frame(q, wx / speed, wy / speed, vz / speed)
        dyn = -0.5 * rho * speed * speed
        for k in range(n):
            j = SIZE + k * FACET_SIZE
            cos = env[j + 1] * ux + env[j + 2] * uy + env[j + 3] * uz
            if cos > 0.0:
                a = dyn * env[j + 9] * env[j] * cos
                fx = a * ux
                fy = a * uy
                fz = a * uz
                tx += env[j + 5] * fz - env[j + 6] * fy
                ty += env[j + 6] * fx - env[j + 4] * fz
                tz += env[j + 4] * fy - env[j + 5] * fx
    return tx, ty, tz
