"""DOP853 with dense output (integrators.dop853_dense) against scipy's solve_ivp(t_eval=...).

A run sampled by consecutive calls must give scipy's dense-output values at the sample
times, to round-off, and cost the steps of the unsampled run plus 3 evaluations per step
that has a sample inside it (scipy's own cost with t_eval) — independent of how many
samples.

Tolerance (:func:`tolerance`): 1e-12 on states of size ≤ 3, or the interpolant's own
round-off if larger. Our step sizes are computed in local time, scipy's in absolute time
(h = (t + h_abs) − t, rounded to ulps of t ≤ 12 s: 1.8e-15 s per step), and our error norm
sums in another order (test_dop853); both move the solution by ~1e-14. The interpolant
F[3:] = h·D·K sums 16 terms of up to Σ|D| = 1363 × h|f| into rows ~100× smaller, in
another order than numpy's dot, from stage derivatives K that our right-hand side sums in
another order than scipy's: its round-off is ≤ 32·eps·1363·h|f|, a rounding per term and
one in each K (7.8e-12 for the tumble at rtol 1e-6, steps ~1 s: measured 1.2e-12; 6.5e-12
for the viscous torqued scene there: measured 3.6e-12 on an AVX-512 EPYC, over the bound of
one rounding per term; the floor 1e-12 at rtol 1e-10, steps ≤ 0.3 s: measured ≤ 1e-13).
"""
import numpy as np
import pytest
from jit_modes import run_both
from scipy.integrate import DOP853, solve_ivp

from rigid_body_sim.physics import Dissipation, Dynamics, IntegrationError, create, dynamics_kernel
from rigid_body_sim.physics.integrators import dop853_dense, dop853_kernel
from rigid_body_sim.physics.integrators import dop853 as dop853_method

# the evaluations a step holding a sample adds: the method's own fact, checked here
BUILD = dop853_method.DOP853.sample_cost.evaluations

OFF = None  # the free body: no environment's torque

MOMENTS = np.array([1.0, 2.0, 3.0])
Q0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
M0, TAU = np.array([0.3, 0.6, 2.7]), np.array([0.01, -0.02, 0.005])
TOL = 1e-12
# (model, coefficient, torque): a torque-free tumble and two dissipative, torqued scenes
SCENES = [('none', 0.0, None), ('viscous', 0.2, TAU), ('double_bracket', 0.3, TAU)]


def scipy_rhs(model, coefficient, tau):
    """dynamics_kernel._rates (the kernel's own right-hand side) on y = (q, m), for scipy."""
    code, tau = dynamics_kernel.MODEL_CODES[model], np.zeros(3) if tau is None else tau

    def rhs(_, y):
        dq, dm = np.empty(4), np.empty(3)
        dynamics_kernel._rates(y[:4], y[4:], MOMENTS, tau, code, coefficient, dq, dm)
        return np.concatenate((dq, dm))
    return rhs


def normalised(y):
    """Rows (q, m) with q normalised, as the integrator returns them."""
    y = np.array(y, dtype=float)
    y[..., :4] /= np.linalg.norm(y[..., :4], axis=-1, keepdims=True)
    return y


def scipy_cost(rhs, y0, t0, times, rtol, atol, first_step=None):
    """Evaluations scipy's DOP853 spends reaching the last of ``times`` with t_eval: its
    steps up to the one holding it (bound far away: no clipping) + 3 per step holding an
    output. Also (steps holding outputs, step proposed after the last one)."""
    solver = DOP853(rhs, t0, y0, t0 + 1e3, rtol=rtol, atol=atol, first_step=first_step)
    with_outputs, solver.h_max = 0, 0.0
    while solver.t < times[-1]:
        t_old = solver.t
        assert solver.step() is None
        solver.h_max = max(solver.h_max, solver.t - t_old)
        with_outputs += bool(np.any((times > t_old) & (times <= solver.t)))
    return solver.nfev + BUILD * with_outputs, with_outputs, solver


