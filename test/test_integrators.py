"""Integrators against analytic invariants, convergence orders and known failure modes.

Standard scene (Hairer–Lubich–Wanner VII.5): I = (2, 1, 2/3) kg·m², m0 = (cos 1.1, 0, sin 1.1).
Each test states its tolerance and why it could fail.
"""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rigid_body_sim.physics import (Dissipation, Dynamics, IntegrationError, create,
                                    dynamics_kernel, rotation)
from rigid_body_sim.physics.integrators import INTEGRATORS

pytestmark = pytest.mark.fast  # make check

I_STD = np.array([2.0, 1.0, 2.0 / 3.0])
M_STD = np.array([np.cos(1.1), 0.0, np.sin(1.1)])
Q_ID = np.array([0.0, 0.0, 0.0, 1.0])


def run(name, dyn, q, m, h, n, torque=None, every=None, **opts):
    """n steps of h by the method's own loop (``Integrator.run``: the compiled one where the
    method has it; test_kernels checks it against the step-by-step numpy path), the state
    kept every ``every`` steps. Stepping in Python cost 2-4 CPU-s a test at 5,000-20,000
    steps (issue 32)."""
    integ = create(name, dyn, **opts)
    out, done = [], 0
    while done < n:
        chunk = min(every or n, n - done)
        q, m = integ.run(q, m, h, chunk, torque, done * h)
        done += chunk
        if every and done % every == 0:
            out.append((q, m))
    return q, m, out


def reference(dyn, q0, m0, t_end, torque=None):
    def f(_, y):
        return np.concatenate((dyn.attitude_rate(y[:4], y[4:]), dyn.momentum_rate(y[4:], torque)))
    y = solve_ivp(f, (0, t_end), np.concatenate((q0, m0)), method='DOP853', rtol=1e-13,
                  atol=1e-15).y[:, -1]
    return y[:4] / np.linalg.norm(y[:4]), y[4:]


def test_registry_has_required_methods_with_one_interface():
    required = {'euler', 'rk4', 'dop853', 'implicit_midpoint', 'splitting2', 'splitting4',
                'splitting6', 'exact'}
    assert required <= set(INTEGRATORS)
    dyn = Dynamics(I_STD)
    for name, cls in INTEGRATORS.items():
        if cls.requires_actuators:  # test_actuators steps it with its wheels/CMGs
            continue
        d = cls.describe()
        assert d['name'] == name and isinstance(d['order'], int) and d['summary']
        q, m = create(name, dyn).step(Q_ID, M_STD, 0.01)
        assert q.shape == (4,) and m.shape == (3,)


