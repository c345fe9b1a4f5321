"""One body's row of :mod:`.kernel` constants built by compiled code: the regime
classification, working frame, signs and constants of :class:`.exact.TorqueFreeSolution`,
without its numpy overhead (hundreds of µs per body), so that a one-shot flow — the
``exact`` integrator's step with torque or dissipation, a new solution every step —
costs about as much as an evaluation.

The rules are exact.py's (see its docstring): moments equal within MOMENT_RTOL of the
largest; steady spin when the momentum off the nearest principal axis is ≤ STEADY_RTOL·G;
separatrix when |Δ2| ≤ SEPARATRIX_RTOL·Σ|terms|; working frames A (x, y, z) = (1, ±2, 3)
and B = (3, ∓2, 1) with det +1. The tests check the classification and the rows against
TorqueFreeSolution's.
"""
import math

import numpy as np

from .. import jit as jit_settings
from . import constants as exact_constants, double_double, elliptic_kernel
from . import kernel as exact_kernel
from .kernel import (CLOSED, E, ELLIPTIC, G, KIND, LH, M0, MX, MY, MZ, NCONST, Q0, RL_H, S,
                     SEPARATRIX, SIGD, SIGX, W, WC, WS_H, anchor_one, evaluate_into)
from ..jit import depends_on, jit

MOMENT_RTOL = 1e-12
SEPARATRIX_RTOL = 16 * np.finfo(float).eps
STEADY_RTOL = 1e-100


@jit
def _rotate(q, x, y, z):
    """q ⊗ (x, y, z) ⊗ q*, q = (x, y, z, w) unit."""
    qx, qy, qz, qw = q[0], q[1], q[2], q[3]
    tx = 2.0 * (qy * z - qz * y)
    ty = 2.0 * (qz * x - qx * z)
    tz = 2.0 * (qx * y - qy * x)
    return (x + qw * tx + qy * tz - qz * ty, y + qw * ty + qz * tx - qx * tz,
            z + qw * tz + qx * ty - qy * tx)


@jit
def _quat_of_transpose(r, out):
    """out ← the quaternion of the rotation Rᵀ, R (3, 3) a signed permutation, det +1
    (Shepperd's method; either sign, it cancels in C ⊗ E ⊗ w*)."""
    m00, m11, m22 = r[0, 0], r[1, 1], r[2, 2]
    # Rᵀ[i, j] = r[j, i]
    tr = m00 + m11 + m22
    if tr >= m00 and tr >= m11 and tr >= m22:
        w = 0.5 * math.sqrt(1.0 + tr)
        out[0], out[1], out[2], out[3] = ((r[1, 2] - r[2, 1]) / (4 * w),
                                          (r[2, 0] - r[0, 2]) / (4 * w),
                                          (r[0, 1] - r[1, 0]) / (4 * w), w)
    elif m00 >= m11 and m00 >= m22:
        x = 0.5 * math.sqrt(1.0 + m00 - m11 - m22)
        out[0], out[1], out[2], out[3] = (x, (r[1, 0] + r[0, 1]) / (4 * x),
                                          (r[2, 0] + r[0, 2]) / (4 * x),
                                          (r[1, 2] - r[2, 1]) / (4 * x))
    elif m11 >= m22:
        y = 0.5 * math.sqrt(1.0 - m00 + m11 - m22)
        out[0], out[1], out[2], out[3] = ((r[1, 0] + r[0, 1]) / (4 * y), y,
                                          (r[2, 1] + r[1, 2]) / (4 * y),
                                          (r[2, 0] - r[0, 2]) / (4 * y))
    else:
        z = 0.5 * math.sqrt(1.0 - m00 - m11 + m22)
        out[0], out[1], out[2], out[3] = ((r[2, 0] + r[0, 2]) / (4 * z),
                                          (r[2, 1] + r[1, 2]) / (4 * z), z,
                                          (r[0, 1] - r[1, 0]) / (4 * z))


