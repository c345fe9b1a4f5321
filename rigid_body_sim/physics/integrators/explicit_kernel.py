"""The explicit Runge–Kutta methods' compiled loops (``explicit.py``'s classes), in the
conventions of ``dynamics_kernel``.
Each loop takes ``t0`` (the time of its first step, s) and ``env`` (the orbit's element
array, ``orbit.kernel``, or None for the free body): the environment's torque is a term of
the right-hand side, evaluated at each stage's instant.
"""
import math

import numpy as np

from .. import dynamics_kernel
from ..dynamics_kernel import (_environment, _environment_at, _finite, _normalise, _rates,
                              orbit_at, rates)
from ..jit import COMPILED, depends_on, inline, jit
from ..environment import facets_kernel, magnetic_kernel
from ..orbit import kernel as orbit_kernel


@jit
def euler_run(q, m, h, n, moments, tau, model, coefficient, t0, env):
    """n explicit Euler steps (q renormalised); first non-finite step or -1."""
    return euler_steps(q, m, h, n, moments, tau, model, coefficient, np.empty((2, 4)), t0, env)


@jit
def euler_steps(q, m, h, n, moments, tau, model, coefficient, scratch, t0, env):
    """euler_run with caller-owned scratch (2, 4): no allocation per call, for callers
    that run many short stretches (the engine's compiled closed loop)."""
    dq = scratch[0]
    dm = scratch[1, :3]
    for k in range(n):
        _rates(q, m, moments, tau, model, coefficient, dq, dm)
        if env is not None:
            _environment(q, t0 + k * h, env, moments, dm)
        for i in range(4):
            q[i] += h * dq[i]
        for i in range(3):
            m[i] += h * dm[i]
        _normalise(q)
        if not _finite(q, m):
            return k
    return -1


@jit
def rk4_run(q, m, h, n, moments, tau, model, coefficient, t0, env):
    """n classical RK4 steps (q renormalised after each); first non-finite step or -1."""
    return rk4_steps(q, m, h, n, moments, tau, model, coefficient, np.empty((10, 4)), t0, env)


@jit
def rk4_steps(q, m, h, n, moments, tau, model, coefficient, scratch, t0, env):
    """rk4_run with caller-owned scratch (10, 4): no allocation per call (see euler_steps).
    The orbit is evaluated once per instant (stages 2 and 3 share t + h/2) and its frame
    once per call (``orbit_kernel.frame``): the same numbers, ~1/3 less work a step."""
    k1q, k2q, k3q, k4q, qs = scratch[0], scratch[1], scratch[2], scratch[3], scratch[4]
    k1m, k2m, k3m, k4m = scratch[5, :3], scratch[6, :3], scratch[7, :3], scratch[8, :3]
    ms = scratch[9, :3]
    if env is not None:
        fr = orbit_kernel.frame(env, t0)
    for k in range(n):
        t = t0 + k * h
        _rates(q, m, moments, tau, model, coefficient, k1q, k1m)
        if env is not None:
            _environment_at(q, t, env, moments, k1m, orbit_at(env, t, fr))
        for i in range(4):
            qs[i] = q[i] + 0.5 * h * k1q[i]
        for i in range(3):
            ms[i] = m[i] + 0.5 * h * k1m[i]
        _rates(qs, ms, moments, tau, model, coefficient, k2q, k2m)
        if env is not None:
            mid = orbit_at(env, t + 0.5 * h, fr)
            _environment_at(qs, t + 0.5 * h, env, moments, k2m, mid)
        for i in range(4):
            qs[i] = q[i] + 0.5 * h * k2q[i]
        for i in range(3):
            ms[i] = m[i] + 0.5 * h * k2m[i]
        _rates(qs, ms, moments, tau, model, coefficient, k3q, k3m)
        if env is not None:
            _environment_at(qs, t + 0.5 * h, env, moments, k3m, mid)
        for i in range(4):
            qs[i] = q[i] + h * k3q[i]
        for i in range(3):
            ms[i] = m[i] + h * k3m[i]
        _rates(qs, ms, moments, tau, model, coefficient, k4q, k4m)
        if env is not None:
            _environment_at(qs, t + h, env, moments, k4m, orbit_at(env, t + h, fr))
        for i in range(4):
            q[i] += (h / 6.0) * (k1q[i] + 2.0 * k2q[i] + 2.0 * k3q[i] + k4q[i])
        for i in range(3):
            m[i] += (h / 6.0) * (k1m[i] + 2.0 * k2m[i] + 2.0 * k3m[i] + k4m[i])
        _normalise(q)
        if not _finite(q, m):
            return k
    return -1


