"""The compiled DOP853 (physics.dop853_kernel) against scipy's, the exact solution and itself.

It must take scipy's steps on the same right-hand side, reach order 8, continue across
calls without restarting, agree with its uncompiled run, and name method, step and time
when it fails. Standard scene (Hairer–Lubich–Wanner VII.5) as in test_integrators.
"""

import numpy as np
import pytest
from jit_modes import run_both, run_in_mode
from scipy.integrate import solve_ivp

from rigid_body_sim.physics import (Dissipation, Dynamics, IntegrationError, create,
                                    dynamics_kernel, rotation)
from rigid_body_sim.physics.integrators import dop853_kernel
from rigid_body_sim.physics.exact import TorqueFreeSolution

OFF = None  # the free body: no environment's torque

pytestmark = pytest.mark.fast  # make check

I_STD = np.array([2.0, 1.0, 2.0 / 3.0])
M_STD = np.array([np.cos(1.1), 0.0, np.sin(1.1)])
Q_ID = np.array([0.0, 0.0, 0.0, 1.0])
MOMENTS = np.array([1.0, 2.0, 3.0])
Q0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
M0, TAU = np.array([0.3, 0.6, 2.7]), np.array([0.01, -0.02, 0.005])


@pytest.mark.parametrize('model', ['none', 'double_bracket', 'viscous'])
@pytest.mark.parametrize('rtol', [1e-3, 1e-6, 1e-10, 1e-13])
def test_takes_scipys_steps_on_the_same_rhs(model, rtol):
    """nfev equal and the state equal to 1e-12 after 5 s: the same tableau, error norm, step
    control and initial step as solve_ivp(method='DOP853') on dynamics_kernel._rates. The error
    norm is a sum with cancellation, summed in another order than scipy's BLAS: its 8th digit
    differs, which moves h in its 9th, so at rtol 1e-3 the state differs by ~rtol·1e-9
    (measured 3.6e-12; ≤ 2e-15 at rtol ≤ 1e-6)."""
    code = dynamics_kernel.MODEL_CODES[model]
    coefficient = 0.0 if model == 'none' else 0.2
    atol = rtol * 1e-2

    def rhs(_, y):
        dq, dm = np.empty(4), np.empty(3)
        dynamics_kernel._rates(y[:4], y[4:], MOMENTS, TAU, code, coefficient, dq, dm)
        return np.concatenate((dq, dm))

    y0 = np.concatenate((Q0, M0))
    ref = solve_ivp(rhs, (0.0, 5.0), y0, method='DOP853', rtol=rtol, atol=atol)
    y, f = y0.copy(), np.empty(7)
    status, t, _, nfev = dop853_kernel.integrate(y, f, 5.0, 0.0, True, MOMENTS, TAU, code,
                                                 coefficient, rtol, atol, *dop853_kernel.TABLEAU,
                                                 0.0, OFF)
    assert (status, t, nfev) == (dop853_kernel.OK, 5.0, ref.nfev)
    tol = max(1e-12, 1e-8 * rtol)
    np.testing.assert_allclose(y, ref.y[:, -1], rtol=0, atol=tol)
    # (the integrator's dense-output runs against solve_ivp(t_eval): test_dop853_dense)


def test_accuracy_and_order_against_the_exact_solution():
    """rtol 1e-10 over 20 s: attitude within 1e-8 rad of the closed form (measured 6e-11).
    With a tolerance no step fails (rtol = atol = 1e3) each call of the kernel's one-interval
    ``integrate`` over h, trying h, is one step of h: the observed order from h = 0.8, 0.4
    is 8 ± 0.5 (measured 8.3; smaller h meets round-off)."""
    dyn = Dynamics(I_STD)
    q_ex, m_ex = TorqueFreeSolution(I_STD, Q_ID, M_STD).at(20.0)
    integ = create('dop853', dyn, rtol=1e-10, atol=1e-12)
    q, m = integ.run(Q_ID, M_STD, 20.0, 1)
    assert rotation.angle_between(q, q_ex) < 1e-8 and np.linalg.norm(m - m_ex) < 1e-8
    errs = []
    for h in (0.8, 0.4):
        y, f, nfev = np.concatenate((Q_ID, M_STD)), np.empty(7), 0
        for k in range(int(round(20.0 / h))):
            status, t, _, n = dop853_kernel.integrate(y, f, h, h, k == 0, I_STD, np.zeros(3),
                                                      0, 0.0, 1e3, 1e3,
                                                      *dop853_kernel.TABLEAU, 0.0, OFF)
            assert (status, t) == (dop853_kernel.OK, h)
            nfev += n
        assert nfev == 1 + 12 * int(round(20.0 / h))  # one step per call
        errs.append(rotation.angle_between(y[:4] / np.linalg.norm(y[:4]), q_ex))
    assert abs(np.log2(errs[0] / errs[1]) - 8.0) < 0.5, errs


