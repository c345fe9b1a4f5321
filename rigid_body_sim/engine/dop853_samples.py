"""dop853's samples up to the next event, written from one loop of its natural steps.

``closed_loop_run`` answers the samples between two events (a law instant, the limit)
with :func:`sampled_steps`: it takes dop853's steps as ``dop853_dense.advance`` takes them
and, after each step, writes the samples that lie in it a chunk of lanes at a time
(``dop853_dense.interpolate_lanes``), the step's first sample among them; at a law instant
it also restarts the integration where the torque changes, and makes the output at the
next law instant, as ``advance`` does. Each row is the output that calling ``advance``
once a sample gives (the same operations in the same order: the positions ``clock +
span`` with each step's length subtracted, the interpolant built at the step's first
output, ``t0 + base`` for the environment's instants), and the memory ends as after the
last such call: test_dop853_samples compares them bit for bit, test_samples and
test_gravity_gradient the whole loop's samples with the event path's.

Why one loop: with ~5-12 samples a step, an out-of-line ``advance`` for each step's first
sample (its views, its entry checks, that sample interpolated alone) and a second pass of
the event loop for the rest of the step cost ~300 ns a step over the samples' floor
(bench.sampling_floor: the build and each sample's interpolation and store), 2.2-2.4x that
floor on the generated scenes it judges; under a law at 25 Hz, three or four such calls
an interval. Now: one call an interval between events.

Inlined into ``closed_loop_run`` (a call between kernels costs a reference count round
trip per array, ~0.1 µs for these, once a law interval), which takes ``env`` as an
argument of its own so that numba types the environment's ``env is None`` branches away.

Frames as in ``closed_loop``: q principal → inertial, m and ``tau_p`` in the principal
frame, ``tau_body`` (the rows' torque) in the body frame.
"""
import math

import numpy as np

from ..physics import dynamics_kernel
from ..physics.dynamics_kernel import _finite
from ..physics.environment import facets_kernel, magnetic_kernel
from ..physics.integrators import dop853_dense, dop853_kernel
from ..physics.integrators.dop853_dense import (_CLOCK, _LAST, _SCRATCH, A_EXTRA, D, DIM,
                                                MEMORY, _build, interpolate_lanes, step_on,
                                                views)
from ..physics.integrators.dop853_kernel import NON_FINITE, OK, _rhs, _rhs_environment
from ..physics.jit import depends_on, inline
from ..physics.orbit import kernel as orbit_kernel
from . import sample_kernel
from .sample_kernel import CHUNK, split

# lanes' rows, by index (views of them cost reference counts): the targets, x, 1 − x,
# |q|, the interpolant (DIM rows)
TARGET, X, Y, NORM, RAW = 0, 1, 2, 3, 4


