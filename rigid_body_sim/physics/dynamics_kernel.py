"""The compiled twin of ``dynamics``: what every method's loop shares — the rates, the
exact flow about one principal axis, the dissipation flows and the finiteness check.

One body's state is q (4,) = (x, y, z, w), principal → inertial, and m (3,), the body
angular momentum in the principal frame; both are float64 arrays updated in place. A
method's loop (``integrators/*_kernel.py``) runs ``n`` steps of size ``h`` with a held
torque ``tau`` (principal frame) and returns the index of the first step after which the
state is not finite (-1 if none), so the caller raises IntegrationError with the right
step and time. Compiled by ``jit`` (see that module); plain Python under
NUMBA_DISABLE_JIT=1.

The environment's torques (the gravity gradient along the orbit) depend on the attitude
and the time: the loops take ``t0`` (s, the time of their first step) and ``env``, the
orbit's element array (``orbit.kernel``), or None for the free body: numba then prunes
every ``if env is not None`` branch, so the free body's loops are compiled as they were
before the orbit existed (same code, same results bit for bit, same cost).

Dissipation models: 0 none, 1 double bracket (α), 2 viscous (c); see ``dynamics``. Code 3
is the double bracket by its exact flow (``splitting2_lstable``).
"""
import math

from .jit import depends_on, inline, jit
from .environment import facets_kernel, magnetic_kernel
from .orbit import kernel as orbit_kernel

MODEL_CODES = {'none': 0, 'double_bracket': 1, 'viscous': 2}


@jit
def _finite(q, m):
    s = q[0] + q[1] + q[2] + q[3] + m[0] + m[1] + m[2]
    return s - s == 0.0  # False for NaN and ±Inf


@jit
def _axis_flow(q, m, axis, t, moments):
    """Exact flow of m_axis²/(2 I_axis) for time t: m turns by −φ, q by +φ about the axis."""
    _rotate_half(q, m, axis, m[axis] * (0.5 * t / moments[axis]))


@inline
def _rotate_half(q, m, axis, half):
    """m turns by −2·half, q by +2·half about ``axis`` (in place): the rotation of every
    axis flow, the body's (_axis_flow) and the gyrostat's (gyrostat_kernel._flow)."""
    b = (axis + 1) % 3
    c = (axis + 2) % 3
    s = math.sin(half)
    w = math.cos(half)
    cos_phi = w * w - s * s
    sin_phi = 2.0 * s * w
    mb = m[b]
    mc = m[c]
    m[b] = cos_phi * mb + sin_phi * mc
    m[c] = cos_phi * mc - sin_phi * mb
    qa = q[axis]
    qb = q[b]
    qc = q[c]
    qw = q[3]
    q[axis] = w * qa + s * qw
    q[b] = w * qb + s * qc
    q[c] = w * qc - s * qb
    q[3] = w * qw - s * qa


@jit
def _rotated(x, y, z, t0, t1, t2):
    """exp([θ]×) (x, y, z) (Rodrigues), stable for small |θ|; on scalars (no allocation)."""
    a2 = t0 * t0 + t1 * t1 + t2 * t2
    half = 0.5 * math.sqrt(a2)
    sinc_half = math.sin(half) / half if half > 1e-8 else 1.0 - half * half / 6.0
    s1 = sinc_half * math.cos(half)
    s2 = 0.5 * sinc_half * sinc_half
    c = 1.0 - a2 * s2
    dot = t0 * x + t1 * y + t2 * z
    tx = t1 * z - t2 * y
    ty = t2 * x - t0 * z
    tz = t0 * y - t1 * x
    return (c * x + s1 * tx + s2 * dot * t0, c * y + s1 * ty + s2 * dot * t1,
            c * z + s1 * tz + s2 * dot * t2)


@jit
def _bracket_theta(x, y, z, dt, moments, alpha):
    """θ = dt·w(m), w = −α m×Ω: the rotation the double bracket applies to m."""
    o0 = x / moments[0]
    o1 = y / moments[1]
    o2 = z / moments[2]
    k = -alpha * dt
    return k * (y * o2 - z * o1), k * (z * o0 - x * o2), k * (x * o1 - y * o0)


