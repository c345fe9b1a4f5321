"""Samples between steps: a fixed-step method's steps do not land on the sample instants.

Landing on every sample shortened the steps to divide the sample period (detumble's
splitting6 at 20 ms became splitting4 at 5 ms at 100 samples/s, 1.6x the CPU). Here the
steps are the method's own, splitting only the intervals between the events that change
the physics (control instants, the end, a command's expiry), and a sample inside a step is
the cubic Hermite interpolant of the step's two ends and their derivatives (two
right-hand-side evaluations per step holding a sample, shared by consecutive steps;
a chunk at a time, :func:`hermite_run`; rk4 on the free body takes them from its stages,
``sample_steps``): its error, ~(hΩ)⁴/384 of the rotation, is
checked against the budget before use (:func:`interpolation_allowed`). The state only
advances by whole steps; interpolated values go to the block, never to the trajectory.

:func:`fixed_steps` runs n steps of any fixed-step method's compiled loop (the closed
loop's dispatch, shared by both paths); :func:`segment` runs one interval between events
with its samples interpolated. Frames and arguments as in ``closed_loop.closed_loop_run``.
All are inlined into it, and rk4's loop and ends in numbers for the free body (a call
between kernels costs ~0.1 µs of reference counts for these ~20 arrays and views).
"""
import math

import numpy as np

from ..physics import dynamics_kernel
from ..physics.integrators import (dop853_dense, dop853_kernel, exact_flow_kernel,
                                   explicit_kernel, splitting_kernel)
from ..physics.exact.grid_kernel import grid_instants  # noqa: F401 (stepping calls it)
from . import sample_steps
# a sample this close to a step's end (in steps) is that end's own state; one a step
from .sample_steps import ON_STEP, hermite_one as _hermite_one, rk4_free_segment
from ..physics.integrators.dop853_dense import _CLOCK, _LAST, DIM
from ..physics.jit import depends_on, inline
from ..physics.environment import facets_kernel, magnetic_kernel
from ..physics.orbit import kernel as orbit_kernel

# the methods' loops (their classes' ``loop_code``)
SPLITTING, RK4, EULER, DOP853, EXACT = range(5)
# samples per pass of the interpolants (hermite_run, dense_samples): scratch of a few rows
# of CHUNK stays in the L1 cache; LANES rows of it (the closed loop allocates them once)
CHUNK = 64
LANES = 16


@inline
def fixed_steps(method, q, m, h, n, weights, split_axes, moments, tau_p, has_tau, model,
                coefficient, inner, scratch, q_flow, m_flow, t0, env):
    """n steps of h of a fixed-step method's loop from (q, m) at t0 (s), in place: (first
    failing step or -1, right-hand-side evaluations)."""
    if method == SPLITTING:
        return splitting_kernel.splitting_run(q, m, h, n, weights, split_axes, moments, tau_p,
                                              has_tau, model, coefficient, inner, t0, env)
    if method == RK4:
        if env is None:  # stages in numbers (_free_end)
            failed = explicit_kernel.rk4_free_steps(q, m, h, n, moments, tau_p, model,
                                                    coefficient)
        else:
            failed = explicit_kernel.rk4_steps(q, m, h, n, moments, tau_p, model, coefficient,
                                               scratch, t0, env)
        return failed, 4 * (n if failed < 0 else failed + 1)
    if method == EXACT:
        return exact_flow_kernel.exact_steps(q, m, h, n, moments, tau_p, has_tau, model,
                                             coefficient, q_flow, m_flow)
    failed = explicit_kernel.euler_steps(q, m, h, n, moments, tau_p, model, coefficient,
                                         scratch, t0, env)
    return failed, n if failed < 0 else failed + 1


# a step's ends for the Hermite: any right-hand side, and the free body's in numbers
_end, _free_end = explicit_kernel.hermite_end, explicit_kernel.rk4_free_end