def tolerance(rhs, solver, ys):
    """max(1e-12, 32·eps·Σ|D|·h_max·|f|_max): see the module docstring. ``solver`` has
    stepped past the outputs; ys are the reference states."""
    f_max = max(np.max(np.abs(rhs(0.0, y))) for y in ys)
    sum_d = np.max(np.sum(np.abs(dop853_dense.EXTENSION[1]), axis=1))
    return max(TOL, 32 * np.finfo(float).eps * sum_d * solver.h_max * f_max)


def sampled(integ, q, m, spans, tau, t0=0.0):
    """Consecutive calls of the given spans; rows (q, m) after each."""
    out, t = [], t0
    for span in spans:
        q, m = integ.run(q, m, span, 1, tau, t)
        t += span
        out.append(np.concatenate((q, m)))
    return np.array(out), q, m


@pytest.mark.parametrize('model,coefficient,tau', SCENES)
@pytest.mark.parametrize('rtol', [1e-6, 1e-10])
def test_a_sampled_run_is_solve_ivp_t_eval_and_costs_no_more_per_sample(model, coefficient,
                                                                         tau, rtol):
    """1000 samples at 100 Hz via 1000 calls = solve_ivp(t_eval) to 1e-12; evaluations
    exactly scipy's with t_eval, = the unsampled run's + 3 per step with samples, the same
    as 10 samples' + 3 per extra step with samples (a clipped step per sample would cost
    12 each: ≥ 12,000). The 10 samples are the 1000's at their times to 1e-14."""
    atol = rtol * 1e-2
    rhs, y0 = scipy_rhs(model, coefficient, tau), np.concatenate((Q0, M0))
    dyn = Dynamics(MOMENTS, Dissipation(model, coefficient))
    times = 0.01 * np.arange(1, 1001)
    integ = create('dop853', dyn, rtol=rtol, atol=atol)
    got, _, _ = sampled(integ, Q0, M0, np.full(1000, 0.01), tau)
    ref = solve_ivp(rhs, (0.0, 12.0), y0, method='DOP853', rtol=rtol, atol=atol,
                    t_eval=times)
    cost, with_outputs, solver = scipy_cost(rhs, y0, 0.0, times, rtol, atol)
    tol = tolerance(rhs, solver, ref.y.T)
    assert tol < 2e-11  # the bound stays far below the method's own error (rtol ≥ 1e-10)
    np.testing.assert_allclose(got, normalised(ref.y.T), rtol=0, atol=tol)
    assert integ.nfev == cost
    one = create('dop853', dyn, rtol=rtol, atol=atol)
    q1, m1 = one.run(Q0, M0, 10.0, 1, tau)  # unsampled: its one output is the end
    np.testing.assert_allclose(np.concatenate((q1, m1)), got[-1], rtol=0, atol=tol)
    assert integ.nfev == one.nfev + BUILD * (with_outputs - 1)
    ten = create('dop853', dyn, rtol=rtol, atol=atol)
    got10, _, _ = sampled(ten, Q0, M0, np.full(10, 1.0), tau)
    # the same steps, bit for bit, whatever the outputs (each step from local time 0):
    # only the interpolation point's round-off differs
    np.testing.assert_allclose(got10, got[99::100], rtol=0, atol=1e-14)
    steps10 = scipy_cost(rhs, y0, 0.0, times[99::100], rtol, atol)[1]
    assert integ.nfev - ten.nfev == BUILD * (with_outputs - steps10)
    assert integ.nfev < 1.3 * one.nfev