@jit
def _double_bracket(m, t, moments, alpha):
    """ṁ = α m×(m×Ω) for time t > 0 by the Lie midpoint rule in substeps short enough for
    the stiffness (α|m|²t(1/I_min − 1/I_max) ≤ 0.5); |m| stays exact. Returns substeps."""
    x, y, z = m[0], m[1], m[2]
    norm2 = x * x + y * y + z * z
    i_min = min(moments[0], min(moments[1], moments[2]))
    i_max = max(moments[0], max(moments[1], moments[2]))
    rate = alpha * norm2 * (1.0 / i_min - 1.0 / i_max)
    n = max(1, int(math.ceil(rate * t / 0.5)))
    dt = t / n
    for _ in range(n):
        t0, t1, t2 = _bracket_theta(x, y, z, 0.5 * dt, moments, alpha)
        hx, hy, hz = _rotated(x, y, z, t0, t1, t2)
        t0, t1, t2 = _bracket_theta(hx, hy, hz, dt, moments, alpha)
        x, y, z = _rotated(x, y, z, t0, t1, t2)
    m[0] = x
    m[1] = y
    m[2] = z
    return n


SYMMETRIC_TOL = 4e-16  # relative change that ends the symmetric double-bracket iteration
SYMMETRIC_MAX_ITER = 40


@jit
def _double_bracket_symmetric(m, t, moments, alpha):
    """Time-symmetric order-2 step of the double bracket (t of either sign):
    m₁ = exp(t·w(m̄)) m₀, m̄ = (m₀ + m₁)/2, by fixed-point iteration from the explicit
    Lie step; |m| stays exact. Symmetric, so Yoshida compositions of a splitting that
    contains it keep their order (weak damping: |t|·rate ≤ 0.25). Returns rotations."""
    a, b, c = m[0], m[1], m[2]
    t0, t1, t2 = _bracket_theta(a, b, c, t, moments, alpha)
    x, y, z = _rotated(a, b, c, t0, t1, t2)
    scale = math.sqrt(a * a + b * b + c * c)
    count = 1
    for _ in range(SYMMETRIC_MAX_ITER):
        t0, t1, t2 = _bracket_theta(0.5 * (a + x), 0.5 * (b + y), 0.5 * (c + z), t, moments,
                                    alpha)
        nx, ny, nz = _rotated(a, b, c, t0, t1, t2)
        change = abs(nx - x) + abs(ny - y) + abs(nz - z)
        x, y, z = nx, ny, nz
        count += 1
        if change <= SYMMETRIC_TOL * scale:
            break
    m[0] = x
    m[1] = y
    m[2] = z
    return count


@jit
def double_bracket_exact(m, t, moments, alpha):
    """The exact flow of ṁ = α m×(m×Ω) for time t ≥ 0, in place. On the sphere |m| = L it
    is ṁ_i = α m_i (2T − L²/I_i), whose solution is m_i(t) ∝ m_i(0) e^{−αL²t/I_i}, scaled
    back to |m| = L: every transverse mode decays as e^{−λt}, so at any step the stiff ones
    vanish (R(z) = e^z, L-stable) at the cost of three exponentials. Exponents are taken
    relative to the largest I with m_i ≠ 0, so none overflows and that component stays."""
    norm2 = m[0] * m[0] + m[1] * m[1] + m[2] * m[2]
    if norm2 == 0.0:
        return
    c = alpha * norm2 * t
    ref = 0.0  # 1/I of the reference component
    for i in range(3):
        if m[i] != 0.0 and (ref == 0.0 or 1.0 / moments[i] < ref):
            ref = 1.0 / moments[i]
    big = 0.0
    for i in range(3):
        if m[i] != 0.0:  # a zero component stays zero (its factor may overflow)
            m[i] = m[i] * math.exp(c * (ref - 1.0 / moments[i]))
        big = max(big, abs(m[i]))
    s = 0.0  # |m|² after the decay, scaled by the largest component (no underflow)
    for i in range(3):
        r = m[i] / big
        s += r * r
    scale = math.sqrt(norm2) / (big * math.sqrt(s))
    for i in range(3):
        m[i] = m[i] * scale