@inline
def rk4_free_steps(q, m, h, n, moments, tau, model, coefficient):
    """rk4_steps for the free body (env None), its stages in numbers, not scratch views:
    the same operations in the same order, so the same numbers to the bit (test_samples),
    and the same state left on a failing step. Inlined into the closed loop's samples
    (sample_kernel), where a sample between steps runs it twice: the ten views made per
    call cost ~0.1 µs there, a step's whole cost. Returns the first non-finite step or -1."""
    i0, i1, i2 = moments[0], moments[1], moments[2]
    t0, t1, t2 = tau[0], tau[1], tau[2]
    x, y, z, w = q[0], q[1], q[2], q[3]
    m0, m1, m2 = m[0], m[1], m[2]
    failed = -1
    for k in range(n):
        a = rates(x, y, z, w, m0, m1, m2, i0, i1, i2, t0, t1, t2, model, coefficient)
        x, y, z, w, m0, m1, m2, finite = rk4_free_step(x, y, z, w, m0, m1, m2, a, h, i0, i1,
                                                       i2, t0, t1, t2, model, coefficient)
        if not finite:
            failed = k
            break
    q[0], q[1], q[2], q[3] = x, y, z, w
    m[0], m[1], m[2] = m0, m1, m2
    return failed


@inline
def rk4_free_step(x, y, z, w, m0, m1, m2, a, h, i0, i1, i2, t0, t1, t2, model, coefficient):
    """One rk4 step of the free body from the state (x, y, z, w; m0, m1, m2) whose rates a
    (its first stage, ``rates``' 7 numbers) the caller has: the new state, q renormalised
    (rk4_steps' operations in its order), and whether it is finite (``_finite``). A caller
    that needs the rates of a step's ends (the samples' Hermite, sample_steps) takes them
    from the stages instead of evaluating them again."""
    b = rates(x + 0.5 * h * a[0], y + 0.5 * h * a[1], z + 0.5 * h * a[2],
              w + 0.5 * h * a[3], m0 + 0.5 * h * a[4], m1 + 0.5 * h * a[5],
              m2 + 0.5 * h * a[6], i0, i1, i2, t0, t1, t2, model, coefficient)
    c = rates(x + 0.5 * h * b[0], y + 0.5 * h * b[1], z + 0.5 * h * b[2],
              w + 0.5 * h * b[3], m0 + 0.5 * h * b[4], m1 + 0.5 * h * b[5],
              m2 + 0.5 * h * b[6], i0, i1, i2, t0, t1, t2, model, coefficient)
    d = rates(x + h * c[0], y + h * c[1], z + h * c[2], w + h * c[3],
              m0 + h * c[4], m1 + h * c[5], m2 + h * c[6], i0, i1, i2, t0, t1, t2,
              model, coefficient)
    x += (h / 6.0) * (a[0] + 2.0 * b[0] + 2.0 * c[0] + d[0])
    y += (h / 6.0) * (a[1] + 2.0 * b[1] + 2.0 * c[1] + d[1])
    z += (h / 6.0) * (a[2] + 2.0 * b[2] + 2.0 * c[2] + d[2])
    w += (h / 6.0) * (a[3] + 2.0 * b[3] + 2.0 * c[3] + d[3])
    m0 += (h / 6.0) * (a[4] + 2.0 * b[4] + 2.0 * c[4] + d[4])
    m1 += (h / 6.0) * (a[5] + 2.0 * b[5] + 2.0 * c[5] + d[5])
    m2 += (h / 6.0) * (a[6] + 2.0 * b[6] + 2.0 * c[6] + d[6])
    r = 1.0 / math.sqrt(x * x + y * y + z * z + w * w)  # _normalise
    x, y, z, w = x * r, y * r, z * r, w * r
    s = x + y + z + w + m0 + m1 + m2  # x − x is 0 for a finite x, NaN otherwise
    return x, y, z, w, m0, m1, m2, s - s == 0.0


@inline
def rk4_free_end(q, m, moments, tau, model, coefficient, herm, at):
    """sample_kernel._end for the free body (env None), its rates in numbers (no views of
    herm): (q, m, dq, dm) into herm[at:at + 4], the same numbers (see dynamics_kernel.rates)."""
    dq0, dq1, dq2, dq3, dm0, dm1, dm2 = rates(
        q[0], q[1], q[2], q[3], m[0], m[1], m[2], moments[0], moments[1], moments[2],
        tau[0], tau[1], tau[2], model, coefficient)
    herm[at, 0], herm[at, 1], herm[at, 2], herm[at, 3] = q[0], q[1], q[2], q[3]
    herm[at + 1, 0], herm[at + 1, 1], herm[at + 1, 2] = m[0], m[1], m[2]
    herm[at + 2, 0], herm[at + 2, 1], herm[at + 2, 2], herm[at + 2, 3] = dq0, dq1, dq2, dq3
    herm[at + 3, 0], herm[at + 3, 1], herm[at + 3, 2] = dm0, dm1, dm2


