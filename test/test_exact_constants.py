"""The exact solution's constants in double-double (physics.exact.constants) against
mpmath at high precision: Bulirsch's cel for K and Π, and the rates, K, Π·cphi and k'² of
real bodies, down to k'² ~ 1e-14 beside the separatrix, where long double left k'² with a
relative error ~1e-19/k'²."""
import mpmath
import numpy as np
import pytest

from rigid_body_sim.physics.exact import constants as exact_constants, kernel as ek
from rigid_body_sim.physics.exact import TorqueFreeSolution

pytestmark = pytest.mark.fast


def _mp(pair):
    return mpmath.mpf(pair[0]) + mpmath.mpf(pair[1])


@pytest.mark.slow
def test_cel_in_double_double():
    """K = cel(k', 1) and Π(−N|k²) = cel(k', 1 + N) to 1e-30 relative (measured ≤ 2e-31)
    for k'² from 1e-200 to 1 and N from 0 to 1e6 (mpmath at 330 digits: 1 − m = 1e-200
    must be resolved)."""
    worst = 0
    with mpmath.workdps(330):
        for kp2 in (1e-200, 1e-30, 5e-7, 1e-3, 0.5, 1.0):
            kp = float(np.sqrt(kp2))
            m = 1 - mpmath.mpf(kp) ** 2
            for n in (0.0, 1e-8, 0.5, 3.0, 36.05, 1e6):
                got = _mp(exact_constants.cel(kp, 0.0, *exact_constants.two_sum(1.0, n)))
                ref = mpmath.ellippi(-mpmath.mpf(n), m) if n else mpmath.ellipk(m)
                worst = max(worst, abs(got / ref - 1))
    assert worst < 1e-30, worst


def _reference(ix, iy, iz, mw):
    """λ, K, G/Iz, cphi·2Π and k'² of exact.py's formulas, in mpmath from the same floats."""
    lx, ly, lz = (mpmath.mpf(v) for v in (ix, iy, iz))
    sq = [mpmath.mpf(v) ** 2 for v in mw]
    dx = sq[1] * (ly - lx) / ly + sq[2] * (lz - lx) / lz
    dy = sq[0] * (lx - ly) / lx + sq[2] * (lz - ly) / lz
    lam = mpmath.sqrt((lz - ly) * dx / (lx * ly * lz))
    kp2 = dy * (lz - lx) / (dx * (lz - ly))
    n = lz * (ly - lx) / (lx * (lz - ly))
    rate0 = mpmath.sqrt(sum(sq)) / lz
    cphi = rate0 * (lz - lx) / (lx * lam)
    return lam, mpmath.ellipk(1 - kp2), rate0, 2 * cphi * mpmath.ellippi(-n, 1 - kp2), kp2


ROUND = [((1.0, 2.0, 3.0), m0) for m0 in ((0.3, 0.5, 0.9), (0.9, 0.5, 0.3), (1e-3, 2.0, 1e-3),
                                         (1e-7, 2.0, 1e-7), (2e-7, -3.0, -1e-7),
                                         (0.5, 1e-9, 1.2))]
# Beside the separatrix of (2, 3, 6) through (1, 0.5, 1): Δ_y is a sum of two O(1) terms
# that cancel to k'² ~ 1e-6 … 2e-13. Long double gave K there to 6.5e-13 and 2.4e-9.
CANCEL = [((2.0, 3.0, 6.0), m0) for m0 in ((1.0, 0.5, 1 + 1e-6), (1.0, 0.5, 1 - 1e-9),
                                           (1.0, 0.3, 1 + 2.0 ** -40), (0.7, 0.5, 0.7 + 1e-13))]


@pytest.mark.parametrize('moments, m0', ROUND + CANCEL)
def test_rates_and_integrals_of_real_bodies(moments, m0):
    """Every pair to 1e-28 relative plus what k'²'s own cancellation leaves, 1e-31/k'²
    (measured ≤ 6e-32 and 1.4e-21 at k'² = 2.3e-13; the phases carry that times ωt), and
    the float64 k'² to 2 eps relative (measured ≤ 0.5 eps; long double: 7.7e-8 at 2.3e-13)."""
    sol = TorqueFreeSolution(moments, (0.0, 0.0, 0.0, 1.0), m0)
    assert sol.regime in ('A', 'B')
    row = sol._rows[0]
    W = row[ek.W:ek.W + 9].reshape(3, 3)
    ix, iy, iz = np.abs(W) @ sol.moments
    with mpmath.workdps(60):
        lam, K, rate0, cp, kp2 = _reference(ix, iy, iz, W @ np.asarray(m0))
        for (h, lo), ref in (((ek.LAM_H, ek.LAM_L), lam), ((ek.K_H, ek.K_L), K),
                             ((ek.R0_H, ek.R0_L), rate0), ((ek.CP_H, ek.CP_L), cp),
                             ((ek.TK_H, ek.TK_L), 2 * K)):
            assert abs(_mp((row[h], row[lo])) / ref - 1) < 1e-28 + 1e-31 / kp2, (h, m0)
        assert abs(row[ek.KP2] / kp2 - 1) <= 2 * np.finfo(float).eps, (float(kp2), m0)


@pytest.mark.parametrize('m0', [(3e-5, 3.0, 1e-5), (-2e-5, 3.0, 3e-5), (1e-4, -2.0, -1e-4)])
def test_initial_phase_near_the_quarter_period(m0):
    """A state just off the intermediate axis has am u0 within √k' of ±π/2, where cos am
    is small: u0 = F(am u0) is then taken as ±(K − v) from the complementary amplitude
    (relative quantities only). |Δm|/|m| ≤ 1e-14 over 200 s against 40 digits (measured
    ≤ 1.7e-15; from cos am directly, as the numpy path does, 1.8e-12 … 2.2e-12)."""
    from rigid_body_sim.bench.reference40 import Reference40, vector_error
    q0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    sol, ref = TorqueFreeSolution((1.0, 2.0, 3.0), q0, m0), Reference40((1.0, 2.0, 3.0), q0, m0)
    assert sol._row0[ek.KP2] < 1e-8
    g = np.linalg.norm(m0)
    for t in np.linspace(0.5, 200.0, 9):
        assert vector_error(sol.at(t)[1], ref.at(t)[1]) <= 1e-14 * g, t
