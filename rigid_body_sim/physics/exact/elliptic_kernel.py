"""Jacobi elliptic functions and Carlson's symmetric integrals R_F, R_J, R_C on float64
scalars, compiled by ``jit.jit`` (plain Python under NUMBA_DISABLE_JIT=1): the compiled
exact solution (:mod:`.kernel`) cannot call scipy.special from numba.

* :func:`ellipj` is Cephes' ``ellpj`` (descending Landen transformation / AGM, the
  algorithm behind ``scipy.special.ellipj``) with one change: it takes the complementary
  parameter k'² = 1 − m as well, so the AGM starts from b₀ = k' without the cancellation
  of √(1 − m) near m = 1 (the near-separatrix bodies have k'² down to 1e-200).
* :func:`rf`, :func:`rj`, :func:`rc`: Carlson's duplication algorithm with his
  termination test and series (B. C. Carlson, "Numerical computation of real or complex
  elliptic integrals", Numer. Algorithms 10 (1995) 13–26), for the real, non-negative
  arguments used here (x, y, z ≥ 0 with at most one zero, p > 0).

Tested against scipy.special (test_elliptic_kernel.py) to a few ulp.
"""
import math

from ..jit import jit

_MACHEP = 1.11022302462515654042e-16       # Cephes' MACHEP, 2^-53
# Carlson's termination: Q = (3r)^(-1/6)·max|A0 − x|, (r/4)^(-1/6)·… for R_J, with the
# relative error of the truncated series ≈ r; r = 2^-53 / 4 leaves a margin under one ulp.
_R = 2.0 ** -55
_RF_Q = (3.0 * _R) ** (-1.0 / 6.0)
_RJ_Q = (0.25 * _R) ** (-1.0 / 6.0)


@jit
def ellipj(u, m, mc):
    """(sn, cn, dn, am) of u for parameter m = k², given mc = 1 − m too (0 ≤ m ≤ 1).

    Cephes ellpj (as in scipy 1.17's xsf): first-order expansions in m for m < 1e-9 and in
    mc for mc ≤ 1e-10 (errors O(m²), O(mc²·cosh²u)), otherwise the AGM/Landen descent,
    which here starts from b₀ = √mc."""
    if m < 1e-9:
        t = math.sin(u)
        b = math.cos(u)
        ai = 0.25 * m * (u - t * b)
        return t - ai * b, b + ai * t, 1.0 - 0.5 * m * t * t, u - ai
    if m >= 0.9999999999:                           # Cephes' threshold (k'² ≤ 1.00000008e-10)
        ai = 0.25 * mc
        b = math.cosh(u)
        t = math.tanh(u)
        phi = 1.0 / b
        twon = b * math.sinh(u)
        sn = t + ai * (twon - u) / (b * b)
        ph = 2.0 * math.atan(math.exp(u)) - 0.5 * math.pi + ai * (twon - u) / b
        ai *= t * phi
        return sn, phi - ai * (twon - u), phi + ai * (twon + u), ph
    a0 = 1.0
    a1 = a2 = a3 = a4 = a5 = a6 = a7 = a8 = 1.0      # a[i], c[i] as scalars: no allocation
    c1 = c2 = c3 = c4 = c5 = c6 = c7 = c8 = 0.0
    b = math.sqrt(mc)
    c = math.sqrt(m)
    a = a0
    twon = 1.0
    i = 0
    while abs(c / a) > _MACHEP and i < 8:
        ai = a
        c = 0.5 * (ai - b)
        t = math.sqrt(ai * b)
        a = 0.5 * (ai + b)
        b = t
        twon *= 2.0
        i += 1
        if i == 1:
            a1, c1 = a, c
        elif i == 2:
            a2, c2 = a, c
        elif i == 3:
            a3, c3 = a, c
        elif i == 4:
            a4, c4 = a, c
        elif i == 5:
            a5, c5 = a, c
        elif i == 6:
            a6, c6 = a, c
        elif i == 7:
            a7, c7 = a, c
        else:
            a8, c8 = a, c
    phi = twon * a * u
    b = phi
    while i > 0:
        if i == 1:
            a, c = a1, c1
        elif i == 2:
            a, c = a2, c2
        elif i == 3:
            a, c = a3, c3
        elif i == 4:
            a, c = a4, c4
        elif i == 5:
            a, c = a5, c5
        elif i == 6:
            a, c = a6, c6
        elif i == 7:
            a, c = a7, c7
        else:
            a, c = a8, c8
        t = c * math.sin(phi) / a
        b = phi
        phi = 0.5 * (math.asin(t) + phi)
        i -= 1
    sn = math.sin(phi)
    cn = math.cos(phi)
    dnfac = math.cos(phi - b)
    # near u = K the quotient is 0/0 (DLMF 22.20.5 discussion; scipy's fix), where
    # dn² = cn² + k'² sn² has no cancellation
    dn = math.sqrt(cn * cn + mc * sn * sn) if abs(dnfac) < 0.1 else cn / dnfac
    return sn, cn, dn, phi


