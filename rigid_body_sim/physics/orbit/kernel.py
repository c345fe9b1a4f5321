"""The orbit as the compiled loops see it: an element set in one float array, evaluated at
any instant, and the gravity-gradient torque it gives.

``env`` (float64, SIZE): [ON] 1 when the gravity gradient acts; [MU] μ; then the
osculating or mean elements of a conic at time [T0] — [A] semi-major axis (m), [E]
eccentricity, [INC] inclination, [RAAN] node, [ARGP] argument of periapsis, [M0] mean
anomaly (rad) — and their secular rates [RAAN_RATE], [ARGP_RATE], [M_RATE] (rad/s: the
two-body n for Kepler, J2's drifts for ``j2``). ``orbit.py`` builds it; SGP4 re-anchors
an osculating set at each interval. The free body passes None instead.

Each further term has a block of slots after them, in this order:

Magnetic (``physics/environment/magnetic_kernel.py``): the field's model and the
magnetorquers' dipole (the ``# magnetic`` block below).

Sunlight and drag (``environment/facets_kernel``): [SRP_ON], [DRAG_ON] switch the terms;
[SHADOW] 0 cylindrical, 1 conical; the Sun's mean longitude [SUN_L0], mean anomaly
[SUN_G0] at t = 0 and the obliquity [SUN_EPS] (rad; the almanac's formula is evaluated in
the loop at each instant); [DENSITY] 1 the exponential table, 2 a local fit
ρ = [RHO_REF]·exp(−(h − [H_REF])/[SCALE_HEIGHT]) re-made at each interval (NRLMSIS);
[N_FACETS] facets of FACET_SIZE values each from index SIZE on (``facets_kernel``).

Plain numerical Python compiled by ``jit`` (NUMBA_DISABLE_JIT=1 runs it as Python).
"""
import math

import numpy as np

from ..jit import inline, jit

# The slots live in layout.py (numba-free, for the specs); the other kernels read them
# here as kernel.X, so all of them are re-exported.
from .layout import *  # noqa: F403
from .layout import A, ARGP, ARGP_RATE, E, INC, M0, M_RATE, MU, ON, RAAN, RAAN_RATE, SIZE, T0

KEPLER_TOL = 1e-15   # |ΔE| (rad) that ends Newton's iteration
KEPLER_MAX_ITER = 50
TWO_PI = 2.0 * math.pi


def off():
    """A fresh element array of zeros (ON = 0), for an orbit to fill. The free body passes
    None to the loops instead (numba then compiles them without the term)."""
    return np.zeros(SIZE)


@jit
def eccentric_anomaly(mean_anomaly, e):
    """E with M = E − e sin E (Kepler's equation) by Newton's method from E0 = M + e sin M,
    M first reduced to [−π, π); converges in a few iterations for e < 0.9.

    It stops once the step taken leaves at most KEPLER_TOL/2: Newton's error after a step
    δ is ≤ max|f''|/(2 min|f'|)·δ² ≤ e·δ²/(2(1 − e)) (f = E − e sin E − M), so the
    iteration that would only confirm convergence (a step below 1e-15, two of the ~11
    sines and cosines of an orbit position) is not run. A circular orbit stops at once
    (E0 = M, its step is 0)."""
    m = mean_anomaly - TWO_PI * math.floor(mean_anomaly / TWO_PI + 0.5)
    big_e = m + e * math.sin(m)
    for _ in range(KEPLER_MAX_ITER):
        step = (big_e - e * math.sin(big_e) - m) / (1.0 - e * math.cos(big_e))
        big_e -= step
        if abs(step) <= KEPLER_TOL or e * step * step <= (1.0 - e) * KEPLER_TOL:
            break
    return big_e


@inline
def _frame(env, dt):
    """The unit vectors P (to periapsis) and Q (90° ahead of it), inertial frame, at
    t = T0 + dt (the node and the argument of periapsis advanced by their rates)."""
    raan = env[RAAN] + env[RAAN_RATE] * dt
    argp = env[ARGP] + env[ARGP_RATE] * dt
    co, so = math.cos(raan), math.sin(raan)
    cw, sw = math.cos(argp), math.sin(argp)
    ci, si = math.cos(env[INC]), math.sin(env[INC])
    return (co * cw - so * sw * ci, so * cw + co * sw * ci, sw * si,       # P
            -co * sw - so * cw * ci, -so * sw + co * cw * ci, cw * si)     # Q