@inline
def sampled_steps(q, m, tau_p, tau_body, memory, moments, model, coefficient, rtol, atol,
                  env, t_ns, end_ns, to_end, s, period_ns, hn_first, n_first, h_p, n_period,
                  h_max, t_out, q_out, m_out, tau_out, row, room, lanes):
    """The samples at s, s + p, … (p = ``period_ns``) before ``end_ns``, at most ``room``
    rows from ``row`` on, from the state (q, m) of dop853's last output, at ``t_ns``, then
    (``to_end``: a law instant) the output at ``end_ns``, as ``advance`` called once each
    gives them. Each is one output step after the last: ``hn_first`` (its h·n, n =
    ``n_first``, as the caller splits it) for the first, ``h_p``·n (n = ``n_period``) for the
    others, the end's split as the caller splits it (``h_max``). A held torque ``tau_p``
    other than the last call's restarts the integration there, as ``advance`` does. (q, m)
    end as the last output; ``lanes`` (LANES, CHUNK): scratch. It declines (nothing
    written: the caller's ``advance`` takes the output) a state other than the last
    output's, a memory with no step in progress, and rows not (4, 3, 3) wide.

    Returns (rows written, their output steps' n summed (the caller's step count),
    evaluations, status, failed_ns, reached, h): h the last output's step h·n / n
    (-1.0: the end not reached); on a failure (a step's, or an output not finite:
    dop853_kernel's codes), the rows before it are written, failed_ns is the instant of
    the last output before it and reached the time from there to the failure, as
    ``advance`` reports them, and h the step to report."""
    if room <= 0 or row < 0 or not s < end_ns or memory[_CLOCK + 3] <= 0.0:
        return 0, 0, 0, OK, 0, 0.0, -1.0
    # the rows' lengths as constants for the compiler (numba indexes a C array by its
    # runtime shape): the row loops' addresses fold
    if q_out.shape[1] != 4 or m_out.shape[1] != 3 or tau_out.shape[1] != 3:
        return 0, 0, 0, OK, 0, 0.0, -1.0
    for i in range(4):  # advance's own test that it continues from its last output
        if q[i] != memory[_LAST + i]:
            return 0, 0, 0, OK, 0, 0.0, -1.0
    for i in range(3):
        if m[i] != memory[_LAST + 4 + i]:
            return 0, 0, 0, OK, 0, 0.0, -1.0
    y, f, y_old, K, F, clock_view, last_view = views(memory)
    y_stage = memory[_SCRATCH:_SCRATCH + DIM]
    y_new = memory[_SCRATCH + DIM:MEMORY]
    raw = _LAST + 10  # the last output's raw state
    clock = memory[_CLOCK]  # the last output's position in the step in progress
    h_step = memory[_CLOCK + 1]
    built = memory[_CLOCK + 2] != 0.0
    h_abs = memory[_CLOCK + 3]
    tau0, tau1, tau2 = tau_body[0], tau_body[1], tau_body[2]  # (stores to rows may alias)
    written = 0
    steps = 0
    evals = 0
    t_prev = t_ns
    hn = h_p * n_period  # a sample period's output step, as the caller computes it
    span, n = hn_first, n_first
    status = OK
    reached = 0.0
    h_out = -1.0
    if tau_p[0] != memory[_LAST + 7] or tau_p[1] != memory[_LAST + 8] \
            or tau_p[2] != memory[_LAST + 9]:
        # a torque change: restart where the last output is, keeping the step (advance)
        for i in range(DIM):
            y[i] = memory[raw + i]
        clock = 0.0
        h_step = 0.0
        _rhs(y, f, moments, tau_p, model, coefficient)
        if env is not None:
            _rhs_environment(y, f, t_ns / 1e9, env, moments)
        evals += 1
        if not (_finite(y[:4], y[4:]) and _finite(f[:4], f[4:])):
            memory[_CLOCK] = 0.0
            memory[_CLOCK + 1] = 0.0
            memory[_CLOCK + 3] = 0.0
            return 0, 0, evals, NON_FINITE, t_ns, 0.0, h_abs
        for i in range(3):
            memory[_LAST + 7 + i] = tau_p[i]
    last_output = False  # the end's output, after the samples
    while True:
        if not (written < room and s < end_ns):
            if not (to_end and s >= end_ns) or last_output:
                break
            # the output at the end (a law instant), split as the caller splits it
            last_output = True
            span_ns = end_ns - t_prev
            n, h_end = (n_period, h_p) if span_ns == period_ns else split(span_ns, h_max)
            span = h_end * n
        target = clock + span
        if target > h_step:  # advance's loop: step on from the step's end
            t0 = t_prev / 1e9
            base = h_step - clock  # where y lies, from the last output (t0)
            while target > h_step:
                target -= h_step
                status, h, h_abs, e = step_on(y, f, y_old, K, y_stage, y_new, h_abs, base,
                                              moments, tau_p, model, coefficient, rtol, atol,
                                              t0 + base, env)
                evals += e
                if status != OK:
                    reached, h_out = base, h if h > 0.0 else span
                    break
                h_step = h
                base += h
                built = False
                if not _finite(y[:4], y[4:]):
                    status, reached, h_out = NON_FINITE, base, h
                    break
            if status != OK:
                break
            if target < h_step and not built:  # the step's first output: its interpolant
                evals += _build(y_old, y, f, h_step, K, F, moments, tau_p, model,
                                coefficient, A_EXTRA, D, t0 + base - h_step, env, y_stage)
                built = True
        if last_output:  # the end's output: advance's, into the state, no row
            if target == h_step:
                for i in range(DIM):
                    memory[raw + i] = y[i]
            else:
                lanes[TARGET, 0] = target
                x = target / h_step
                lanes[X, 0] = x
                lanes[Y, 0] = 1.0 - x
                interpolate_lanes(memory, lanes, X, Y, RAW, 1)
                for i in range(DIM):
                    memory[raw + i] = lanes[RAW + i, 0]
            norm = math.sqrt(memory[raw] * memory[raw] + memory[raw + 1] * memory[raw + 1]
                             + memory[raw + 2] * memory[raw + 2]
                             + memory[raw + 3] * memory[raw + 3])
            for i in range(4):
                q[i] = memory[raw + i] / norm
            for i in range(3):
                m[i] = memory[raw + 4 + i]
            clock = target
            if not _finite(q, m):  # q fell to zero, or the interpolant overflowed
                status, reached, h_out = NON_FINITE, span, h_abs
                break
            steps += n
            h_out = h_end
            break
        if target == h_step:  # on the step's end: its own state, as advance gives it
            norm = math.sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2] + y[3] * y[3])
            for i in range(DIM):
                memory[raw + i] = y[i]
            if not (math.isfinite(norm) and norm > 0.0 and _finite(y[:4], y[4:])):
                status, reached, h_out = NON_FINITE, span, h_abs
                break
            r = row + written
            t_out[r] = s
            for i in range(4):
                q_out[r, i] = y[i] / norm
            for i in range(3):
                m_out[r, i] = y[4 + i]
            tau_out[r, 0] = tau0
            tau_out[r, 1] = tau1
            tau_out[r, 2] = tau2
            clock = target
            good = 1
            short = False
        else:  # this output and the next ones inside the step, a chunk of lanes
            lanes[TARGET, 0] = target
            count = 1
            limit = min(CHUNK, room - written)
            while count < limit and s + count * period_ns < end_ns:
                target += hn
                if not target < h_step:
                    break
                lanes[TARGET, count] = target
                count += 1
            for k in range(count):
                x = lanes[TARGET, k] / h_step
                lanes[X, k] = x
                lanes[Y, k] = 1.0 - x
            interpolate_lanes(memory, lanes, X, Y, RAW, count)
            good = _checked(lanes, count)
            _rows(lanes, good, s, period_ns, t_out, q_out, m_out, tau_out, tau0, tau1, tau2,
                  row + written)
            short = good < count
            kept = max(good - 1, 0)  # the last output's raw state, as advance keeps it
            for i in range(DIM):
                memory[raw + i] = lanes[RAW + i, kept]
            if good:
                clock = lanes[TARGET, good - 1]
        if good:
            steps += n + (good - 1) * n_period
            written += good
            t_prev = s + (good - 1) * period_ns
            s = t_prev + period_ns
            span, n = hn, n_period
        if short:
            # an output not finite, as advance reports it: from the last output
            status, reached, h_out = NON_FINITE, span, h_abs
            break
    memory[_CLOCK] = clock
    memory[_CLOCK + 1] = h_step
    memory[_CLOCK + 2] = 1.0 if built else 0.0
    memory[_CLOCK + 3] = h_abs if status == OK else 0.0  # a failure leaves no memory
    if written and not last_output:  # the state is the last row's (the end's: set above)
        r = row + written - 1
        for i in range(4):
            q[i] = q_out[r, i]
        for i in range(3):
            m[i] = m_out[r, i]
    for i in range(4):
        memory[_LAST + i] = q[i]
    for i in range(3):
        memory[_LAST + 4 + i] = m[i]
    return written, steps, evals, status, t_prev, reached, h_out