@jit
def rf(x, y, z):
    """Carlson's R_F(x, y, z) = ½∫₀^∞ dt/√((t+x)(t+y)(t+z)), x, y, z ≥ 0, at most one 0."""
    x0, y0 = x, y
    a0 = (x + y + z) / 3.0
    q = _RF_Q * max(abs(a0 - x), max(abs(a0 - y), abs(a0 - z)))
    a = a0
    f = 1.0                                            # 4^-n
    while q * f >= abs(a):
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        lam = sx * sy + sx * sz + sy * sz
        a = 0.25 * (a + lam)
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        f *= 0.25
    xx = (a0 - x0) * f / a                             # (A0 − x0)/(4^n A_n): no cancellation
    yy = (a0 - y0) * f / a
    zz = -(xx + yy)
    e2 = xx * yy - zz * zz
    e3 = xx * yy * zz
    return (1.0 - e2 / 10.0 + e3 / 14.0 + e2 * e2 / 24.0 - 3.0 * e2 * e3 / 44.0) / math.sqrt(a)


@jit
def rc(x, y):
    """Carlson's R_C(x, y) = R_F(x, y, y), x ≥ 0, y > 0, in closed form."""
    if x == y:
        return 1.0 / math.sqrt(x)
    if x < y:
        d = y - x
        return math.atan(math.sqrt(d / x)) / math.sqrt(d) if x > 0.0 else \
            0.5 * math.pi / math.sqrt(y)
    d = x - y
    return math.atanh(math.sqrt(d / x)) / math.sqrt(d)


@jit
def _rc1(e):
    """R_C(1, 1 + e) for e > −1, accurate for small |e| (series below 1e-3)."""
    if abs(e) < 1e-3:
        return 1.0 - e / 3.0 + e * e / 5.0 - e * e * e / 7.0 + e * e * e * e / 9.0
    if e > 0.0:
        s = math.sqrt(e)
        return math.atan(s) / s
    s = math.sqrt(-e)
    return math.atanh(s) / s


@jit
def rj(x, y, z, p):
    """Carlson's R_J(x, y, z, p) = (3/2)∫₀^∞ dt/((t+p)√((t+x)(t+y)(t+z))), x, y, z ≥ 0 (at
    most one 0), p > 0."""
    x0, y0, z0 = x, y, z
    a0 = (x + y + z + 2.0 * p) / 5.0
    delta = (p - x) * (p - y) * (p - z)
    q = _RJ_Q * max(max(abs(a0 - x), abs(a0 - y)), max(abs(a0 - z), abs(a0 - p)))
    a = a0
    f = 1.0                                            # 4^-n
    s = 0.0
    while q * f >= abs(a):
        sx = math.sqrt(x)
        sy = math.sqrt(y)
        sz = math.sqrt(z)
        sp = math.sqrt(p)
        lam = sx * sy + sx * sz + sy * sz
        d = (sp + sx) * (sp + sy) * (sp + sz)
        e = f * f * f * delta / (d * d)
        s += f * _rc1(e) / d
        a = 0.25 * (a + lam)
        x = 0.25 * (x + lam)
        y = 0.25 * (y + lam)
        z = 0.25 * (z + lam)
        p = 0.25 * (p + lam)
        f *= 0.25
    xx = (a0 - x0) * f / a
    yy = (a0 - y0) * f / a
    zz = (a0 - z0) * f / a
    pp = -0.5 * (xx + yy + zz)
    xyz = xx * yy * zz
    p2 = pp * pp
    e2 = xx * yy + xx * zz + yy * zz - 3.0 * p2
    e3 = xyz + 2.0 * e2 * pp + 4.0 * p2 * pp
    e4 = (2.0 * xyz + e2 * pp + 3.0 * p2 * pp) * pp
    e5 = xyz * p2
    series = (1.0 - 3.0 * e2 / 14.0 + e3 / 6.0 + 9.0 * e2 * e2 / 88.0 - 3.0 * e4 / 22.0
              - 9.0 * e2 * e3 / 52.0 + 3.0 * e5 / 26.0)
    return f * series / (a * math.sqrt(a)) + 6.0 * s