@inline
def _perifocal(env, dt):
    """The perifocal position (xp, yp), cos E and sin E at t = T0 + dt."""
    a = env[A]
    e = env[E]
    big_e = eccentric_anomaly(env[M0] + env[M_RATE] * dt, e)
    cos_e = math.cos(big_e)
    sin_e = math.sin(big_e)
    return a * (cos_e - e), a * math.sqrt(1.0 - e * e) * sin_e, cos_e, sin_e


@inline
def _conic(env, t):
    """The conic at t: the perifocal position (xp, yp), cos E, sin E, and the unit vectors
    P (to periapsis) and Q (90° ahead of it) in the inertial frame."""
    dt = t - env[T0]
    xp, yp, cos_e, sin_e = _perifocal(env, dt)
    px, py, pz, qx, qy, qz = _frame(env, dt)
    return xp, yp, cos_e, sin_e, px, py, pz, qx, qy, qz


@jit
def frame(env, t):
    """(P, Q, fixed): :func:`_frame` at t, fixed = 1.0 when the node and the periapsis do
    not move (Kepler: their rates are 0, so raan + 0·dt is raan at every t and P, Q are
    these very numbers at every instant). A loop takes it once per call and passes it to
    :func:`radial_framed`: 6 of the ~11 sines and cosines of an orbit position."""
    px, py, pz, qx, qy, qz = _frame(env, t - env[T0])
    fixed = 1.0 if env[RAAN_RATE] == 0.0 and env[ARGP_RATE] == 0.0 else 0.0
    return px, py, pz, qx, qy, qz, fixed


@jit
def radial_framed(env, t, fr):
    """:func:`radial` (the same numbers) with ``fr`` = :func:`frame`'s result: its P, Q
    when fixed, else computed at t as radial does."""
    dt = t - env[T0]
    xp, yp, _, _ = _perifocal(env, dt)
    if fr[6] != 0.0:
        px, py, pz, qx, qy, qz = fr[0], fr[1], fr[2], fr[3], fr[4], fr[5]
    else:
        px, py, pz, qx, qy, qz = _frame(env, dt)
    x = xp * px + yp * qx
    y = xp * py + yp * qy
    z = xp * pz + yp * qz
    r = math.sqrt(x * x + y * y + z * z)
    return x / r, y / r, z / r, r


@jit
def state_at(env, t, out):
    """Inertial position (m) and velocity (m/s) at time t (s) into out (6,): the conic of
    ``env`` with its angles advanced by their rates from [T0]."""
    xp, yp, cos_e, sin_e, px, py, pz, qx, qy, qz = _conic(env, t)
    a = env[A]
    e = env[E]
    n = math.sqrt(env[MU] / (a * a * a))        # two-body speed along the conic
    k = a * n / (1.0 - e * cos_e)
    vxp = -k * sin_e
    vyp = k * math.sqrt(1.0 - e * e) * cos_e
    out[0] = xp * px + yp * qx
    out[1] = xp * py + yp * qy
    out[2] = xp * pz + yp * qz
    out[3] = vxp * px + vyp * qx
    out[4] = vxp * py + vyp * qy
    out[5] = vxp * pz + vyp * qz


@jit
def position_velocity(env, t):
    """(x, y, z m, vx, vy, vz m/s): ``state_at`` as floats (no array, for the loops)."""
    xp, yp, cos_e, sin_e, px, py, pz, qx, qy, qz = _conic(env, t)
    a = env[A]
    e = env[E]
    k = a * math.sqrt(env[MU] / (a * a * a)) / (1.0 - e * cos_e)
    vxp = -k * sin_e
    vyp = k * math.sqrt(1.0 - e * e) * cos_e
    return (xp * px + yp * qx, xp * py + yp * qy, xp * pz + yp * qz,
            vxp * px + vyp * qx, vxp * py + vyp * qy, vxp * pz + vyp * qz)