@jit
def _dissipate(m, t, moments, model, coefficient, symmetric):
    """D(t); ``symmetric``: by a time-symmetric flow (t of either sign). Viscous damping is
    exact either way; model 3 is the double bracket by its exact flow (t ≥ 0, never inside
    compositions). Returns the dissipative sub-flows evaluated (for nfev)."""
    if model == 3:
        double_bracket_exact(m, t, moments, coefficient)
        return 0
    if model == 2:
        for i in range(3):
            m[i] = m[i] * math.exp(-coefficient * t / moments[i])
        return 0
    if model == 1:
        if symmetric:
            return _double_bracket_symmetric(m, t, moments, coefficient)
        return 2 * _double_bracket(m, t, moments, coefficient)
    return 0


@inline
def rates(x, y, z, w, m0, m1, m2, i0, i1, i2, t0, t1, t2, model, coefficient):
    """dq = ½ q ⊗ (Ω, 0) and dm = m × Ω + τ + dissipation (principal frame) of the state
    (x, y, z, w; m0, m1, m2), moments (i0, i1, i2) and torque (t0, t1, t2), as 7 numbers:
    rk4's free-body stages keep them in numbers (:func:`_rates` writes them into arrays,
    whose views cost a reference-count round trip each per call)."""
    o0 = m0 / i0
    o1 = m1 / i1
    o2 = m2 / i2
    dq0 = 0.5 * (w * o0 + y * o2 - z * o1)
    dq1 = 0.5 * (w * o1 - x * o2 + z * o0)
    dq2 = 0.5 * (w * o2 + x * o1 - y * o0)
    dq3 = 0.5 * (-x * o0 - y * o1 - z * o2)
    c0 = m1 * o2 - m2 * o1
    c1 = m2 * o0 - m0 * o2
    c2 = m0 * o1 - m1 * o0
    dm0 = c0 + t0
    dm1 = c1 + t1
    dm2 = c2 + t2
    if model == 1:  # α m × (m × Ω)
        dm0 += coefficient * (m1 * c2 - m2 * c1)
        dm1 += coefficient * (m2 * c0 - m0 * c2)
        dm2 += coefficient * (m0 * c1 - m1 * c0)
    elif model == 2:  # −c ω
        dm0 -= coefficient * o0
        dm1 -= coefficient * o1
        dm2 -= coefficient * o2
    return dq0, dq1, dq2, dq3, dm0, dm1, dm2


@jit
def _rates(q, m, moments, tau, model, coefficient, dq, dm):
    """dq = ½ q ⊗ (Ω, 0); dm = m × Ω + τ + dissipation (principal frame): :func:`rates`
    into the arrays dq (4) and dm (3)."""
    dq[0], dq[1], dq[2], dq[3], dm[0], dm[1], dm[2] = rates(
        q[0], q[1], q[2], q[3], m[0], m[1], m[2], moments[0], moments[1], moments[2],
        tau[0], tau[1], tau[2], model, coefficient)


@inline
def _plus_rods_and_facets(q, t, env, tx, ty, tz):
    """(tx, ty, tz) + the magnetorquers' m × B (``environment.magnetic_kernel``), then the
    facets' solar radiation pressure and drag (``environment.facets_kernel``), each where
    ``env`` switches it on, added in that order."""
    if env[orbit_kernel.MAG_MODEL] != 0.0:
        mx, my, mz = magnetic_kernel.magnetorquer_torque(q, t, env)
        tx += mx
        ty += my
        tz += mz
    if env[orbit_kernel.SRP_ON] != 0.0 or env[orbit_kernel.DRAG_ON] != 0.0:
        fx, fy, fz = facets_kernel.facets_torque(q, t, env)
        tx += fx
        ty += fy
        tz += fz
    return tx, ty, tz


@jit
def environment_torque(q, t, env, moments):
    """The environment's torque at attitude q and time t (principal frame, N·m) as three
    floats, one branch per term switched on in ``env`` (``orbit.kernel``): the gravity
    gradient, then the rods' and the facets' (``_plus_rods_and_facets``)."""
    tx = 0.0
    ty = 0.0
    tz = 0.0
    if env[orbit_kernel.ON] != 0.0:
        tx, ty, tz = orbit_kernel.gravity_gradient_torque(q, t, env, moments)
    return _plus_rods_and_facets(q, t, env, tx, ty, tz)


@jit
def environment_torque_full(q, t, env, inertia):
    """The same for a full inertia matrix (3, 3) in the frame of q (the gyrostat's)."""
    tx = 0.0
    ty = 0.0
    tz = 0.0
    if env[orbit_kernel.ON] != 0.0:
        tx, ty, tz = orbit_kernel.gravity_gradient_torque_full(q, t, env, inertia)
    return _plus_rods_and_facets(q, t, env, tx, ty, tz)


