"""The compiled evaluation of the torque-free solution (physics.exact.kernel) against the
vectorised numpy path (TorqueFreeSolution.at_numpy: long double, scipy.special), against
the 40-digit reference, and compiled against plain Python (NUMBA_DISABLE_JIT=1).
"""
import itertools
import json

import numpy as np
import pytest
from jit_modes import run_both

from rigid_body_sim.bench.reference40 import Reference40, attitude_error
from rigid_body_sim.physics import rotation
from rigid_body_sim.physics.exact import kernel as exact_kernel
from rigid_body_sim.physics.exact import TorqueFreeSolution

pytestmark = pytest.mark.fast


def _bodies(rng):
    """(label, moments, m0): generic (cases A and B), exactly on the separatrix in every
    relabelling and sign, symmetric, spherical, steady spin about each axis, rest."""
    for _ in range(60):
        yield 'generic', rng.uniform(0.5, 5, 3), rng.normal(size=3) * rng.uniform(0.1, 10)
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            # (2, 3, 6) with |m| = (1, 0.5, 1): Δ2 = −1/2 + 1/2 = 0 exactly
            yield ('separatrix', np.array((2.0, 3.0, 6.0))[list(perm)],
                   (np.array(signs) * (1.0, 0.5, 1.0))[list(perm)])
    for _ in range(10):
        mo = rng.uniform(0.5, 5, 3)
        mo[rng.integers(2)] = mo[2]
        yield 'symmetric', mo, rng.normal(size=3)
        yield 'spherical', np.full(3, rng.uniform(0.5, 5)), rng.normal(size=3)
        m0 = np.zeros(3)
        m0[rng.integers(3)] = rng.normal() * 3
        yield 'steady_spin', rng.uniform(0.5, 5, 3), m0
    yield 'steady_spin', np.array((1.0, 2.0, 3.0)), np.zeros(3)


def test_compiled_path_matches_numpy_path():
    """Over |t| ≤ 1e3 s the two paths agree to 2e-14 rad and 2e-15·|m| (measured ≤ 4.5e-15
    and 1e-15): same formulas, phases in double-double vs long double. Every regime is
    met, and the one-time call gives the many-times call's numbers."""
    rng = np.random.default_rng(11)
    ts = np.concatenate([[0.0], rng.uniform(-1e3, 1e3, 20)])
    seen = set()
    for label, moments, m0 in _bodies(rng):
        q0 = rng.normal(size=4)
        sol = TorqueFreeSolution(moments, q0 / np.linalg.norm(q0), m0)
        assert sol.regime in (('A', 'B') if label == 'generic' else (label,)), (label, m0)
        seen.add(str(sol.regime))
        q, m = sol.at(ts)
        qn, mn = sol.at_numpy(ts)
        g = max(np.linalg.norm(m0), 1e-300)
        assert np.max(rotation.angle_between(q, qn)) < 2e-14, (label, moments, m0)
        assert np.max(np.abs(m - mn)) <= 2e-15 * g, (label, moments, m0)
        q1, m1 = sol.at(float(ts[5]))
        assert np.array_equal(q1, q[5]) and np.array_equal(m1, m[5])
    assert seen == {'A', 'B', 'separatrix', 'symmetric', 'spherical', 'steady_spin'}


def test_near_separatrix_against_the_reference():
    """k'² from 1e-4 down to 1e-9: against 40 digits over 1e3 s the compiled path is within
    1e-13 rad (measured ≤ 3.7e-14; the numpy path up to 6.3e-12 in this set, from k'² as
    1 − m and u0 from a small cos am) and never worse than the numpy path by more than
    5e-14 (round-off of either)."""
    rng = np.random.default_rng(12)
    ts = np.array([3.3, 77.7, 512.0, 1e3])
    for _ in range(6):
        moments = rng.uniform(0.5, 5, 3)
        m0 = np.zeros(3)
        m0[np.argsort(moments)[1]] = 3.0
        m0 += rng.normal(size=3) * 10 ** rng.uniform(-4.5, -2)
        q0 = rng.normal(size=4)
        q0 /= np.linalg.norm(q0)
        sol, ref = TorqueFreeSolution(moments, q0, m0), Reference40(moments, q0, m0)
        refs = [ref.at(t)[0] for t in ts]
        err = max(attitude_error(a, r) for a, r in zip(sol.at(ts)[0], refs))
        err_numpy = max(attitude_error(a, r) for a, r in zip(sol.at_numpy(ts)[0], refs))
        assert err <= err_numpy + 5e-14 and err < 1e-13, (sol._row0[exact_kernel.KP2], err)


