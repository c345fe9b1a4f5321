"""The gravity-gradient torque along the orbit, against its analytic results: small
librations about the orbit frame (pitch, roll–yaw) and the Jacobi integral."""
import math

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from rigid_body_sim.engine import EngineConfig, SampleBlock
from rigid_body_sim.engine.core import Engine
from rigid_body_sim.physics import INTEGRATORS, Dynamics, create, orbit
from rigid_body_sim.physics.orbit import frames

pytestmark = pytest.mark.fast  # make check

A = 7.0e6
N = math.sqrt(orbit.MU / A ** 3)
PERIOD = 2 * math.pi / N
INERTIA = (3.0, 4.0, 2.0)  # I_y > I_x > I_z: the Lagrange region (Hughes §9)


def lvlh_start(offset, a=A, inclination=0.3, raan=0.7, **overrides):
    """Parameters of a circular orbit with the body's principal axes on LVLH's, turned by
    ``offset`` (a rotation vector in LVLH axes), rotating with the frame."""
    o = orbit.KeplerOrbit(a, 0.0, inclination, raan, 0.0, 0.0)
    r, v = o.state(0.0)
    frame = frames.lvlh_axes(r, v)
    body = frame @ Rotation.from_rotvec(offset).as_matrix()
    w_body = body.T @ frames.lvlh_rate(r, v)
    p = {'inertia': list(INERTIA), 'orbit.model': 'kepler', 'orbit.semi_major_axis': a,
         'orbit.inclination': inclination, 'orbit.raan': raan,
         'environment.gravity_gradient': True,
         'initial_attitude': Rotation.from_matrix(body).as_quat().tolist(),
         'initial_angular_velocity': w_body.tolist()}
    p.update(overrides)
    return o, p


def relative_angles(o, block):
    """Rotation vectors (roll, pitch, yaw about LVLH x, y, z) of the body from LVLH: the
    libration figure's (plots.orbit.lvlh_angles), all samples at once."""
    from rigid_body_sim.plots.orbit import lvlh_angles
    return lvlh_angles(block.t_ns / 1e9, block.q, o)


def run(p):
    engine = Engine(EngineConfig.from_parameters(p))
    return engine, SampleBlock.concatenate(list(engine.run()))


