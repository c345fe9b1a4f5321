"""Compiled step loops (integrators/*_kernel.py): the same source compiled and as plain Python.

The compiled loops must agree with the uncompiled run of the same functions
(NUMBA_DISABLE_JIT=1, in a subprocess) and with the numpy batch path of each method,
and must report a diverging step with its method, step size and time in both modes.
"""
import json

import numpy as np
import pytest
from jit_modes import run_both, run_in_mode

from rigid_body_sim import control
from rigid_body_sim.physics import Dissipation, Dynamics, IntegrationError, create, jit

pytestmark = pytest.mark.fast  # make check

CASES = [(name, model) for name in ('splitting2', 'splitting4', 'splitting6', 'rk4', 'euler',
                                    'implicit_midpoint', 'splitting2_lstable', 'exact')
         for model in ('none', 'double_bracket', 'viscous')]
MOMENTS = (1.0, 2.0, 3.0)
Q0, M0, TAU = (0.1, -0.2, 0.3, 0.9), (0.3, 0.6, 2.7), (0.01, -0.02, 0.005)

_SCRIPT = '''
import json, sys, numpy as np
from rigid_body_sim.physics import Dissipation, Dynamics, create, jit
out = {"compiled": jit.COMPILED}
for name, model in json.loads(sys.argv[1]):
    d = Dissipation(model, 0.0 if model == "none" else 0.2)
    integ = create(name, Dynamics(np.array(%r), d))
    q0 = np.array(%r); q0 /= np.linalg.norm(q0)
    q, m = integ.run(q0, np.array(%r), 0.01, 300, np.array(%r), 0.0)
    out[name + "/" + model] = [q.tolist(), m.tolist(), integ.nfev]
from rigid_body_sim.engine import Engine, EngineConfig  # the compiled closed loop
engine = Engine(EngineConfig.from_parameters(
    {"inertia": [1.0, 2.0, 3.0], "integrator": "splitting4",
     "initial_angular_velocity": [0.3, -0.2, 0.4], "publish_rate": 2.0, "duration": 5.0},
    {"mode": "slew", "target_attitude": [0.0, 0.0, 0.6, 0.8], "control_rate": 20.0}))
for _ in engine.run():
    pass
q, m = engine.principal_state
out["closed_loop"] = [q.tolist(), m.tolist(), engine.integrator.nfev]
print(json.dumps(out))
''' % (MOMENTS, Q0, M0, TAU)


@pytest.mark.slow
def test_compiled_and_plain_python_agree():
    compiled, plain = run_both(_SCRIPT, json.dumps(CASES))
    assert compiled.pop('compiled') is True and plain.pop('compiled') is False
    for key, (q, m, nfev) in compiled.items():
        q2, m2, nfev2 = plain[key]
        np.testing.assert_allclose(q, q2, rtol=0, atol=1e-13, err_msg=key)
        np.testing.assert_allclose(m, m2, rtol=0, atol=1e-13, err_msg=key)
        assert nfev == nfev2, key


# the numpy batch path's 300 steps of splitting4/6 with the double bracket take 1.7 CPU-s:
# make test runs them
@pytest.mark.parametrize('name,model', [
    pytest.param(*case, marks=pytest.mark.slow)
    if case in (('splitting4', 'double_bracket'), ('splitting6', 'double_bracket')) else case
    for case in CASES])
