"""rk4 on the free body where its steps hold several samples each (a step longer than the
sample period: a slow torque-free or damped body at 100 samples/s), for
``sample_kernel.segment``.

One loop over the interval's steps, the state and the stages in numbers: each step's
first stage rates(y_k) serves both as the step's k1 and as the Hermite's derivative at
y_k, so a step's samples cost no evaluation of their own but in the interval's last step
(the next interval's first stage has the next law's torque). The samples inside a step
are written as soon as the step is taken (``sample_steps.step_rows``).
Before it, each step holding samples was one pass of ``segment``'s event loop: a call of
the step loop for that one step (its state out to the arrays and back), its end's rates
evaluated apart and the samples placed again: ~17 ns a sample at 12 samples a step where
the rows' own arithmetic and stores are ~7 (generated scene 5, 2026-11-27).
``sample_steps.rk4_free_segment`` keeps the case of one sample a step at most, whose
loop this one's bookkeeping would slow (its rk4 steps under a law, detumble).

The same steps, rows and values as ``segment`` with the steps taken one by one, bit for
bit (test_samples_rk4_segment).
"""
from ..physics import dynamics_kernel
from ..physics.dynamics_kernel import rates
from ..physics.integrators import explicit_kernel
from ..physics.integrators.explicit_kernel import rk4_free_step
from ..physics.jit import depends_on, inline
from . import sample_steps
from .sample_steps import hold, place, state_row, step_rows


@inline
def rk4_free_samples(q, m, a_ns, b_ns, n, sample_ns, sample_period_ns, moments, tau_p,
                     tau_body, model, coefficient, herm, scratch, t_out, q_out, m_out,
                     tau_out, row):
    """``sample_kernel.segment`` for rk4 on the free body: the n steps from (q, m), in
    place, and the samples from sample_ns on before b_ns into rows row, row + 1, … (the
    caller made room; herm (8, 4) and scratch (13, CHUNK): the samples' scratch). Returns
    (first failing step or -1, -2 if a sample was not finite, evaluations, rows)."""
    span = b_ns - a_ns
    h = span / (n * 1e9)
    i0, i1, i2 = moments[0], moments[1], moments[2]
    t0, t1, t2 = tau_p[0], tau_p[1], tau_p[2]
    x, y, z, w = q[0], q[1], q[2], q[3]
    m0, m1, m2 = m[0], m[1], m[2]
    s = sample_ns
    j, theta = place(s, a_ns, b_ns, n, span)
    rows = 0
    failed = -1
    a = rates(x, y, z, w, m0, m1, m2, i0, i1, i2, t0, t1, t2, model, coefficient)
    evals = 1
    for k in range(n):
        while j == k and theta == 0.0:  # a sample on this state (step k's start)
            state_row(x, y, z, w, m0, m1, m2, s, tau_body, t_out, q_out, m_out, tau_out,
                      row + rows)
            rows += 1
            s += sample_period_ns
            j, theta = place(s, a_ns, b_ns, n, span)
        held = j == k  # samples inside this step
        start, rates0 = (x, y, z, w, m0, m1, m2), a
        x, y, z, w, m0, m1, m2, finite = rk4_free_step(x, y, z, w, m0, m1, m2, a, h, i0, i1,
                                                       i2, t0, t1, t2, model, coefficient)
        evals += 3
        if not finite:
            failed = k
            break
        if k < n - 1 or held:  # (the last end's rates are the next interval's torque's)
            a = rates(x, y, z, w, m0, m1, m2, i0, i1, i2, t0, t1, t2, model, coefficient)
            evals += 1
        if held:  # this state and its rates are the step's end: its samples
            hold(herm, start, rates0, (x, y, z, w, m0, m1, m2), a)
            while held:  # (CHUNK at a time)
                written, finite = step_rows(herm, h, a_ns, b_ns, n, span, k, s,
                                            sample_period_ns, scratch, t_out, q_out, m_out,
                                            tau_out, tau_body, row + rows)
                rows += written
                s += written * sample_period_ns
                if not finite:
                    failed = -2
                    break
                j, theta = place(s, a_ns, b_ns, n, span)
                held = j == k
            if failed == -2:
                break
    if failed == -1:
        while j == n and theta == 0.0:  # a sample on the interval's end (within ON_STEP)
            state_row(x, y, z, w, m0, m1, m2, s, tau_body, t_out, q_out, m_out, tau_out,
                      row + rows)
            rows += 1
            s += sample_period_ns
            j, theta = place(s, a_ns, b_ns, n, span)
    q[0], q[1], q[2], q[3] = x, y, z, w
    m[0], m[1], m[2] = m0, m1, m2
    return failed, evals, rows


# it inlines the rk4 step, the rates and the rows from their own files (see jit.depends_on)
for _kernel in (rk4_free_samples,):
    depends_on(_kernel, sample_steps, explicit_kernel, dynamics_kernel)
