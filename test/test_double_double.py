"""Double-double arithmetic (physics.exact.double_double) against exact rational arithmetic.

TwoSum and TwoProd must be error-free (hi + lo equals the exact sum/product as a
Fraction, with hi the rounded result); the compound operations must meet their stated
relative bounds; the period reduction must match the exact remainder. Run compiled here;
test_exact_kernel.py runs a subset with NUMBA_DISABLE_JIT=1.
"""
from fractions import Fraction as F

import numpy as np
import pytest

from rigid_body_sim.physics.exact import double_double as dd

pytestmark = pytest.mark.fast
EPS2 = F(1, 2 ** 106)                      # double-double unit round-off (2^-106 = 1.2e-32)


def _doubles(rng, n, spread=60):
    """Random float64 with random signs and exponents in ±spread (binary)."""
    return rng.uniform(-1, 1, n) * np.exp2(rng.integers(-spread, spread, n)).astype(float)


def test_two_sum_and_two_prod_are_exact():
    rng = np.random.default_rng(1)
    a, b = _doubles(rng, 4000), _doubles(rng, 4000)
    for x, y in zip(a.tolist(), b.tolist()):
        s, e = dd.two_sum(x, y)
        assert s == x + y and F(s) + F(e) == F(x) + F(y)
        p, f = dd.two_prod(x, y)
        assert p == x * y and F(p) + F(f) == F(x) * F(y)
        if abs(x) >= abs(y):
            s2, e2 = dd.fast_two_sum(x, y)
            assert F(s2) + F(e2) == F(x) + F(y)
        hi, lo = dd.split(x)
        assert hi + lo == x and F(hi) + F(lo) == F(x)
        # each half fits in 26 bits: its product with another half is exact in float64
        assert F(hi * hi) == F(hi) * F(hi) and F(lo * lo) == F(lo) * F(lo)


def test_add_and_mul_meet_their_bounds():
    """dd_add ≤ 2 eps², dd_mul and dd_mul_d ≤ 4 eps² relative to the exact result
    (non-overlapping inputs: lo = the rounding error of a float64 operation)."""
    rng = np.random.default_rng(2)
    worst_add = worst_mul = F(0)
    for _ in range(3000):
        a1, a2, b1, b2 = _doubles(rng, 4, spread=20).tolist()
        ah, al = dd.two_prod(a1, a2)
        bh, bl = dd.two_prod(b1, b2)
        exact_a, exact_b = F(ah) + F(al), F(bh) + F(bl)
        sh, sl = dd.dd_add(ah, al, bh, bl)
        if exact_a + exact_b != 0:
            worst_add = max(worst_add, abs((F(sh) + F(sl)) / (exact_a + exact_b) - 1))
        ph, pl = dd.dd_mul(ah, al, bh, bl)
        worst_mul = max(worst_mul, abs((F(ph) + F(pl)) / (exact_a * exact_b) - 1))
        qh, ql = dd.dd_mul_d(ah, al, b1)
        worst_mul = max(worst_mul, abs((F(qh) + F(ql)) / (exact_a * F(b1)) - 1))
        assert abs(sl) <= abs(sh) * 2.0 ** -53 and abs(pl) <= abs(ph) * 2.0 ** -53
    assert worst_add <= 2 * EPS2, float(worst_add / EPS2)
    assert worst_mul <= 4 * EPS2, float(worst_mul / EPS2)


def test_reduction_modulo_a_period_is_exact_to_double_double():
    """x = rate·t (rate a long-double-like pair, t up to 1e7 s) reduced mod a period p:
    r = x − j·p with the exact j, |r| ≤ p/2 (+ulp), and r off the exact remainder by
    ≤ 8 eps²·|x| (the j·p product is exact in its high part)."""
    rng = np.random.default_rng(3)
    for _ in range(2000):
        rate = rng.uniform(0.01, 40.0)
        rate_h, rate_l = dd.two_prod(rate, 1.0 + rng.uniform(-1, 1) * 2.0 ** -40)
        ph, pl = dd.two_prod(rng.uniform(0.5, 20.0), 1.0 + rng.uniform(-1, 1) * 2.0 ** -40)
        t = float(rng.uniform(-1e7, 1e7))
        xh, xl = dd.dd_mul_d(rate_h, rate_l, t)
        rh, rl, j = dd.dd_reduce(xh, xl, ph, pl)
        x, p = F(xh) + F(xl), F(ph) + F(pl)
        k = x / p
        if abs(k - round(k)) < F(1, 2) - F(1, 10 ** 6):      # not at a tie: j is round(x/p)
            assert j == round(k)
        exact = x - int(j) * p
        assert abs(F(rh) + F(rl) - exact) <= 8 * EPS2 * abs(x) + F(2) ** -1074
        assert abs(exact) <= p / 2 * (1 + F(1, 2 ** 50))


def test_reduce_4pi_matches_exact_pi():
    """4π as (hi, lo) is π to ~1e-32: x − 4π·round(x/4π) agrees with the reduction by a
    50-digit π (from mpmath) to 1e-30·|x| + 1 ulp of the result, for |x| up to 1e9 rad."""
    import mpmath
    with mpmath.workdps(60):
        four_pi = F(str(4 * mpmath.pi))
        for x in (1e-3, 3.0, 12.5, 1e3 + 0.1, -7.7e6, 1.23456789e9, 6.283185307179586 * 2):
            got = dd.reduce_4pi(x, 0.0)
            exact = F(x) - round(F(x) / four_pi) * four_pi
            assert abs(F(got) - exact) <= F(1e-30) * abs(F(x)) + F(2.0 ** -52) * 8, x
            assert abs(got) <= 6.283185307179587


def test_division_and_square_root_meet_their_bounds():
    """dd_div ≤ 8 eps², dd_sqrt ≤ 4 eps² relative (sqrt checked by squaring exactly)."""
    rng = np.random.default_rng(4)
    worst_div = worst_sqrt = F(0)
    for _ in range(3000):
        a1, a2, b1, b2 = _doubles(rng, 4, spread=20).tolist()
        ah, al = dd.two_prod(a1, a2)
        bh, bl = dd.two_prod(b1, b2)
        exact_a, exact_b = F(ah) + F(al), F(bh) + F(bl)
        qh, ql = dd.dd_div(ah, al, bh, bl)
        worst_div = max(worst_div, abs((F(qh) + F(ql)) * exact_b / exact_a - 1))
        xh, xl = (ah, al) if ah > 0 else (-ah, -al)
        sh, sl = dd.dd_sqrt(xh, xl)
        x = F(xh) + F(xl)
        root = F(sh) + F(sl)
        worst_sqrt = max(worst_sqrt, abs(root * root / x - 1) / 2)  # δ(√x) ≈ δ(x)/2
    assert worst_div <= 8 * EPS2, float(worst_div / EPS2)
    assert worst_sqrt <= 4 * EPS2, float(worst_sqrt / EPS2)
    assert dd.dd_sqrt(0.0, 0.0) == (0.0, 0.0)