@inline
def _checked(lanes, count):
    """The lanes before the first whose output is not finite (|q| and the check in one
    pass, counted: a sum over the lanes, not a search that leaves the loop; x − x is 0
    for a finite x, NaN otherwise, and |q| finite covers q's components), |q| in NORM."""
    bad = 0
    for k in range(count):
        norm = math.sqrt(lanes[RAW, k] * lanes[RAW, k] + lanes[RAW + 1, k] * lanes[RAW + 1, k]
                         + lanes[RAW + 2, k] * lanes[RAW + 2, k]
                         + lanes[RAW + 3, k] * lanes[RAW + 3, k])
        lanes[NORM, k] = norm
        check = ((norm - norm) + (lanes[RAW + 4, k] - lanes[RAW + 4, k])
                 + (lanes[RAW + 5, k] - lanes[RAW + 5, k])
                 + (lanes[RAW + 6, k] - lanes[RAW + 6, k]))
        bad += not (check == 0.0 and norm > 0.0)
    if bad:
        for k in range(count):
            norm = lanes[NORM, k]
            if not ((norm - norm) + (lanes[RAW + 4, k] - lanes[RAW + 4, k])
                    + (lanes[RAW + 5, k] - lanes[RAW + 5, k])
                    + (lanes[RAW + 6, k] - lanes[RAW + 6, k]) == 0.0 and norm > 0.0):
                return k
    return count


@inline
def _rows(lanes, good, s, period_ns, t_out, q_out, m_out, tau_out, tau0, tau1, tau2, row):
    """Rows row, row + 1, … from the first ``good`` lanes, at s, s + p, …: a column at a
    time, each loop's stores at fixed strides, which the compiler runs several samples to
    an instruction (sample by sample, all columns in one loop: ~1.5 ns a sample more), q
    divided by |q| on its way; unsigned rows: no wraparound test for a negative index
    (row ≥ 0, tested by the caller)."""
    base = np.uint64(row)
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
        t_out[base + np.uint64(k)] = s + k * period_ns


# numba's disk cache checks only this file; it embeds dop853's and the dynamics' code
sampled_steps = depends_on(sampled_steps, sample_kernel, dop853_dense, dop853_kernel,
                           dynamics_kernel, orbit_kernel, magnetic_kernel, facets_kernel)
