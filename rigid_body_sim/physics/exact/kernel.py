"""Compiled evaluation of the torque-free solution (:mod:`.exact`): one body's constants
in a float64 row (built by :mod:`.build`), evaluated at one time or at many.

The formulas, frames and conventions are those of :mod:`.exact` (read its docstring). The
quantities that grow with t — λt + u0, its reduction u = 2jK + r, (G/Iz)t + cphi·2jΠ and
its reduction modulo 4π — are formed in double-double (:mod:`.double_double`, ~106 bits):
each rate and complete integral is stored as a pair (hi, lo) computed in double-double
(:mod:`.constants`), and the products with t and j and the reductions are
error-free transformations, so the phases keep ~1e-32 relative error. The Jacobi
functions and Carlson's integrals (:mod:`.elliptic_kernel`) see only |r| ≤ K in float64,
with k'² passed as such.

Kinds (row[KIND]): 0 closed form (symmetric or spherical body, steady spin, rest),
1 elliptic (cases A and B in their working frames), 2 separatrix. The closed form is the
cheap one: two reduced phases, two sin/cos pairs, two quaternion products.

Plain numerical Python compiled by ``jit.jit``; under NUMBA_DISABLE_JIT=1 the same
source runs on floats. Its disk cache is keyed on the callees' files too (``depends_on``).
"""
import math

import numpy as np

from .. import jit as jit_settings
from . import constants as exact_constants, double_double, elliptic_kernel
from .double_double import dd_add, dd_mul_d, dd_reduce, reduce_4pi
from .elliptic_kernel import ellipj, rf, rj
from ..jit import depends_on, jit

# Row layout. Closed form: L̂ (space), q0, m0, e (body), rates (hi, lo) of the space
# precession G/I_t and the body spin ω_s.
KIND, LH, Q0, M0, E = 0, 1, 4, 8, 11
RL_H, RL_L, WS_H, WS_L = 14, 15, 16, 17
# Elliptic / separatrix: C, conj(w), W (3×3, rows = working axes), then the scalars of
# exact.py; pairs (hi, lo) for λ, 2K, K, G/Iz, cphi·2Π(−N|k²) and the separatrix's rate.
C, WC, W = 18, 22, 26
MX, MY, MZ, S, SIGD, SIGX, G, N, KP, KP2, KF, U0, P0, CPHI = range(35, 49)
LAM_H, LAM_L, TK_H, TK_L, K_H, K_L, R0_H, R0_L, CP_H, CP_L, RS_H, RS_L = range(49, 61)
NCONST = 61
CLOSED, ELLIPTIC, SEPARATRIX = 0, 1, 2


@jit
def fill_elliptic(r, out, kind):
    """Row entries from exact_constants.elliptic's ``out``."""
    r[LAM_H], r[LAM_L], r[TK_H], r[TK_L], r[K_H], r[K_L] = (out[0], out[1], out[2], out[3],
                                                           out[4], out[5])
    r[R0_H], r[R0_L], r[CP_H], r[CP_L], r[RS_H], r[RS_L] = (out[6], out[7], out[8], out[9],
                                                           out[10], out[11])
    r[N], r[KP2], r[KP], r[KF], r[CPHI], r[U0] = (out[12], out[13], out[14], out[15],
                                                  out[16], out[17])
    if kind == ELLIPTIC:
        r[MX], r[MY], r[MZ] = out[18], out[19], out[20]


@jit
def _qmul(px, py, pz, pw, qx, qy, qz, qw):
    return (pw * qx + px * qw + py * qz - pz * qy, pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw, pw * qw - px * qx - py * qy - pz * qz)


