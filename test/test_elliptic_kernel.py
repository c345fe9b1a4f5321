"""Compiled Jacobi elliptic functions and Carlson integrals (physics.exact.elliptic_kernel)
against scipy.special (the same algorithms) and mpmath (the truth, near m → 1 too).

Tolerances (eps = 2.2e-16), stated per function, with the measured values in brackets:
  ellipj vs scipy, m in [0, 1), |u| ≤ 3K: |Δ| ≤ 2 eps·max(1, |value|) for sn, cn, dn, am
    [sn, cn, am bit for bit; dn ≤ 0.5 eps, from dn = √(cn² + k'² sn²) near u = K];
  ellipj vs mpmath from k'² = 1 − m (no cancellation), k'² = 1e-3 … 1e-100, |u| ≤ K/2
    (the range exact_kernel uses): |Δ| ≤ 64 eps [31 eps at k'² = 1e-9, where the Landen
    descent's asin near 1 amplifies rounding by ~1/(2√k'), as in scipy; ≤ 1.5 eps below
    k'² = 1e-10, where Cephes' expansion in k'² takes over];
  R_F, R_J vs scipy: ≤ 8 and ≤ 16 ulp relative [3.1, 6.0]; vs mpmath ≤ 4 ulp [2.4, 2.3],
    for p ≥ 1e-2·max(x, y, z). With p far below x, y, z, R_J's duplication loses up to
    ~1e3 ulp (scipy's too: 4e3 ulp at p = 1e-6, x, z ~ 1e6), a regime exact_kernel never
    enters (p = 1 + N sn² ≥ 1 ≥ cn², dn²).
"""
import mpmath
import numpy as np
import pytest
import scipy.special as sp

from rigid_body_sim.physics.exact import elliptic_kernel as ek

pytestmark = pytest.mark.fast
EPS = np.finfo(float).eps


def _parameters():
    rng = np.random.default_rng(7)
    # 1 − m exact for m ≥ 0.5 (Sterbenz), so mc = 1 − m is the same parameter scipy sees
    return list(rng.uniform(0, 1, 120)) + [0.0, 1e-12, 1e-9, 2e-9, 0.5, 0.999, 1 - 1e-6,
                                           1 - 1e-9, 0.9999999999, 1 - 1e-11, 1 - 2.0 ** -40]


def test_ellipj_matches_scipy():
    worst = np.zeros(4)
    for m in _parameters():
        k = sp.ellipk(m)
        for u in np.linspace(-3 * k, 3 * k, 61):
            got = np.array(ek.ellipj(u, m, 1.0 - m))
            ref = np.array(sp.ellipj(u, m))
            worst = np.maximum(worst, np.abs(got - ref) / np.maximum(1.0, np.abs(ref)))
    assert np.all(worst <= 2 * EPS), worst / EPS


@pytest.mark.parametrize('mc', [1e-3, 1e-6, 1e-9, 1e-10, 1e-12, 1e-16, 1e-30, 1e-100])
def test_ellipj_near_m_1_from_the_complementary_parameter(mc):
    with mpmath.workdps(130):
        m = 1 - mpmath.mpf(mc)
        k = float(mpmath.ellipk(m))
        worst = 0.0
        for u in np.linspace(-0.5 * k, 0.5 * k, 21):
            sn, cn, dn, am = ek.ellipj(u, 1.0 - mc, mc)
            ref_sn = mpmath.ellipfun('sn', u, m=m)
            for got, ref in ((sn, ref_sn), (cn, mpmath.ellipfun('cn', u, m=m)),
                             (dn, mpmath.ellipfun('dn', u, m=m)), (am, mpmath.asin(ref_sn))):
                worst = max(worst, float(abs(got - ref)))
    assert worst <= 64 * EPS, worst / EPS


def _carlson_points():
    rng = np.random.default_rng(8)
    pts = []
    for _ in range(600):                  # as exact_kernel calls them: (cn², dn², 1, 1 + N sn²)
        x, y = rng.uniform(0, 1, 2) ** 3
        pts.append((x, y, 1.0, 1.0 + rng.uniform(0, 40) * rng.uniform(0, 1)))
    for _ in range(200):                  # general positive arguments, p ≥ 1e-2·max(x, y, z)
        x, y, z = 10.0 ** rng.uniform(-8, 8, 3)
        pts.append((x, y, z, max(x, y, z) * 10.0 ** rng.uniform(-2, 2)))
    pts += [(0.0, 1e-200, 1.0, 3.0), (0.0, 1e-10, 1.0, 1.5), (1e-300, 0.5, 1.0, 40.0),
            (0.0, 1.0, 1.0, 1.0), (1.0, 1.0, 1.0, 1.0)]
    return pts


def test_carlson_matches_scipy():
    worst_f = worst_j = 0.0
    for x, y, z, p in _carlson_points():
        worst_f = max(worst_f, abs(ek.rf(x, y, z) / sp.elliprf(x, y, z) - 1))
        worst_j = max(worst_j, abs(ek.rj(x, y, z, p) / sp.elliprj(x, y, z, p) - 1))
    assert worst_f <= 8 * EPS and worst_j <= 16 * EPS, (worst_f / EPS, worst_j / EPS)


def test_carlson_matches_mpmath():
    worst_f = worst_j = 0.0
    with mpmath.workdps(40):
        for x, y, z, p in _carlson_points()[::4]:
            ref_f = mpmath.elliprf(x, y, z)
            ref_j = mpmath.elliprj(x, y, z, p)
            worst_f = max(worst_f, float(abs(ek.rf(x, y, z) / ref_f - 1)))
            worst_j = max(worst_j, float(abs(ek.rj(x, y, z, p) / ref_j - 1)))
    assert worst_f <= 4 * EPS and worst_j <= 4 * EPS, (worst_f / EPS, worst_j / EPS)


def test_rc_closed_form():
    """R_C(x, y) = R_F(x, y, y) on both sides of x = y (scipy's elliprc), ≤ 4 ulp."""
    for x, y in ((0.0, 1.0), (0.3, 2.0), (2.0, 0.3), (1.0, 1.0), (1e-12, 1.0), (5.0, 5.0001)):
        assert abs(ek.rc(x, y) / sp.elliprc(x, y) - 1) <= 4 * EPS, (x, y)