def test_consecutive_calls_continue_one_integration():
    """100 calls of 1 s vs one call of 100 s at rtol 1e-10: the same solution to 1e-9 rad
    (both within 2e-9 of the exact one) and no restart — after the first call every call
    costs whole steps (12 evaluations each: no new initial step, the derivative carried)
    plus the 3 extra stages of the dense output in the step it ends in (the ~0.2 s steps
    hold one output each), and the total is the single call's plus those 3 per step."""
    dyn = Dynamics(I_STD)
    q_ex, _ = TorqueFreeSolution(I_STD, Q_ID, M_STD).at(100.0)
    one = create('dop853', dyn, rtol=1e-10, atol=1e-12)
    q1, m1 = one.run(Q_ID, M_STD, 100.0, 1)
    many, q, m, costs = create('dop853', dyn, rtol=1e-10, atol=1e-12), Q_ID, M_STD, []
    for k in range(100):
        before = many.nfev
        q, m = many.run(q, m, 0.5, 2, None, float(k))
        costs.append(many.nfev - before)
    assert rotation.angle_between(q, q1) < 1e-9 and np.linalg.norm(m - m1) < 1e-9
    assert rotation.angle_between(q, q_ex) < 2e-9 and rotation.angle_between(q1, q_ex) < 2e-9
    assert costs[0] % 12 == 2 + 3 and all(c % 12 == 3 for c in costs[1:]), costs
    assert many.nfev == one.nfev + 3 * 99
    # reset() (or a state that is not the last result) starts afresh: initial step again
    many.reset()
    before = many.nfev
    many.run(q, m, 1.0, 1)
    assert (many.nfev - before) % 12 == 2 + 3


def test_a_torque_change_keeps_the_step_and_recomputes_the_derivative():
    """Torque τ1 for 1 s then τ2 for 1 s, vs solve_ivp restarted at the switch (rtol 1e-12):
    equal to 1e-10; the second call costs whole steps plus one evaluation (the derivative
    under the new torque) and the 3 extra stages of its end's interpolant, no initial-step
    selection."""
    dyn = Dynamics(MOMENTS, Dissipation('viscous', 0.2))
    integ = create('dop853', dyn, rtol=1e-12, atol=1e-14)
    q, m = integ.run(Q0, M0, 1.0, 1, TAU)
    before = integ.nfev
    q, m = integ.run(q, m, 0.25, 4, -3.0 * TAU, 1.0)
    assert (integ.nfev - before) % 12 == 1 + 3
    y = np.concatenate((Q0, M0))
    for tau in (TAU, -3.0 * TAU):
        y = solve_ivp(lambda _, y, tau=tau: np.concatenate(
            (dyn.attitude_rate(y[:4], y[4:]), dyn.momentum_rate(y[4:], tau))), (0.0, 1.0), y,
            method='DOP853', rtol=1e-13, atol=1e-15).y[:, -1]
    assert rotation.angle_between(q, y[:4] / np.linalg.norm(y[:4])) < 1e-10
    np.testing.assert_allclose(m, y[4:], rtol=0, atol=1e-10)


_SCRIPT = '''
import json, numpy as np
from rigid_body_sim.physics import Dissipation, Dynamics, create, jit
out = {"compiled": jit.COMPILED}
for model in ("none", "double_bracket", "viscous"):
    integ = create("dop853", Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation(model, 0.2)),
                   rtol=1e-9, atol=1e-11)
    q, m = np.array(%r), np.array(%r)
    for k in range(6):  # continuing calls, a torque change at k = 3
        q, m = integ.run(q, m, 0.25, 2, np.array(%r) * (1.0 if k < 3 else -2.0), 0.5 * k)
    out[model] = [q.tolist(), m.tolist(), integ.nfev]
print(json.dumps(out))
''' % (Q0.tolist(), M0.tolist(), TAU.tolist())


