"""The torque-free solution on an equally spaced grid of times, at a fraction of the cost
of evaluating it at each (:func:`at_grid`; the engine's samples are such a grid).

A direct evaluation (:mod:`.kernel`) costs ~0.7 µs: Landen/AGM for sn, cn, dn (about
half) and Carlson's R_F and R_J for Π (about a third). On a grid t_k = t0 + k·dt the
samples are taken in blocks of 2H + 1 about an *anchor* evaluated directly, and each
sample at offset j·dt from its anchor comes from the anchor and a table of the offsets
(computed directly once per call) by addition theorems, with no series and no trig:

* sn, cn, dn(u + v) from those of u and v (DLMF 22.8.1–3), v = λ·j·dt;
* P(u + v) = P(u) + P(v) + c·atan2(Y, X), P(u) = Π(−N; am u | k²) (Jacobi's addition
  theorem for Π, Whittaker & Watson §22.741, with the parameter a = iβ, sn a = i√N/k, so
  cn a = √(1 + N/k²), dn a = √(1 + N)): X = 1 + N sn²w − N sn u sn v cn w dn w,
  Y = −√(N(k² + N)(1 + N)) sn u sn v sn w, w = u + v, and c = √N/√((k² + N)(1 + N)) =
  1/|cphi|, so φ's share is ± the angle of X + iY: its half-angle is algebraic;
* ψ is the continuous angle of M_x cn u + i M_y sn u (the rotation's tan ψ = m_x/m_y), so
  ψ/2 at the sample is the anchor's plus half the angle between the two, and θ/2 is the
  half-angle of (m_z, |m_xy|).

Each sample is one addition away from two direct evaluations, so the error does not grow
along the grid. The offsets are kept to |λ j dt| ≤ UMAX, where 1 − k² sn²u sn²v (the
theorems' denominator) stays clear of 0 even beside the separatrix and each angle step
stays below π; a grid too coarse for two offsets, a separatrix or a closed-form body is
evaluated directly, and so is a nearly symmetric body (N outside [NMIN, NMAX]). Tested against the
direct evaluation and the 40-digit reference (test_exact_grid.py).
"""
import math

from .. import jit as jit_settings
from . import constants as exact_constants, double_double, elliptic_kernel, kernel as exact_kernel
from .double_double import dd_add, dd_mul_d, reduce_4pi
from .elliptic_kernel import ellipj, rf, rj
from .kernel import (C, CPHI, ELLIPTIC, G, KIND, KP2, LAM_H, LAM_L, MX, MY, MZ, N, P0, R0_H, R0_L,
                     S, SIGD, U0, W, WC, _qmul, _reduced, _secular, evaluate_into)
from ..jit import depends_on, inline, jit
import numpy as np

HMAX = 32      # at most 2·HMAX + 1 samples per anchor
CHAIN = 4      # one anchor in CHAIN evaluated directly, the others two hops from the last,
# where k'² ≥ CHAIN_KP2: closer to the separatrix a chained anchor's phase error shows (at
# k'² 1e-5, the tennis racket, 4.6e-14 rad and 1.8e-14·|m| against the 40-digit reference,
# direct 1.5e-14 and 1e-16; at k'² 1e-9 2e-12·|m|)
CHAIN_KP2 = 1e-6
UMAX = 1.0     # |λ·j·dt| ≤ UMAX: sn v ≤ tanh 1 < 0.77 (any k), so the denominator ≥ 0.4
# N = Iz(Iy − Ix)/[Ix(Iz − Iy)] outside [NMIN, NMAX] (a body symmetric to ~1e-4): near
# Iz = Iy φ turns by ~π within Δu ~ 1/√N, near Ix = Iy φ and ψ nearly cancel, and an ulp
# of u or of a constant moves the Euler angles by ~max(√N, 1/√N) ulp however they are
# computed; there the grid and the direct evaluation differ by up to 3e-10 (1e-13 inside;
# both as far from the 40-digit reference), so such bodies are evaluated directly
NMIN, NMAX = 1e-4, 1e4
_RH = math.sqrt(0.5)


@inline
def _half(x, y):
    """(cos a/2, sin a/2) of a = atan2(y, x) ∈ (−π, π], (x, y) ≠ 0, by square roots.
    Branch-free (the larger of the two by a square root, the other from it), so that a
    loop of them runs several samples to an instruction (:func:`_lanes`); each branch's
    numbers are the same: 1 − c = 1 + |c| for c < 0, and a division by ±b is ± that by b."""
    ir = 1.0 / math.sqrt(x * x + y * y)
    cx = x * ir
    big = math.sqrt(0.5 * (1.0 + abs(cx)))
    other = 0.5 * (y * ir) / big
    pos = cx >= 0.0
    return (big if pos else abs(other)), (other if pos else math.copysign(big, y))