@jit
def _reduced(c, uh, ul):
    """u = (uh, ul) = 2jK + r, |r| ≤ K: (sn, cn, dn of r, j, P_r(r)) of an elliptic row."""
    nn = c[N]
    kk = c[KF]
    rh, rl, j = dd_reduce(uh, ul, c[TK_H], c[TK_L])      # u = 2jK + r, |r| ≤ K
    r = rh + rl
    near = abs(r) > 0.5 * kk
    if near:                                             # quarter-period identities at K − |r|
        sg = 1.0 if r >= 0.0 else -1.0
        xh, xl = dd_add(c[K_H], c[K_L], -sg * rh, -sg * rl)
        x = xh + xl
    else:
        x = abs(r)
    kp = c[KP]
    sv, cv, dv, _ = ellipj(x, 1.0 - c[KP2], c[KP2])
    sn = math.copysign(cv / dv if near else sv, r)
    cn = kp * sv / dv if near else cv
    dn = kp / dv if near else dv
    s2 = sn * sn
    p = sn * rf(cn * cn, dn * dn, 1.0) - (nn / 3.0) * sn * s2 * rj(cn * cn, dn * dn, 1.0,
                                                                   1.0 + nn * s2)
    return sn, cn, dn, j, p


@jit
def _secular(c, t, j):
    """(G/Iz)t + j·cphi·2Π(−N|k²) in double-double (φ's part that grows with t)."""
    sh, sl = dd_mul_d(c[R0_H], c[R0_L], t)
    ph, pl = dd_mul_d(c[CP_H], c[CP_L], j)
    return dd_add(sh, sl, ph, pl)


@jit
def _moving(c, t):
    """Working-frame E(t) = Rz(φ)Rx(θ)Rz(ψ) as (x, y, z, w), m_work and P_r (exact.py's
    _moving for one elliptic or separatrix body)."""
    uh, ul = dd_mul_d(c[LAM_H], c[LAM_L], t)
    uh, ul = dd_add(uh, ul, c[U0], 0.0)
    nn = c[N]
    if c[KIND] == SEPARATRIX:
        u = uh + ul
        th = math.tanh(u)
        ex = math.exp(-abs(u))
        se = 2.0 * ex / (1.0 + ex * ex)                  # sech without overflow
        rn = math.sqrt(nn)
        p = (c[U0] + rn * math.atan(rn * th)) / (1.0 + nn)
        mx = c[SIGX] * c[MX] * se
        my = c[S] * c[G] * th
        mz = c[SIGD] * c[MZ] * se
        psi = math.atan2(mx, my)
        sh, sl = dd_mul_d(c[RS_H], c[RS_L], t)
    else:
        sn, cn, dn, j, p = _reduced(c, uh, ul)
        s2 = sn * sn
        c2 = cn * cn
        jm2 = j - 2.0 * math.floor(0.5 * j)                # j mod 2, j mod 4 in [0, 2), [0, 4)
        jm4 = j - 4.0 * math.floor(0.25 * j)
        par = 1.0 - 2.0 * jm2
        mx = c[MX] * par * cn
        my = c[S] * c[MY] * par * sn
        mz = c[SIGD] * c[MZ] * dn
        delta = math.atan2((c[MY] - c[MX]) * sn * cn, c[MX] * c2 + c[MY] * s2)
        psi = 0.5 * math.pi - c[S] * (jm4 * math.pi + math.atan2(sn, cn) + delta)
        sh, sl = _secular(c, t, j)
    phi = reduce_4pi(sh, sl) + c[CPHI] * (p - c[P0])
    theta = math.atan2(math.hypot(mx, my), mz)
    sp, cp = math.sin(0.5 * phi), math.cos(0.5 * phi)
    st, ct = math.sin(0.5 * theta), math.cos(0.5 * theta)
    ss, cs = math.sin(0.5 * psi), math.cos(0.5 * psi)
    x, y, z, w = st * cs, -st * ss, ct * ss, ct * cs    # Rx(θ)·Rz(ψ)
    return (cp * x - sp * y, cp * y + sp * x, cp * z + sp * w, cp * w - sp * z,
            mx, my, mz, p)