@pytest.mark.slow
def test_compiled_and_plain_python_agree():
    compiled, plain = run_both(_SCRIPT)
    assert compiled.pop('compiled') is True and plain.pop('compiled') is False
    for key, (q, m, nfev) in compiled.items():
        np.testing.assert_allclose(q, plain[key][0], rtol=0, atol=1e-13, err_msg=key)
        np.testing.assert_allclose(m, plain[key][1], rtol=0, atol=1e-13, err_msg=key)
        assert nfev == plain[key][2], key


_FAIL = '''
import numpy as np
from rigid_body_sim.physics import Dynamics, IntegrationError, create
integ = create("dop853", Dynamics(np.array([1.0, 2.0, 3.0])))
q, m = np.array([0.0, 0.0, 0.0, 1.0]), np.array([0.1, 0.2, 0.3])
q, m = integ.run(q, m, 0.5, 2, None, 4.0)
for state, torque in (((q, m * np.nan), None), ((q, m), np.array([1e306, 0.0, 0.0]))):
    try:
        integ.run(*state, 0.5, 2, torque, 5.0)
    except IntegrationError as exc:
        print(exc.integrator, exc.h > 0, 5.0 <= exc.t <= 6.0, exc.reason.split()[0])
'''


@pytest.mark.parametrize('disable_jit', ['0', pytest.param('1', marks=pytest.mark.slow)])
def test_failures_name_method_step_and_time_in_both_modes(disable_jit):
    """A non-finite state fails at once; a torque that overflows the state makes every
    step fail until the step underflows. Both raise IntegrationError within the call's
    interval [5, 6] s."""
    out = run_in_mode(_FAIL, disable_jit == '1')
    assert out.split('\n')[:2] == ['dop853 True True state', 'dop853 True True step']


def test_a_non_finite_state_is_reported_with_method_step_and_time():
    integ = create('dop853', Dynamics(MOMENTS))
    with pytest.raises(IntegrationError, match=r'dop853 failed at t = 5 s with step h = 1 s: '
                                               r'state became non-finite'):
        integ.run(Q0, M0 * np.nan, 0.5, 2, None, 5.0)
    with pytest.raises(IntegrationError, match='finite and positive'):
        integ.run(Q0, M0, float('inf'), 1)


def test_the_engine_runs_one_integration_through_its_events():
    """dop853 in the engine at 100 Hz (2000 events, 1 ms step): one call per event, ending
    inside a natural ~0.2 s step (dense output); every sample within 5e-9 rad of the closed
    form at rtol 1e-10 (measured 1.0e-9: the natural steps' error, as the accuracy test
    above; the 10 ms clipped steps had reached 2e-14). One start only: the initial step's
    2 evaluations once, then 12 per step + 3 for its interpolant, whatever the sample rate:
    ~100 steps for 20 s (landing on every event cost 12 per event, 24,002; scipy
    restarted: 14 per event)."""
    from rigid_body_sim.engine import Engine, EngineConfig
    from rigid_body_sim.physics import RigidBody
    moments, w0 = np.array([1.0, 2.0, 3.0]), np.array([0.05, 1.0, 0.02])
    config = EngineConfig(RigidBody.from_inertia(moments), Dissipation(), Q_ID, w0,
                          integrator='dop853', step=1e-3, sample_period_ns=10_000_000,
                          duration_ns=20_000_000_000,
                          integrator_options={'rtol': 1e-10, 'atol': 1e-12})
    engine = Engine(config)
    blocks = list(engine.run())
    t = np.concatenate([b.t for b in blocks])
    attitude = np.concatenate([b.attitude for b in blocks])
    assert len(t) == 2001
    q_ex, _ = TorqueFreeSolution(moments, Q_ID, moments * w0).at(t)
    assert np.max(rotation.angle_between(attitude, q_ex)) < 5e-9
    nfev = engine.integrator.nfev
    assert (nfev - 2) % 15 == 0 and 50 <= (nfev - 2) // 15 <= 200, nfev


def test_the_cached_kernels_are_keyed_on_dynamics_kernel_py_too():
    """They embed dynamics_kernel._rates: after dynamics_kernel.py changes they must recompile,
    not run the old rates from numba's cache (which checks only the defining file)."""
    import numba
    from rigid_body_sim.physics.integrators import dop853_dense
    for kernel in (dop853_kernel._rhs, dop853_kernel._initial_step, dop853_kernel._rk_step,
                   dop853_kernel.attempt, dop853_kernel.integrate, dop853_dense._build,
                   dop853_dense._interpolate, dop853_dense.advance):
        plain = numba.njit(cache=True)(kernel.py_func)
        assert (kernel._cache._cache_file._source_stamp
                != plain._cache._cache_file._source_stamp), kernel.__name__