@jit
def hermite_end(q, m, moments, tau_p, model, coefficient, t, env, herm, at):
    """The state and its derivative into herm[at:at + 4] = (q, m, dq, dm): one evaluation
    (sample_kernel.segment's step ends, any right-hand side)."""
    for i in range(4):
        herm[at, i] = q[i]
    for i in range(3):
        herm[at + 1, i] = m[i]
        herm[at + 3, i] = 0.0
    _rates(herm[at], herm[at + 1, :3], moments, tau_p, model, coefficient, herm[at + 2],
           herm[at + 3, :3])
    if env is not None:
        _environment(herm[at], t, env, moments, herm[at + 3, :3])


@inline
def hermite_lanes(herm, h, count, scratch):
    """The cubic Hermite interpolant of the step whose ends herm (8, 4) holds (q0, m0, dq0,
    dm0, q1, m1, dq1, dm1) at the θ of scratch[0, :count]: q and m in rows 5-11, |q| in row
    12, with the weights a0 = 2θ³ − 3θ² + 1, a1 = 1 − a0, b0 = (θ³ − 2θ² + θ)h, b1 = (θ³ −
    θ²)h. One loop over the lanes (independent: the compiler runs several to an
    instruction; sample_steps.rows_in_lanes, the samples' floor), the ends in numbers: a
    loop per operation (weights, then each component) cost ~0.1 µs a step to set up, ~15
    ns a sample at 12 samples a step where this loop takes ~12 (2026-11-28)."""
    y00, y01, y02, y03 = herm[0, 0], herm[0, 1], herm[0, 2], herm[0, 3]
    y04, y05, y06 = herm[1, 0], herm[1, 1], herm[1, 2]
    d00, d01, d02, d03 = herm[2, 0], herm[2, 1], herm[2, 2], herm[2, 3]
    d04, d05, d06 = herm[3, 0], herm[3, 1], herm[3, 2]
    y10, y11, y12, y13 = herm[4, 0], herm[4, 1], herm[4, 2], herm[4, 3]
    y14, y15, y16 = herm[5, 0], herm[5, 1], herm[5, 2]
    d10, d11, d12, d13 = herm[6, 0], herm[6, 1], herm[6, 2], herm[6, 3]
    d14, d15, d16 = herm[7, 0], herm[7, 1], herm[7, 2]
    for c in range(count):
        theta = scratch[0, c]
        t2 = theta * theta
        t3 = t2 * theta
        a0 = 2.0 * t3 - 3.0 * t2 + 1.0
        a1, b0, b1 = 1.0 - a0, (t3 - 2.0 * t2 + theta) * h, (t3 - t2) * h
        v0 = a0 * y00 + b0 * d00 + a1 * y10 + b1 * d10
        v1 = a0 * y01 + b0 * d01 + a1 * y11 + b1 * d11
        v2 = a0 * y02 + b0 * d02 + a1 * y12 + b1 * d12
        v3 = a0 * y03 + b0 * d03 + a1 * y13 + b1 * d13
        scratch[5, c], scratch[6, c], scratch[7, c], scratch[8, c] = v0, v1, v2, v3
        scratch[9, c] = a0 * y04 + b0 * d04 + a1 * y14 + b1 * d14
        scratch[10, c] = a0 * y05 + b0 * d05 + a1 * y15 + b1 * d15
        scratch[11, c] = a0 * y06 + b0 * d06 + a1 * y16 + b1 * d16
        scratch[12, c] = math.sqrt(0.0 + v0 * v0 + v1 * v1 + v2 * v2 + v3 * v3)


# they call the shared rates of another file (see jit.depends_on)
for _kernel in (euler_run, euler_steps, rk4_run, rk4_steps, hermite_end):
    depends_on(_kernel, dynamics_kernel, orbit_kernel, magnetic_kernel, facets_kernel)


def warm():
    """Compile (or load from the cache) the Runge–Kutta loops."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    m = np.array([0.1, 1.0, 0.2])
    moments = np.array([1.0, 2.0, 3.0])
    rk4_run(q, m, 1e-3, 1, moments, np.zeros(3), 0, 0.0, 0.0, None)
    euler_run(q, m, 1e-3, 1, moments, np.zeros(3), 0, 0.0, 0.0, None)
    return COMPILED