@pytest.mark.parametrize('model,coefficient,tau', SCENES[1:])
def test_a_torque_change_restarts_from_the_returned_state_keeping_the_step(model,
                                                                           coefficient, tau):
    """τ for 100 samples (to t = 1.005 s, inside a step), then −3τ: scipy stepped to the
    switch, its dense output there, restarted with its proposed step as first_step — equal
    to 1e-12 and the same evaluations (1 for the new derivative, no initial-step guess)."""
    rtol, atol = 1e-10, 1e-12
    dyn = Dynamics(MOMENTS, Dissipation(model, coefficient))
    integ = create('dop853', dyn, rtol=rtol, atol=atol)
    t1 = 0.005 + 0.01 * np.arange(1, 101)
    t2 = t1[-1] + 0.01 * np.arange(1, 201)
    spans = np.diff(np.concatenate(([0.0], t1)))
    first, q, m = sampled(integ, Q0, M0, spans, tau)
    before = integ.nfev
    second, _, _ = sampled(integ, q, m, np.full(200, 0.01), -3.0 * tau, t1[-1])
    rhs1, rhs2 = scipy_rhs(model, coefficient, tau), scipy_rhs(model, coefficient, -3.0 * tau)
    y0 = np.concatenate((Q0, M0))
    cost1, _, solver = scipy_cost(rhs1, y0, 0.0, t1, rtol, atol)
    assert solver.t > t1[-1]  # the switch is inside a step, not on its end
    y_switch = solver.dense_output()(t1[-1])
    ref1 = solve_ivp(rhs1, (0.0, 3.0), y0, method='DOP853', rtol=rtol, atol=atol, t_eval=t1)
    ref2 = solve_ivp(rhs2, (t1[-1], 5.0), y_switch, method='DOP853', rtol=rtol, atol=atol,
                     t_eval=t2, first_step=solver.h_abs)
    np.testing.assert_allclose(first, normalised(ref1.y.T), rtol=0, atol=TOL)
    np.testing.assert_allclose(second, normalised(ref2.y.T), rtol=0, atol=TOL)
    assert before == cost1
    cost2 = scipy_cost(rhs2, y_switch, t1[-1], t2, rtol, atol, first_step=solver.h_abs)[0]
    assert integ.nfev - before == cost2  # scipy's nfev counts the restart's f(y0) too


def test_a_call_ending_on_a_step_end_returns_that_state_and_steps_on():
    """The kernel directly: a span that reaches the step's end exactly returns its state
    (no interpolation, no evaluation); the next call steps on from it, and the run still
    equals solve_ivp(t_eval) there and after."""
    rtol, atol = 1e-10, 1e-12
    args = (MOMENTS, 2, 0.2, rtol, atol, 0.0, OFF)
    memory = np.zeros(dop853_dense.MEMORY)
    y, *_, clock, _ = dop853_dense.views(memory)
    q, m = Q0.copy(), M0.copy()
    status, _, _, n0 = dop853_dense.advance(q, m, 0.01, TAU, memory, *args)
    assert status == dop853_kernel.OK and clock[0] == 0.01 < clock[1]
    span = clock[1] - clock[0]
    assert clock[0] + span == clock[1]  # exactly on the end in the kernel's arithmetic
    status, _, _, n1 = dop853_dense.advance(q, m, span, TAU, memory, *args)
    assert status == dop853_kernel.OK and n1 == 0
    np.testing.assert_array_equal(m, y[4:])
    np.testing.assert_array_equal(q, y[:4] / np.linalg.norm(y[:4]))
    y_end = y.copy()
    t_end = 0.01 + span
    status, _, _, n2 = dop853_dense.advance(q, m, 0.01, TAU, memory, *args)
    assert status == dop853_kernel.OK and n2 == 12 + 3 and abs(clock[0] - 0.01) < 1e-15
    rhs, y0 = scipy_rhs('viscous', 0.2, TAU), np.concatenate((Q0, M0))
    times = np.array([0.01, t_end, t_end + 0.01])
    ref = solve_ivp(rhs, (0.0, 5.0), y0, method='DOP853', rtol=rtol, atol=atol, t_eval=times)
    np.testing.assert_allclose(y_end, ref.y[:, 1], rtol=0, atol=TOL)
    np.testing.assert_allclose(np.concatenate((q, m)), normalised(ref.y[:, 2]), rtol=0,
                               atol=TOL)
    assert n0 + n1 + n2 == scipy_cost(rhs, y0, 0.0, times, rtol, atol)[0]


_SCRIPT = '''
import json, sys, numpy as np
sys.path.insert(0, %r)
from test_dop853_dense import SCENES, Q0, M0, sampled
from rigid_body_sim.physics import Dissipation, Dynamics, create, jit
out = {"compiled": jit.COMPILED}
for model, coefficient, tau in SCENES:
    dyn = Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation(model, coefficient))
    integ = create("dop853", dyn, rtol=1e-10, atol=1e-12)
    got, q, m = sampled(integ, Q0, M0, np.full(150, 0.01), tau)
    if tau is not None:  # a torque change, then on
        got2, q, m = sampled(integ, q, m, np.full(50, 0.01), -3.0 * tau, 1.5)
        got = np.concatenate((got, got2))
    out[model] = [got.tolist(), integ.nfev]
print(json.dumps(out))
'''