@jit
def evaluate_into(c, t, q, m):
    """q (4,) ← attitude (principal → inertial), m (3,) ← body momentum at time t (s)."""
    if c[KIND] == CLOSED:
        ah, al = dd_mul_d(c[RL_H], c[RL_L], t)
        bh, bl = dd_mul_d(c[WS_H], c[WS_L], t)
        a = 0.5 * reduce_4pi(ah, al)
        b2 = reduce_4pi(bh, bl)
        sa, sb = math.sin(a), math.sin(0.5 * b2)
        ex, ey, ez = c[E], c[E + 1], c[E + 2]
        x, y, z, w = _qmul(c[LH] * sa, c[LH + 1] * sa, c[LH + 2] * sa, math.cos(a),
                           c[Q0], c[Q0 + 1], c[Q0 + 2], c[Q0 + 3])
        x, y, z, w = _qmul(x, y, z, w, ex * sb, ey * sb, ez * sb, math.cos(0.5 * b2))
        # m0 turned by −ω_s t about e (Rodrigues)
        cb, sb2 = math.cos(b2), math.sin(b2)
        m0x, m0y, m0z = c[M0], c[M0 + 1], c[M0 + 2]
        dot = (ex * m0x + ey * m0y + ez * m0z) * (1.0 - cb)
        m[0] = cb * m0x - sb2 * (ey * m0z - ez * m0y) + ex * dot
        m[1] = cb * m0y - sb2 * (ez * m0x - ex * m0z) + ey * dot
        m[2] = cb * m0z - sb2 * (ex * m0y - ey * m0x) + ez * dot
    else:
        ex, ey, ez, ew, mx, my, mz, _ = _moving(c, t)
        x, y, z, w = _qmul(c[C], c[C + 1], c[C + 2], c[C + 3], ex, ey, ez, ew)
        x, y, z, w = _qmul(x, y, z, w, c[WC], c[WC + 1], c[WC + 2], c[WC + 3])
        for i in range(3):                               # m = Wᵀ m_work
            m[i] = c[W + i] * mx + c[W + 3 + i] * my + c[W + 6 + i] * mz
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    q[0] = x / norm
    q[1] = y / norm
    q[2] = z / norm
    q[3] = w / norm


@jit
def evaluate(rows, body, ts, q, m):
    """q[k], m[k] ← body ``body[k]`` (row of ``rows``) at ts[k], for every k."""
    for k in range(ts.shape[0]):
        evaluate_into(rows[body[k]], ts[k], q[k], m[k])


@jit
def at_one(c, t):
    """(q (4,), m (3,)) of one body at one time."""
    q = np.empty(4)
    m = np.empty(3)
    evaluate_into(c, t, q, m)
    return q, m


@jit
def at_times(c, ts):
    """(q (n, 4), m (n, 3)) of one body at the times ts (n,)."""
    q = np.empty((ts.shape[0], 4))
    m = np.empty((ts.shape[0], 3))
    for k in range(ts.shape[0]):
        evaluate_into(c, ts[k], q[k], m[k])
    return q, m


@jit
def anchor_one(c):
    """Set P0 = P_r(u0) and C = q0 ⊗ w ⊗ E(0)* of one elliptic/separatrix row, E(0) from
    the very code of at(t), so at(0) returns q0 to round-off whatever φ(0)."""
    c[P0] = 0.0
    c[P0] = _moving(c, 0.0)[7]
    ex, ey, ez, ew, _, _, _, _ = _moving(c, 0.0)          # E(0) with the final P0
    x, y, z, w = _qmul(c[Q0], c[Q0 + 1], c[Q0 + 2], c[Q0 + 3],
                       -c[WC], -c[WC + 1], -c[WC + 2], c[WC + 3])
    c[C], c[C + 1], c[C + 2], c[C + 3] = _qmul(x, y, z, w, -ex, -ey, -ez, ew)


for _kernel in (fill_elliptic, _reduced, _secular, _moving, evaluate_into, evaluate, at_one,
                at_times, anchor_one):
    depends_on(_kernel, double_double, elliptic_kernel, exact_constants, jit_settings)