@inline
def hermite_run(herm, h, a_ns, b_ns, n, span, held, s, sample_period_ns, scratch, t_out,
                q_out, m_out, tau_out, tau_body, row):
    """:func:`segment`'s samples from s on that fall strictly inside the step ``held``
    whose ends herm holds, before b_ns, at most CHUNK: its x, j and theta for each, then
    the cubic Hermite interpolant one operation at a time over them all (explicit_kernel.
    hermite_lanes: independent lanes, which the compiler runs several to an instruction,
    each lane's values the scalar ones; sample by sample this cost ~32 ns a sample), q
    normalised. Then the checks and rows sample by sample. ``scratch`` (13,
    CHUNK). Returns (rows written, False if a sample was not finite: the rows before it
    are written)."""
    count = 0
    while count < CHUNK:
        x = (s + count * sample_period_ns - a_ns) * (n / span)
        j = int(math.floor(x))
        theta = x - j
        if s + count * sample_period_ns >= b_ns or j != held or theta > 1.0 - ON_STEP \
                or theta < ON_STEP:
            break
        scratch[0, count] = theta
        count += 1
    explicit_kernel.hermite_lanes(herm, h, count, scratch)
    for c in range(count):
        r = row + c
        norm = scratch[12, c]
        finite = math.isfinite(norm) and norm > 0.0
        for i in range(3):
            finite = finite and math.isfinite(scratch[9 + i, c])
        if not finite:
            return c, False
        for i in range(4):
            q_out[r, i] = scratch[5 + i, c] / norm
        for i in range(3):
            m_out[r, i] = scratch[9 + i, c]
            tau_out[r, i] = tau_body[i]
        t_out[r] = s + c * sample_period_ns
    return count, True


@inline
def segment(method, q, m, a_ns, b_ns, n, sample_ns, sample_period_ns, weights, split_axes,
            moments, tau_p, tau_body, has_tau, model, coefficient, inner, scratch, q_flow,
            m_flow, env, herm, lanes, t_out, q_out, m_out, tau_out, row):
    """n equal steps from a_ns to b_ns (ns) from (q, m), in place, writing every sample
    instant sample_ns + k·sample_period_ns < b_ns into rows row, row + 1, … (the caller
    made room): a step's own end where the sample falls on it, else the step's Hermite
    interpolant (herm (8, 4): scratch). Returns (first failing step of the segment or -1,
    -2 if an interpolated sample was not finite, evaluations, rows written)."""
    span = b_ns - a_ns
    if method == RK4 and env is None and sample_period_ns * n >= span:
        return rk4_free_segment(q, m, a_ns, b_ns, n, sample_ns, sample_period_ns, moments,
                                tau_p, tau_body, model, coefficient, t_out, q_out, m_out,
                                tau_out, row)
    h = span / (n * 1e9)
    t0 = a_ns / 1e9
    k = 0  # steps taken: the state is at a + k·h
    held = -2  # the step whose two ends herm holds (none yet: not j - 1 of step 0)
    evals = 0
    rows = 0
    s = sample_ns
    while s < b_ns:
        x = (s - a_ns) * (n / span)
        j = int(math.floor(x))
        theta = x - j
        if theta > 1.0 - ON_STEP:
            j += 1
            theta = 0.0
        elif theta < ON_STEP:
            theta = 0.0
        r = row + rows
        if theta == 0.0 or held != j:
            if j > k:
                failed, e = fixed_steps(method, q, m, h, j - k, weights, split_axes, moments,
                                        tau_p, has_tau, model, coefficient, inner, scratch,
                                        q_flow, m_flow, t0 + k * h, env)
                evals += e
                if failed >= 0:
                    return k + failed, evals, rows
                k = j
        if theta != 0.0 and held != j:
            if held >= 0 and held == j - 1:  # the previous step's end is this one's start
                for i in range(4):
                    herm[0, i], herm[2, i] = herm[4, i], herm[6, i]
                for i in range(3):
                    herm[1, i], herm[3, i] = herm[5, i], herm[7, i]
            elif env is None:  # rates in numbers
                _free_end(q, m, moments, tau_p, model, coefficient, herm, 0)
                evals += 1
            else:
                _end(q, m, moments, tau_p, model, coefficient, t0 + k * h, env, herm, 0)
                evals += 1
            failed, e = fixed_steps(method, q, m, h, 1, weights, split_axes, moments, tau_p,
                                    has_tau, model, coefficient, inner, scratch, q_flow, m_flow,
                                    t0 + k * h, env)
            evals += e
            if failed >= 0:
                return k + failed, evals, rows
            k += 1
            if env is None:
                _free_end(q, m, moments, tau_p, model, coefficient, herm, 4)
            else:
                _end(q, m, moments, tau_p, model, coefficient, t0 + k * h, env, herm, 4)
            evals += 1
            held = j
        if theta != 0.0:  # this sample and the next ones inside the same step
            if sample_period_ns * n >= span:  # the next sample is in a later step
                written, finite = _hermite_one(herm, h, theta, s, q_out, m_out, t_out,
                                               tau_out, tau_body, r)
            else:
                written, finite = hermite_run(herm, h, a_ns, b_ns, n, span, held, s,
                                              sample_period_ns, lanes, t_out, q_out, m_out,
                                              tau_out, tau_body, r)
            rows += written
            s += written * sample_period_ns
            if not finite:
                return -2, evals, rows
            continue
        for i in range(4):
            q_out[r, i] = q[i]
        for i in range(3):
            m_out[r, i] = m[i]
        t_out[r] = s
        for i in range(3):
            tau_out[r, i] = tau_body[i]
        rows += 1
        s += sample_period_ns
    if k < n:
        failed, e = fixed_steps(method, q, m, h, n - k, weights, split_axes, moments, tau_p,
                                has_tau, model, coefficient, inner, scratch, q_flow, m_flow,
                                t0 + k * h, env)
        evals += e
        if failed >= 0:
            return k + failed, evals, rows
    return -1, evals, rows