@inline
def _half_r(x, y, r):
    """:func:`_half` given r = |(x, y)| (> 0): with s = r + |x| (no cancellation), the
    larger half is s/√(2rs) and the other y/√(2rs): one square root and one division
    where :func:`_half` takes two of each. The same halves to round-off (a few ulp)."""
    s = r + abs(x)
    w = 1.0 / math.sqrt(2.0 * r * s)
    big = s * w
    other = y * w
    pos = x >= 0.0
    return (big if pos else abs(other)), (other if pos else math.copysign(big, y))


@jit
def offsets(c, dt, h):
    """(2h + 3, 5) table of the offsets j·dt, j = −h − 1…h + 1 (row j + h + 1): sn, cn,
    dn of v = λ j dt and cos, sin of τ/2, τ = (G/Iz)·j dt + cphi·P(v) (φ's change but the
    addition term)."""
    h += 1
    tab = np.empty((2 * h + 1, 5))
    lam = c[LAM_H] + c[LAM_L]
    nn = c[N]
    for i in range(2 * h + 1):
        tj = (i - h) * dt
        v = lam * tj
        s, cv, d, _ = ellipj(abs(v), 1.0 - c[KP2], c[KP2])
        s = math.copysign(s, v)
        s2 = s * s
        p = s * rf(cv * cv, d * d, 1.0) - (nn / 3.0) * s * s2 * rj(cv * cv, d * d, 1.0,
                                                                   1.0 + nn * s2)
        th, tl = dd_mul_d(c[R0_H], c[R0_L], tj)
        tau = th + tl + c[CPHI] * p
        tab[i, 0], tab[i, 1], tab[i, 2] = s, cv, d
        tab[i, 3], tab[i, 4] = math.cos(0.5 * tau), math.sin(0.5 * tau)
    return tab


@jit
def _anchor(c, t):
    """An elliptic row at t, directly: sn, cn, dn of u (not reduced), cos, sin of φ/2 and
    of (A + δ)/2 (ψ = π/2 − s(A + δ), A = am u, as in kernel._moving)."""
    uh, ul = dd_mul_d(c[LAM_H], c[LAM_L], t)
    uh, ul = dd_add(uh, ul, c[U0], 0.0)
    sn, cn, dn, j, p = _reduced(c, uh, ul)
    jm2 = j - 2.0 * math.floor(0.5 * j)
    jm4 = j - 4.0 * math.floor(0.25 * j)
    par = 1.0 - 2.0 * jm2
    sh, sl = _secular(c, t, j)
    phi = reduce_4pi(sh, sl) + c[CPHI] * (p - c[P0])
    delta = math.atan2((c[MY] - c[MX]) * sn * cn, c[MX] * cn * cn + c[MY] * sn * sn)
    ha = 0.5 * (jm4 * math.pi + math.atan2(sn, cn) + delta)
    return (par * sn, par * cn, dn, math.cos(0.5 * phi), math.sin(0.5 * phi), math.cos(ha),
            math.sin(ha))


@inline
def _hop(c, a, tab, j, g):
    """The state ``a`` (:func:`_anchor`'s tuple) moved by the offset of table row j;
    g = √(N(k² + N)(1 + N))."""
    s1, c1, d1, cpa, spa, caa, saa = a
    s2, c2, d2 = tab[j, 0], tab[j, 1], tab[j, 2]
    k2 = 1.0 - c[KP2]
    nn = c[N]
    s12 = s1 * s2
    inv = 1.0 / (1.0 - k2 * s12 * s12)
    sw = (s1 * c2 * d2 + s2 * c1 * d1) * inv
    cw = (c1 * c2 - s12 * d1 * d2) * inv
    dw = (d1 * d2 - k2 * s12 * c1 * c2) * inv
    # φ/2: the anchor's, the offset's τ/2, and half of ±atan2(Y, X) (the sign of cphi)
    x = 1.0 + nn * sw * sw - nn * s12 * cw * dw
    y = -g * s12 * sw
    ch, sh = _half(x, math.copysign(y, y * c[CPHI]))
    ct, st = tab[j, 3], tab[j, 4]
    cp0, sp0 = cpa * ct - spa * st, spa * ct + cpa * st
    cp, sp = cp0 * ch - sp0 * sh, sp0 * ch + cp0 * sh
    # (A + δ)/2: the anchor's plus half the angle from z_a to z = M_x cn + i M_y sn
    za, zb = c[MX] * c1, c[MY] * s1
    zx, zy = c[MX] * cw, c[MY] * sw
    ch, sh = _half(zx * za + zy * zb, zy * za - zx * zb)
    return sw, cw, dw, cp, sp, caa * ch - saa * sh, saa * ch + caa * sh


