"""Compiled batch loop (splitting_batch_kernel) behind ``Integrator.run`` on a batch.

Every body of a batch must come out as if it had been run alone by the single-body kernel
(bitwise where no half-flows merge, to round-off where they do), compiled and as plain
Python (NUMBA_DISABLE_JIT=1, in a subprocess), and a body turning non-finite must raise
IntegrationError naming the method, step and time in both modes.
"""
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from rigid_body_sim.physics import Dissipation, Dynamics, IntegrationError, create, jit
from rigid_body_sim.physics.integrators import splitting_batch_kernel

pytestmark = pytest.mark.fast  # make check

MOMENTS = (1.0, 2.0, 3.0)
TOL = 1e-13
CASES = [(name, model, torque) for name in ('splitting2', 'splitting4', 'splitting6')
         for model in ('none', 'double_bracket', 'viscous')
         for torque in ('none', 'shared', 'per_body')]


def _bodies(count, seed):
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(count, 4))
    q /= np.linalg.norm(q, axis=-1, keepdims=True)
    return q, rng.normal(size=(count, 3)), 0.05 * rng.normal(size=(count, 3))


def _torque(kind, tau):
    return {'none': None, 'shared': tau[0], 'per_body': tau}[kind]


def _dynamics(model):
    return Dynamics(np.array(MOMENTS), Dissipation(model, 0.0 if model == 'none' else 0.2))


def _single_runs(name, dyn, q, m, h, n, torque):
    """Each body alone through the single-body compiled loop."""
    out_q, out_m = np.empty_like(q), np.empty_like(m)
    for i in range(len(q)):
        tau = None if torque is None else (torque if torque.ndim == 1 else torque[i])
        out_q[i], out_m[i] = create(name, dyn).run(q[i], m[i], h, n, tau)
    return out_q, out_m


# splitting6 with the double bracket (1.1 CPU-s for its three): make test runs it
@pytest.mark.parametrize('name,model,torque', [
    pytest.param(*case, marks=pytest.mark.slow) if case[:2] == ('splitting6', 'double_bracket')
    else case for case in CASES])
def test_batch_run_equals_single_body_runs(name, model, torque):
    """150 bodies (two full blocks and a partial one), 200 steps of 0.01 s."""
    q0, m0, tau = _bodies(2 * splitting_batch_kernel.BLOCK + 22, 3)
    dyn, torque = _dynamics(model), _torque(torque, tau)
    integ = create(name, dyn)
    q, m = integ.run(q0, m0, 0.01, 200, torque)
    q_ref, m_ref = _single_runs(name, dyn, q0, m0, 0.01, 200, torque)
    assert q.shape == q0.shape and m.shape == m0.shape
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=TOL)
    np.testing.assert_allclose(m, m_ref, rtol=0, atol=TOL)
    assert integ.nfev > 0
    if model != 'none' or torque is not None:  # nothing merged: the same operations
        assert np.array_equal(q, q_ref) and np.array_equal(m, m_ref)


def test_merged_half_flows_equal_single_steps():
    """The torque-free run merges the half-flows of consecutive steps; it still equals n
    single steps (and moves the state, so the comparison is not vacuous)."""
    q0, m0, _ = _bodies(10, 4)
    integ = create('splitting2', _dynamics('none'))
    q, m = integ.run(q0, m0, 0.01, 100)
    qs, ms = q0, m0
    for k in range(100):
        qs, ms = integ.step(qs, ms, 0.01, None, 0.01 * k)
    np.testing.assert_allclose(q, qs, rtol=0, atol=TOL)
    np.testing.assert_allclose(m, ms, rtol=0, atol=TOL)
    assert np.min(np.abs(m - m0)) > 1e-4 and np.min(np.abs(q - q0)) > 1e-6


def test_batch_shapes_broadcast_and_inputs_are_not_modified():
    q0, m0, _ = _bodies(6, 5)
    q_in, m_in = q0.reshape(2, 3, 4).copy(), m0.reshape(2, 3, 3).copy()
    q, m = create('splitting4', _dynamics('none')).run(q_in, m_in, 0.02, 30)
    assert q.shape == (2, 3, 4) and m.shape == (2, 3, 3)
    assert np.array_equal(q_in, q0.reshape(2, 3, 4)) and np.array_equal(m_in, m0.reshape(2, 3, 3))
    q_ref, m_ref = _single_runs('splitting4', _dynamics('none'), q0, m0, 0.02, 30, None)
    np.testing.assert_allclose(q.reshape(6, 4), q_ref, rtol=0, atol=TOL)
    np.testing.assert_allclose(m.reshape(6, 3), m_ref, rtol=0, atol=TOL)
    # one attitude shared by many momenta
    q1, m1 = create('splitting2', _dynamics('none')).run(q0[0], m0, 0.02, 30)
    q_ref, m_ref = _single_runs('splitting2', _dynamics('none'), np.tile(q0[0], (6, 1)), m0,
                                0.02, 30, None)
    np.testing.assert_allclose(q1, q_ref, rtol=0, atol=TOL)


