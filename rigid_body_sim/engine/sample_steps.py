"""A step's samples, for ``sample_kernel.segment``: the cubic Hermite interpolant of the
step's two ends.

:func:`step_rows` finds the samples strictly inside a step (their θ) and writes them
(:func:`rows_in_lanes`: one loop over the samples, then the rows); :func:`hermite_one`
writes the one sample of a step from its ends in numbers (:func:`hermite_row`), the same
values.
:func:`rk4_free_segment` is ``segment`` for rk4 on the free body (no orbit) where a step
holds one sample at most (a sample period at least the step: rk4 under a law at 100
samples/s; ``rk4_samples`` where steps hold more): one loop over the interval's steps,
each step's first stage rates(y_k) serving both as the step's k1 and as the Hermite's
derivative at y_k, so the ends of a step holding a sample cost no evaluation of their
own (``segment`` evaluated both again: 2 of ~26 ns of arithmetic a sample's floor, ~20
ns) and the step loop is not left and re-entered per sample. Only a sample in the
interval's last step evaluates its end once (the next interval's first stage has the
next law's torque). The same steps, rows and values as ``segment`` with the steps taken
one by one, bit for bit (test_samples_rk4_segment).
"""
import math

from ..physics import dynamics_kernel
from ..physics.dynamics_kernel import rates
from ..physics.integrators import explicit_kernel
from ..physics.integrators.explicit_kernel import rk4_free_step
from ..physics.jit import depends_on, inline

# a sample this close to a step's end (in steps) is that end's own state
ON_STEP = 1e-9
# samples per pass of the interpolants (hermite_run, dop853_samples): scratch of a few rows
# of CHUNK stays in the L1 cache; LANES rows of it (the closed loop allocates them once)
CHUNK = 64
LANES = 16
NONE = 1 << 62  # place()'s step for an instant at or past the interval's end (none)


@inline
def place(s, a_ns, b_ns, n, span):
    """The step j of the n equal ones over [a_ns, b_ns) holding the instant s (ns) and θ
    in it (0: on the state of step j's start, within ON_STEP), as ``segment`` places its
    samples; (NONE, 0.0) at or past b_ns."""
    if s >= b_ns:
        return NONE, 0.0
    x = (s - a_ns) * (n / span)
    j = int(math.floor(x))
    theta = x - j
    if theta > 1.0 - ON_STEP:
        return j + 1, 0.0
    if theta < ON_STEP:
        return j, 0.0
    return j, theta


@inline
def step_rows(herm, h, a_ns, b_ns, n, span, held, s, sample_period_ns, scratch, t_out, q_out,
              m_out, tau_out, tau_body, row):
    """The samples from s on (sample_period_ns apart) that fall strictly inside the step
    ``held`` of the n equal ones over [a_ns, b_ns), before b_ns, at most CHUNK, as
    :func:`place` places them, into rows row, row + 1, …: the cubic Hermite interpolant
    of the step whose ends herm (8, 4) holds, q normalised (:func:`rows_in_lanes`). Returns
    (rows written, False if a sample was not finite: the rows before it are written)."""
    count = 0
    scale = n / span
    while count < CHUNK:
        x = (s + count * sample_period_ns - a_ns) * scale
        j = int(math.floor(x))
        theta = x - j
        if s + count * sample_period_ns >= b_ns or j != held or theta > 1.0 - ON_STEP \
                or theta < ON_STEP:
            break
        scratch[0, count] = theta
        count += 1
    return rows_in_lanes(herm, h, count, s, sample_period_ns, scratch, t_out, q_out, m_out,
                         tau_out, tau_body, row)