@inline
def _onto(c, st):
    """The state ``st`` put back on sn² + cn² = 1, dn² = k'² + k² cn² (dn > 0) and unit
    half-angle rotations: a chained anchor's round-off would otherwise grow hop by hop."""
    sw, cw, dw, cp, sp, ca, sa = st
    r = 1.0 / math.sqrt(sw * sw + cw * cw)
    sw, cw = sw * r, cw * r
    dw = math.sqrt(c[KP2] + (1.0 - c[KP2]) * cw * cw)
    r = 1.0 / math.sqrt(cp * cp + sp * sp)
    cp, sp = cp * r, sp * r
    r = 1.0 / math.sqrt(ca * ca + sa * sa)
    return sw, cw, dw, cp, sp, ca * r, sa * r


@jit
def _lanes(c, a, cols, j0, count, g, out):
    """out[0:4, k], out[4:7, k] ← q and m of the state ``a`` (:func:`_anchor`'s tuple) moved
    by the offset of table row j0 + k (``cols``: the table transposed), k < count: as
    :func:`_hop` then the attitude and momentum of kernel.evaluate_into's frames (ψ/2 =
    π/4 − s(A + δ)/2, θ/2 from cos θ = m_z/G, then C ⊗ R_z(φ) ⊗ R_x(θ)R_z(ψ) ⊗ W_C, and
    m = Wᵀ m_work). One loop over the samples with no branch and the row's constants in
    locals, on contiguous lanes: the compiler runs several samples to an instruction
    (~26 ns a sample, where one after another with the stores between cost ~62). Its
    half-angles come from a norm it already has (:func:`_half_r`: |z| is |m_xy|, and
    |z_a| is the anchor's), 6 roots and 5 divisions a sample where :func:`_hop`'s
    arithmetic takes 7 and 7: the same numbers to a few ulp; the loop ~5 % faster."""
    s1, c1, d1, cpa, spa, caa, saa = a
    k2, nn, cphi, sg, sigd = 1.0 - c[KP2], c[N], c[CPHI], c[S], c[SIGD]
    mx, my, mz = c[MX], c[MY], c[MZ]
    px, py, pz, pw = c[C], c[C + 1], c[C + 2], c[C + 3]
    wx, wy, wz, ww = c[WC], c[WC + 1], c[WC + 2], c[WC + 3]
    w0, w1, w2, w3, w4, w5, w6, w7, w8 = (c[W], c[W + 1], c[W + 2], c[W + 3], c[W + 4],
                                          c[W + 5], c[W + 6], c[W + 7], c[W + 8])
    za, zb = mx * c1, my * s1
    ra = math.sqrt(za * za + zb * zb)                    # |z_a|, for the angle to z
    g2 = 2.0 * c[G]
    t_s, t_c, t_d = cols[0, j0:j0 + count], cols[1, j0:j0 + count], cols[2, j0:j0 + count]
    t_ct, t_st = cols[3, j0:j0 + count], cols[4, j0:j0 + count]
    for k in range(count):
        s2, c2, d2 = t_s[k], t_c[k], t_d[k]
        s12 = s1 * s2                                    # _hop: sn, cn, dn(u + v)
        inv = 1.0 / (1.0 - k2 * s12 * s12)
        sw = (s1 * c2 * d2 + s2 * c1 * d1) * inv
        cw = (c1 * c2 - s12 * d1 * d2) * inv
        dw = (d1 * d2 - k2 * s12 * c1 * c2) * inv
        x = 1.0 + nn * sw * sw - nn * s12 * cw * dw     # φ/2
        y = -g * s12 * sw
        ch, sh = _half_r(x, math.copysign(y, y * cphi), math.sqrt(x * x + y * y))
        ct, st = t_ct[k], t_st[k]
        cp0, sp0 = cpa * ct - spa * st, spa * ct + cpa * st
        cp, sp = cp0 * ch - sp0 * sh, sp0 * ch + cp0 * sh
        m0 = mx * cw
        m1 = sg * my * sw
        m2 = sigd * mz * dw
        mxy = math.sqrt(m0 * m0 + m1 * m1)              # |z|: ψ's step and θ share it
        zx, zy = m0, my * sw                             # (A + δ)/2: z = M_x cn + i M_y sn
        ch, sh = _half_r(zx * za + zy * zb, zy * za - zx * zb, mxy * ra)
        ca, sa = caa * ch - saa * sh, saa * ch + caa * sh
        cs, ss = (ca + sg * sa) * _RH, (ca - sg * sa) * _RH
        # θ/2 = half the angle of (m2, |m_xy|), |m| = G to round-off; q is normalised below
        s = c[G] + abs(m2)
        r = 1.0 / math.sqrt(g2 * s)
        big, other = s * r, mxy * r
        pos = m2 >= 0.0
        ch = big if pos else other
        sh = other if pos else big
        x, y, z, w = sh * cs, -sh * ss, ch * ss, ch * cs                 # Rx(θ)·Rz(ψ)
        x, y, z, w = _qmul(px, py, pz, pw,
                           cp * x - sp * y, cp * y + sp * x, cp * z + sp * w, cp * w - sp * z)
        x, y, z, w = _qmul(x, y, z, w, wx, wy, wz, ww)
        inorm = 1.0 / math.sqrt(x * x + y * y + z * z + w * w)
        out[0, k] = x * inorm
        out[1, k] = y * inorm
        out[2, k] = z * inorm
        out[3, k] = w * inorm
        out[4, k] = w0 * m0 + w3 * m1 + w6 * m2                     # m = Wᵀ m_work
        out[5, k] = w1 * m0 + w4 * m1 + w7 * m2
        out[6, k] = w2 * m0 + w5 * m1 + w8 * m2


