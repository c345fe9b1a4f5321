"""Compiled batch loops: N independent bodies × n splitting steps, on one core.

The bodies are q (N, 4) and m (N, 3), C-contiguous float64 arrays updated in place, in
the conventions of ``dynamics_kernel``. Bodies go through in blocks of ``BLOCK``, each
block's state held component by component (4 + 3 rows of BLOCK) in L1 cache for all n
steps. One body's axis flows form a dependent chain (each sin/cos waits for the previous
flow), so a loop over one body at a time is latency-bound; a flow applied across a block
has independent iterations that the CPU overlaps — about twice the throughput.

Torque-free motion without dissipation merges the touching outer half-flows of
consecutive stages and steps (first same as last): … b a(w_j h/2) · a(w_{j+1} h/2) b … =
… b a((w_j + w_{j+1}) h/2) b …, exact because the flow about one axis keeps that momentum
component. Strang then costs four axis flows per step instead of five: a fifth fewer
sin/cos, and an n-step run equals n single steps to round-off. A torque kick between the
half-flows changes that component, so with torque each stage runs unmerged (bit for bit
the operations of ``splitting_kernel.splitting_run``, which ``_block_flow`` repeats on columns).
With dissipation every body runs ``splitting_kernel.splitting_run`` itself (through
``splitting_kernel.splitting_bodies``): the double bracket's substep count is per body.

A block whose state turns non-finite is re-run body by body from its initial state by
``splitting_kernel.splitting_run``: that names each body's exact first non-finite step (a merged
state lacks a half-flow at step boundaries) and keeps the single-step result where only
a merged angle overflows.

Like ``splitting_kernel``, the source is plain Python that numba compiles (``jit.jit``) and
that runs as such under NUMBA_DISABLE_JIT=1. No ``parallel=True``: the target is one core.
"""
import math

import numpy as np

from ..jit import jit
from .splitting_kernel import splitting_bodies

BLOCK = 64  # bodies stepped side by side: enough independent flows, 5 kB of state


@jit
def _block_flow(qb, mb, count, axis, t, moments):
    """dynamics_kernel._axis_flow for time t on the first ``count`` bodies (columns) of a block."""
    b = (axis + 1) % 3
    c = (axis + 2) % 3
    k = 0.5 * t / moments[axis]
    for i in range(count):
        half = mb[axis, i] * k
        if half - half != 0.0:  # ±Inf (a merged angle can overflow): uncompiled math.sin
            half = math.nan     # would raise ValueError where compiled code gives NaN
        s = math.sin(half)
        w = math.cos(half)
        cos_phi = w * w - s * s
        sin_phi = 2.0 * s * w
        mb_ = mb[b, i]
        mc_ = mb[c, i]
        mb[b, i] = cos_phi * mb_ + sin_phi * mc_
        mb[c, i] = cos_phi * mc_ - sin_phi * mb_
        qa = qb[axis, i]
        qb_ = qb[b, i]
        qc = qb[c, i]
        qw = qb[3, i]
        qb[axis, i] = w * qa + s * qw
        qb[b, i] = w * qb_ + s * qc
        qb[c, i] = w * qc - s * qb_
        qb[3, i] = w * qw - s * qa


@jit
def _block_kick(mb, tb, count, t):
    for i in range(count):
        for j in range(3):
            mb[j, i] = mb[j, i] + t * tb[j, i]


@jit
def _block_finite(qb, mb, count):
    s = 0.0
    for i in range(count):
        s += qb[0, i] + qb[1, i] + qb[2, i] + qb[3, i] + mb[0, i] + mb[1, i] + mb[2, i]
    return s - s == 0.0  # False for NaN and ±Inf (or an overflowing sum: then re-run)