_SCRIPT = '''
import json, sys, numpy as np
from rigid_body_sim.physics import jit
from rigid_body_sim.physics.exact import double_double as dd, elliptic_kernel as ek
from rigid_body_sim.physics.exact import kernel as exact_kernel
from rigid_body_sim.physics.exact import TorqueFreeSolution
from rigid_body_sim.bench.exact_horizon import case
from rigid_body_sim.bench.reference40 import Reference40, attitude_error
out = {"compiled": jit.COMPILED}
out["ellipj"] = [ek.ellipj(u, m, 1.0 - m) for u in (0.3, -2.0, 5.0)
                 for m in (0.0, 1e-10, 0.3, 0.99, 1.0 - 1e-11)]
out["carlson"] = [(ek.rf(x, y, 1.0), ek.rj(x, y, 1.0, p))
                  for x, y, p in ((0.0, 0.5, 1.5), (0.3, 0.9, 30.0), (1e-9, 1e-3, 1.0))]
out["dd"] = [dd.two_prod(0.1, 3.3), dd.dd_mul_d(*dd.two_prod(0.7, 1.1), 1e6),
             dd.reduce_4pi(*dd.two_prod(9.87654321, 1.234e6))]
bodies = [((1.0, 2.0, 3.0), (0.3, 0.5, 0.9)), ((1.0, 2.0, 3.0), (0.9, 0.5, 0.3)),
          ((2.0, 3.0, 6.0), (1.0, -0.5, 1.0)), ((2.0, 2.0, 3.0), (0.3, 0.4, 1.0)),
          ((1.0, 2.0, 3.0), (0.0, 0.0, 2.0))]
ts = [0.0, 0.7, 1e3, 1e6]
out["exact"] = []
for moments, m0 in bodies:
    sol = TorqueFreeSolution(moments, (0.1, -0.2, 0.3, 0.9), m0)
    out["exact"].append([[a.tolist() for a in sol.at(t)] for t in ts])
    q, m = sol.at(np.array(ts))
    out["exact"].append([q.tolist(), m.tolist()])
errors = []
for name in json.loads(sys.argv[1]):
    c = case(name)
    sol, ref = TorqueFreeSolution(c.moments, c.q0, c.m0), Reference40(c.moments, c.q0, c.m0)
    errors.append([attitude_error(sol.at(t)[0], ref.at(t)[0]) for t in (1e3, 1e6)])
out["long_horizon"] = errors
print(json.dumps(out))
'''
EPS = np.finfo(float).eps


def _flat(x):
    return [v for item in x for v in _flat(item)] if isinstance(x, list) else [float(x)]


SCENES = ['intermediate_axis', 'config/tennis_racket', 'symmetric_top']


@pytest.mark.slow
def test_compiled_and_plain_python_agree():
    """The same source compiled and as plain Python: the elliptic functions, double-double
    operations and exact evaluations (one and many times, every kind) agree to 4 eps (the
    libm of numba and of CPython may round sin/cos differently), and the plain mode meets
    the long-horizon targets too (1e-12 rad at 1e3 s, 1e-9 at 1e6 s vs 40 digits)."""
    compiled, plain = run_both(_SCRIPT, json.dumps(SCENES))
    assert compiled.pop('compiled') is True and plain.pop('compiled') is False
    for key in ('ellipj', 'carlson', 'dd'):
        np.testing.assert_allclose(_flat(compiled[key]), _flat(plain[key]), rtol=4 * EPS,
                                   atol=1e-300, err_msg=key)
    # q and m are O(1) (|m0| ≤ 1.1 here): 4 eps absolute
    np.testing.assert_allclose(_flat(compiled['exact']), _flat(plain['exact']), rtol=0,
                               atol=4 * EPS)
    for run in (compiled, plain):
        for name, (e3, e6) in zip(SCENES, run['long_horizon']):
            assert e3 <= 1e-12 and e6 <= 1e-9, (name, e3, e6)


