"""Compiled adaptive Dormand–Prince 8(5,3) (DOP853) for one body: the method and its steps.

The same method as scipy's ``solve_ivp(method='DOP853')`` — its tableau (imported from
scipy, so the coefficients are the same numbers), its error estimator (the 5th and 3rd
order combination), step-size control (safety 0.9, factors 0.2–10, exponent −1/8) and
initial step selection — so on the same right-hand side it takes the same steps, to
round-off. The right-hand side is the rigid body's ``dynamics_kernel._rates`` on the packed state
y = (q (4), m (3)), with the torque held over the call.

:func:`integrate` is solve_ivp over one interval (landing on its end by clipping the last
step); :func:`attempt` is one accepted step. The integrator runs across output steps with
:mod:`dop853_dense` instead: natural steps, outputs from the dense output, no restarts.

Plain numerical Python on float arrays, compiled by ``jit.jit``; with
NUMBA_DISABLE_JIT=1 the same source runs as ordinary Python (the tests compare the two).
The kernels embed ``dynamics_kernel._rates``, so their disk cache is keyed on
dynamics_kernel.py too.
"""
import math

import numpy as np

from .. import dynamics_kernel
from .dop853_tableau import coefficients as _coefficients
from ..dynamics_kernel import _environment, _finite, _rates
from ..jit import COMPILED, depends_on, jit
from ..environment import facets_kernel, magnetic_kernel
from ..orbit import kernel as orbit_kernel

N_STAGES = _coefficients.N_STAGES  # 12; stage 0 is the FSAL derivative, so 11 new + f_new
# (A, B, E3, E5): scipy's arrays, contiguous copies so numba sees plain C arrays.
TABLEAU = (np.ascontiguousarray(_coefficients.A[:N_STAGES, :N_STAGES]),
           np.ascontiguousarray(_coefficients.B),
           np.ascontiguousarray(_coefficients.E3),
           np.ascontiguousarray(_coefficients.E5))
# The nodes C: the stages' instants, which only the environment's torques (functions of
# time) read; a module constant, compiled in.
NODES = np.ascontiguousarray(_coefficients.C[:N_STAGES])

# scipy.integrate._ivp.rk: SAFETY, MIN_FACTOR, MAX_FACTOR; error estimator order 7.
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
ERROR_EXPONENT = -1.0 / 8.0
DIM = 7  # q (4) + m (3)

OK, NON_FINITE, STEP_UNDERFLOW = 0, 1, 2
REASONS = {NON_FINITE: 'state became non-finite (the method diverged)',
           STEP_UNDERFLOW: 'step size fell below 10 ulps of t (tolerance unreachable: '
                           'too stiff or singular)'}


@jit
def _rhs(y, out, moments, tau, model, coefficient):
    """out = dy/dt at y, both (7,) = (q, m), without the environment's torque."""
    _rates(y[:4], y[4:], moments, tau, model, coefficient, out[:4], out[4:])


@jit
def _rhs_environment(y, out, t, env, moments):
    """out[4:] += the environment's torque at y and time t (callers test env for None, so
    the free body's code is what it was: see dynamics_kernel)."""
    _environment(y[:4], t, env, moments, out[4:])


@jit
def _initial_step(y, f, span, moments, tau, model, coefficient, rtol, atol, y1, f1, t, env):
    """scipy's select_initial_step (Hairer–Nørsett–Wanner II.4) for an order-7 error
    estimate, over an interval of ``span`` from time t; one evaluation."""
    d0 = 0.0
    d1 = 0.0
    for i in range(DIM):
        scale = atol + abs(y[i]) * rtol
        d0 += (y[i] / scale) ** 2
        d1 += (f[i] / scale) ** 2
    root_n = math.sqrt(DIM)
    d0 = math.sqrt(d0) / root_n
    d1 = math.sqrt(d1) / root_n
    h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
    h0 = min(h0, span)
    for i in range(DIM):
        y1[i] = y[i] + h0 * f[i]
    _rhs(y1, f1, moments, tau, model, coefficient)
    if env is not None:
        _rhs_environment(y1, f1, t + h0, env, moments)
    if h0 == 0.0:  # |f| overflowed the scale: no guess; the caller starts at its floor
        return 0.0
    d2 = 0.0
    for i in range(DIM):
        scale = atol + abs(y[i]) * rtol
        d2 += ((f1[i] - f[i]) / scale) ** 2
    d2 = math.sqrt(d2) / root_n / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / 8.0)
    return min(100.0 * h0, min(h1, span))


