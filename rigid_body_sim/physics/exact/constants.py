"""The exact solution's constants in double-double (:mod:`.double_double`), compiled: the
rates that multiply t, the complete integrals K and Π that multiply the half-period count
j, and the float64 constants that follow from them (k'², the amplitudes, u0).

Why double-double rather than long double: long double is plain double on macOS arm64 and
MSVC, and even as x87 (eps 1.1e-19) it limits k'² near the separatrix, where
Δ_y = Σ m_i²(I_i − I_y)/I_i cancels to k'²·G²: its relative error there is eps/k'² (1e-7
at k'² = 1e-12 in x87). In double-double the squares m_i² and the differences I_i − I_j
are exact and the sums keep ~1e-32, so k'², K, Π and the rates come out as exact as
float64 inputs allow, on any platform.

The formulas are those of :mod:`.exact` (``_elliptic_constants``); K = cel(k', 1) and
Π(−N|k²) = cel(k', 1 + N) by Bulirsch's iteration (as :mod:`.extended` does it in long
double), here in double-double.
"""
import math

from .. import jit as jit_settings
from . import double_double, elliptic_kernel
from .double_double import dd_add, dd_div, dd_mul, dd_mul_d, dd_sqrt, two_prod, two_sum
from .elliptic_kernel import rf
from ..jit import depends_on, jit

_HALF_PI_H, _HALF_PI_L = 1.5707963267948966, 6.123233995736766e-17
_CA = 1e-17                       # ~0.1·√eps_dd: the result is good to ~CA² (Bulirsch)


@jit
def cel(kh, kl, ph, pl):
    """Bulirsch's cel(k_c, p, 1, 1) = ∫₀^{π/2} dθ/((cos²θ + p sin²θ)√(cos²θ + k_c² sin²θ))
    in double-double, k_c > 0, p > 0. K(m) = cel(k', 1), Π(n|m) = cel(k', 1 − n)."""
    ph, pl = dd_sqrt(ph, pl)
    ah, al = 1.0, 0.0
    bh, bl = dd_div(1.0, 0.0, ph, pl)
    eh, el = kh, kl
    mh, ml = 1.0, 0.0
    for _ in range(100):                      # ~log2(log(1/k_c)) + 7 steps
        fh, fl = ah, al
        th, tl = dd_div(bh, bl, ph, pl)
        ah, al = dd_add(ah, al, th, tl)
        gh, gl = dd_div(eh, el, ph, pl)
        th, tl = dd_mul(fh, fl, gh, gl)
        bh, bl = dd_add(bh, bl, th, tl)
        bh, bl = 2.0 * bh, 2.0 * bl
        ph, pl = dd_add(gh, gl, ph, pl)
        gh, gl = mh, ml
        mh, ml = dd_add(kh, kl, mh, ml)
        dh, dl = dd_add(gh, gl, -kh, -kl)
        if abs(dh + dl) <= (gh + gl) * _CA:
            break
        kh, kl = dd_sqrt(eh, el)
        kh, kl = 2.0 * kh, 2.0 * kl
        eh, el = dd_mul(kh, kl, mh, ml)
    th, tl = dd_mul(ah, al, mh, ml)
    nh, nl = dd_add(bh, bl, th, tl)                     # b + a·em
    dh, dl = dd_add(mh, ml, ph, pl)
    dh, dl = dd_mul(mh, ml, dh, dl)                     # em·(em + p)
    nh, nl = dd_mul(_HALF_PI_H, _HALF_PI_L, nh, nl)
    return dd_div(nh, nl, dh, dl)


@jit
def _delta(sa, ia, sb, ib, ij):
    """Σ m_i²(I_i − I_j)/I_i over the two axes a, b ≠ j, m_i² given exactly as pairs."""
    dh, dl = two_sum(ia, -ij)
    xh, xl = dd_div(*dd_mul(sa[0], sa[1], dh, dl), ia, 0.0)
    dh, dl = two_sum(ib, -ij)
    yh, yl = dd_div(*dd_mul(sb[0], sb[1], dh, dl), ib, 0.0)
    return dd_add(xh, xl, yh, yl)


@jit
def sum_squares(x, y, z):
    """x² + y² + z² as a pair (each square exact)."""
    ah, al = two_prod(x, x)
    bh, bl = two_prod(y, y)
    ch, cl = two_prod(z, z)
    ah, al = dd_add(ah, al, bh, bl)
    return dd_add(ah, al, ch, cl)


@jit
def closed_rates(g2h, g2l, me, ie, it):
    """(G/I_t, ω_s = m_e(1/I_e − 1/I_t)) as pairs, from G² as a pair."""
    gh, gl = dd_sqrt(g2h, g2l)
    rh, rl = dd_div(gh, gl, it, 0.0)
    ah, al = dd_div(1.0, 0.0, ie, 0.0)
    bh, bl = dd_div(1.0, 0.0, it, 0.0)
    wh, wl = dd_add(ah, al, -bh, -bl)
    wh, wl = dd_mul_d(wh, wl, me)
    return rh, rl, wh, wl