@jit
def build(moments, q0, m0, row):
    """row (NCONST,) ← the constants of the body (q0, m0) with principal ``moments``,
    anchored (C, P0 set). Returns the kind (0 closed, 1 elliptic, 2 separatrix)."""
    for i in range(NCONST):
        row[i] = 0.0
    # stable argsort of three
    o0, o1, o2 = 0, 1, 2
    if moments[o1] < moments[o0]:
        o0, o1 = o1, o0
    if moments[o2] < moments[o1]:
        o1, o2 = o2, o1
        if moments[o1] < moments[o0]:
            o0, o1 = o1, o0
    i1, i2, i3 = moments[o0], moments[o1], moments[o2]
    scale = max(i1, max(i2, i3))
    eq12 = i2 - i1 <= MOMENT_RTOL * scale
    eq23 = i3 - i2 <= MOMENT_RTOL * scale
    g = math.sqrt(m0[0] * m0[0] + m0[1] * m0[1] + m0[2] * m0[2])
    for i in range(4):
        row[Q0 + i] = q0[i]
    for i in range(3):
        row[M0 + i] = m0[i]
    kind = ELLIPTIC
    axis = -1
    it = 1.0
    d2 = 0.0
    if eq12 and eq23:
        kind, axis, it = CLOSED, o2, (moments[0] + moments[1] + moments[2]) / 3.0
    elif eq12 or eq23:
        kind, axis = CLOSED, (o2 if eq12 else o0)
        it = 0.5 * (i1 + i2) if eq12 else 0.5 * (i2 + i3)
    else:
        a0, a1, a2 = abs(m0[o0]), abs(m0[o1]), abs(m0[o2])
        j = 0
        if a1 > a0:
            j = 1
        if a2 > max(a0, a1):
            j = 2
        perp = (math.sqrt(a1 * a1 + a2 * a2) if j == 0 else
                math.sqrt(a0 * a0 + a2 * a2) if j == 1 else math.sqrt(a0 * a0 + a1 * a1))
        if perp <= STEADY_RTOL * g:
            axis = (o0, o1, o2)[j]
            kind, it = CLOSED, moments[axis]
        else:
            t1 = m0[o0] ** 2 * (i1 - i2) / i1
            t3 = m0[o2] ** 2 * (i3 - i2) / i3
            d2 = t1 + t3
            if abs(d2) <= SEPARATRIX_RTOL * (abs(t1) + t3):
                kind = SEPARATRIX
    row[KIND] = kind
    if kind == CLOSED:
        row[E + axis] = 1.0
        if g > 0.0:
            lx, ly, lz = _rotate(q0, m0[0] / g, m0[1] / g, m0[2] / g)
        else:
            lx, ly, lz = 0.0, 0.0, 1.0
        row[LH], row[LH + 1], row[LH + 2] = lx, ly, lz
        g2h, g2l = exact_constants.sum_squares(m0[0], m0[1], m0[2])
        row[RL_H], row[RL_H + 1], row[WS_H], row[WS_H + 1] = exact_constants.closed_rates(
            g2h, g2l, m0[axis], moments[axis], it)
        return kind
    # working frame: rows of W are the working axes in caller indices
    wm = np.zeros((3, 3))
    wm[0, o0] = 1.0
    wm[1, o1] = 1.0
    wm[2, o2] = 1.0
    det = (wm[0, 0] * (wm[1, 1] * wm[2, 2] - wm[1, 2] * wm[2, 1])
           - wm[0, 1] * (wm[1, 0] * wm[2, 2] - wm[1, 2] * wm[2, 0])
           + wm[0, 2] * (wm[1, 0] * wm[2, 1] - wm[1, 1] * wm[2, 0]))
    if det < 0.0:                                      # odd sort: flip the intermediate axis
        for i in range(3):
            wm[1, i] = -wm[1, i]
    if kind == ELLIPTIC and d2 < 0.0:                  # case B: (3, ∓2, 1)
        for i in range(3):
            a, b = wm[0, i], wm[2, i]
            wm[0, i], wm[1, i], wm[2, i] = b, -wm[1, i], a
    for i in range(3):
        for k in range(3):
            row[W + 3 * i + k] = wm[i, k]
    w = np.empty(4)
    _quat_of_transpose(wm, w)
    row[WC], row[WC + 1], row[WC + 2], row[WC + 3] = -w[0], -w[1], -w[2], w[3]
    mw0 = wm[0, 0] * m0[0] + wm[0, 1] * m0[1] + wm[0, 2] * m0[2]
    mw1 = wm[1, 0] * m0[0] + wm[1, 1] * m0[1] + wm[1, 2] * m0[2]
    mw2 = wm[2, 0] * m0[0] + wm[2, 1] * m0[1] + wm[2, 2] * m0[2]
    ix = abs(wm[0, 0]) * moments[0] + abs(wm[0, 1]) * moments[1] + abs(wm[0, 2]) * moments[2]
    iy = abs(wm[1, 0]) * moments[0] + abs(wm[1, 1]) * moments[1] + abs(wm[1, 2]) * moments[2]
    iz = abs(wm[2, 0]) * moments[0] + abs(wm[2, 1]) * moments[1] + abs(wm[2, 2]) * moments[2]
    sigd = -1.0 if mw2 < 0.0 else 1.0
    sigx = -1.0 if mw0 < 0.0 else 1.0
    s = (sigx if kind == SEPARATRIX else 1.0) * sigd * (1.0 if iz > iy else -1.0)
    row[SIGD], row[SIGX], row[S], row[G] = sigd, sigx, s, g
    if kind == SEPARATRIX:
        row[MX] = g * math.sqrt(ix * (iz - iy) / (iy * (iz - ix)))
        row[MZ] = g * math.sqrt(iz * (iy - ix) / (iy * (iz - ix)))
        row[MY] = g
    out = np.empty(21)
    exact_constants.elliptic(ix, iy, iz, mw0, mw1, mw2, kind == SEPARATRIX, s, out)
    exact_kernel.fill_elliptic(row, out, kind)
    anchor_one(row)
    return kind


@jit
def flow(moments, q, m, t, q_out, m_out):
    """q_out, m_out ← the torque-free motion from (q, m) after time t (one-shot: the
    ``exact`` integrator's split step). Returns the kind."""
    row = np.empty(NCONST)
    kind = build(moments, q, m, row)
    evaluate_into(row, t, q_out, m_out)
    return kind


for _kernel in (_rotate, _quat_of_transpose, build, flow):
    depends_on(_kernel, double_double, elliptic_kernel, exact_constants, exact_kernel,
               jit_settings)


def pack(sol):
    """(n, NCONST) anchored rows for a TorqueFreeSolution's bodies, each built by compiled
    code (:func:`.build.build`: the same classification and frames, the rates, K, Π
    and what follows from them in double-double)."""
    n = len(sol._kind)
    rows = np.empty((n, NCONST))
    for b in range(n):
        kind = build(sol.moments, sol._q0[b], sol._m0[b], rows[b])
        if kind != sol._kind[b]:                         # the two classifications are one rule
            raise RuntimeError(f'exact_build classified body {b} as kind {kind}, '
                               f'TorqueFreeSolution as {sol._kind[b]}')
    return rows
