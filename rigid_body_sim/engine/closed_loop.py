"""The loop compiled: samples, the control law and the steps between them in one kernel.

Offline runs, the bench and campaigns run the control law in-process (``ControlLaw``).
Driven event by event from Python, every control instant and every sample costs ~10-20 µs
of interpreter work around a sub-microsecond law and a few sub-microsecond steps: at 100
samples/s that was 10-30x the physics. This kernel runs every event up to the next one it
cannot handle (the end, a command's expiry, a full block) instead: at each control
instant it evaluates the same law (``control_kernel.control_torque``) with the same mission
schedule and clip; at each sample instant it writes the state into the engine's
preallocated block (``BlockBuilder``); between them it steps the same compiled integrator
loop (``physics.integrators``), with the step split exactly as :meth:`Engine._integrate`
splits it. The samples are the event-by-event path's (test_samples compares them bit for
bit). Offline (``ticks[INTERPOLATE]``, ``Engine.interpolate_samples``), a fixed-step
method's steps split only the law's intervals and the samples inside are interpolated
(``sample_kernel``): the steps and auto's choice then do not depend on the sample rate.
The engine's side (when the kernel applies, its arguments, its results taken back) is
``closed_loop_args``.

Frames: q is principal → inertial and m the principal-frame momentum (what the
integrators advance); the law sees the body frame (attitude body → inertial, ω body), as
everywhere else. ``p2b`` is the principal → body rotation (x, y, z, w), ``axes`` its
matrix (v_body = axes @ v_principal).
"""
import math

import numpy as np

from .. import control_kernel, control_law
from ..control_kernel import control_torque
from ..physics import dynamics_kernel
from ..physics.integrators import (dop853_dense, dop853_kernel, exact_flow_kernel,
                                   explicit_kernel, splitting_kernel)
from . import dop853_samples, rk4_samples, sample_kernel, sample_steps
from .sample_kernel import DOP853, EXACT, EULER, RK4, SPLITTING, fixed_steps, split
from ..physics.jit import depends_on, jit
from ..physics.environment import facets_kernel, magnetic_kernel
from ..physics.orbit import kernel as orbit_kernel
from .sources import NEVER

NEVER_NS = NEVER  # numba reads module globals as compile-time constants


# closed_loop_run's integer arguments (int64 array ``ticks``): instants and periods in ns,
# codes and the block's first free row
T_NS, LIMIT_NS, CONTROL_NS, PERIOD_NS, SAMPLE_NS, SAMPLE_PERIOD_NS, METHOD, MODEL, MODE, \
    GYROSCOPIC, FREE, ROW, INTERPOLATE, N_TICKS = range(14)
# and its real ones (float64 array ``reals``)
H_MAX, COEFFICIENT, RATE_LIMIT, TORQUE_LIMIT, CLIP, MISSION_START, FREE_TIME, EXIT_RATE, \
    RTOL, ATOL, N_REALS = range(11)
__all__ = ['SPLITTING', 'RK4', 'EULER', 'DOP853', 'EXACT', 'closed_loop_run']
ADAPTIVE_FAILED = -3  # out[5] when dop853 failed: out[9] its status, out[10] where (ns)
NEED_ROOM = -4  # out[5] when the next law interval's samples do not fit in the block
N_OUT = 11


@jit
def _stopped(out, at_ns, steps, evals, failed, rows, status=0, reached=0.0):
    """The record of a run that stopped on a failure (``closed_loop_run``'s ``out``):
    where (ns), the steps and evaluations done, the failure's code, the rows written;
    dop853's (``ADAPTIVE_FAILED``): its status, and where it failed, ``reached`` s on."""
    out[0] = at_ns
    out[3] = steps
    out[4] = evals
    out[5] = failed
    out[6] = rows
    if failed == ADAPTIVE_FAILED:
        out[9] = status
        out[10] = at_ns + int(reached * 1e9)