@inline
def dense_samples(q, m, tau_p, memory, hn_first, hn, room, s, sample_period_ns, t_out,
                  q_out, m_out, tau_out, tau_body, row, lanes):
    """Samples inside dop853's step in progress, in one loop: at most ``room`` rows from
    ``row`` on, at the instants s, s + p, … (p = sample_period_ns), each one output step
    of h·n (``hn_first`` for the first, ``hn`` for the others, as ``closed_loop_run``
    splits them) after the last. Each is ``dop853_dense._interpolated``'s output, the same
    operations in the same order, and the memory ends as after its last call; the
    per-call checks that the state (q, m) is the last output's, with the same torque
    (tau_p; true from the second sample on: the loop wrote them), are made once; q and m
    are left to the caller (the last row's). It stops at the first output not strictly
    inside the step, or not finite (the caller's usual path then takes it). ``lanes``
    (LANES, CHUNK): scratch. Returns the rows written.

    The samples go CHUNK at a time, each operation over the chunk's samples in a loop of
    its own: independent lanes, which the compiler runs several to an instruction (each
    lane's arithmetic is the scalar one, so the values are), the checks included, and the
    rows a column at a time (q divided by |q| there). At 100 samples/s on a slow body,
    calling ``_interpolated`` sample by sample from the event loop cost ~95 ns a sample;
    one sample after another here, ~24 ns; lane by lane, ~12 ns (the scratch allocated
    per call cost ~250 ns a call, once a step: ~100 ns a sample at ~3 samples a step);
    then the rows' loops as below, ~10.6 → 6.7 ns a sample (~200 samples a call, its
    arithmetic and stores alone, bench.sampling_floor's dense + store: ~8).
    A block whose rows are not (4, 3, 3) wide, or a negative row: 0."""
    if memory[_CLOCK + 3] <= 0.0 or memory[_CLOCK + 2] == 0.0 or room <= 0 or row < 0 \
            or not memory[_CLOCK] + hn_first < memory[_CLOCK + 1]:
        return 0
    # the rows' lengths as constants for the compiler (numba indexes a C array by its
    # runtime shape): the row loops' addresses fold (~0.5 ns a sample); any other block
    # is not this loop's (nothing written: the caller's usual path takes the samples)
    if q_out.shape[1] != 4 or m_out.shape[1] != 3 or tau_out.shape[1] != 3:
        return 0
    last = _LAST
    for i in range(4):
        if q[i] != memory[last + i]:
            return 0
    for i in range(3):
        if m[i] != memory[last + 4 + i] or tau_p[i] != memory[last + 7 + i]:
            return 0
    out = last + 10
    h_step = memory[_CLOCK + 1]
    clock = memory[_CLOCK]  # the last output's position in the step
    # lanes' rows, by index (views of them cost reference counts): the targets, x, 1 − x,
    # |q|, the interpolant (DIM rows)
    TARGET, X, Y, NORM, RAW = 0, 1, 2, 3, 4
    tau0, tau1, tau2 = tau_body[0], tau_body[1], tau_body[2]  # (stores to rows may alias)
    written = 0
    tried = -1  # the chunk column whose raw output the memory keeps (-1: none)
    span = hn_first
    stop = False
    while written < room and not stop:
        count = 0
        target = clock
        while count < min(CHUNK, room - written):
            target += span
            if not target < h_step:
                stop = True
                break
            lanes[TARGET, count] = target
            span = hn
            count += 1
        if count == 0:
            break
        for k in range(count):
            x = lanes[TARGET, k] / h_step
            lanes[X, k] = x
            lanes[Y, k] = 1.0 - x
        dop853_dense.interpolate_lanes(memory, lanes, X, Y, RAW, count)
        # |q| and the finiteness check in one pass, the check counted (a sum over the
        # lanes, not a search that leaves the loop); x − x is 0 for a finite x, NaN
        # otherwise, and |q| finite covers q's components
        bad = 0
        for k in range(count):
            norm = math.sqrt(lanes[RAW, k] * lanes[RAW, k]
                             + lanes[RAW + 1, k] * lanes[RAW + 1, k]
                             + lanes[RAW + 2, k] * lanes[RAW + 2, k]
                             + lanes[RAW + 3, k] * lanes[RAW + 3, k])
            lanes[NORM, k] = norm
            check = ((norm - norm) + (lanes[RAW + 4, k] - lanes[RAW + 4, k])
                     + (lanes[RAW + 5, k] - lanes[RAW + 5, k])
                     + (lanes[RAW + 6, k] - lanes[RAW + 6, k]))
            bad += not (check == 0.0 and norm > 0.0)
        good = count
        if bad:  # the first output not finite: the rows stop before it
            for k in range(count):
                norm = lanes[NORM, k]
                if not ((norm - norm) + (lanes[RAW + 4, k] - lanes[RAW + 4, k])
                        + (lanes[RAW + 5, k] - lanes[RAW + 5, k])
                        + (lanes[RAW + 6, k] - lanes[RAW + 6, k]) == 0.0 and norm > 0.0):
                    good = k
                    stop = True
                    break
        tried = good if good < count else count - 1
        # the rows a column at a time, each loop's stores at fixed strides, which the
        # compiler runs several samples to an instruction (sample by sample, all columns
        # in one loop: ~1.5 ns a sample more), q divided by |q| on its way (a pass of its
        # own into lanes: ~0.6 ns more); unsigned rows: numba adds no wraparound test for
        # a negative index (row ≥ 0, tested above)
        base = np.uint64(row + written)
        for k in range(good):
            r = base + np.uint64(k)
            norm = lanes[NORM, k]
            q_out[r, 0] = lanes[RAW, k] / norm
            q_out[r, 1] = lanes[RAW + 1, k] / norm
            q_out[r, 2] = lanes[RAW + 2, k] / norm
            q_out[r, 3] = lanes[RAW + 3, k] / norm
        for k in range(good):
            r = base + np.uint64(k)
            m_out[r, 0] = lanes[RAW + 4, k]
            m_out[r, 1] = lanes[RAW + 5, k]
            m_out[r, 2] = lanes[RAW + 6, k]
        for k in range(good):
            r = base + np.uint64(k)
            tau_out[r, 0] = tau0
            tau_out[r, 1] = tau1
            tau_out[r, 2] = tau2
        for k in range(good):
            t_out[base + np.uint64(k)] = s + k * sample_period_ns
        if good:
            clock = lanes[TARGET, good - 1]
            written += good
            s += good * sample_period_ns
    if tried >= 0:
        for i in range(DIM):  # as _interpolated leaves it: the last output tried
            memory[out + i] = lanes[RAW + i, tried]
    if written:
        memory[_CLOCK] = clock
        r = row + written - 1
        for i in range(4):
            memory[last + i] = q_out[r, i]
        for i in range(3):
            memory[last + 4 + i] = m_out[r, i]
    return written


def interpolation_allowed(engine, m) -> bool:
    """Whether an offline engine (``Engine.interpolate_samples``) may interpolate samples
    between its fixed method's steps: the cubic Hermite's attitude error, ~(hΩ)⁴/3072 for
    a rotation at Ω (q turns at Ω/2; its fourth derivative is (Ω/2)⁴), taken at 2Ω for a
    tumble's nutation, ≤ a tenth of the run's accuracy budget. Ω: the body's rate now, or
    the torque's rate scale if larger (``EngineConfig.torque_rate``: the law's bandwidth)."""
    if not engine.interpolate_samples:
        return False
    c = engine.config
    rate = float(np.linalg.norm(m / engine.dynamics.moments))
    rate = max(rate, c.torque_rate(c.control is not None or engine.torque is not None))
    return (engine.step_max * rate) ** 4 / 192.0 <= 0.1 * c.accuracy


# they call the step loops from their own files (see jit.depends_on)
for _kernel in (fixed_steps, segment, dense_samples):
    depends_on(_kernel, sample_steps, splitting_kernel, explicit_kernel, dop853_kernel,
               dop853_dense, exact_flow_kernel, dynamics_kernel, orbit_kernel, magnetic_kernel,
               facets_kernel)