@jit
def half_width(c, dt):
    """H: samples per anchor 2H + 1 (the table reaches H + 1); 0 where the grid is
    evaluated directly."""
    if c[KIND] != ELLIPTIC or not dt > 0.0 or not NMIN <= c[N] <= NMAX:
        return 0
    step = abs(c[LAM_H]) * dt
    if not step > 0.0:
        return 0
    return int(min(HMAX, math.floor(UMAX / step) - 1))


@jit
def at_grid(c, ts, dt, tab, q, m):
    """q[k], m[k] ← one body's row c at ts[k], times spaced by dt (to their rounding);
    ``tab``: :func:`offsets` of (c, dt, :func:`half_width`) (a caller sampling in several
    calls keeps it), or an empty table to evaluate each time directly (then the very
    numbers of kernel.evaluate_into). Blocks of 2H + 1 samples about an anchor: every
    CHAIN-th evaluated directly at its ts[k], the others two hops (H, H + 1) from the
    previous one."""
    n = ts.shape[0]
    h = (tab.shape[0] - 3) // 2
    if h < 2 or n < 2 * h + 1:
        for k in range(n):
            evaluate_into(c, ts[k], q[k], m[k])
        return
    nn = c[N]
    g = math.sqrt(nn * (1.0 - c[KP2] + nn) * (1.0 + nn))
    chain = CHAIN if c[KP2] >= CHAIN_KP2 else 1
    cols = np.ascontiguousarray(tab.T)                  # the offsets' columns: lanes
    lanes = np.empty((7, 2 * h + 1))
    a = _anchor(c, ts[h])
    block = 0
    for first in range(0, n, 2 * h + 1):
        last = min(n - 1, first + 2 * h)
        centre = (first + last) // 2                     # offsets within −h…h
        if block % chain == 0 or last - first < 2 * h:
            a = _anchor(c, ts[centre])
        else:                                            # from the previous block's anchor
            a = _onto(c, _hop(c, _hop(c, a, tab, 2 * h + 1, g), tab, 2 * h + 2, g))
        count = last - first + 1
        _lanes(c, a, cols, first - centre + h + 1, count, g, lanes)
        for k in range(count):
            for i in range(4):
                q[first + k, i] = lanes[i, k]
            for i in range(3):
                m[first + k, i] = lanes[4 + i, k]
        block += 1


@jit
def grid_instants(first_ns, period_ns, anchor_ns, t_ns, ts):
    """t_ns[k] ← first_ns + k·period_ns and ts[k] ← (t_ns[k] − anchor_ns)/1e9 s, k <
    len(ts): a torque-free exact stretch's sample instants (``Engine._free_samples``) and
    their times from its anchor, in one pass, numpy's arithmetic to the bit (its six
    passes over the stretch cost ~8 ns a sample, a third of the closed form's own)."""
    for k in range(ts.shape[0]):
        t = first_ns + k * period_ns
        t_ns[k] = t
        ts[k] = (t - anchor_ns) / 1e9


for _kernel in (_half, _half_r, offsets, _anchor, _hop, _onto, _lanes, half_width, at_grid):
    depends_on(_kernel, double_double, elliptic_kernel, exact_constants, exact_kernel,
               jit_settings)
