"""The 40-digit torque-free reference (mpmath; bench/reference40.py) checked two ways.

Closed form (mpmath elliptic functions) against mpmath.odefun on Euler's equations and the
quaternion kinematics at t = 10 s, and its period arithmetic at 1e6 s against a restart
from its own state and against mpmath's unreduced elliptic functions.
"""
import mpmath
import pytest

from rigid_body_sim.bench.exact_horizon import case, ode_check
from rigid_body_sim.bench.reference40 import Reference40, attitude_error, vector_error

pytestmark = pytest.mark.fast


@pytest.mark.parametrize('name', ['intermediate_axis', 'tumble', 'symmetric_top'])
@pytest.mark.slow
def test_closed_form_matches_mpmath_ode(name):
    """Agreement to 1e-30 at t = 10 s (measured ≤ 1e-35 with the ODE at 34 digits, ≤ 1e-41
    at 40): the constants, signs and phase conventions of the closed form are right.
    ~3.3 CPU-s for the three on mpmath's GMP backend (10 on its pure-Python one)."""
    att, mom = ode_check(name, 10.0, dps=34)
    assert att < 1e-30 and mom < 1e-30


@pytest.mark.parametrize('name', ['intermediate_axis', 'tumble', 'symmetric_top',
                                  'config/tennis_racket'])
def test_period_arithmetic_at_1e6_s(name):
    """The state at 1e6 s equals the one reached by restarting at 1e6 − 7.25 s (1e-45):
    the reduction u = 2jK + r, am u = jπ + am r and the precession's quasi-periodicity
    hold at j ~ 1e6; sn(u) without the reduction agrees too."""
    c = case(name)
    ref = Reference40(c.moments, c.q0, c.m0)
    q1, m1 = ref.at(1e6 - 7.25)
    q2, m2 = Reference40(c.moments, q1, m1).at(7.25)
    q, m = ref.at(1e6)
    g = float(mpmath.norm(mpmath.matrix(m)))
    assert attitude_error(q2, q) < 1e-45
    assert vector_error(m2, m) < 1e-45 * g
    if ref.regime != 'closed':
        with mpmath.workdps(60):
            u = ref._lam * 10 ** 6 + ref._u0
            sn = mpmath.ellipfun('sn', u, m=ref._k2) * ref._sy * ref._My
            mw = [sum(r[k] * m[k] for k in range(3)) for r in ref._rows]
            assert abs(sn - mw[1]) < 1e-45 * g


def test_mpmath_runs_on_its_gmp_backend():
    """requirements.txt installs gmpy2, which mpmath takes at import: the same digits at a
    third of the CPU of its pure-Python integers (issue 32)."""
    assert mpmath.libmp.BACKEND == 'gmpy'


def test_inputs_are_taken_exactly():
    """float64 inputs become mpf without rounding; mpf inputs pass through."""
    ref = Reference40((1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), (0.1, 0.2, 0.3))
    with mpmath.workdps(60):
        assert ref.m0[0] == mpmath.mpf(0.1) and ref.m0[0] != mpmath.mpf('0.1')
    with pytest.raises(ValueError):
        Reference40((2.0, 3.0, 6.0), (0.0, 0.0, 0.0, 1.0), (1.0, 0.5, 1.0))  # Δ2 = 0