@inline
def rows_in_lanes(herm, h, count, s, sample_period_ns, scratch, t_out, q_out, m_out, tau_out,
                  tau_body, row):
    """count rows from row on at s, s + sample_period_ns, …: the cubic Hermite interpolant
    at the θ of scratch[0, :count] of the step whose ends herm (8, 4) holds, in one loop
    over the samples (explicit_kernel.hermite_lanes: independent lanes, which the
    compiler runs several to an instruction), then the checks and rows sample by sample.
    ``scratch`` (13, CHUNK). Returns (rows written, False if a sample was not finite: the
    rows before it are written)."""
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
def ends(herm):
    """The (q, m) and their rates at a step's two ends that herm (8, 4) holds, in numbers:
    (y0, d0, y1, d1), 7 each."""
    return ((herm[0, 0], herm[0, 1], herm[0, 2], herm[0, 3], herm[1, 0], herm[1, 1],
             herm[1, 2]),
            (herm[2, 0], herm[2, 1], herm[2, 2], herm[2, 3], herm[3, 0], herm[3, 1],
             herm[3, 2]),
            (herm[4, 0], herm[4, 1], herm[4, 2], herm[4, 3], herm[5, 0], herm[5, 1],
             herm[5, 2]),
            (herm[6, 0], herm[6, 1], herm[6, 2], herm[6, 3], herm[7, 0], herm[7, 1],
             herm[7, 2]))


@inline
def hold(herm, y0, d0, y1, d1):
    """herm (8, 4) := the step's ends given in numbers (:func:`ends`' inverse)."""
    herm[0, 0], herm[0, 1], herm[0, 2], herm[0, 3] = y0[0], y0[1], y0[2], y0[3]
    herm[1, 0], herm[1, 1], herm[1, 2] = y0[4], y0[5], y0[6]
    herm[2, 0], herm[2, 1], herm[2, 2], herm[2, 3] = d0[0], d0[1], d0[2], d0[3]
    herm[3, 0], herm[3, 1], herm[3, 2] = d0[4], d0[5], d0[6]
    herm[4, 0], herm[4, 1], herm[4, 2], herm[4, 3] = y1[0], y1[1], y1[2], y1[3]
    herm[5, 0], herm[5, 1], herm[5, 2] = y1[4], y1[5], y1[6]
    herm[6, 0], herm[6, 1], herm[6, 2], herm[6, 3] = d1[0], d1[1], d1[2], d1[3]
    herm[7, 0], herm[7, 1], herm[7, 2] = d1[4], d1[5], d1[6]


@inline
def state_row(x, y, z, w, m0, m1, m2, s, tau_body, t_out, q_out, m_out, tau_out, r):
    """Row r at s: the state (x, y, z, w; m0, m1, m2) itself, on a step's end."""
    q_out[r, 0], q_out[r, 1], q_out[r, 2], q_out[r, 3] = x, y, z, w
    m_out[r, 0], m_out[r, 1], m_out[r, 2] = m0, m1, m2
    t_out[r] = s
    tau_out[r, 0], tau_out[r, 1], tau_out[r, 2] = tau_body[0], tau_body[1], tau_body[2]


@inline
def hermite_one(herm, h, theta, s, q_out, m_out, t_out, tau_out, tau_body, r):
    """``sample_kernel.hermite_run`` where a step holds one sample at most, row r at s, the
    same values (its loops cost ~36 ns of ~140 a sample: rk4 under a law, generated scene
    13): :func:`hermite_row` of the ends herm (8, 4) holds. Returns (rows written,
    finite)."""
    y0, d0, y1, d1 = ends(herm)
    return hermite_row(h, theta, s, y0, d0, y1, d1, q_out, m_out, t_out, tau_out, tau_body, r)


