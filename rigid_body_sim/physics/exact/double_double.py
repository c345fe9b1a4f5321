"""Double-double arithmetic: a value is an unevaluated sum hi + lo of two float64 with
|lo| ≤ ulp(hi)/2, about 106 bits (eps ≈ 1.2e-32), for the secular phases of the exact
solution (:mod:`.kernel`).

Why not np.longdouble: numba has no long double, and long double is plain double on MSVC
and macOS arm64. Error-free transformations (Knuth's TwoSum, Dekker's TwoProd with
Veltkamp's split — ``math.fma`` is not available in numba) need only IEEE float64 with
round-to-nearest, so the same source gives the same bits compiled and as plain Python.
Dekker's split is exact for |a| < 2^996 (the phases here are < 1e12).

References: T. J. Dekker, Numer. Math. 18 (1971) 224; D. E. Knuth, TAOCP vol. 2, 4.2.2;
Y. Hida, X. S. Li, D. H. Bailey, "Library for double-double and quad-double arithmetic"
(2007) — the algorithms below are theirs (``sloppy`` add where stated).
"""
import math

from ..jit import jit

_SPLITTER = 134217729.0          # 2^27 + 1: Veltkamp's split of a 53-bit significand
# 2π and 4π as (hi, lo): hi = float64(π)·k exactly, lo = the next 53 bits of π·k.
PI_HI, PI_LO = 3.141592653589793, 1.2246467991473532e-16
FOUR_PI_HI, FOUR_PI_LO = 4.0 * PI_HI, 4.0 * PI_LO


@jit
def two_sum(a, b):
    """s + e = a + b exactly, s = fl(a + b) (Knuth; no condition on |a|, |b|)."""
    s = a + b
    bb = s - a
    e = (a - (s - bb)) + (b - bb)
    return s, e


@jit
def fast_two_sum(a, b):
    """s + e = a + b exactly for |a| ≥ |b| (or a = 0) (Dekker)."""
    s = a + b
    e = b - (s - a)
    return s, e


@jit
def split(a):
    """a = hi + lo, each with at most 26 significant bits (Veltkamp)."""
    t = _SPLITTER * a
    hi = t - (t - a)
    return hi, a - hi


@jit
def two_prod(a, b):
    """p + e = a·b exactly, p = fl(a·b) (Dekker), barring overflow/underflow."""
    p = a * b
    ah, al = split(a)
    bh, bl = split(b)
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


@jit
def dd_add(ah, al, bh, bl):
    """(ah, al) + (bh, bl), relative error ≤ 2 eps² (Hida–Li–Bailey's IEEE add)."""
    s, e = two_sum(ah, bh)
    t, f = two_sum(al, bl)
    e += t
    s, e = fast_two_sum(s, e)
    e += f
    return fast_two_sum(s, e)


@jit
def dd_mul(ah, al, bh, bl):
    """(ah, al)·(bh, bl), relative error ≤ ~4 eps²."""
    p, e = two_prod(ah, bh)
    e += ah * bl + al * bh
    return fast_two_sum(p, e)


@jit
def dd_mul_d(ah, al, b):
    """(ah, al)·b for a float64 b."""
    p, e = two_prod(ah, b)
    e += al * b
    return fast_two_sum(p, e)


@jit
def dd_reduce(xh, xl, ph, pl):
    """(x − j·p, j) with j = round(x/p): the remainder r (|r| ≲ p/2) as a double-double and
    the integer j as a float. j·p is formed exactly in its high part, so r keeps ~106 bits
    relative to x whatever j (j below 2^53)."""
    j = math.floor(xh / ph + 0.5)
    if j == 0.0:
        return xh, xl, 0.0
    jh, jl = two_prod(j, ph)
    rh, rl = dd_add(xh, xl, -jh, -jl)
    rh, rl = dd_add(rh, rl, -j * pl, 0.0)
    return rh, rl, j


@jit
def reduce_4pi(xh, xl):
    """x − 4π·round(x/4π) as a float64 (|result| ≤ 2π + ulp): the secular phases enter
    quaternions as half angles, so 4π (not 2π) keeps the quaternion's sign continuous."""
    rh, rl, _ = dd_reduce(xh, xl, FOUR_PI_HI, FOUR_PI_LO)
    return rh + rl


@jit
def dd_div(ah, al, bh, bl):
    """(ah, al)/(bh, bl), relative error ≤ ~8 eps² (long division, one correction)."""
    q1 = ah / bh
    ph, pl = dd_mul_d(bh, bl, q1)
    s, f = two_sum(ah, -ph)
    f = f - pl + al
    q2 = (s + f) / bh
    return fast_two_sum(q1, q2)


@jit
def dd_sqrt(ah, al):
    """√(ah, al) for (ah, al) ≥ 0, one Newton correction of the float64 root (~2 eps²)."""
    if ah <= 0.0:
        return 0.0, 0.0
    x = math.sqrt(ah)
    p, e = two_prod(x, x)
    return fast_two_sum(x, ((ah - p) - e + al) / (2.0 * x))