def test_kernel_module_is_registered_for_warm_up():
    """compiled.warm runs exact.warm (a kernel module of the registered ``exact``), which
    compiles (or loads) the exact kernels."""
    from rigid_body_sim.physics import INTEGRATORS, exact, jit
    assert exact in INTEGRATORS['exact'].kernel_modules
    assert exact.warm() is jit.COMPILED


def test_compiled_classification_is_the_numpy_one():
    """exact_build.build (compiled) and TorqueFreeSolution (numpy) classify alike — pack
    raises otherwise — at the rules' edges too: moments equal within 1e-12 of the largest
    or just beyond, momentum exactly on an axis or 1e-90·G off it, Δ2 = 0 exactly."""
    from rigid_body_sim.physics.exact import build as exact_build
    cases = [((1.0, 1.0 + 1e-12, 2.0), (0.3, 0.4, 0.5)),
             ((1.0, 1.0 + 3e-12, 2.0), (0.3, 0.4, 0.5)),
             ((2.0, 2.0 - 1e-12 * 2.0, 2.0), (0.3, 0.4, 0.5)), ((1.0, 2.0, 3.0), (0.0, 2.0, 0.0)),
             ((1.0, 2.0, 3.0), (1e-90, 2.0, 0.0)), ((3.0, 6.0, 2.0), (0.5, 1.0, 1.0)),
             ((3.0, 6.0, 2.0), (0.5, -1.0, 1.0 + 2.0 ** -52)), ((1.0, 2.0, 3.0), (0.0, 0.0, 0.0))]
    row = np.empty(exact_kernel.NCONST)
    kinds = {'spherical': 0, 'symmetric': 0, 'steady_spin': 0, 'A': 1, 'B': 1, 'separatrix': 2}
    seen = set()
    for moments, m0 in cases:
        sol = TorqueFreeSolution(moments, (0.0, 0.0, 0.0, 1.0), m0)   # pack checks too
        kind = exact_build.build(np.array(moments), np.array([0.0, 0.0, 0.0, 1.0]),
                                 np.array(m0), row)
        assert kind == kinds[sol.regime], (moments, m0, sol.regime)
        seen.add(str(sol.regime))
    assert seen == set(kinds)


def test_one_shot_flow_is_the_solution():
    """exact_build.flow (the exact integrator's split step) gives TorqueFreeSolution.at's
    result for every regime (to 4 eps: TorqueFreeSolution re-normalises q0), and a
    non-finite state through the integrator raises IntegrationError (not ValueError), as
    in every method."""
    from rigid_body_sim.physics import Dissipation, Dynamics, IntegrationError, create
    from rigid_body_sim.physics.exact import build as exact_build
    rng = np.random.default_rng(13)
    for label, moments, m0 in _bodies(rng):
        q0 = rng.normal(size=4)
        q0 /= np.linalg.norm(q0)
        t = float(rng.uniform(-50, 50))
        q, m = np.empty(4), np.empty(3)
        exact_build.flow(np.asarray(moments, float), q0, np.asarray(m0, float), t, q, m)
        q_ref, m_ref = TorqueFreeSolution(moments, q0, m0).at(t)
        assert np.max(np.abs(q - q_ref)) <= 4 * EPS, label
        assert np.max(np.abs(m - m_ref)) <= 4 * EPS * max(1.0, np.linalg.norm(m0)), label
    integ = create('exact', Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation('viscous', 0.1)))
    q, m = integ.step(np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.3, 0.5, 0.9]), 0.1)
    assert np.isclose(np.linalg.norm(q), 1.0)
    assert np.linalg.norm(m) < np.linalg.norm([0.3, 0.5, 0.9])          # viscous damping
    with pytest.raises(IntegrationError):
        integ.step(np.array([0.0, 0.0, 0.0, 1.0]), np.array([np.nan, 0.5, 0.9]), 0.1)