@jit
def radial(env, t):
    """(unit radial vector x, y, z, radius r): the position at t, inertial frame."""
    xp, yp, _, _, px, py, pz, qx, qy, qz = _conic(env, t)
    x = xp * px + yp * qx
    y = xp * py + yp * qy
    z = xp * pz + yp * qz
    r = math.sqrt(x * x + y * y + z * z)
    return x / r, y / r, z / r, r


@inline
def to_body(q, ux, uy, uz):
    """q⁻¹ u q: an inertial vector in the frame of q (principal → inertial; q normalised
    here: the RK loops' stages are not unit). The radial vector's and the field's."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    s = 1.0 / (x * x + y * y + z * z + w * w)
    c0 = ((1.0 - 2.0 * s * (y * y + z * z)) * ux + 2.0 * s * (x * y + w * z) * uy
          + 2.0 * s * (x * z - w * y) * uz)
    c1 = (2.0 * s * (x * y - w * z) * ux + (1.0 - 2.0 * s * (x * x + z * z)) * uy
          + 2.0 * s * (y * z + w * x) * uz)
    c2 = (2.0 * s * (x * z + w * y) * ux + 2.0 * s * (y * z - w * x) * uy
          + (1.0 - 2.0 * s * (x * x + y * y)) * uz)
    return c0, c1, c2


@inline
def _in_body(q, ux, uy, uz, r, env):
    """(ĉ x, y, z, 3μ/r³): the radial unit vector (ux, uy, uz) at radius r in the frame of
    q (:func:`to_body`) and the gradient's factor."""
    c0, c1, c2 = to_body(q, ux, uy, uz)
    return c0, c1, c2, 3.0 * env[MU] / (r * r * r)


@jit
def radial_in_body(q, t, env):
    """(ĉ x, y, z, 3μ/r³) at time t (:func:`_in_body` of :func:`radial`)."""
    ux, uy, uz, r = radial(env, t)
    return _in_body(q, ux, uy, uz, r, env)


@jit
def gravity_gradient_torque(q, t, env, moments):
    """τ_gg = 3μ/r³ · ĉ × (I ĉ) (principal frame, N·m) as three floats, I = diag(moments),
    at time t. Callers test env for None first, so the free body's loops are compiled
    without it (see dynamics_kernel)."""
    ux, uy, uz, r = radial(env, t)
    return gravity_gradient_at(q, ux, uy, uz, r, env, moments)


@jit
def gravity_gradient_at(q, ux, uy, uz, r, env, moments):
    """:func:`gravity_gradient_torque` with the orbit's radial unit vector and radius at
    the instant given (:func:`radial` or :func:`radial_framed`): a loop that needs the
    torque at one instant for several attitudes evaluates the orbit once."""
    c0, c1, c2, k = _in_body(q, ux, uy, uz, r, env)
    i0 = moments[0] * c0
    i1 = moments[1] * c1
    i2 = moments[2] * c2
    return k * (c1 * i2 - c2 * i1), k * (c2 * i0 - c0 * i2), k * (c0 * i1 - c1 * i0)


@jit
def gravity_gradient_torque_full(q, t, env, inertia):
    """The same for a full inertia matrix (3, 3) in the frame of q: a gyrostat's whole mass
    distribution, its wheels' rotors included."""
    c0, c1, c2, k = radial_in_body(q, t, env)
    i0 = inertia[0, 0] * c0 + inertia[0, 1] * c1 + inertia[0, 2] * c2
    i1 = inertia[1, 0] * c0 + inertia[1, 1] * c1 + inertia[1, 2] * c2
    i2 = inertia[2, 0] * c0 + inertia[2, 1] * c1 + inertia[2, 2] * c2
    return k * (c1 * i2 - c2 * i1), k * (c2 * i0 - c0 * i2), k * (c0 * i1 - c1 * i0)


@jit
def gravity_gradient(q, t, env, moments, out):
    """τ_gg (principal frame, N·m) into out (3,): zero when env[ON] is 0."""
    if env[ON] == 0.0:
        out[0] = 0.0
        out[1] = 0.0
        out[2] = 0.0
        return
    out[0], out[1], out[2] = gravity_gradient_torque(q, t, env, moments)
