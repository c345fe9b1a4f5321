"""DOP853 across output steps with dense output: natural steps, outputs interpolated.

:func:`advance` answers one output step (event to event) of the integrator. It takes
DOP853's own steps (:func:`dop853_kernel.attempt`, scipy's tableau and step control) and
never clips one to land on an output time: when the requested time lies inside an
accepted step, the state there comes from DOP853's 7th-order continuous extension,
built exactly as scipy's ``DOP853._dense_output_impl`` builds it (3 extra stages with
``A_EXTRA``, then F from the step's y, f and the ``D`` matrix; coefficients imported from
scipy) and evaluated as ``Dop853DenseOutput`` does. So a run sampled at any number of
times costs the steps of the unsampled run plus 3 evaluations per step that has an
output inside it (the extra stages, built once per step), as
``solve_ivp(method='DOP853', t_eval=times)`` costs, and gives its values to round-off.

The step in progress lives in arrays the caller owns, so the next call, when it
continues from the state returned last (same q, m, torque), is answered by interpolation
if it ends inside the same step, else steps on from the step's end. A call ending exactly
on a step's end returns that step's state itself, and the next call steps on from it. A
torque change is a discontinuity: the integration restarts from the returned (raw,
interpolated) state at that time, keeping the proposed step; any other state starts
afresh (initial step selection, as solve_ivp would). q is returned normalised; the raw y
stays internal.

Local time: positions are measured from the start of the step in progress (``clock``);
the held torque is constant over a call. Absolute time enters only through the
environment's torques (``env``): the call's start is at ``t0``, so the step in progress
ends at t0 + (its length − the last output's position), and every stage is evaluated at
its own instant.

Measured (CPU of the run loop; evaluations = the integrator's nfev), landing on every
output → dense output:

* explorer1 (double-bracket, 10 rev/s, natural steps ~10 ms), 6900 s,
  ``rigid-body-sim run explorer1 --integrator dop853 --set publish_rate=100``:
  11,971,682 → 7,879,805 evaluations, 5.94 → 5.56 CPU s (the 690,000 calls' overhead
  dominates); at the scene's 1 Hz: 6,619,814 → 6,595,406, 0.30 → 0.32 s (steps far
  shorter than the sample period: nothing to gain). Its final attitude at 1 Hz and at
  100 Hz differed by 4e-4 rad when landing (the clipped steps change the trajectory);
  now by 2e-12.
* tennis_racket with viscous damping 0.01 N·m·s, 600 s at 100 Hz (~1 s steps):
  720,014 → 6,944 evaluations, 0.51 → 0.44 CPU s.
* one call inside a step (interpolation only): 2.3 µs, of which ~all is numba's dispatch.
"""
import math

import numpy as np
from numpy.lib.stride_tricks import as_strided

from .. import dynamics_kernel
from .dop853_tableau import coefficients as _coefficients
from . import dop853_kernel
from .dop853_kernel import (DIM, N_STAGES, NON_FINITE, OK, _initial_step, _rhs,
                            _rhs_environment, attempt)
from ..dynamics_kernel import _finite
from ..jit import COMPILED, depends_on, inline, jit
from ..environment import facets_kernel, magnetic_kernel
from ..orbit import kernel as orbit_kernel

N_EXTENDED = _coefficients.N_STAGES_EXTENDED  # 16: the 13 of a step + 3 extra stages
POWER = _coefficients.INTERPOLATOR_POWER  # 7 rows of F
# (A_EXTRA, D): the extra stages' rows of scipy's A and its interpolant matrix D (4, 16).
EXTENSION = (np.ascontiguousarray(_coefficients.A[N_STAGES + 1:]),
             np.ascontiguousarray(_coefficients.D))
# the extra stages' nodes (their instants: read by the environment's torques only)
C_EXTRA = np.ascontiguousarray(_coefficients.C[N_STAGES + 1:])
A_EXTRA, D = EXTENSION
A, B, E3, E5 = dop853_kernel.TABLEAU  # constants compiled into advance: fewer arguments
# the stages each row of A_EXTRA and D weighs (their other coefficients are exact zeros:
# stages 2-6 enter neither), in order: _build's sums skip the zero terms, whose products
# add ±0 to a finite sum (an accepted step's stages are finite), the same values with
# 24 of 42 products for the extra stages and 48 of 64 for F, per component; the build,
# once a step holding a sample, cost as much as the step at ~3 samples a step
_EXTRA_USED = np.array([np.flatnonzero(A_EXTRA[e, :N_STAGES + 1 + e])
                        for e in range(len(A_EXTRA))])
