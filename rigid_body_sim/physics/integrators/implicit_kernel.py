"""Compiled implicit midpoint loop: ``ImplicitMidpoint`` for one body, on floats.

The same step as the numpy path of :mod:`.integrators.implicit`, operation for
operation where it matters for the result: x = (m₀ + m₁)/2 solves
x − m₀ − h/2 F(x) = 0 by damped Newton with the exact Jacobian, started from m₀;
m₁ = 2x − m₀; the attitude turns by the Cayley transform of ½[Ω(x)]. The 3×3 Newton
systems are solved by Gaussian elimination with partial pivoting on a scratch array
allocated once per call, so a step allocates nothing.

Failures keep the numpy path's semantics: a sub-step whose Newton iteration does not
converge (or diverges) is retried as two halves, down to h/16; the caller raises
IntegrationError with the failing sub-step's size and start time. Evaluations of F are
counted as there (one per residual, line-search trials included).
"""
import math

import numpy as np

from .. import dynamics_kernel
from ..dynamics_kernel import _finite
from ..jit import depends_on, jit

EPS = 2.220446049250313e-16  # np.finfo(float).eps
HALVINGS = 4                 # a step fails when its h/2⁴ sub-steps fail too
SUBSTEPS = 1 << HALVINGS     # positions within a step count in units of h/16
# Status of a step (kernel return value): why the loop stopped.
OK, NOT_CONVERGED, DIVERGED, NON_FINITE = 0, 1, 2, 3
REASONS = {NOT_CONVERGED: 'Newton iteration did not converge in {} iterations',
           DIVERGED: 'Newton iteration diverged',
           NON_FINITE: 'state became non-finite (the method diverged)'}


@jit
def _residual(x0, x1, x2, m, h, moments, tau, model, coefficient):
    """x − m − h/2·F(x), F = x × Ω + τ + dissipation, in Dynamics.momentum_rate's order."""
    o0 = x0 / moments[0]
    o1 = x1 / moments[1]
    o2 = x2 / moments[2]
    c0 = x1 * o2 - x2 * o1
    c1 = x2 * o0 - x0 * o2
    c2 = x0 * o1 - x1 * o0
    f0 = c0 + tau[0]
    f1 = c1 + tau[1]
    f2 = c2 + tau[2]
    if model == 1:  # α x × (x × Ω)
        f0 = f0 + coefficient * (x1 * c2 - x2 * c1)
        f1 = f1 + coefficient * (x2 * c0 - x0 * c2)
        f2 = f2 + coefficient * (x0 * c1 - x1 * c0)
    elif model == 2:  # −c Ω
        f0 = f0 + -coefficient * o0
        f1 = f1 + -coefficient * o1
        f2 = f2 + -coefficient * o2
    k = 0.5 * h
    return (x0 - m[0]) - k * f0, (x1 - m[1]) - k * f1, (x2 - m[2]) - k * f2


@jit
def _newton_matrix(a, x0, x1, x2, h, moments, model, coefficient):
    """a[:, :3] ← 1 − h/2·dF/dm at x (ImplicitMidpoint._jacobian, written out)."""
    i0 = 1.0 / moments[0]
    i1 = 1.0 / moments[1]
    i2 = 1.0 / moments[2]
    w0 = x0 * i0
    w1 = x1 * i1
    w2 = x2 * i2
    # d(x × Ω)/dx = −[Ω]× + [x]× diag(1/I)
    a[0, 0] = 0.0
    a[0, 1] = w2 + -x2 * i1
    a[0, 2] = -w1 + x1 * i2
    a[1, 0] = -w2 + x2 * i0
    a[1, 1] = 0.0
    a[1, 2] = w0 + -x0 * i2
    a[2, 0] = w1 + -x1 * i0
    a[2, 1] = -w0 + x0 * i1
    a[2, 2] = 0.0
    if model == 1:
        # α(−[c]× + [x]× J), c = x × Ω: the derivative of α x × c
        c0 = x1 * w2 - x2 * w1
        c1 = x2 * w0 - x0 * w2
        c2 = x0 * w1 - x1 * w0
        for j in range(3):
            j0 = a[0, j]
            j1 = a[1, j]
            j2 = a[2, j]
            s0 = -x2 * j1 + x1 * j2
            s1 = x2 * j0 + -x0 * j2
            s2 = -x1 * j0 + x0 * j1
            if j == 0:
                a[0, j] = j0 + coefficient * (0.0 + s0)
                a[1, j] = j1 + coefficient * (-c2 + s1)
                a[2, j] = j2 + coefficient * (c1 + s2)
            elif j == 1:
                a[0, j] = j0 + coefficient * (c2 + s0)
                a[1, j] = j1 + coefficient * (0.0 + s1)
                a[2, j] = j2 + coefficient * (-c0 + s2)
            else:
                a[0, j] = j0 + coefficient * (-c1 + s0)
                a[1, j] = j1 + coefficient * (c0 + s1)
                a[2, j] = j2 + coefficient * (0.0 + s2)
    elif model == 2:
        a[0, 0] -= coefficient * i0
        a[1, 1] -= coefficient * i1
        a[2, 2] -= coefficient * i2
    k = 0.5 * h
    for r in range(3):
        for j in range(3):
            a[r, j] = (1.0 if r == j else 0.0) - k * a[r, j]