@jit
def _rk_step(y, h, K, y_stage, y_new, moments, tau, model, coefficient, A, B, t, env):
    """One DOP853 step of h from y at time t, K[0] = f(y) given: stages into K[1:12], the
    8th-order solution into y_new and f(y_new) into K[12] (FSAL). 12 evaluations."""
    for s in range(1, N_STAGES):
        # j outer, i inner: seven independent sums (same order per component as j inner)
        for i in range(DIM):
            y_stage[i] = 0.0
        for j in range(s):
            a = A[s, j]
            for i in range(DIM):
                y_stage[i] += K[j, i] * a
        for i in range(DIM):
            y_stage[i] = y[i] + y_stage[i] * h
        _rhs(y_stage, K[s], moments, tau, model, coefficient)
        if env is not None:
            _rhs_environment(y_stage, K[s], t + NODES[s] * h, env, moments)
    for i in range(DIM):
        y_new[i] = 0.0
    for j in range(N_STAGES):
        b = B[j]
        for i in range(DIM):
            y_new[i] += K[j, i] * b
    for i in range(DIM):
        y_new[i] = y[i] + h * y_new[i]
    _rhs(y_new, K[N_STAGES], moments, tau, model, coefficient)
    if env is not None:
        _rhs_environment(y_new, K[N_STAGES], t + h, env, moments)


@jit
def _error_norm(y, y_new, h, K, rtol, atol, E3, E5):
    """scipy's DOP853 error norm: |h|·‖e5‖² / √((‖e5‖² + 0.01‖e3‖²)·n), weighted by
    atol + rtol·max(|y|, |y_new|)."""
    err5 = 0.0
    err3 = 0.0
    for i in range(DIM):
        scale = atol + max(abs(y[i]), abs(y_new[i])) * rtol
        e5 = 0.0
        e3 = 0.0
        for j in range(N_STAGES + 1):
            e5 += K[j, i] * E5[j]
            e3 += K[j, i] * E3[j]
        err5 += (e5 / scale) ** 2
        err3 += (e3 / scale) ** 2
    if err5 == 0.0 and err3 == 0.0:
        return 0.0
    return abs(h) * err5 / math.sqrt((err5 + 0.01 * err3) * DIM)


@jit
def attempt(y, t, t_floor, t_bound, h_abs, K, y_stage, y_new, moments, tau, model,
            coefficient, rtol, atol, A, B, E3, E5, t_abs, env):
    """One accepted step from (t, y), K[0] = f(y) given, of the step ``h_abs`` or less
    (``t_abs``: the absolute time of y, where the environment's torques are evaluated)
    (rejections shrink it; a step past ``t_bound`` is clipped to it, as scipy does). The
    step is rounded as t + h − t, and fails below 10 ulps of ``t_floor``.

    Returns (status, t reached, step taken — or the failing step —, step proposed next,
    evaluations); on OK y_new and K[1:13] hold the step (K[12] = f(y_new))."""
    nfev = 0
    # scipy's floor: 10 ulps of t (local time here, so never coarser than scipy's)
    min_step = 10.0 * (np.nextafter(t_floor, np.inf) - t_floor)
    if h_abs < min_step:
        h_abs = min_step
    rejected = False
    while True:
        if h_abs < min_step:
            return STEP_UNDERFLOW, t, h_abs, h_abs, nfev
        t_new = t + h_abs
        clipped = t_new > t_bound
        if clipped:
            t_new = t_bound  # land on the end exactly
        h = t_new - t  # the step actually taken, rounded as scipy rounds it
        _rk_step(y, h, K, y_stage, y_new, moments, tau, model, coefficient, A, B, t_abs, env)
        nfev += N_STAGES
        err = _error_norm(y, y_new, h, K, rtol, atol, E3, E5)
        if err < 1.0:
            if err == 0.0:
                factor = MAX_FACTOR
            else:
                factor = min(MAX_FACTOR, SAFETY * err ** ERROR_EXPONENT)
            if rejected:
                factor = min(1.0, factor)
            if clipped:
                # The next call should resume at the step this one interrupted, not at
                # ≤ 10× a possibly tiny clipped step; the clipped step's own (uncapped)
                # proposal still wins if it asks for less.
                if err > 0.0:
                    h_abs = min(h_abs, h * SAFETY * err ** ERROR_EXPONENT)
            else:
                h_abs = h * factor
            return OK, t_new, h, h_abs, nfev
        # rejected; a NaN error (overflow inside the step) shrinks by the most, as in scipy
        factor = SAFETY * err ** ERROR_EXPONENT if err == err else MIN_FACTOR
        h_abs = h * max(MIN_FACTOR, factor)
        rejected = True