_D_USED = np.flatnonzero(np.any(D != 0.0, axis=0))
# The memory, one flat array (each array argument costs numba's dispatch ~0.1 µs, and a
# call's whole work can be 1 µs): y, f, y_old (7 each), K (16·7), F (7·7), clock (4):
# pos (the last output, from the step's start), h (its length), built, h_abs; last (17):
# q (4), m (3) and torque (3) of the last call, raw y it returned (7); then scratch (2·7)
# for a step's stage and its result: an array allocated in a call costs ~50 ns, and at
# ~3 samples a step advance is called once a step (two of them were ~100 ns a sample)
_Y, _F_, _Y_OLD, _K = 0, DIM, 2 * DIM, 3 * DIM
_FF = _K + N_EXTENDED * DIM
_CLOCK = _FF + POWER * DIM
_LAST = _CLOCK + 4
_SCRATCH = _LAST + 17
MEMORY = _SCRATCH + 2 * DIM


@inline
def views(memory):
    """(y, f, y_old, K (16, 7), F (7, 7), clock, last): views into the flat memory. K and
    F by their strides: numba's reshape calls a helper out of line (~12 ns each, at every
    advance that steps, once a step holding samples), as_strided costs nothing here."""
    row = memory.itemsize * DIM
    return (memory[_Y:_F_], memory[_F_:_Y_OLD], memory[_Y_OLD:_K],
            as_strided(memory[_K:_FF], shape=(N_EXTENDED, DIM),
                       strides=(row, memory.itemsize)),
            as_strided(memory[_FF:_CLOCK], shape=(POWER, DIM),
                       strides=(row, memory.itemsize)), memory[_CLOCK:_LAST],
            memory[_LAST:MEMORY])


@inline
def _build(y_old, y, f, h, K, F, moments, tau, model, coefficient, A_EXTRA, D, t_old, env,
           y_stage):
    """scipy's DOP853._dense_output_impl: the extra stages K[13:16] from the step's K[0:13]
    (K[0] = f(y_old), K[12] = f(y); y_old at time t_old), then F (7, 7). 3 evaluations;
    y_stage (7,): scratch."""
    # each sum in a local (the same terms in the same order as summing into the arrays,
    # which, views of one memory, the compiler must load and store at every term)
    for e in range(N_EXTENDED - N_STAGES - 1):
        s = N_STAGES + 1 + e
        for i in range(DIM):
            acc = 0.0
            for j in _EXTRA_USED[e]:
                acc += K[j, i] * A_EXTRA[e, j]
            y_stage[i] = y_old[i] + acc * h
        _rhs(y_stage, K[s], moments, tau, model, coefficient)
        if env is not None:
            _rhs_environment(y_stage, K[s], t_old + C_EXTRA[e] * h, env, moments)
    for i in range(DIM):
        delta = y[i] - y_old[i]
        F[0, i] = delta
        F[1, i] = h * K[0, i] - delta
        F[2, i] = 2.0 * delta - h * (f[i] + K[0, i])
    for r in range(POWER - 3):
        for i in range(DIM):
            acc = 0.0
            for j in _D_USED:
                acc += K[j, i] * D[r, j]
            F[3 + r, i] = acc * h
    return 3


@inline
def _interpolate(y_old, F, x, out):
    """Dop853DenseOutput at x = (t − t_old)/h: Horner in x and 1 − x, alternately."""
    for i in range(DIM):
        v = 0.0
        for k in range(POWER):
            v += F[POWER - 1 - k, i]
            if k % 2 == 0:
                v *= x
            else:
                v *= 1.0 - x
        out[i] = v + y_old[i]