def test_compiled_and_plain_python_agree_with_each_other_and_scipy():
    """NUMBA_DISABLE_JIT=1 runs the same source as Python: the same samples (1e-13) and
    evaluations; and the plain run's first 150 samples are solve_ivp(t_eval) to 1e-12."""
    import os
    compiled, plain = run_both(_SCRIPT % os.path.dirname(__file__))
    assert compiled.pop('compiled') is True and plain.pop('compiled') is False
    times = 0.01 * np.arange(1, 151)
    for model, coefficient, tau in SCENES:
        got, nfev = compiled[model]
        np.testing.assert_allclose(got, plain[model][0], rtol=0, atol=1e-13, err_msg=model)
        assert nfev == plain[model][1], model
        ref = solve_ivp(scipy_rhs(model, coefficient, tau), (0.0, 3.0),
                        np.concatenate((Q0, M0)), method='DOP853', rtol=1e-10, atol=1e-12,
                        t_eval=times)
        np.testing.assert_allclose(np.array(plain[model][0])[:150], normalised(ref.y.T),
                                   rtol=0, atol=TOL, err_msg=model)


def test_a_non_finite_state_inside_a_run_names_method_step_and_time():
    """A state that is not the last output starts afresh and fails at once, at the call's
    start time; the next good call starts afresh again."""
    integ = create('dop853', Dynamics(MOMENTS))
    q, m = integ.run(Q0, M0, 0.01, 1, None, 0.0)
    with pytest.raises(IntegrationError, match=r'dop853 failed at t = 0.01 s with step '
                                               r'h = 0.01 s: state became non-finite'):
        integ.run(q, m * np.inf, 0.01, 1, None, 0.01)
    before = integ.nfev
    integ.run(q, m, 0.01, 1, None, 0.01)
    assert (integ.nfev - before - 2 - 3) % 12 == 0  # f, the initial step, steps, extras


def test_an_output_inside_a_built_step_is_the_full_paths_bit_for_bit():
    """An output inside the step in progress whose interpolant is built is answered on the
    flat memory alone (``_interpolated``: no views, no scratch); its state and memory are
    those of the full path, which rebuilds F (3 evaluations) when told F is not built."""
    args = (MOMENTS, 2, 0.2, 1e-10, 1e-12, 0.0, OFF)
    memory = np.zeros(dop853_dense.MEMORY)
    q, m = Q0.copy(), M0.copy()
    dop853_dense.advance(q, m, 0.01, TAU, memory, *args)  # steps, builds F, interpolates
    *_, clock, _ = dop853_dense.views(memory)
    assert clock[2] == 1.0 and clock[0] + 0.01 < clock[1]
    fast_memory, slow_memory = memory.copy(), memory.copy()
    slow_memory[dop853_dense._CLOCK + 2] = 0.0  # F "not built": the full path
    (qf, mf), (qs, ms) = (q.copy(), m.copy()), (q.copy(), m.copy())
    fast = dop853_dense.advance(qf, mf, 0.01, TAU, fast_memory, *args)
    slow = dop853_dense.advance(qs, ms, 0.01, TAU, slow_memory, *args)
    assert fast[0] == slow[0] == dop853_kernel.OK and fast[3] == 0 and slow[3] == 3
    assert fast[1:3] == slow[1:3]
    np.testing.assert_array_equal(qf, qs)
    np.testing.assert_array_equal(mf, ms)
    np.testing.assert_array_equal(fast_memory, slow_memory)
    # a changed torque, or another state, is not a continuation: the full path's
    assert not dop853_dense._interpolated(qf, mf, 0.01, TAU * 2, fast_memory.copy())
    assert not dop853_dense._interpolated(qf + 1e-9, mf, 0.01, TAU, fast_memory.copy())