def test_a_merged_angle_that_overflows_falls_back_to_single_steps():
    """m_a = 1e308 about the outer axis with h = 4: the merged a(h) angle is Inf where two
    a(h/2) are finite. The batch must give the single steps' finite result, not fail."""
    q0, m0, _ = _bodies(3, 6)
    m0[1] = (1e308, 0.0, 0.0)  # axis 0 is the outer (minor) axis for I = (1, 2, 3)
    q, m = create('splitting2', _dynamics('none')).run(q0, m0, 4.0, 3)
    q_ref, m_ref = _single_runs('splitting2', _dynamics('none'), q0, m0, 4.0, 3, None)
    assert np.all(np.isfinite(q)) and np.array_equal(m[1], m_ref[1])
    np.testing.assert_allclose(q, q_ref, rtol=0, atol=TOL)


def _failing_batch():
    """Per-body torques that overflow bodies 30, 70 and 100 (alone: at t = 7, 19 and 8 s
    from t0 = 2 s with h = 1 s; 30 in the first block of 64, the others in the second).
    The batch must name the earliest, though later bodies fail after it."""
    q0, m0, tau = _bodies(130, 7)
    tau[30] = (0.0, 5e307, 0.0)
    tau[70] = (0.0, 3e307, 0.0)
    tau[100] = (0.0, 5e307, 0.0)
    return q0, m0, tau


def test_a_non_finite_body_raises_with_method_step_and_time():
    q0, m0, tau = _failing_batch()
    alone = []
    for i in (30, 70, 100):
        with pytest.raises(IntegrationError) as single:
            create('splitting2', _dynamics('none')).run(q0[i], m0[i], 1.0, 100, tau[i], 2.0)
        alone.append(single.value.t)
    assert alone == [7.0, 19.0, 8.0]
    with pytest.raises(IntegrationError) as batch:
        create('splitting2', _dynamics('none')).run(q0, m0, 1.0, 100, tau, 2.0)
    assert batch.value.integrator == 'splitting2' and batch.value.h == 1.0
    assert batch.value.t == 7.0
    assert 'non-finite' in str(batch.value) and 'body 30' in str(batch.value)
    # within one block too: the earlier failure first, a later one after it
    pick = [100, 70]
    with pytest.raises(IntegrationError, match=r'at t = 8 s .* body 0$'):
        create('splitting2', _dynamics('none')).run(q0[pick], m0[pick], 1.0, 100, tau[pick], 2.0)
    # a NaN from the start, torque-free (merged path): the first step, t0 + h
    m0[5, 1] = np.nan
    with pytest.raises(IntegrationError, match=r'splitting4 failed at t = 1\.5 s .* body 5'):
        create('splitting4', _dynamics('none')).run(q0, m0, 0.5, 10, None, 1.0)


_SCRIPT = '''
import json, sys, numpy as np
sys.path.insert(0, %r)
from test_batch import CASES, _bodies, _dynamics, _failing_batch, _torque
from rigid_body_sim.physics import IntegrationError, create, jit
out = {"compiled": jit.COMPILED}
q0, m0, tau = _bodies(5, 8)
for name, model, torque in CASES:
    q, m = create(name, _dynamics(model)).run(q0, m0, 0.01, 40, _torque(torque, tau))
    out["/".join((name, model, torque))] = [q.tolist(), m.tolist()]
q0, m0, tau = _failing_batch()
try:
    create("splitting2", _dynamics("none")).run(q0, m0, 1.0, 100, tau, 2.0)
except IntegrationError as exc:
    out["error"] = [exc.integrator, exc.h, exc.t, str(exc)]
print(json.dumps(out))
''' % os.path.dirname(os.path.abspath(__file__))


@pytest.mark.slow
def test_plain_python_agrees_with_the_compiled_batch_loop():
    """The same source uncompiled (NUMBA_DISABLE_JIT=1) on a small batch: same states to
    1e-13, the same IntegrationError."""
    env = dict(os.environ, NUMBA_DISABLE_JIT='1')
    proc = subprocess.run([sys.executable, '-W', 'ignore', '-c', _SCRIPT], env=env,
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    plain = json.loads(proc.stdout)
    assert plain.pop("compiled") is False and jit.COMPILED
    q0, m0, tau = _bodies(5, 8)
    for name, model, torque in CASES:
        q, m = create(name, _dynamics(model)).run(q0, m0, 0.01, 40, _torque(torque, tau))
        q2, m2 = plain['/'.join((name, model, torque))]
        np.testing.assert_allclose(q, q2, rtol=0, atol=TOL, err_msg=(name, model, torque))
        np.testing.assert_allclose(m, m2, rtol=0, atol=TOL, err_msg=(name, model, torque))
    q0, m0, tau = _failing_batch()
    with pytest.raises(IntegrationError) as compiled:
        create('splitting2', _dynamics('none')).run(q0, m0, 1.0, 100, tau, 2.0)
    exc = compiled.value
    assert plain['error'] == [exc.integrator, exc.h, exc.t, str(exc)]