@inline
def kick_environment(q, t, env, moments, m, s):
    """m += s · the environment's torque at attitude q and time t (principal frame), in
    place, term by term in ``environment_torque``'s order: ``_environment``'s rate (s = 1)
    and the splittings' kicks at fixed attitude (s = half the stage's step).

    Each term is spelled out here, not summed through a tuple-returning function: through
    one the gravity gradient alone ran 5-13 % slower in rk4 and the splittings' kicks."""
    if env[orbit_kernel.ON] != 0.0:
        gx, gy, gz = orbit_kernel.gravity_gradient_torque(q, t, env, moments)
        m[0] = m[0] + s * gx
        m[1] = m[1] + s * gy
        m[2] = m[2] + s * gz
    if env[orbit_kernel.MAG_MODEL] != 0.0:
        bx, by, bz = magnetic_kernel.magnetorquer_torque(q, t, env)
        m[0] = m[0] + s * bx
        m[1] = m[1] + s * by
        m[2] = m[2] + s * bz
    if env[orbit_kernel.SRP_ON] != 0.0 or env[orbit_kernel.DRAG_ON] != 0.0:
        fx, fy, fz = facets_kernel.facets_torque(q, t, env)
        m[0] = m[0] + s * fx
        m[1] = m[1] + s * fy
        m[2] = m[2] + s * fz


@jit
def _environment(q, t, env, moments, dm):
    """dm += the environment's torque at time t (``kick_environment`` with s = 1: exact,
    1.0·x is x).
    The loops call it after ``_rates`` under ``if env is not None``: for the free body
    (env None) numba prunes the branch, so their code is what it was before the orbit
    existed (a parameter of ``_rates`` instead kept LLVM from inlining it: rk4's step
    3-4× slower with the term off)."""
    kick_environment(q, t, env, moments, dm, 1.0)


@inline
def orbit_at(env, t, fr):
    """The orbit's (r̂ x, y, z, r) at t when the gravity gradient is on (``fr``:
    ``orbit_kernel.frame``), else a placeholder the kicks below do not read."""
    if env[orbit_kernel.ON] != 0.0:
        return orbit_kernel.radial_framed(env, t, fr)
    return 0.0, 0.0, 0.0, 1.0


@inline
def kick_environment_at(q, t, env, moments, m, s, rad):
    """:func:`kick_environment` with the orbit at t given (:func:`orbit_at`), the same
    numbers: a loop evaluating several attitudes at one instant evaluates the orbit once."""
    if env[orbit_kernel.ON] != 0.0:
        gx, gy, gz = orbit_kernel.gravity_gradient_at(q, rad[0], rad[1], rad[2], rad[3], env,
                                                      moments)
        m[0] = m[0] + s * gx
        m[1] = m[1] + s * gy
        m[2] = m[2] + s * gz
    if env[orbit_kernel.MAG_MODEL] != 0.0:
        bx, by, bz = magnetic_kernel.magnetorquer_torque(q, t, env)
        m[0] = m[0] + s * bx
        m[1] = m[1] + s * by
        m[2] = m[2] + s * bz
    if env[orbit_kernel.SRP_ON] != 0.0 or env[orbit_kernel.DRAG_ON] != 0.0:
        fx, fy, fz = facets_kernel.facets_torque(q, t, env)
        m[0] = m[0] + s * fx
        m[1] = m[1] + s * fy
        m[2] = m[2] + s * fz


@jit
def _environment_at(q, t, env, moments, dm, rad):
    """:func:`_environment` with the orbit at t given (:func:`orbit_at`)."""
    kick_environment_at(q, t, env, moments, dm, 1.0, rad)


# they embed the terms' kernels
_environment_at = depends_on(_environment_at, orbit_kernel, magnetic_kernel, facets_kernel)
environment_torque = depends_on(environment_torque, orbit_kernel, magnetic_kernel,
                                facets_kernel)
environment_torque_full = depends_on(environment_torque_full, orbit_kernel, magnetic_kernel,
                                     facets_kernel)
_environment = depends_on(_environment, orbit_kernel, magnetic_kernel, facets_kernel)


@jit
def _normalise(q):
    r = 1.0 / math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    for i in range(4):
        q[i] *= r