def test_compiled_loop_matches_the_numpy_batch_path(name, model):
    """300 steps of one body through the kernel vs a batch of two through numpy."""
    d = Dissipation(model, 0.0 if model == 'none' else 0.2)
    integ = create(name, Dynamics(np.array(MOMENTS), d))
    q0 = np.array(Q0) / np.linalg.norm(Q0)
    q, m = integ.run(q0, np.array(M0), 0.01, 300, np.array(TAU))
    qb, mb = np.tile(q0, (2, 1)), np.tile(M0, (2, 1))
    for k in range(300):
        qb, mb = integ.step(qb, mb, 0.01, np.array(TAU), k * 0.01)
    np.testing.assert_allclose(q, qb[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(m, mb[0], rtol=0, atol=1e-12)


_DIVERGE = '''
import numpy as np
from rigid_body_sim.physics import Dissipation, Dynamics, IntegrationError, create
integ = create("rk4", Dynamics(np.array([1.0, 2.0, 3.0]), Dissipation("double_bracket", 1000.0)))
q = np.array([0.0, 0.0, 0.0, 1.0]); m = np.array([0.3, 0.3, 0.9]) / np.linalg.norm([0.3, 0.3, 0.9])
try:
    integ.run(q, m, 0.05, 10000, None, 2.0)
except IntegrationError as exc:
    print(exc.integrator, exc.h, exc.t > 2.0, exc.t <= 2.0 + 0.05 * 10000)
'''


_NEWTON_FAILS = '''
import json, numpy as np
from rigid_body_sim.physics import Dynamics, IntegrationError, create
from rigid_body_sim.physics.integrators import Integrator
dyn = Dynamics(np.array([2.0, 1.0, 2.0 / 3.0]))
m0 = 50 * np.array([np.cos(1.1), 0.0, np.sin(1.1)])
out = []
# h = 100 fails at once (reported at h/16 = 6.25 at the step's start); h = 0.3 at scale 0.1
# first fails at h/16 after one sub-step of h/16 succeeded (t = 1 + 0.3/16)
for scale, h, t0, cap in ((1.0, 100.0, 3.0, 1), (0.1, 0.3, 1.0, 3)):
    for loop in ("kernel", "numpy"):
        integ = create("implicit_midpoint", dyn, max_iterations=cap)
        run = integ.run if loop == "kernel" else lambda *a: Integrator.run(integ, *a)
        try:
            run(np.array([0.0, 0.0, 0.0, 1.0]), scale * m0, h, 5, None, t0)
        except IntegrationError as exc:
            out.append([loop, exc.integrator, exc.h, exc.t, exc.reason, integ.nfev])
print(json.dumps(out))
'''


@pytest.mark.parametrize('disable_jit', [False, pytest.param(True, marks=pytest.mark.slow)])
def test_implicit_midpoint_newton_failure_is_the_numpy_paths_in_both_modes(disable_jit):
    """A Newton iteration capped too low: the compiled loop retries on halved steps and
    fails at h/16 with the same step, time, reason and evaluation count as the numpy path."""
    rows = json.loads(run_in_mode(_NEWTON_FAILS, disable_jit))
    assert len(rows) == 4
    for kernel, numpy_path in (rows[0:2], rows[2:4]):
        assert kernel[0] == 'kernel' and numpy_path[0] == 'numpy'
        assert kernel[1:] == numpy_path[1:]
    assert rows[0][1:5] == ['implicit_midpoint', 6.25, 3.0,
                            'Newton iteration did not converge in 1 iterations']
    assert rows[2][2:4] == [0.3 / 16, 1.0 + 0.3 / 16]


@pytest.mark.parametrize('disable_jit', [False, pytest.param(True, marks=pytest.mark.slow)])
def test_divergence_raises_integration_error_in_both_modes(disable_jit):
    assert run_in_mode(_DIVERGE, disable_jit).split() == ['rk4', '0.05', 'True', 'True']


def test_a_non_positive_step_is_refused_before_the_loop():
    integ = create('splitting2', Dynamics(np.array(MOMENTS)))
    with pytest.raises(IntegrationError, match='finite and positive'):
        integ.run(np.array([0, 0, 0, 1.0]), np.array(M0), float('nan'), 3)
    assert jit.COMPILED


_CONTROL = '''
import json, numpy as np
from rigid_body_sim import control as C
rng = np.random.default_rng(7)
out = []
for k in range(60):
    inertia = [[1.5, 0.1, 0.0], [0.1, 2.0, 0.2], [0.0, 0.2, 2.5]] if k % 2 else [1.0, 2.0, 2.5]
    cfg = C.ControlConfig(inertia=inertia, natural_frequency=0.8, max_torque=(0.0, 0.05)[k % 2],
                          gyroscopic_compensation=bool(k % 3))
    q, w, t = rng.normal(size=4), rng.normal(size=3), rng.normal(size=4)
    for mode in C.MODES:
        law = C.AttitudeController(cfg, mode, t / np.linalg.norm(t))
        r = law.compute(q / np.linalg.norm(q), w)
        out.append(r.torque.tolist() + [r.saturated, r.rate_limited, r.error_angle])
print(json.dumps(out))
'''


@pytest.mark.slow
def test_control_law_compiled_and_plain_python_agree():
    """The control law kernel: same torques, flags and error angles in both modes."""
    runs = [np.array(r, dtype=float) for r in run_both(_CONTROL)]
    # every mode's torque (bdot's is zero: the rods act instead); some saturate
    assert runs[0].shape == (60 * len(control.MODES), 6) and runs[0][:, 3].any()
    np.testing.assert_allclose(runs[0], runs[1], rtol=0, atol=1e-13)


def test_a_kernel_is_keyed_on_the_files_it_calls(tmp_path):
    """numba's disk cache checks only the defining file; ``depends_on`` mixes the callee
    files into the key, so a kernel calling the step loops is recompiled, not run stale,
    after those change — and loaded from the cache while they don't."""
    import types
    import numba
    from rigid_body_sim.engine import closed_loop
    dep = tmp_path / 'dep.py'
    dep.write_text('x = 1\n')
    module = types.SimpleNamespace(__file__=str(dep))

    def f():
        return 1

    def stamp(kernel):
        return kernel._cache._cache_file._source_stamp
    first = stamp(jit.depends_on(numba.njit(cache=True)(f), module))
    again = stamp(jit.depends_on(numba.njit(cache=True)(f), module))
    dep.write_text('x = 2\n')
    changed = stamp(jit.depends_on(numba.njit(cache=True)(f), module))
    assert first == again != changed
    plain = numba.njit(cache=True)(closed_loop.closed_loop_run.py_func)
    assert stamp(closed_loop.closed_loop_run) != stamp(plain)