@jit
def elliptic(ix, iy, iz, mx, my, mz, separatrix, s, out):
    """Constants of one elliptic or separatrix body in its working frame (moments ix, iy,
    iz; momentum mx, my, mz; s the sign of exact.py). ``out`` (18,): lam, 2K, K, G/Iz,
    cphi·2Π, separatrix rate as pairs (0–11), then N, k'², k', K, cphi, u0 (12–17); for an
    elliptic body also the amplitudes Mx, My, Mz (18–20) (out has 21 entries)."""
    sx = two_prod(mx, mx)
    sy = two_prod(my, my)
    sz = two_prod(mz, mz)
    dxh, dxl = _delta(sy, iy, sz, iz, ix)
    dyh, dyl = _delta(sx, ix, sz, iz, iy)
    dzh, dzl = _delta(sx, ix, sy, iy, iz)
    gh, gl = dd_add(*dd_add(sx[0], sx[1], sy[0], sy[1]), sz[0], sz[1])
    gh, gl = dd_sqrt(gh, gl)
    zy = two_sum(iz, -iy)
    yx = two_sum(iy, -ix)
    zx = two_sum(iz, -ix)
    nh, nl = dd_div(*dd_mul_d(yx[0], yx[1], iz), *dd_mul_d(zy[0], zy[1], ix))
    vh, vl = two_prod(ix, iy)
    vh, vl = dd_mul_d(vh, vl, iz)                                   # Ix·Iy·Iz
    if separatrix:
        lh, ll = dd_div(*dd_mul(zy[0], zy[1], yx[0], yx[1]), *two_prod(ix, iz))
        lh, ll = dd_mul(*dd_sqrt(lh, ll), *dd_div(gh, gl, iy, 0.0))
        kph, kpl = 0.5, 0.0
        k2h, k2l = 0.5, 0.0
    else:
        lh, ll = dd_sqrt(*dd_div(*dd_mul(zy[0], zy[1], dxh, dxl), vh, vl))
        k2h, k2l = dd_div(*dd_mul(dyh, dyl, zx[0], zx[1]), *dd_mul(dxh, dxl, zy[0], zy[1]))
        kph, kpl = dd_sqrt(k2h, k2l)
        out[18] = math.sqrt(ix * -(dzh + dzl) / (zx[0] + zx[1]))
        out[19] = math.sqrt(iy * -(dzh + dzl) / (zy[0] + zy[1]))
        out[20] = math.sqrt(iz * (dxh + dxl) / (zx[0] + zx[1]))
    kh, kl = cel(kph, kpl, 1.0, 0.0)
    n1h, n1l = dd_add(nh, nl, 1.0, 0.0)
    ph, pl = cel(kph, kpl, n1h, n1l)
    rh, rl = dd_div(gh, gl, iz, 0.0)                                # G/Iz
    ch, cl = dd_div(*dd_mul(rh, rl, zx[0], zx[1]), *dd_mul_d(lh, ll, ix))
    out[0], out[1] = lh, ll
    out[2], out[3] = 2.0 * kh, 2.0 * kl
    out[4], out[5] = kh, kl
    out[6], out[7] = rh, rl
    out[8], out[9] = dd_mul(2.0 * ch, 2.0 * cl, ph, pl)
    out[10], out[11] = dd_add(rh, rl, *dd_div(*dd_mul(ch, cl, lh, ll), n1h, n1l))
    kf = kh + kl
    out[12], out[13], out[14], out[15], out[16] = nh + nl, k2h + k2l, kph + kpl, kf, ch + cl
    if separatrix:
        out[17] = math.asinh(s * my / math.hypot(mx, mz))
    else:
        # u0 = F(am u0 | k²), am u0 from (cn, sn) = (m_x/Mx, m_y/(s My)), reduced to
        # |am| ≤ π/2 (u0 = 2K·turn + r). Near the quarter period (|am| > π/4) cos am is
        # small and its rounding would cost eps/cos am in F: there r = ±(K − v) with
        # tan(am v) = cn/(k' |sn|) (cn(K − v) = k' sd v, sn(K − v) = cd v), all relative.
        sn0 = my / (s * out[19])
        cn0 = mx / out[18]
        turn = 0.0
        if cn0 < 0.0:
            turn = 1.0 if sn0 >= 0.0 else -1.0
            sn0, cn0 = -sn0, -cn0
        kp = out[14]
        if abs(sn0) <= cn0:
            h = math.hypot(sn0, cn0)
            sr, cr = sn0 / h, cn0 / h
            r = sr * rf(cr * cr, cr * cr + out[13] * sr * sr, 1.0)
        else:
            a, b = cn0, kp * abs(sn0)
            h = math.hypot(a, b)
            sv, cv = a / h, b / h
            v = sv * rf(cv * cv, cv * cv + out[13] * sv * sv, 1.0)
            r = math.copysign((kh - v) + kl, sn0)             # K − v with K a pair
        out[17] = turn * 2.0 * kf + r

for _kernel in (cel, _delta, sum_squares, closed_rates, elliptic):
    depends_on(_kernel, double_double, elliptic_kernel, jit_settings)