@inline
def interpolate_lanes(memory, lanes, xs, ys, raw, count):
    """:func:`_interpolate` over ``count`` lanes: lanes[raw + i, k] ← the interpolant of
    the step whose F and y_old ``memory`` holds, at lanes[xs, k] (lanes[ys, k] = 1 − that);
    each lane's arithmetic the scalar one, lanes in one loop that the compiler runs several
    to an instruction (engine.dop853_samples; the samples' floor,
    bench.sampling_floor). Rows by index into the one scratch array, not views of it: a
    view costs its parent's reference count (~2-5 ns each, 7-9 a call, a call or two a
    step holding samples)."""
    for i in range(DIM):
        y_old = memory[_Y_OLD + i]
        f0 = memory[_FF + (POWER - 1) * DIM + i]
        f1 = memory[_FF + (POWER - 2) * DIM + i]
        f2 = memory[_FF + (POWER - 3) * DIM + i]
        f3 = memory[_FF + (POWER - 4) * DIM + i]
        f4 = memory[_FF + (POWER - 5) * DIM + i]
        f5 = memory[_FF + (POWER - 6) * DIM + i]
        f6 = memory[_FF + (POWER - 7) * DIM + i]
        r = raw + i
        for k in range(count):
            x = lanes[xs, k]
            y = lanes[ys, k]
            # _interpolate's operations in its order (0.0 + f0 included: the same bits,
            # signed zeros too; no fastmath, so nothing is fused or reordered)
            v = ((((((0.0 + f0) * x + f1) * y + f2) * x + f3) * y + f4) * x + f5) * y
            lanes[r, k] = (v + f6) * x + y_old


@jit
def advance(q, m, span, tau, memory, moments, model, coefficient, rtol, atol, t0, env):
    """One output step of ``span`` s from time ``t0`` for an integrator that keeps its
    memory between calls (``env``: the orbit's element array, ``orbit.kernel``).

    q (4,), m (3,): the state to advance, overwritten with the result (q normalised).
    ``memory`` (MEMORY,), the caller's (zero it to start afresh; :func:`views` names its
    parts): y, f (7,) the raw state at the end of the step in progress and its
    derivative; y_old (7,) the state at its start; K (16, 7) its stages; F (7, 7) its
    interpolant; clock (4,) = (pos, h, built, h_abs): the last output's position in the
    step, the step's length, whether F is built, the step proposed next (0: no memory);
    last (17,) the q, m and torque of the last call and the raw state it returned.

    Returns (status, t from the call's start reached, step proposed next — or the failing
    step —, evaluations)."""
    if _interpolated(q, m, span, tau, memory):  # inside the step, its F built: nothing else
        return OK, span, memory[_CLOCK + 3], 0
    y, f, y_old, K, F, clock, last = views(memory)
    nfev = 0
    h_abs = clock[3]
    warm = h_abs > 0.0
    for i in range(4):
        warm = warm and q[i] == last[i]
    for i in range(3):
        warm = warm and m[i] == last[4 + i]
    same_torque = tau[0] == last[7] and tau[1] == last[8] and tau[2] == last[9]
    if not (warm and same_torque):
        if warm:  # a torque change: restart where the last call ended, keeping the step
            for i in range(DIM):
                y[i] = last[10 + i]
        else:  # another state: afresh
            for i in range(4):
                y[i] = q[i]
            for i in range(3):
                y[4 + i] = m[i]
            h_abs = 0.0
        clock[0] = 0.0  # no step in progress: the current point is y
        clock[1] = 0.0
        _rhs(y, f, moments, tau, model, coefficient)
        if env is not None:
            _rhs_environment(y, f, t0, env, moments)
        nfev += 1
        if not (_finite(y[:4], y[4:]) and _finite(f[:4], f[4:])):
            clock[3] = 0.0  # no memory left: the next call starts afresh
            return NON_FINITE, 0.0, h_abs, nfev
        if h_abs == 0.0:  # no interval to cap the guess: the integration has no set end
            h_abs = _initial_step(y, f, np.inf, moments, tau, model, coefficient, rtol, atol,
                                  y_old, F[0], t0, env)
            nfev += 1
    target = clock[0] + span  # the output, from the step's start
    h_step = clock[1]
    base = h_step - clock[0]  # where y (the step's end) lies, from the call's start
    y_stage = memory[_SCRATCH:_SCRATCH + DIM]
    y_new = memory[_SCRATCH + DIM:MEMORY]
    while target > h_step:  # not inside this step: step on from its end
        target -= h_step
        status, h, h_abs, n = step_on(y, f, y_old, K, y_stage, y_new, h_abs, base, moments,
                                      tau, model, coefficient, rtol, atol, t0 + base, env)
        nfev += n
        if status != OK:
            clock[3] = 0.0
            return status, base, h, nfev
        h_step = h
        base += h
        clock[2] = 0.0  # F belongs to the previous step
        if not _finite(y[:4], y[4:]):
            clock[3] = 0.0
            return NON_FINITE, base, h, nfev
    out = last[10:]
    if target == h_step:  # on the step's end: its own state (scipy's t_eval takes sol(t))
        for i in range(DIM):
            out[i] = y[i]
    else:
        if clock[2] == 0.0:  # the first output inside this step: the extra stages, once
            nfev += _build(y_old, y, f, h_step, K, F, moments, tau, model, coefficient,
                           A_EXTRA, D, t0 + base - h_step, env, y_stage)
            clock[2] = 1.0
        _interpolate(y_old, F, target / h_step, out)
    clock[0] = target
    clock[1] = h_step
    clock[3] = h_abs
    norm = math.sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3])
    for i in range(4):
        q[i] = out[i] / norm
        last[i] = q[i]
    for i in range(3):
        m[i] = out[4 + i]
        last[4 + i] = m[i]
        last[7 + i] = tau[i]
    if not _finite(q, m):  # q fell to zero, or the interpolant overflowed
        clock[3] = 0.0
        return NON_FINITE, span, h_abs, nfev
    return OK, span, h_abs, nfev


