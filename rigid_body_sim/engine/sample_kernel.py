"""Samples between steps: a fixed-step method's steps do not land on the sample instants.

Landing on every sample shortened the steps to divide the sample period (detumble's
splitting6 at 20 ms became splitting4 at 5 ms at 100 samples/s, 1.6x the CPU). Here the
steps are the method's own, splitting only the intervals between the events that change
the physics (control instants, the end, a command's expiry), and a sample inside a step is
the cubic Hermite interpolant of the step's two ends and their derivatives (two
right-hand-side evaluations per step holding a sample, shared by consecutive steps;
a chunk at a time, :func:`hermite_run`; rk4 on the free body takes them from its stages,
``sample_steps`` and ``rk4_samples``): its error, ~(hΩ)⁴/384 of the rotation, is
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
from . import rk4_samples, sample_steps
from .rk4_samples import rk4_free_samples
# a sample this close to a step's end (in steps) is that end's own state; one a step
from .sample_steps import (CHUNK, LANES, ON_STEP,  # noqa: F401 (theirs)
                           hermite_one as _hermite_one, rk4_free_segment, step_rows)
from ..physics.jit import depends_on, inline
from ..physics.environment import facets_kernel, magnetic_kernel
from ..physics.orbit import kernel as orbit_kernel

# the methods' loops (their classes' ``loop_code``)
SPLITTING, RK4, EULER, DOP853, EXACT = range(5)


@inline
def split(span_ns, h_max):
    """(n, h): ``span_ns`` in n equal steps no longer than ``h_max`` s, as
    ``Engine._integrate`` splits an interval between events (the compiled loops' one
    split, so that their steps are the event path's to the bit)."""
    n = max(1, int(math.ceil(span_ns / (h_max * 1e9) - 1e-9)))
    return n, span_ns / (n * 1e9)


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
    whose ends herm holds, before b_ns, at most CHUNK, q normalised (sample_steps.
    step_rows). ``scratch`` (13, CHUNK). Returns (rows written, False if a sample was not
    finite: the rows before it are written)."""
    return step_rows(herm, h, a_ns, b_ns, n, span, held, s, sample_period_ns, scratch, t_out,
                     q_out, m_out, tau_out, tau_body, row)


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
    if method == RK4 and env is None:  # in numbers, a step's ends from its stages
        if sample_period_ns * n >= span:  # a sample a step at most
            return rk4_free_segment(q, m, a_ns, b_ns, n, sample_ns, sample_period_ns,
                                    moments, tau_p, tau_body, model, coefficient, t_out,
                                    q_out, m_out, tau_out, row)
        return rk4_free_samples(q, m, a_ns, b_ns, n, sample_ns, sample_period_ns, moments,
                                tau_p, tau_body, model, coefficient, herm, lanes, t_out,
                                q_out, m_out, tau_out, row)
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
for _kernel in (fixed_steps, segment):
    depends_on(_kernel, sample_steps, rk4_samples, splitting_kernel, explicit_kernel,
               dop853_kernel, dop853_dense, exact_flow_kernel, dynamics_kernel, orbit_kernel,
               magnetic_kernel, facets_kernel)