@jit
def closed_loop_run(state, ticks, reals, spec, body, env, law, block, out):
    """Advance ``state`` = (q, m, tau_body, tau_p) in place from ``ticks[T_NS]`` through
    every event instant before ``ticks[LIMIT_NS]``: the law at each control instant
    ``ticks[CONTROL_NS] + k·ticks[PERIOD_NS]`` (``NEVER``: no law; ``tau_p`` is then the
    held principal-frame torque), and a sample at each instant ``ticks[SAMPLE_NS] +
    k·ticks[SAMPLE_PERIOD_NS]``, written to rows ``ticks[ROW], ticks[ROW] + 1, …`` of
    ``block`` = (t_out, q_out, m_out, tau_out (body-frame torque)) until they are full.
    Every event at ``T_NS`` has been processed by the caller; the state ends at the last
    event processed (a law instant and a sample at one instant: the law first, as the
    engine's event loop does). ``spec`` = (weights, split_axes, memory) of the method
    (``ticks[METHOD]``: its ``loop_code``; memory: dop853's step in progress, carried
    between calls as ``DOP853.run`` carries it, with ``reals[RTOL]``, ``reals[ATOL]``;
    ``ticks[MODEL]``: the method's damping code, ``Integrator.loop_model``); ``body`` =
    (moments, axes, p2b, env): the simulated body and its environment (``orbit.kernel``'s
    array; ON = 0: none), ``env`` also as an argument of its own: numba types away the
    inlined loops' ``env is None`` branches for an argument, not for a tuple's item;
    ``law`` = (target, axes, moments, kp, kd, kw, inertia) and ``reals``' law entries:
    the controller's model of it (its own ``inertia`` parameter), as
    :class:`control.AttitudeController` uses.

    ``tau_body`` (in/out): the held body-frame torque (zeros = none). ``out`` (int64,
    N_OUT): [next control instant, mode, free (1/0), steps, evaluations, failed step or -1,
    rows written, time reached (ns), next sample instant, dop853's status, where it failed
    (ns)]; on a failure, ``out[0]`` is the start (ns) of the failing segment and the return
    value its step h (dop853: ``out[5]`` = ADAPTIVE_FAILED). Returns the last step h."""
    q, m, tau_body, tau_p = state
    t_out, q_out, m_out, tau_out = block
    weights, split_axes, memory = spec
    moments, axes, p2b, _ = body
    target, law_axes, law_moments, kp, kd, kw, inertia = law
    limit_ns = ticks[LIMIT_NS]
    control_ns = ticks[CONTROL_NS]
    period_ns = ticks[PERIOD_NS]
    sample_ns = ticks[SAMPLE_NS]
    sample_period_ns = ticks[SAMPLE_PERIOD_NS]
    method = ticks[METHOD]
    model = ticks[MODEL]
    mode = ticks[MODE]
    gyroscopic = ticks[GYROSCOPIC] != 0
    row = ticks[ROW]
    h_max = reals[H_MAX]
    coefficient = reals[COEFFICIENT]
    rate_limit = reals[RATE_LIMIT]
    torque_limit = reals[TORQUE_LIMIT]
    clip = reals[CLIP]
    mission_start = reals[MISSION_START]
    free_time = reals[FREE_TIME]
    exit_rate = reals[EXIT_RATE]
    rtol = reals[RTOL]
    atol = reals[ATOL]
    tau_unsat = np.empty(3)
    scratch = np.empty((10, 4))  # the Runge–Kutta loops' stages, allocated once
    qb = np.empty(4)
    wb = np.empty(3)
    q_flow = np.empty(4)  # the exact flow's output
    m_flow = np.empty(3)
    law = control_ns < NEVER_NS
    has_tau = False
    for i in range(3):
        has_tau = has_tau or tau_body[i] != 0.0
    if law:
        for j in range(3):
            tau_p[j] = (tau_body[0] * axes[0, j] + tau_body[1] * axes[1, j]
                        + tau_body[2] * axes[2, j])
    free = ticks[FREE]
    steps = 0
    evals = 0
    h = 0.0
    t = ticks[T_NS]
    rows = 0
    capacity = len(t_out)
    interpolate = ticks[INTERPOLATE] != 0
    need_room = False
    herm = np.empty((8, 4))  # a step's two ends and derivatives (sample_kernel.segment)
    # the samples' scratch (hermite_run, dop853_samples)
    lanes = np.empty((sample_kernel.LANES, sample_kernel.CHUNK))
    # dop853's output step between samples, split as below (a run's constants)
    n_p, h_p = split(sample_period_ns, h_max)
    while row + rows < capacity:
        dop853_done = False
        if interpolate:
            # the steps split only the intervals between law instants (and the limit, a
            # physics event here: closed_loop_args.advance); samples inside are interpolated
            seg_end = min(control_ns, limit_ns)
            if seg_end <= t:
                break
            at_limit = seg_end == limit_ns
            # the samples it writes: before seg_end, and at it unless that is the limit
            count = 0
            if sample_ns < seg_end or (sample_ns == seg_end and not at_limit):
                count = (seg_end - sample_ns) // sample_period_ns + 1
                if at_limit and (seg_end - sample_ns) % sample_period_ns == 0:
                    count -= 1
            if count > capacity - row - rows:
                if law:  # a law interval is never cut: the next block takes it whole
                    need_room = True
                    break
                seg_end = sample_ns + (capacity - row - rows - 1) * sample_period_ns
                at_limit = False
        else:
            seg_end = min(control_ns, sample_ns)
            if seg_end >= limit_ns:
                break
            at_limit = False  # the limit ends the loop before it is stepped to
            span = seg_end - t
            # equal steps no longer than h_max, split as Engine._integrate splits them (a
            # sample period's split is the run's constant: two divisions less a pass)
            if span == sample_period_ns:
                n, h = n_p, h_p
            else:
                n, h = split(span, h_max)
            if method == DOP853 and sample_ns < min(control_ns, limit_ns):
                # the samples before the next event and the output at it (a law instant),
                # in one loop of dop853's steps (dop853_samples): each the
                # output the call below would give, its output step split as above, the
                # integration restarted at a new torque as the call restarts it. It
                # declines (0 rows, no output) the first call and rows not its own
                written, n_done, e, status, t_failed, reached, h_out = \
                    dop853_samples.sampled_steps(
                        q, m, tau_p, tau_body, memory, moments, model, coefficient, rtol,
                        atol, env, t, min(control_ns, limit_ns), control_ns < limit_ns,
                        sample_ns, sample_period_ns, h * n, n, h_p, n_p, h_max, t_out, q_out,
                        m_out, tau_out, row + rows, capacity - row - rows, lanes)
                evals += e
                steps += n_done
                rows += written
                if status != dop853_kernel.OK:
                    _stopped(out, t_failed, steps, evals, ADAPTIVE_FAILED, rows, status,
                             reached)
                    return h_out
                if written > 0:
                    sample_ns += written * sample_period_ns
                    if h_out < 0.0:  # at its last sample (the block full, or the limit next)
                        t = sample_ns - sample_period_ns
                        h = h_p if written > 1 else h
                        continue
                    t = control_ns  # at the law instant: its events below
                    h = h_out
                    seg_end = t
                    at_limit = False
                    dop853_done = True
        if not dop853_done:  # (else sampled_steps has reached the law instant)
            if interpolate:
                n, h = split(seg_end - t, h_max)
            t0 = t / 1e9  # as Engine._integrate: the environment's torques see these instants
            failed = -1
            if method == DOP853:  # (never interpolating: closed_loop_args.advance)
                # one integration over n·h, as DOP853.run: natural steps, the end
                # interpolated. A sample inside the step in progress is advance's first
                # test, inlined here: the call itself (its arrays' reference counts) cost
                # ~150 ns of a sample's ~200
                if dop853_dense._interpolated(q, m, h * n, tau_p, memory):
                    status, e = dop853_kernel.OK, 0
                else:
                    status, reached, h_next, e = dop853_dense.advance(
                        q, m, h * n, tau_p, memory, moments, model, coefficient, rtol, atol,
                        t0, env)
                evals += e
                if status != dop853_kernel.OK:
                    _stopped(out, t, steps, evals, ADAPTIVE_FAILED, rows, status, reached)
                    return h_next if h_next > 0.0 else h * n
            else:
                inner = method == SPLITTING and splitting_kernel.inner_dissipation(
                    m, h, weights, moments, model, coefficient)
                if interpolate:
                    failed, e, written = sample_kernel.segment(
                        method, q, m, t, seg_end, n, sample_ns, sample_period_ns, weights,
                        split_axes, moments, tau_p, tau_body, has_tau, model, coefficient, inner,
                        scratch, q_flow, m_flow, env, herm, lanes, t_out, q_out, m_out, tau_out,
                        row + rows)
                    rows += written
                    sample_ns += written * sample_period_ns
                    if failed == -2:  # an interpolated sample was not finite
                        _stopped(out, sample_ns, steps, evals + e, -2, rows)
                        return h
                else:
                    failed, e = fixed_steps(method, q, m, h, n, weights, split_axes, moments,
                                            tau_p, has_tau, model, coefficient, inner, scratch,
                                            q_flow, m_flow, t0, env)
                evals += e
            if failed >= 0:  # a step failed: the segment's start, and that step's index in it
                _stopped(out, t, steps + failed + 1, evals, failed, rows)
                return h
            steps += n
            t = seg_end
            if at_limit:  # (interpolating) the limit's own events are the caller's
                break
        if t == control_ns:
            # the body-frame state the law sees (Engine.attitude / angular_velocity)
            cx, cy, cz, cw = -p2b[0], -p2b[1], -p2b[2], p2b[3]
            qb[0] = q[3] * cx + q[0] * cw + q[1] * cz - q[2] * cy
            qb[1] = q[3] * cy - q[0] * cz + q[1] * cw + q[2] * cx
            qb[2] = q[3] * cz + q[0] * cy - q[1] * cx + q[2] * cw
            qb[3] = q[3] * cw - q[0] * cx - q[1] * cy - q[2] * cz
            # as published (sources.published_attitude): what the controller node sees
            n = math.sqrt(qb[0] * qb[0] + qb[1] * qb[1] + qb[2] * qb[2] + qb[3] * qb[3])
            for i in range(4):
                qb[i] /= n
            for i in range(3):
                wb[i] = (axes[i, 0] * (m[0] / moments[0]) + axes[i, 1] * (m[1] / moments[1])
                         + axes[i, 2] * (m[2] / moments[2]))
            # Mission.update, then the law (ControlLaw.evaluate / on_event)
            if t / 1e9 - mission_start < free_time:
                free = 1
                for i in range(3):
                    tau_body[i] = 0.0
            else:
                free = 0
                if mode == 1 and exit_rate > 0.0 and \
                        math.sqrt(wb[0] * wb[0] + wb[1] * wb[1] + wb[2] * wb[2]) < exit_rate:
                    mode = 2
                control_torque(mode, qb, wb, target, law_axes, law_moments, kp, kd, kw,
                               rate_limit, torque_limit, gyroscopic, inertia, tau_body,
                               tau_unsat)
                for i in range(3):
                    tau_body[i] = min(max(tau_body[i], -clip), clip)
            has_tau = tau_body[0] != 0.0 or tau_body[1] != 0.0 or tau_body[2] != 0.0
            for j in range(3):
                tau_p[j] = (tau_body[0] * axes[0, j] + tau_body[1] * axes[1, j]
                            + tau_body[2] * axes[2, j])
            control_ns += period_ns
        if t == sample_ns:
            finite = True
            for i in range(4):
                finite = finite and math.isfinite(q[i])
            for i in range(3):
                finite = finite and math.isfinite(m[i])
            if not finite:  # the loops check every step; this is the sample's own check
                _stopped(out, t, steps, evals, -2, rows)
                return h
            r = row + rows
            t_out[r] = t
            for i in range(4):
                q_out[r, i] = q[i]
            for i in range(3):
                m_out[r, i] = m[i]
                tau_out[r, i] = tau_body[i]
            rows += 1
            sample_ns += sample_period_ns
    out[0] = control_ns
    out[1] = mode
    out[2] = free
    out[3] = steps
    out[4] = evals
    out[5] = NEED_ROOM if need_room else -1
    out[6] = rows
    out[7] = t
    out[8] = sample_ns
    return h


# it calls the step loops and the law from their own files (see jit.depends_on)
closed_loop_run = depends_on(closed_loop_run, dop853_samples, rk4_samples, sample_kernel,
                             sample_steps, splitting_kernel, explicit_kernel, dop853_kernel,
                             dop853_dense,
                             exact_flow_kernel, dynamics_kernel, control_kernel, control_law,
                             orbit_kernel, magnetic_kernel, facets_kernel)