@jit
def _solve(a):
    """Solve a[:, :3] y = a[:, 3] in place (partial pivoting); y in a[:, 3]. A zero pivot
    gives non-finite y, which the Newton loop reports as divergence."""
    for k in range(3):
        p = k
        for i in range(k + 1, 3):
            if abs(a[i, k]) > abs(a[p, k]):
                p = i
        if p != k:
            for j in range(k, 4):
                a[k, j], a[p, j] = a[p, j], a[k, j]
        pivot = a[k, k]
        for i in range(k + 1, 3):
            f = a[i, k] / pivot
            for j in range(k + 1, 4):
                a[i, j] -= f * a[k, j]
    for k in range(2, -1, -1):
        s = a[k, 3]
        for j in range(k + 1, 3):
            s -= a[k, j] * a[j, 3]
        a[k, 3] = s / a[k, k]


@jit
def _midpoint(q, m, h, moments, tau, model, coefficient, max_iterations, a):
    """One midpoint step of size h; (status, F evaluations). Only a converged step
    updates q and m (in place), so a failed one can be retried from the same state."""
    x0, x1, x2 = m[0], m[1], m[2]
    r0, r1, r2 = _residual(x0, x1, x2, m, h, moments, tau, model, coefficient)
    evals = 1
    status = NOT_CONVERGED
    for _ in range(max_iterations):
        _newton_matrix(a, x0, x1, x2, h, moments, model, coefficient)
        a[0, 3] = r0
        a[1, 3] = r1
        a[2, 3] = r2
        _solve(a)
        d0, d1, d2 = a[0, 3], a[1, 3], a[2, 3]
        norm0 = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
        lam = 1.0
        while True:  # backtracking: an update must not increase the residual
            t0 = x0 - lam * d0
            t1 = x1 - lam * d1
            t2 = x2 - lam * d2
            s0, s1, s2 = _residual(t0, t1, t2, m, h, moments, tau, model, coefficient)
            evals += 1
            sum_r = s0 + s1 + s2
            if (math.sqrt(s0 * s0 + s1 * s1 + s2 * s2) <= norm0 or lam < 1e-3
                    or not sum_r - sum_r == 0.0):
                break
            lam *= 0.5
        x0, x1, x2, r0, r1, r2 = t0, t1, t2, s0, s1, s2
        sum_x = x0 + x1 + x2
        if not sum_x - sum_x == 0.0:
            status = DIVERGED
            break
        tol = 4.0 * EPS * max(abs(x0), max(abs(x1), abs(x2)))
        if abs(lam * d0) <= tol and abs(lam * d1) <= tol and abs(lam * d2) <= tol:
            status = OK
            break
    if status != OK:
        return status, evals
    m[0] = 2.0 * x0 - m[0]
    m[1] = 2.0 * x1 - m[1]
    m[2] = 2.0 * x2 - m[2]
    # Cayley transform of ½[Ω(x)]: right-multiplication by the unit quaternion
    # (2u, 1 − |u|²)/(1 + |u|²), u = h/4·Ω(x).
    k = 0.25 * h
    u0 = k * (x0 / moments[0])
    u1 = k * (x1 / moments[1])
    u2 = k * (x2 / moments[2])
    uu = u0 * u0 + u1 * u1 + u2 * u2
    denom = 1.0 + uu
    cx = 2.0 * u0 / denom
    cy = 2.0 * u1 / denom
    cz = 2.0 * u2 / denom
    cw = (1.0 - uu) / denom
    px, py, pz, pw = q[0], q[1], q[2], q[3]
    q[0] = pw * cx + px * cw + py * cz - pz * cy
    q[1] = pw * cy - px * cz + py * cw + pz * cx
    q[2] = pw * cz + px * cy - py * cx + pz * cw
    q[3] = pw * cw - px * cx - py * cy - pz * cz
    return OK, evals


@jit
def implicit_midpoint_run(q, m, h, n, moments, tau, model, coefficient, max_iterations):
    """n implicit midpoint steps of h, in place. Returns (failed step or -1, status,
    level, position, evaluations): on a failure, the sub-step of size h/2^level starting
    at position·h/16 within step ``failed`` (status NOT_CONVERGED or DIVERGED), or the
    state after step ``failed`` is not finite (NON_FINITE)."""
    a = np.empty((3, 4))
    evals = 0
    for k in range(n):
        # The numpy path's recursion (try h; on failure two halves, each tried whole
        # first) walked iteratively: after a success at ``pos`` the next pending sub-step
        # is the largest dyadic block aligned at pos, i.e. the coarsest level ≥ 1 it fits.
        pos = 0
        level = 0
        while pos < SUBSTEPS:
            hs = h
            for _ in range(level):
                hs = 0.5 * hs
            status, e = _midpoint(q, m, hs, moments, tau, model, coefficient, max_iterations,
                                  a)
            evals += e
            if status == OK:
                pos += SUBSTEPS >> level
                level = 1
                while pos % (SUBSTEPS >> level) != 0:
                    level += 1
            elif level >= HALVINGS:
                return k, status, level, pos, evals
            else:
                level += 1
        if not _finite(q, m):
            return k, NON_FINITE, 0, 0, evals
    return -1, OK, 0, 0, evals


# it embeds dynamics_kernel._finite from another file (see jit.depends_on)
implicit_midpoint_run = depends_on(implicit_midpoint_run, dynamics_kernel)


def substep_time(t, h, level, pos):
    """Start time of the sub-step (level, pos) of the step [t, t + h), summed as the
    numpy path's recursion sums it (t + h/2, then + h/4, …), so both report the same t."""
    for lev in range(1, level + 1):
        if (pos >> (HALVINGS - lev)) & 1:
            t = t + 0.5 ** lev * h
    return t


def warm():
    """Compile (or load from the cache) the loop; one specialisation serves every model."""
    q = np.array([0.0, 0.0, 0.0, 1.0])
    m = np.array([0.1, 1.0, 0.2])
    implicit_midpoint_run(q, m, 1e-3, 1, np.array([1.0, 2.0, 3.0]), np.zeros(3), 1, 0.1, 30)