@jit
def integrate(y, f, span, h_abs, fresh, moments, tau, model, coefficient, rtol, atol,
              A, B, E3, E5, t0, env):
    """solve_ivp over (0, span) from time ``t0``: advance y (7,) in place to ``span``
    exactly, clipping the
    last step; f holds dy/dt at y (recomputed first if ``fresh``) and on return at the new
    y. ``h_abs`` > 0: the step to try first; otherwise scipy's initial step selection
    (over the interval ``span``) picks it. The integrator uses :mod:`dop853_dense`
    instead, which never clips; this is the one-interval method the tests hold to scipy.

    Returns (status, t reached, step proposed next — or the failing step —, evaluations)."""
    nfev = 0
    K = np.empty((N_STAGES + 1, DIM))
    y_stage = np.empty(DIM)
    y_new = np.empty(DIM)
    if fresh:
        _rhs(y, f, moments, tau, model, coefficient)
        if env is not None:
            _rhs_environment(y, f, t0, env, moments)
        nfev += 1
    if not (_finite(y[:4], y[4:]) and _finite(f[:4], f[4:])):
        return NON_FINITE, 0.0, h_abs, nfev
    if not h_abs > 0.0:
        h_abs = _initial_step(y, f, span, moments, tau, model, coefficient, rtol, atol,
                              y_stage, y_new, t0, env)
        nfev += 1
    t = 0.0
    while t < span:
        for i in range(DIM):
            K[0, i] = f[i]
        status, t_new, h, h_abs, n = attempt(y, t, t, span, h_abs, K, y_stage, y_new, moments,
                                             tau, model, coefficient, rtol, atol, A, B, E3, E5,
                                             t0 + t, env)
        nfev += n
        if status != OK:
            return status, t, h, nfev
        t = t_new
        for i in range(DIM):
            y[i] = y_new[i]
            f[i] = K[N_STAGES, i]
        if not _finite(y[:4], y[4:]):
            return NON_FINITE, t, h, nfev
    return OK, t, h_abs, nfev


# numba's disk cache checks only this file; each of these embeds dynamics_kernel._rates or _finite
for _kernel in (_rhs, _rhs_environment, _initial_step, _rk_step, attempt, integrate):
    depends_on(_kernel, dynamics_kernel, orbit_kernel, magnetic_kernel, facets_kernel)


def warm():
    """Compile (or load from the cache) the kernel on representative arguments."""
    y = np.array([0.0, 0.0, 0.0, 1.0, 0.1, 1.0, 0.2])
    integrate(y, np.empty(DIM), 1e-3, 0.0, True, np.array([1.0, 2.0, 3.0]), np.zeros(3), 1,
              0.1, 1e-10, 1e-12, *TABLEAU, 0.0, None)
    return COMPILED