def fitted_frequencies(t, signals, guesses):
    """Frequencies of a sum of sinusoids shared by ``signals`` (columns), least squares from
    ``guesses``; returns (frequencies, rms residual / rms signal)."""
    def residual(w):
        basis = np.column_stack([f(wk * t) for wk in w for f in (np.cos, np.sin)])
        coef, *_ = np.linalg.lstsq(basis, signals, rcond=None)
        return (basis @ coef - signals).ravel()
    fit = least_squares(residual, guesses, x_scale=N, xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return fit.x, math.sqrt(np.mean(fit.fun ** 2) / np.mean(signals ** 2))


# splitting4's libration in make check; the other methods' (0.6 CPU-s each) in make test
@pytest.mark.parametrize('method,step', [
    ('splitting4', 20.0), pytest.param('rk4', 20.0, marks=pytest.mark.slow),
    pytest.param('splitting2', 2.0, marks=pytest.mark.slow),
    pytest.param('dop853', 60.0, marks=pytest.mark.slow)])
def test_small_pitch_libration_at_its_frequency(method, step):
    ix, iy, iz = INERTIA
    expected = N * math.sqrt(3 * (ix - iz) / iy)
    o, p = lvlh_start([0.0, 0.01, 0.0], integrator=method, step=step,
                      duration=6 * 2 * math.pi / expected, publish_rate=0.1)
    engine, block = run(p)
    assert engine.method == method and 'gravity gradient' in engine.reason
    angles = relative_angles(o, block)
    t = block.t_ns / 1e9
    assert np.abs(angles[:, 0]).max() < 1e-9 and np.abs(angles[:, 2]).max() < 1e-9  # planar
    assert 0.0099 < np.abs(angles[:, 1]).max() < 0.0101
    (w,), rel = fitted_frequencies(t, angles[:, 1:2], [expected * 1.01])
    assert rel < 1e-3
    print(method, 'pitch relative error', w / expected - 1)
    assert abs(w / expected - 1) < 1e-4, (w / expected - 1)


@pytest.mark.slow
def test_roll_yaw_libration_at_the_roots_of_the_quartic():
    ix, iy, iz = INERTIA
    k_r, k_y = (iy - iz) / ix, (iy - ix) / iz
    b, c = 1 + 3 * k_r + k_r * k_y, 4 * k_r * k_y
    root = math.sqrt(b * b - 4 * c)
    expected = N * np.sqrt([(b + root) / 2, (b - root) / 2])
    o, p = lvlh_start([0.01, 0.0, 0.0], integrator='splitting4', step=20.0,
                      duration=10 * 2 * math.pi / expected[1], publish_rate=0.05)
    engine, block = run(p)
    angles = relative_angles(o, block)
    t = block.t_ns / 1e9
    assert np.abs(angles[:, 1]).max() < 1e-3  # pitch: second order in the amplitude
    assert np.abs(angles[:, 2]).max() > 1e-3  # the roll excites the yaw
    w, rel = fitted_frequencies(t, angles[:, [0, 2]], expected * [1.01, 0.99])
    assert rel < 1e-3
    print('roll-yaw relative errors', np.sort(w)[::-1] / expected - 1)
    np.testing.assert_allclose(np.sort(w)[::-1] / expected, 1.0, rtol=1e-4, atol=0)


def test_outside_the_stable_region_pitch_diverges():
    """I_x < I_z: pitch is unstable (ω_p² < 0): the same start tumbles away."""
    o, p = lvlh_start([0.0, 0.01, 0.0], inertia=[2.0, 4.0, 3.0], integrator='splitting4',
                      step=20.0, duration=2 * PERIOD, publish_rate=0.01)
    _, block = run(p)
    assert np.abs(relative_angles(o, block)[:, 1]).max() > 0.5


def jacobi(o, block):
    """J = ½ω_rᵀIω_r − ½n² b̂ᵀIb̂ + (3/2)n² ĉᵀIĉ at each sample (body = principal axes).
    All samples at once: a Rotation a sample cost 0.7 CPU-s a run of 10⁴ samples (issue 32);
    the same J to 2e-15 relative."""
    inertia = np.array(INERTIA)
    r, v = (np.array(x) for x in zip(*(o.state(t) for t in block.t_ns / 1e9)))
    to_body = Rotation.from_quat(block.q).as_matrix().transpose(0, 2, 1)  # rot.T a sample
    h = np.cross(r, v)
    b_hat = np.einsum('nij,nj->ni', to_body, h / np.linalg.norm(h, axis=1)[:, None])
    c_hat = np.einsum('nij,nj->ni', to_body, r / np.linalg.norm(r, axis=1)[:, None])
    w_r = block.m / inertia - N * b_hat
    return (0.5 * np.sum(w_r * inertia * w_r, axis=1)
            - 0.5 * N ** 2 * np.sum(b_hat * inertia * b_hat, axis=1)
            + 1.5 * N ** 2 * np.sum(c_hat * inertia * c_hat, axis=1))


def jacobi_errors(method, step, orbits):
    """|J − J₀|/|J₀| ten times an orbit, and J − J₀'s linear trend over the run (relative)."""
    # a large libration (about 0.5 rad, all axes) inside the Lagrange region
    o, p = lvlh_start([0.3, 0.4, 0.2], integrator=method, step=step,
                      duration=orbits * PERIOD, publish_rate=10.0 / PERIOD)
    _, block = run(p)
    j = jacobi(o, block)
    trend = np.polyfit(np.arange(len(j)), j - j[0], 1)[0] * len(j) / abs(j[0])
    return np.abs(j - j[0])[1:].reshape(orbits // 10, -1) / abs(j[0]), trend


@pytest.mark.slow
@pytest.mark.parametrize('method,order', [('splitting2', 2), ('splitting4', 4)])
def test_splittings_keep_the_jacobi_integral_bounded_at_their_order(method, order):
    """10³ orbits at 100 and 200 steps an orbit. Measured: splitting2's largest error
    5.9e-4 → 1.4e-4 (2.07 in log2), splitting4's 2.3e-6 → 1.4e-7 (4.07); the trend over
    the run is a few % of the error's amplitude, the last 100 orbits' mean error that of
    the first 100 within 20 %."""
    h = PERIOD / 100
    (coarse, trend_c), (fine, trend_f) = jacobi_errors(method, h, 1000), \
        jacobi_errors(method, h / 2, 1000)
    for e, trend in ((coarse, trend_c), (fine, trend_f)):
        assert e[-10:].mean() < 1.5 * e[:10].mean()  # bounded: no growth over 10³ orbits
        assert abs(trend) < 0.2 * e.max()             # no drift
    ratio = coarse.max() / fine.max()
    assert abs(math.log2(ratio) - order) < 0.3, ratio


@pytest.mark.slow
def test_runge_kutta_drifts_in_the_jacobi_integral():
    """RK4 at 100 steps an orbit: the error grows linearly (measured 7e-6 mean over the
    first 100 orbits, 1.1e-4 over the last), its trend the whole of it."""
    e, trend = jacobi_errors('rk4', PERIOD / 100, 1000)
    assert e[-10:].mean() > 5 * e[:10].mean()
    assert abs(trend) > 0.5 * e.max()


@pytest.mark.parametrize('model,coefficient', [('double_bracket', 1e-3), ('viscous', 1e-3)])
def test_with_dissipation_the_splitting_agrees_with_dop853(model, coefficient):
    """Every dissipation model with the gravity gradient: the splitting (kicks) and dop853
    (a term of its right-hand side) integrate the same dynamics."""
    o, p = lvlh_start([0.3, 0.2, 0.1], duration=PERIOD / 4, publish_rate=0.01,
                      **{'dissipation.model': model, 'dissipation.coefficient': coefficient})
    _, ref = run(dict(p, integrator='dop853'))
    _, split = run(dict(p, integrator='splitting4', step=5.0))
    np.testing.assert_allclose(split.q, ref.q, atol=1e-7)
    np.testing.assert_allclose(split.m, ref.m, atol=1e-7 * np.abs(ref.m).max())
    # and the torque acted: without it the attitude differs at once
    _, free = run(dict(p, integrator='dop853', **{'environment.gravity_gradient': False}))
    assert np.abs(free.q[-1] - ref.q[-1]).max() > 1e-3


def test_the_torque_is_three_mu_over_r_cubed_c_cross_ic():
    o = orbit.KeplerOrbit(A, 0.1, 0.4, 0.2, 0.3, 1.0)
    env = o.elements()
    env[orbit.kernel.ON] = 1.0
    dyn = Dynamics(np.array(INERTIA), environment=env)
    q = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_quat()
    t = 1234.0
    r, _ = o.state(t)
    c = Rotation.from_quat(q).as_matrix().T @ (r / np.linalg.norm(r))
    expected = 3 * orbit.MU / np.linalg.norm(r) ** 3 * np.cross(c, np.array(INERTIA) * c)
    np.testing.assert_allclose(dyn.environment_torque(q, t), expected, rtol=1e-12)
    # with a principal axis along the radius, none
    q_axis = Rotation.align_vectors([r], [[1.0, 0.0, 0.0]])[0].as_quat()
    assert np.abs(dyn.environment_torque(q_axis, t)).max() < 1e-12 * np.abs(expected).max()


def test_methods_without_the_term_are_refused():
    o, p = lvlh_start([0.0, 0.0, 0.0], integrator='implicit_midpoint')
    with pytest.raises(ValueError, match='integrator: implicit_midpoint does not integrate '
                       'environment.gravity_gradient'):
        EngineConfig.from_parameters(p)
    env = o.elements()
    env[orbit.kernel.ON] = 1.0
    with pytest.raises(ValueError, match='exact does not integrate the gravity-gradient'):
        create('exact', Dynamics(np.array(INERTIA), environment=env))


def test_auto_names_the_gravity_gradient_and_picks_a_method_that_integrates_it():
    _, p = lvlh_start([0.01, 0.0, 0.0], duration=600.0, publish_rate=1.0)
    engine, _ = run(p)
    assert engine.reason.startswith('auto: gravity gradient →'), engine.reason
    assert INTEGRATORS[engine.method].environment
    # the same orbit without the term: the free body, in closed form
    free, _ = run(dict(p, **{'environment.gravity_gradient': False}))
    assert free.method == 'exact' and 'gravity' not in free.reason


_SCRIPT = '''
import json, math, sys
sys.path.insert(0, %r)
import numpy as np
import test_gravity_gradient as g
from rigid_body_sim.physics import jit
ix, iy, iz = g.INERTIA
expected = g.N * math.sqrt(3 * (ix - iz) / iy)
out = {"compiled": jit.COMPILED}
for method, step in (("splitting4", 40.0), ("rk4", 40.0), ("dop853", 60.0)):
    o, p = g.lvlh_start([0.0, 0.01, 0.0], integrator=method, step=step,
                        duration=4 * 2 * math.pi / expected, publish_rate=0.02)
    engine, block = g.run(p)
    (w,), rel = g.fitted_frequencies(block.t_ns / 1e9, g.relative_angles(o, block)[:, 1:2],
                                     [expected * 1.01])
    out[method] = [w / expected - 1, rel, block.q[-1].tolist()]
print(json.dumps(out))
'''


@pytest.mark.slow
def test_compiled_and_plain_loops_librate_alike():
    """The kernels are one source: compiled and as plain Python (NUMBA_DISABLE_JIT=1) the
    pitch libration comes out at its frequency and the runs agree to round-off."""
    import os
    from jit_modes import run_both
    compiled, plain = run_both(_SCRIPT % os.path.dirname(os.path.abspath(__file__)))
    assert compiled.pop('compiled') is True and plain.pop('compiled') is False
    for method in compiled:
        for out in (compiled, plain):
            assert abs(out[method][0]) < 1e-4 and out[method][1] < 1e-3, (method, out[method])
        np.testing.assert_allclose(plain[method][2], compiled[method][2], atol=1e-12,
                                   err_msg=method)


@pytest.mark.parametrize('integrator,rate', [('splitting4', 2.0), ('dop853', 20.0)])
def test_with_a_control_law_the_compiled_loop_gives_the_event_loop_samples(integrator, rate):
    """The gravity gradient with an in-process law (detumble): the engine's compiled closed
    loop evaluates the torque at the instants the event-by-event path does, bit for bit.
    dop853: its samples between law instants from one loop of its steps
    (engine.dop853_samples), the stages' instants the environment sees included."""
    from rigid_body_sim.engine.config import ControlSettings
    _, p = lvlh_start([0.1, 0.2, 0.3], initial_angular_velocity=[0.01, -0.02, 0.015],
                      integrator=integrator, step=0.5, duration=200.0, publish_rate=rate)
    law = ControlSettings.from_parameters({'mode': 'detumble', 'inertia': list(INERTIA),
                                           'control_rate': 1.0, 'rate_gain': 0.05})
    blocks = []
    for compiled in (False, True):
        engine = Engine(EngineConfig.from_parameters(p).replace(control=law))
        engine._compiled_samples = compiled
        blocks.append(SampleBlock.concatenate(list(engine.run())))
    for field in ('t_ns', 'q', 'm', 'torque'):
        np.testing.assert_array_equal(blocks[1].__getattribute__(field),
                                      blocks[0].__getattribute__(field), err_msg=field)
    assert np.abs(blocks[1].torque).max() > 0.0
    # and the gravity gradient acted inside the kernel: without it the run differs
    free = Engine(EngineConfig.from_parameters(
        dict(p, **{'environment.gravity_gradient': False})).replace(control=law))
    last = SampleBlock.concatenate(list(free.run()))
    assert np.abs(last.m[-1] - blocks[1].m[-1]).max() > 1e-9


ISS = ['1 25544U 98067A   19343.69339541  .00001764  00000-0  38792-4 0  9991',
       '2 25544  51.6439 211.2001 0007417  17.6667  85.6398 15.50103472202482']


@pytest.mark.slow
def test_sgp4_orbit_drives_the_gradient_and_its_failure_stops_the_run():
    """SGP4's osculating conic, re-anchored at every interval: the splitting agrees with
    dop853 on it; a propagation failure stops the run with the time and SGP4's code."""
    from rigid_body_sim.physics import IntegrationError
    p = {'inertia': list(INERTIA), 'orbit.model': 'sgp4', 'orbit.tle': ISS,
         'environment.gravity_gradient': True, 'initial_attitude_frame': 'lvlh',
         'initial_attitude': Rotation.from_rotvec([0.1, 0.2, 0.0]).as_quat().tolist(),
         'initial_angular_velocity': [0.0, 0.0, 0.0], 'duration': 1000.0,
         'publish_rate': 0.1}
    _, ref = run(dict(p, integrator='dop853'))
    _, split = run(dict(p, integrator='splitting4', step=2.0))
    np.testing.assert_allclose(split.q, ref.q, atol=1e-8)
    # the libration is about SGP4's LVLH: 0.2 rad pitch stays of that size
    o = orbit.from_tle(ISS)
    angles = relative_angles(o, split)
    assert np.allclose(angles[0], [0.1, 0.2, 0.0], atol=1e-9)
    assert 0.1 < np.abs(angles[:, 1]).max() < 0.3
    # SGP4 reports this set decayed after ~9,400 days: the run stops there, naming the
    # time and SGP4's code
    late = dict(p, integrator='splitting2', step=600.0, duration=1.0e9, publish_rate=1e-6)
    engine = Engine(EngineConfig.from_parameters(late))
    with pytest.raises(IntegrationError, match=r'SGP4 error \d'):
        list(engine.run())
    assert 'SGP4 error' in engine.fault and engine.t > 0


def test_diagnostics_report_no_drift_where_the_environment_acts():
    """|L| and T change under the gravity gradient: that is physics, not drift."""
    _, p = lvlh_start([0.3, 0.2, 0.1], integrator='splitting4', step=10.0, duration=600.0,
                      publish_rate=0.1)
    engine, _ = run(p)
    d = engine.diagnostics()
    for key in ('kinetic_energy_drift', 'angular_momentum_norm_drift',
                'angular_momentum_inertial_drift'):
        assert d[key] == 'n/a (environment torque: gravity gradient)', (key, d[key])
    assert d['energy_dissipated'] == 0.0


def test_with_reaction_wheels_the_gyrostat_kicks_with_the_gradient():
    """Three orthogonal wheels of equal rotor inertia started with zero absolute momentum
    and never commanded: their momentum stays zero and Σ J a aᵀ = J·1 adds no gradient
    torque (ĉ × ĉ = 0), so the gyrostat with the gravity gradient is the rigid body with
    it: the same librating trajectory as splitting2's at the same step."""
    o, p = lvlh_start([0.1, 0.2, 0.05], integrator='splitting2', step=5.0, duration=3000.0,
                      publish_rate=0.02)
    _, rigid = run(p)
    w = p['initial_angular_velocity']
    wheels = dict(p, **{'actuators.wheels.axes': [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0],
                        'actuators.wheels.inertia': [0.05],
                        'actuators.wheels.initial_speed': [-w[0], -w[1], -w[2]]})
    engine, gyro = run(wheels)
    assert INTEGRATORS[engine.method].requires_actuators
    np.testing.assert_allclose(gyro.q, rigid.q, atol=1e-12)
    np.testing.assert_allclose(gyro.m, rigid.m, atol=1e-12 * np.abs(rigid.m).max())
    assert np.abs(relative_angles(o, gyro)).max() > 0.05  # it librated


def test_a_wheels_rotor_adds_its_inertia_to_the_gradient():
    """One wheel on x (rotor J): the gradient acts on diag(I) + J x xᵀ."""
    from rigid_body_sim.engine.actuators import ActuatorConfig, Actuators
    from rigid_body_sim.param_spec import coerce_all
    from rigid_body_sim.engine import specs
    from rigid_body_sim.physics import RigidBody
    from rigid_body_sim.physics.orbit import kernel
    values = coerce_all(specs.SIMULATOR, {'actuators.wheels.axes': [1.0, 0.0, 0.0],
                                          'actuators.wheels.inertia': [0.5]})
    body = RigidBody.from_inertia(list(INERTIA))
    act = Actuators(ActuatorConfig.from_parameters(values), body)
    full = act._mass_inertia(body.principal_moments)
    np.testing.assert_allclose(full, np.diag(INERTIA) + np.diag([0.5, 0.0, 0.0]))
    o = orbit.KeplerOrbit(A, 0.0, 0.3, 0.0, 0.0, 0.0)
    env = o.elements()
    env[kernel.ON] = 1.0
    q = Rotation.from_rotvec([0.4, -0.2, 0.9]).as_quat()
    r, _ = o.state(100.0)
    c = Rotation.from_quat(q).as_matrix().T @ (r / np.linalg.norm(r))
    expected = 3 * orbit.MU / np.linalg.norm(r) ** 3 * np.cross(c, full @ c)
    np.testing.assert_allclose(kernel.gravity_gradient_torque_full(q, 100.0, env, full),
                               expected, rtol=1e-12)