@jit
def _block_steps(qb, mb, tb, count, h, n, weights, axes, moments, joins, has_tau):
    """n steps of Π_w [K(wh/2) a(wh/2) b(wh/2) c(wh) b(wh/2) a(wh/2) K(wh/2)] on a block;
    without torque the a half-flows that touch are merged (``joins[j]``: the a-flow time
    after stage j). Returns -1, or a step after which some body is not finite."""
    if n <= 0:
        return -1
    a = axes[0]
    b = axes[1]
    c = axes[2]
    stages = len(weights)
    t_a = 0.5 * weights[0] * h  # merged: the run's first a half-flow
    for k in range(n):
        for j in range(stages):
            hw = weights[j] * h
            if has_tau:
                _block_kick(mb, tb, count, 0.5 * hw)
                _block_flow(qb, mb, count, a, 0.5 * hw, moments)
            else:
                _block_flow(qb, mb, count, a, t_a, moments)
                t_a = joins[j]
            _block_flow(qb, mb, count, b, 0.5 * hw, moments)
            _block_flow(qb, mb, count, c, hw, moments)
            _block_flow(qb, mb, count, b, 0.5 * hw, moments)
            if has_tau:
                _block_flow(qb, mb, count, a, 0.5 * hw, moments)
                _block_kick(mb, tb, count, 0.5 * hw)
        if not _block_finite(qb, mb, count):
            return k
    if not has_tau:
        _block_flow(qb, mb, count, a, 0.5 * weights[stages - 1] * h, moments)  # the last
        if not _block_finite(qb, mb, count):
            return n - 1
    return -1


@jit
def _blocks(q, m, lo, h, n, weights, axes, moments, tau, has_tau):
    """Blocks of bodies from ``lo`` on through ``_block_steps``, in place; stops at the
    first block that turns non-finite, left in its initial state. Returns its first body,
    or N when every block went through."""
    count = q.shape[0]
    stages = len(weights)
    joins = np.empty(stages)
    for j in range(stages):  # a-flow time after stage j: its last half and the next first
        joins[j] = 0.5 * (weights[j] + weights[(j + 1) % stages]) * h
    qb = np.empty((4, BLOCK))
    mb = np.empty((3, BLOCK))
    tb = np.zeros((3, BLOCK))
    for start in range(lo, count, BLOCK):
        size = min(BLOCK, count - start)
        for i in range(size):
            for j in range(4):
                qb[j, i] = q[start + i, j]
            for j in range(3):
                mb[j, i] = m[start + i, j]
                tb[j, i] = tau[(start + i) % tau.shape[0], j]
        if _block_steps(qb, mb, tb, size, h, n, weights, axes, moments, joins, has_tau) >= 0:
            return start
        for i in range(size):
            for j in range(4):
                q[start + i, j] = qb[j, i]
            for j in range(3):
                m[start + i, j] = mb[j, i]
    return count


def batch_run(q, m, h, n, weights, axes, moments, tau, has_tau, model, coefficient, inner):
    """n steps of ``splitting_kernel.splitting_run`` for every body of q (N, 4), m (N, 3), in
    place.

    tau (1, 3) shared or (N, 3) per body; inner (1,) shared or (N,) per body: damping inside
    the stages (``Splitting2.inner_dissipation``). Returns (first non-finite step or -1,
    a body that fails there, the largest sub-flow count of one body: the bodies' sub-flows
    run side by side, as the numpy path counts them).

    Plain Python around two compiled loops, ``_blocks`` and ``splitting_kernel.splitting_bodies``:
    a compiled call from this file into splitting_kernel.py would be frozen into this file's disk
    cache, which numba invalidates only when this file changes. The Python here runs once
    per call and once per failing block."""
    count = q.shape[0]
    if model != 0:
        return splitting_bodies(q, m, 0, count, h, n, weights, axes, moments, tau, has_tau,
                                model, coefficient, inner)
    failed, failed_body, evals, limit, lo = -1, -1, 0, n, 0
    while lo < count:
        stop = _blocks(q, m, lo, h, limit, weights, axes, moments, tau, has_tau)
        if stop > lo:
            evals = max(evals, len(weights) * limit)
        if stop == count:
            break
        # the failing block, body by body from its initial state: exact steps (see above)
        bad, body, used = splitting_bodies(q, m, stop, min(stop + BLOCK, count), h, limit,
                                           weights, axes, moments, tau, has_tau, 0, 0.0,
                                           inner)
        evals = max(evals, used)
        if bad >= 0:
            failed, failed_body, limit = bad, body, bad
        lo = stop + BLOCK
    return failed, failed_body, evals


def warm():
    """Compile (or load from the cache) the batch loops on representative arguments."""
    q = np.array([[0.0, 0.0, 0.0, 1.0]])
    m = np.array([[0.1, 1.0, 0.2]])
    args = (np.array([1.0]), np.array([0, 2, 1]), np.array([1.0, 2.0, 3.0]), np.zeros((1, 3)))
    _blocks(q, m, 0, 1e-3, 1, *args, False)
    splitting_bodies(q, m, 0, 1, 1e-3, 1, *args, False, 1, 0.1, np.zeros(1, dtype=np.bool_))