@inline
def step_on(y, f, y_old, K, y_stage, y_new, h_abs, base, moments, tau, model, coefficient,
            rtol, atol, t_abs, env):
    """DOP853's next accepted step from y, the end of the step in progress (``base`` s
    after the last output, at ``t_abs``), as :func:`advance` and engine.dop853_samples
    take it: K[0] ← f, then y_old ← y, y ← the new state and f ← its derivative. Each
    step from local time 0: h exactly h_abs, so the steps (and the trajectory) do not
    depend on where the outputs fall; the floor is from the last output. Returns (status,
    the step taken — or the failing one —, the step proposed next, evaluations); on a
    failure only K and the scratch (y_stage, y_new) are written."""
    for i in range(DIM):
        K[0, i] = f[i]
    status, _, h, h_abs, n = attempt(y, 0.0, base, np.inf, h_abs, K, y_stage, y_new, moments,
                                     tau, model, coefficient, rtol, atol, A, B, E3, E5, t_abs,
                                     env)
    if status == OK:
        for i in range(DIM):
            y_old[i] = y[i]
            y[i] = y_new[i]
            f[i] = K[N_STAGES, i]
    return status, h, h_abs, n


@inline
def _interpolated(q, m, span, tau, memory):
    """:func:`advance` where the call continues from its last output with the same torque
    and ends strictly inside the step in progress, whose interpolant is built: the same
    operations on the flat memory (no views, no scratch arrays: ~0.35 µs a call, 100
    outputs a step at 100 samples/s). False, with nothing written, otherwise. A result
    that is not finite is the slow path's to report."""
    if memory[_CLOCK + 3] <= 0.0 or memory[_CLOCK + 2] == 0.0:
        return False
    last = _LAST
    for i in range(4):
        if q[i] != memory[last + i]:
            return False
    for i in range(3):
        if m[i] != memory[last + 4 + i] or tau[i] != memory[last + 7 + i]:
            return False
    target = memory[_CLOCK] + span
    h_step = memory[_CLOCK + 1]
    if not target < h_step:
        return False
    x = target / h_step
    out = last + 10
    for i in range(DIM):  # _interpolate
        v = 0.0
        for k in range(POWER):
            v += memory[_FF + (POWER - 1 - k) * DIM + i]
            if k % 2 == 0:
                v *= x
            else:
                v *= 1.0 - x
        memory[out + i] = v + memory[_Y_OLD + i]
    norm = math.sqrt(memory[out] * memory[out] + memory[out + 1] * memory[out + 1]
                     + memory[out + 2] * memory[out + 2] + memory[out + 3] * memory[out + 3])
    finite = math.isfinite(norm) and norm > 0.0
    for i in range(DIM):
        finite = finite and math.isfinite(memory[out + i])
    if not finite:
        return False
    memory[_CLOCK] = target
    for i in range(4):
        q[i] = memory[out + i] / norm
        memory[last + i] = q[i]
    for i in range(3):
        m[i] = memory[out + 4 + i]
        memory[last + 4 + i] = m[i]
    return True


# numba's disk cache checks only this file; these embed dop853_kernel's and dynamics_kernel's code
# (and advance its tableau, imported from scipy through dop853_kernel)
for _kernel in (views, _build, _interpolate, step_on, _interpolated, advance):
    depends_on(_kernel, dynamics_kernel, dop853_kernel, orbit_kernel, magnetic_kernel,
               facets_kernel)


def warm():
    """Compile (or load from the cache) the kernel on representative arguments."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    m = np.array([0.1, 1.0, 0.2])
    advance(q, m, 1e-3, np.zeros(3), np.zeros(MEMORY), np.array([1.0, 2.0, 3.0]), 1, 0.1,
            1e-10, 1e-12, 0.0, None)
    return COMPILED