@pytest.mark.parametrize('name', ['splitting2', 'splitting4', 'splitting6'])
def test_splitting_keeps_momentum_norm_and_bounded_energy(name):
    """|L| to 1e-12 relative over 10⁵ steps of h = 0.1; energy error bounded (no drift)."""
    dyn = Dynamics(I_STD)
    n = 100_000 if name == 'splitting2' else 20_000
    t0 = dyn.kinetic_energy(M_STD)
    q, m, samples = run(name, dyn, Q_ID, M_STD, 0.1, n, every=100)
    norms = np.array([np.linalg.norm(s[1]) for s in samples])
    assert np.max(np.abs(norms - 1.0)) < 1e-12
    energy_err = np.array([dyn.kinetic_energy(s[1]) / t0 - 1.0 for s in samples])
    first, last = (np.max(np.abs(energy_err[: len(energy_err) // 10])),
                   np.max(np.abs(energy_err[-len(energy_err) // 10:])))
    assert last < 1.5 * first + 1e-15, 'energy error must stay bounded, not drift'
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12


@pytest.mark.parametrize('name,order', [('splitting2', 2), ('splitting4', 4), ('splitting6', 6),
                                        ('rk4', 4), ('implicit_midpoint', 2), ('euler', 1),
                                        ('splitting2_lstable', 2)])
def test_observed_order_of_convergence(name, order):
    """Observed order within ±0.1 (±0.2 for 6, where round-off starts to show) at T = 10 s."""
    dyn = Dynamics(I_STD)
    t_end = 10.0
    q_ref, m_ref = reference(dyn, Q_ID, M_STD, t_end)
    hs = (0.004, 0.002) if name == 'euler' else (0.2, 0.1) if order == 6 else (0.1, 0.05)
    errs = []
    for h in hs:
        q, m, _ = run(name, dyn, Q_ID, M_STD, h, int(round(t_end / h)))
        errs.append(max(rotation.angle_between(q, q_ref), np.linalg.norm(m - m_ref)))
    observed = np.log2(errs[0] / errs[1])
    assert abs(observed - order) < (0.2 if order == 6 else 0.1), (errs, observed)


@pytest.mark.parametrize('model', ['double_bracket', 'viscous'])
@pytest.mark.parametrize('name,order', [('splitting2', 2), ('splitting4', 4), ('splitting6', 6),
                                        ('rk4', 4), ('implicit_midpoint', 2),
                                        ('splitting2_lstable', 2), ('exact', 2)])
def test_observed_order_with_damping_and_torque(name, order, model):
    """With weak damping (λh ≪ 1) and a held torque the compositions keep their order:
    the damping runs inside every stage by a time-symmetric flow; ``exact`` splits both
    off its closed-form free flow (order 2). Against DOP853 at rtol 1e-13 on the same
    equations; ±0.15 (±0.25 for order 6). ``auto`` uses these orders."""
    dyn = Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation(model, 0.1))
    q0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    m0, tau = np.array([0.3, 0.6, 2.7]), np.array([0.01, -0.02, 0.005])
    q_ref, m_ref = create('dop853', dyn, rtol=1e-13, atol=1e-15).step(q0, m0, 10.0, tau)
    errs = []
    for h in ((0.1, 0.05) if order < 6 else (0.2, 0.1)):
        integ = create(name, dyn)
        assert integ.effective_order(m0, h) == order
        q, m = integ.run(q0, m0, h, int(round(10.0 / h)), tau)
        errs.append(max(rotation.angle_between(q, q_ref), np.linalg.norm(m - m_ref)))
    observed = np.log2(errs[0] / errs[1])
    assert abs(observed - order) < (0.25 if order == 6 else 0.15), (errs, observed)


def test_stiff_damping_stays_outside_the_composition():
    """Stiff damping (λh ≫ 1) must not run backwards in negative stages: it stays outside,
    the method reports order 2 there, and the state still decays to the major axis."""
    dyn = Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation('double_bracket', 1000.0))
    integ = create('splitting6', dyn)
    m0 = np.array([0.3, 0.3, 0.9]) / np.linalg.norm([0.3, 0.3, 0.9])
    assert not integ.inner_dissipation(m0, 0.01) and integ.effective_order(m0, 0.01) == 2
    q, m = integ.run(np.array([0.0, 0.0, 0.0, 1.0]), m0, 0.01, 500)
    assert abs(np.linalg.norm(m) - 1.0) < 1e-12 and abs(m[2]) > 1.0 - 1e-9


@pytest.mark.parametrize('alpha,t', [(0.5, 2.0), (1000.0, 0.15)])
def test_exact_double_bracket_flow_solves_its_equation(alpha, t):
    """The closed form of ṁ = α m×(m×Ω) that splitting2_lstable uses for its damping, mild
    and stiff (λt ≈ 1 and 77): the ODE's solution (DOP853, rtol 1e-13) to 1e-12, |m| to
    round-off."""
    dyn = Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation('double_bracket', alpha))
    m0 = np.array([0.6, -0.5, 0.4])
    ref = solve_ivp(lambda _, m: dyn.dissipation_rate(m), (0.0, t), m0, method='DOP853',
                    rtol=1e-13, atol=1e-15).y[:, -1]
    m = m0.copy()
    dynamics_kernel.double_bracket_exact(m, t, dyn.moments, alpha)
    np.testing.assert_allclose(m, ref, rtol=0, atol=1e-12)
    assert abs(np.linalg.norm(m) / np.linalg.norm(m0) - 1.0) < 1e-15


def test_lstable_splitting_kills_the_stiff_mode_where_implicit_midpoint_rings():
    """The bench's stiff scene (I = (1, 2, 3), |L| = 1 started 1e-3 off the major axis,
    α = 1000: stiffness λ = 667/s) at hλ = 100. Implicit midpoint (A- but not L-stable)
    damps the transverse momentum by only ~0.95 per step (its factor → −1 as hλ → ∞);
    splitting2_lstable by ≤ 0.1 (its exact damping sub-flow: e^{−hλ}), keeping |m| to
    1e-12 and T non-increasing, and ends on the major axis like the reference (DOP853,
    rtol 1e-13; truth: transverse 1e-13× its start)."""
    dyn = Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation('double_bracket', 1000.0))
    m0 = np.array([1e-3, 1e-3, 1.0]) / np.linalg.norm([1e-3, 1e-3, 1.0])
    h = 100.0 / dyn.dissipation_stiffness(1.0)
    n = 33
    q_ref, m_ref = create('dop853', dyn, rtol=1e-13, atol=1e-15).step(Q_ID, m0, n * h)
    per_step = {}
    for name in ('splitting2_lstable', 'implicit_midpoint'):
        integ, q, m = create(name, dyn), Q_ID, m0
        transverse, energy, norm = [np.hypot(m[0], m[1])], [dyn.kinetic_energy(m)], []
        for _ in range(n):
            q, m = integ.run(q, m, h, 1)
            transverse.append(np.hypot(m[0], m[1]))
            energy.append(dyn.kinetic_energy(m))
            norm.append(np.linalg.norm(m))
        transverse = np.array(transverse)
        live = transverse[:-1] > 1e-250  # before the mode is gone below the denormals
        per_step[name] = np.max(transverse[1:][live] / transverse[:-1][live])
        if name == 'implicit_midpoint':
            per_step['implicit_midpoint_mean'] = (transverse[-1] / transverse[0]) ** (1 / n)
            continue
        assert np.max(np.abs(np.array(norm) - 1.0)) < 1e-12
        assert np.all(np.diff(energy) <= 1e-15)
        np.testing.assert_allclose(m, m_ref, rtol=0, atol=1e-12)
        assert rotation.angle_between(q, q_ref) < 1e-5
    assert per_step['splitting2_lstable'] <= 0.1
    assert per_step['implicit_midpoint'] < 1.0 and per_step['implicit_midpoint_mean'] > 0.9, \
        per_step


def test_implicit_midpoint_keeps_energy_and_momentum_norm():
    dyn = Dynamics(I_STD)
    t0 = dyn.kinetic_energy(M_STD)
    q, m, _ = run('implicit_midpoint', dyn, Q_ID, M_STD, 0.1, 5000)
    assert abs(dyn.kinetic_energy(m) / t0 - 1.0) < 1e-12
    assert abs(np.linalg.norm(m) - 1.0) < 1e-12
    assert abs(np.linalg.norm(q) - 1.0) < 1e-12


def test_rk4_energy_error_grows_linearly_in_time():
    """HLW scene at h = 0.1: ΔT/T ≈ −1.44e-6 at t = 1000 and twice that at 2000 (ratio 2 ± 0.1)."""
    dyn = Dynamics(I_STD)
    t0 = dyn.kinetic_energy(M_STD)
    _, m2, samples = run('rk4', dyn, Q_ID, M_STD, 0.1, 20_000, every=10_000)
    m1 = samples[0][1]
    e1, e2 = dyn.kinetic_energy(m1) / t0 - 1.0, dyn.kinetic_energy(m2) / t0 - 1.0
    assert e1 < 0 and e2 < 0
    assert abs(e2 / e1 - 2.0) < 0.1


def test_euler_increases_momentum_norm_and_energy_at_every_step():
    """|m_{n+1}|² = |m_n|² + h²|ṁ|² and T grows likewise: strictly increasing, every step."""
    dyn = Dynamics(I_STD)
    integ = create('euler', dyn)
    q, m = Q_ID, M_STD
    for k in range(500):
        q2, m2 = integ.step(q, m, 0.05)
        assert np.linalg.norm(m2) > np.linalg.norm(m)
        assert dyn.kinetic_energy(m2) > dyn.kinetic_energy(m)
        f = dyn.momentum_rate(m)
        assert np.linalg.norm(m2) ** 2 == pytest.approx(
            np.linalg.norm(m) ** 2 + 0.05 ** 2 * f @ f, rel=1e-12)
        q, m = q2, m2


def test_splitting_axis_order_is_the_measured_best_and_matters():
    """The chosen axis order beats the worst one (major axis outermost) on random bodies."""
    import itertools
    from rigid_body_sim.physics.integrators import splitting
    rng = np.random.default_rng(3)
    bodies = []
    while len(bodies) < 12:
        moments = np.sort(rng.uniform(1, 3, 3))
        if moments[0] + moments[1] >= moments[2]:
            bodies.append((moments, moments * rng.normal(size=3)))
    saved = splitting._ORDER
    errors = {}
    try:
        for order in itertools.permutations((0, 1, 2)):
            splitting._ORDER = order
            errs = []
            for moments, m0 in bodies:
                dyn = Dynamics(moments)
                h = 0.2 / np.max(np.abs(m0 / moments))
                integ, q, m, worst = create('splitting2', dyn), Q_ID, m0, 0.0
                for _ in range(300):
                    q, m = integ.step(q, m, h)
                    worst = max(worst, abs(dyn.kinetic_energy(m) / dyn.kinetic_energy(m0) - 1.0))
                errs.append(worst)
            errors[order] = np.exp(np.mean(np.log(errs)))
    finally:
        splitting._ORDER = saved
    assert errors[saved] == min(errors.values())
    assert max(errors.values()) / errors[saved] > 2.5


def test_intermediate_axis_growth_rate():
    """I = (1, 2, 3), ω0 = (1e-6, 1, 0): ln|ω1| grows at ω2·√((I2−I1)(I3−I2)/(I1 I3))
    within 1 %."""
    moments = np.array([1.0, 2.0, 3.0])
    dyn = Dynamics(moments)
    sigma = 1.0 * np.sqrt((2 - 1) * (3 - 2) / (1 * 3))
    q, m = Q_ID, moments * np.array([1e-6, 1.0, 0.0])
    integ = create('splitting4', dyn)
    h, log_w1 = 0.01, []
    for k in range(1, 1001):
        q, m = integ.step(q, m, h)
        if k % 100 == 0:
            log_w1.append((k * h, np.log(abs(m[0] / moments[0]))))
    t, y = np.array(log_w1).T
    slope = np.polyfit(t[2:], y[2:], 1)[0]  # skip the first 2 s: the decaying mode dies out
    assert slope == pytest.approx(sigma, rel=0.01)


@pytest.mark.parametrize('axis', [0, 2])
def test_spins_near_stable_axes_stay_within_small_polhodes(axis):
    moments = np.array([1.0, 2.0, 3.0])
    w0 = np.full(3, 1e-3)
    w0[axis] = 1.0
    q, m, samples = run('splitting2', Dynamics(moments), Q_ID, moments * w0, 0.01, 5000, every=10)
    off = max(np.max(np.abs(np.delete(s[1] / moments, axis))) for s in samples)
    # the polhode stays a small loop around the axis (it would reach ~1 if unstable)
    assert off < 5e-3


def test_symmetric_top_body_precession_rate():
    """I1 = I2: ω⊥ rotates in the body at Ωb = (I3 − I1)ω3/I1 (splitting4, 1e-8 relative)."""
    moments = np.array([1.0, 1.0, 2.0])
    w0 = np.array([0.1, 0.0, 1.0])
    q, m, _ = run('splitting4', Dynamics(moments), Q_ID, moments * w0, 0.01, 300)
    w = m / moments
    expected = (2.0 - 1.0) * 1.0 / 1.0 * 3.0
    assert np.arctan2(w[1], w[0]) == pytest.approx(expected - 2 * np.pi * 0, rel=1e-8)
    assert w[2] == pytest.approx(1.0, rel=1e-14)


@pytest.mark.parametrize('name', ['splitting2', 'splitting4', 'implicit_midpoint', 'rk4',
                                  'exact', 'splitting2_lstable'])
def test_double_bracket_goes_to_major_axis_keeping_momentum_norm(name):
    """|L| const (1e-10; explicit rk4 only to its error), T monotone, T → |L|²/(2 I3)."""
    moments = np.array([1.0, 2.0, 3.0])
    # slowest rate α|L|²(1/I2 − 1/I3) ≈ 0.33/s
    dyn = Dynamics(moments, Dissipation('double_bracket', 2.0))
    m0 = moments * np.array([1.0, 0.02, 0.02])  # near the minor axis
    g = np.linalg.norm(m0)
    integ, q, m = create(name, dyn), Q_ID, m0
    energies = [dyn.kinetic_energy(m)]
    h = 0.04 if name == 'exact' else 0.01  # exact re-solves the elliptic problem every step
    for k in range(int(40.0 / h)):
        q, m = integ.run(q, m, h, 1)  # its loop, one step at a time (see run)
        energies.append(dyn.kinetic_energy(m))
    assert np.all(np.diff(energies) <= 1e-15)
    norm_tol = 1e-6 if name == 'rk4' else 1e-10
    assert abs(np.linalg.norm(m) / g - 1.0) < norm_tol
    assert energies[-1] == pytest.approx(g ** 2 / (2 * 3.0), rel=1e-6)
    assert abs(m[2]) / g == pytest.approx(1.0, abs=1e-6)


def test_viscous_decays_both_invariants_at_the_linear_rate():
    """τ = −cω about a principal axis: ω3(t) = ω3(0) e^{−c t / I3} (1e-9 relative)."""
    moments = np.array([1.0, 2.0, 3.0])
    dyn = Dynamics(moments, Dissipation('viscous', 0.3))
    q, m, _ = run('splitting2', dyn, Q_ID, np.array([0.0, 0.0, 3.0]), 0.01, 1000)
    assert m[2] / 3.0 == pytest.approx(np.exp(-0.3 * 10.0 / 3.0), rel=1e-9)


def test_constant_torque_changes_momentum_by_its_integral():
    """Torque along a principal axis of a body spinning about it: Δm = τ·t exactly (1e-12)."""
    moments = np.array([1.0, 2.0, 3.0])
    for name in ('splitting2', 'splitting4', 'rk4', 'implicit_midpoint', 'exact', 'dop853'):
        q, m, _ = run(name, Dynamics(moments), Q_ID, np.array([0.0, 0.0, 0.5]), 0.01, 100,
                      torque=np.array([0.0, 0.0, 0.2]))
        assert m[2] == pytest.approx(0.5 + 0.2 * 1.0, rel=1e-12), name
        spin_angle = 2 * np.arctan2(q[2], q[3])
        # Implicit midpoint turns by 2·atan(hΩ/2) per step instead of hΩ: an O(h²) phase error.
        tol = 1e-6 if name == 'implicit_midpoint' else 1e-9
        assert spin_angle == pytest.approx((0.5 * 1.0 + 0.5 * 0.2 * 1.0) / 3.0, rel=tol), name


def test_batches_match_single_bodies():
    rng = np.random.default_rng(5)
    m0 = rng.normal(size=(5, 3))
    q0 = rotation.validated(rng.normal(size=(5, 4)))
    torque = rng.normal(size=(5, 3)) * 0.1
    for name in INTEGRATORS:
        if INTEGRATORS[name].requires_actuators:
            continue  # one body and its actuators: no batch
        if name == 'dop853':
            continue  # one adaptive system for the whole batch picks other steps: not bitwise
        dyn = Dynamics(I_STD, Dissipation('double_bracket', 0.1))
        qb, mb = create(name, dyn).step(q0, m0, 0.05, torque)
        for i in range(5):
            qi, mi = create(name, dyn).step(q0[i], m0[i], 0.05, torque[i])
            assert (np.allclose(qb[i], qi, rtol=0, atol=1e-14)
                    and np.allclose(mb[i], mi, rtol=0, atol=1e-14)), name


def test_failures_are_reported_with_method_step_and_time():
    dyn = Dynamics(I_STD)
    # One Newton iteration cannot converge; after 4 halvings the failure names h/16.
    with pytest.raises(IntegrationError,
                       match=r'implicit_midpoint failed at t = 3 s with step h = 6.25 s: Newton'):
        create('implicit_midpoint', dyn, max_iterations=1).step(Q_ID, M_STD * 50, 100.0, t=3.0)
    euler = create('euler', dyn)
    q, m = Q_ID, M_STD
    with pytest.raises(IntegrationError, match='euler failed .* non-finite'):
        for k in range(200):
            q, m = euler.step(q, m, 1.0, t=float(k))
    with pytest.raises(IntegrationError, match='step must be finite and positive'):
        create('rk4', dyn).step(Q_ID, M_STD, float('nan'))