@inline
def hermite_row(h, theta, s, y0, d0, y1, d1, q_out, m_out, t_out, tau_out, tau_body, r):
    """Row r at s: the cubic Hermite interpolant at θ of the step of h from the state y0
    (q, m: 7 numbers) with rates d0 to y1 with rates d1, q normalised (hermite_run's
    operations in its order). Returns (rows written, finite): none where not finite."""
    t2 = theta * theta
    t3 = t2 * theta
    a0 = 2.0 * t3 - 3.0 * t2 + 1.0
    a1, b0, b1 = 1.0 - a0, (t3 - 2.0 * t2 + theta) * h, (t3 - t2) * h
    v0 = a0 * y0[0] + b0 * d0[0] + a1 * y1[0] + b1 * d1[0]
    v1 = a0 * y0[1] + b0 * d0[1] + a1 * y1[1] + b1 * d1[1]
    v2 = a0 * y0[2] + b0 * d0[2] + a1 * y1[2] + b1 * d1[2]
    v3 = a0 * y0[3] + b0 * d0[3] + a1 * y1[3] + b1 * d1[3]
    w0 = a0 * y0[4] + b0 * d0[4] + a1 * y1[4] + b1 * d1[4]
    w1 = a0 * y0[5] + b0 * d0[5] + a1 * y1[5] + b1 * d1[5]
    w2 = a0 * y0[6] + b0 * d0[6] + a1 * y1[6] + b1 * d1[6]
    norm = math.sqrt(0.0 + v0 * v0 + v1 * v1 + v2 * v2 + v3 * v3)
    # x − x is 0 for a finite x, NaN otherwise
    if not (norm - norm + (w0 - w0) + (w1 - w1) + (w2 - w2) == 0.0 and norm > 0.0):
        return 0, False
    q_out[r, 0], q_out[r, 1], q_out[r, 2], q_out[r, 3] = v0 / norm, v1 / norm, v2 / norm, \
        v3 / norm
    m_out[r, 0], m_out[r, 1], m_out[r, 2] = w0, w1, w2
    tau_out[r, 0], tau_out[r, 1], tau_out[r, 2] = tau_body[0], tau_body[1], tau_body[2]
    t_out[r] = s
    return 1, True


@inline
def rk4_free_segment(q, m, a_ns, b_ns, n, sample_ns, sample_period_ns, moments, tau_p,
                     tau_body, model, coefficient, t_out, q_out, m_out, tau_out, row):
    """``sample_kernel.segment`` for rk4 on the free body where a step holds one sample at
    most (sample_period_ns·n ≥ b_ns − a_ns): the n steps from (q, m), in place, and the
    samples from sample_ns on before b_ns into rows row, row + 1, … Returns (first
    failing step or -1, -2 if a sample was not finite, evaluations, rows written)."""
    span = b_ns - a_ns
    h = span / (n * 1e9)
    i0, i1, i2 = moments[0], moments[1], moments[2]
    t0, t1, t2 = tau_p[0], tau_p[1], tau_p[2]
    x, y, z, w = q[0], q[1], q[2], q[3]
    m0, m1, m2 = m[0], m[1], m[2]
    s = sample_ns
    j, theta = place(s, a_ns, b_ns, n, span)
    evals = 0
    rows = 0
    failed = -1
    held = False  # the step just taken holds the sample s (start, rates0: its start)
    a = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # the rates of the state (k1 of its step)
    start = rates0 = a
    for k in range(n + 1):
        if k < n or held:  # (the last end's rates are the next interval's, its torque's)
            a = rates(x, y, z, w, m0, m1, m2, i0, i1, i2, t0, t1, t2, model, coefficient)
            evals += 1
            if held:  # this state and its rates are that step's end
                written, finite = hermite_row(h, theta, s, start, rates0,
                                              (x, y, z, w, m0, m1, m2), a, q_out, m_out,
                                              t_out, tau_out, tau_body, row + rows)
                if not finite:
                    failed = -2
                    break
                rows += 1
                s += sample_period_ns
                j, theta = place(s, a_ns, b_ns, n, span)
                held = False
        while j <= k and theta == 0.0:  # a sample on this state
            state_row(x, y, z, w, m0, m1, m2, s, tau_body, t_out, q_out, m_out, tau_out,
                      row + rows)
            rows += 1
            s += sample_period_ns
            j, theta = place(s, a_ns, b_ns, n, span)
        if k == n:
            break
        if j <= k:  # the sample falls inside this step: its start and rates kept
            start, rates0 = (x, y, z, w, m0, m1, m2), a
            held = True
        x, y, z, w, m0, m1, m2, finite = rk4_free_step(x, y, z, w, m0, m1, m2, a, h, i0, i1,
                                                       i2, t0, t1, t2, model, coefficient)
        evals += 3
        if not finite:
            failed = k
            break
    q[0], q[1], q[2], q[3] = x, y, z, w
    m[0], m[1], m[2] = m0, m1, m2
    return failed, evals, rows


# they inline the rk4 step and the rates from their own files (see jit.depends_on)
for _kernel in (step_rows, rows_in_lanes, ends, hold, state_row,
                hermite_one, hermite_row, rk4_free_segment):
    depends_on(_kernel, explicit_kernel, dynamics_kernel)
