"""The Earth's field along the orbit and the magnetorquers' torque, against closed forms:
the dipole in the loops against its formula, IGRF's table against ppigrf, τ = m × B at
random states (compiled and plain), the engine's held and clipped dipole against an
independent integration, and the scene keys' refusals."""
from datetime import datetime, timezone
import math
import os

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from rigid_body_sim.engine import EngineConfig, SampleBlock
from rigid_body_sim.engine.core import Engine
from rigid_body_sim.physics import Dynamics, create, orbit
from rigid_body_sim.physics.environment import earth, magnetic_field, magnetic_kernel
from rigid_body_sim.physics.orbit import kernel as k

pytestmark = pytest.mark.fast  # make check

EPOCH = datetime(2026, 3, 20, 12, tzinfo=timezone.utc)
A = 6878137.0  # 500 km up
INC = math.radians(97.4)


def kepler(model='kepler', inc=INC):
    cls = orbit.J2Orbit if model == 'j2' else orbit.KeplerOrbit
    return cls(A, 0.001, inc, 0.4, 0.3, 1.0)


def scene(**overrides):
    p = {'inertia': [0.03, 0.025, 0.01], 'orbit.model': 'kepler', 'orbit.semi_major_axis': A,
         'orbit.inclination': INC, 'environment.magnetic_field': 'dipole',
         'epoch': '2026-03-20T12:00:00Z', 'magnetorquer.max_dipole': [0.2, 0.2, 0.2],
         'initial_angular_velocity': [0.05, -0.03, 0.04], 'duration': 60.0,
         'publish_rate': 1.0, 'integrator': 'splitting4', 'step': 0.05,
         'command_timeout': 1000.0}
    p.update(overrides)
    return p


@pytest.mark.parametrize('model', ['kepler', 'j2'])
def test_the_loops_dipole_is_its_closed_form(model):
    """B = μ0/(4π r³)[3(m·r̂)r̂ − m] with m IGRF-14's degree 1 at the epoch, turned with the
    Earth by GMST: the compiled field at instants over a day against numpy's formula."""
    o = kepler(model)
    field = magnetic_field.FieldAlongOrbit('dipole', o, EPOCH)
    env = o.elements()
    field.fill(env)
    moment = magnetic_field.dipole_moment(EPOCH)
    assert 7.0e22 < np.linalg.norm(moment) < 8.5e22
    tilt = math.degrees(math.acos(abs(moment[2]) / np.linalg.norm(moment)))
    assert 8.0 < tilt < 11.0
    for t in np.random.default_rng(1).uniform(0.0, 86400.0, 40):
        r, _ = o.state(t)
        angle = earth.gmst(EPOCH, t)
        expected = earth.ecef_to_eci(magnetic_field.dipole_field(
            earth.eci_to_ecef(r, angle), moment), angle)
        got = np.array(magnetic_kernel.field_world(t, env))
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.linalg.norm(expected))
        assert 1.5e-5 < np.linalg.norm(got) < 6e-5  # 500 km: 20-50 µT


def test_the_models_range_is_read_from_the_file_as_ppigrf_reads_it():
    """The epoch check reads IGRF-14's range from the coefficient file's header, without
    ppigrf and pandas: the same file as ppigrf's, the same first and last dates as its
    read_shc."""
    from ppigrf import ppigrf
    assert os.path.samefile(magnetic_field.coefficient_file(), ppigrf.shc_fn_igrf14)
    g, _ = ppigrf.read_shc(ppigrf.shc_fn_igrf14)
    first, last = magnetic_field.model_range()
    assert (first, last) == (g.index[0].to_pydatetime().replace(tzinfo=timezone.utc),
                             g.index[-1].to_pydatetime().replace(tzinfo=timezone.utc))
    assert (first.year, last.year) == (1900, 2030)


@pytest.mark.slow  # a fresh interpreter: make test
def test_loading_an_igrf_scene_leaves_ppigrf_and_pandas_unimported():
    """A fresh process loads bdot_detumble (IGRF) and builds its configuration, the epoch
    checked: ppigrf and pandas (~0.5 CPU-s) wait until the field is evaluated."""
    import subprocess
    import sys
    proc = subprocess.run([sys.executable, '-c', (
        'import sys; from rigid_body_sim.scene import load; '
        'from rigid_body_sim.engine import EngineConfig; s = load("bdot_detumble"); '
        'c = EngineConfig.from_parameters(s.simulator); '
        'assert c.environment.magnetic.field.model == "igrf"; '
        'print(sorted(m for m in ("pandas", "ppigrf") if m in sys.modules))')],
        capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert proc.stdout.strip().splitlines()[-1] == '[]'


def test_igrf_along_the_orbit_is_ppigrfs_to_a_nanotesla():
    """The table (every 5 s, linear between) at the midpoints, where its error is largest,
    against ppigrf itself over an orbit at 500 km, i = 97.4°: within 1.5 nT and 6e-5 of
    |B| (measured 1.01 nT, 4.1e-5). The loops' line over an interval is the table's chord."""
    o = kepler()
    field = magnetic_field.FieldAlongOrbit('igrf', o, EPOCH)
    times = np.arange(0.0, o.period(), 5.0) + 2.5
    exact = field.exact(times)
    table = np.array([field.at(t) for t in times])
    error = np.linalg.norm(table - exact, axis=1)
    assert error.max() < 1.5e-9
    assert (error / np.linalg.norm(exact, axis=1)).max() < 6e-5
    # not the dipole: IGRF differs from it by several µT at 500 km
    dipole = magnetic_field.FieldAlongOrbit('dipole', o, EPOCH).exact(times)
    assert np.linalg.norm(dipole - exact, axis=1).max() > 2e-6
    env = o.elements()
    field.fill(env, 100.0, 101.0)
    assert env[k.MAG_MODEL] == 2.0
    for t in (100.0, 100.5, 101.0):
        np.testing.assert_allclose(magnetic_kernel.field_world(t, env), field.at(t),
                                   rtol=0, atol=1e-15)


def _torque_errors(seed=7):
    """Max |τ_loops − (τ_gg + m × B_body)| / |τ| over random states (run compiled and
    plain by the test below)."""
    rng = np.random.default_rng(seed)
    moments = np.array([0.03, 0.025, 0.01])
    out = []
    for model in ('dipole', 'igrf'):
        o = kepler()
        field = magnetic_field.FieldAlongOrbit(model, o, EPOCH)
        for _ in range(20):
            t = float(rng.uniform(0.0, 3000.0))
            env = o.elements()
            env[k.ON] = 1.0
            field.fill(env, t, t + 1.0)
            dipole = rng.uniform(-0.2, 0.2, 3)
            env[k.MAG_DIPOLE:k.MAG_DIPOLE + 3] = dipole
            q = rng.normal(size=4) * 1.3  # not unit: the RK stages' are not
            rot = Rotation.from_quat(q)
            b_body = rot.inv().apply(field.at(t))
            r, _ = o.state(t)
            c = rot.inv().apply(r / np.linalg.norm(r))
            gg = 3 * orbit.MU / np.linalg.norm(r) ** 3 * np.cross(c, moments * c)
            expected = gg + np.cross(dipole, b_body)
            got = Dynamics(moments, environment=env).environment_torque(q, t)
            out.append(float(np.linalg.norm(got - expected) / np.linalg.norm(expected)))
            env[k.ON] = 0.0
            got = Dynamics(moments, environment=env).environment_torque(q, t)
            assert np.linalg.norm(got - np.cross(dipole, b_body)) < 1e-9 * np.linalg.norm(got)
    return max(out)


_SCRIPT = '''
import json, sys
sys.path.insert(0, %r)
import test_magnetic as t
from rigid_body_sim.physics import jit
print(json.dumps({"compiled": jit.COMPILED, "error": t._torque_errors()}))
'''


@pytest.mark.slow
def test_magnetorquer_torque_is_m_cross_b_compiled_and_plain():
    """τ = m × B_body (+ the gravity gradient when both act) at random attitudes, times and
    dipoles, for both field models, in the compiled loops and as plain Python."""
    from jit_modes import run_both
    compiled, plain = run_both(_SCRIPT % os.path.dirname(os.path.abspath(__file__)))
    assert compiled['compiled'] is True and plain['compiled'] is False
    for out in (compiled, plain):
        assert out['error'] < 1e-12, out


def _reference(p, dipole_body, t_end, t_off=math.inf):
    """(q, ω) at t_end by scipy DOP853 at rtol 1e-12 of I ω̇ = Iω × ω + m × B_body,
    q̇ = ½ q ⊗ ω, with the field's own closed form (the body frame's full inertia); the
    dipole acts until t_off."""
    o = orbit.KeplerOrbit(A, 0.0, INC, 0.0, 0.0, 0.0)
    field = magnetic_field.FieldAlongOrbit('dipole', o, EPOCH)
    inertia = np.array(p['inertia'], float).reshape(3, 3)

    def rhs(t, y):
        q, w = y[:4], y[4:]
        b = Rotation.from_quat(q).inv().apply(field.exact(t)[0])
        m = dipole_body if t < t_off else np.zeros(3)
        dw = np.linalg.solve(inertia, np.cross(inertia @ w, w) + np.cross(m, b))
        x, y_, z, s = q
        dq = 0.5 * np.array([s * w[0] + y_ * w[2] - z * w[1], s * w[1] - x * w[2] + z * w[0],
                             s * w[2] + x * w[1] - y_ * w[0], -x * w[0] - y_ * w[1] - z * w[2]])
        return np.concatenate([dq, dw])

    y0 = np.concatenate([[0.0, 0.0, 0.0, 1.0], p['initial_angular_velocity']])
    if t_off < t_end:  # in two pieces: the right-hand side jumps there
        sol = solve_ivp(rhs, (0.0, t_off), y0, method='DOP853', rtol=1e-12, atol=1e-14)
        y0, t0 = sol.y[:, -1], t_off
    else:
        t0 = 0.0
    sol = solve_ivp(rhs, (t0, t_end), y0, method='DOP853', rtol=1e-12, atol=1e-14)
    return sol.y[:4, -1], sol.y[4:, -1]


@pytest.mark.parametrize('method,step', [('splitting4', 0.05), ('rk4', 0.05),
                                         ('dop853', 1.0)])
def test_the_engine_holds_clips_and_integrates_the_commanded_dipole(method, step):
    """A dipole command (one rod clipped to its 0.2 A·m², counted) held for the command
    timeout, 30.5 s, on a body whose principal axes are not its body axes: the engine's
    60 s run against an independent integration of the same equations with the field's
    closed form (an adaptive step in progress must not carry the dipole past its end)."""
    inertia = [0.03, 0.002, 0.0, 0.002, 0.025, 0.001, 0.0, 0.001, 0.01]
    p = scene(inertia=inertia, integrator=method, step=step, command_timeout=30.5)
    engine = Engine(EngineConfig.from_parameters(p))
    assert engine.method == method and 'magnetorquers' in engine.reason
    engine.apply_dipole_command([0.1, 0.5, -0.15])
    assert engine.magnetics.hold.saturated == 1
    np.testing.assert_array_equal(engine.magnetics.dipole(), [0.1, 0.2, -0.15])
    block = SampleBlock.concatenate(list(engine.run()))
    assert engine.magnetics.hold.timed_out == 1
    q_ref, w_ref = _reference(p, np.array([0.1, 0.2, -0.15]), 60.0, 30.5)
    tolerance = 1e-9 if method != 'rk4' else 1e-8
    np.testing.assert_allclose(block.angular_velocity[-1], w_ref, rtol=0, atol=tolerance)
    turn = Rotation.from_quat(block.attitude[-1]).inv() * Rotation.from_quat(q_ref)
    assert turn.magnitude() < 10 * tolerance
    # and the torque changed the motion: the free body's differs by far more
    free_q, free_w = _reference(p, np.zeros(3), 60.0)
    assert np.linalg.norm(free_w - w_ref) > 1e-4


def test_a_held_dipole_expires_after_the_command_timeout():
    p = scene(command_timeout=2.0, duration=5.0)
    engine = Engine(EngineConfig.from_parameters(p))
    engine.apply_dipole_command([0.1, 0.0, 0.0])
    engine.advance(int(1.5e9))
    np.testing.assert_array_equal(engine.magnetics.dipole(), [0.1, 0.0, 0.0])
    assert engine.dynamics.environment[k.MAG_DIPOLE] != 0.0
    # its share of the environment's torque now (diagnostics): m × B_body
    b = Rotation.from_quat(engine.attitude).inv().apply(
        engine.config.environment.magnetic.field.at(engine.t))
    np.testing.assert_allclose(engine.magnetics.torque(engine.t, engine.attitude),
                               np.cross([0.1, 0.0, 0.0], b), rtol=1e-12, atol=0)
    engine.advance(int(3e9))
    assert not engine.magnetics.dipole().any() and engine.magnetics.hold.timed_out == 1
    assert engine.dynamics.environment[k.MAG_DIPOLE] == 0.0


def test_without_a_dipole_the_field_costs_nothing():
    """Rods never commanded: the same run as without them, bit for bit (the torque is
    m × B with m = 0, and the kick adds exact zeros)."""
    with_rods = Engine(EngineConfig.from_parameters(scene()))
    without = Engine(EngineConfig.from_parameters(scene(**{
        'magnetorquer.max_dipole': [0.0, 0.0, 0.0], 'environment.magnetic_field': 'none',
        'orbit.model': 'none'})))
    a = SampleBlock.concatenate(list(with_rods.run()))
    b = SampleBlock.concatenate(list(without.run()))
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.m, b.m)


@pytest.mark.parametrize('overrides,message', [
    ({'orbit.model': 'none'}, 'environment.magnetic_field: dipole needs an orbit'),
    ({'environment.magnetic_field': 'igrf', 'epoch': ''}, 'epoch: environment.magnetic_field '
                                                         'igrf needs'),
    ({'environment.magnetic_field': 'igrf', 'epoch': '1850-01-01T00:00:00Z'},
     'epoch: epoch 1850-01-01.*outside the IGRF-14'),
    ({'environment.magnetic_field': 'igrf', 'epoch': '2031-06-01T00:00:00Z'},
     'epoch: epoch 2031-06-01.*outside the IGRF-14'),
    ({'environment.magnetic_field': 'none'}, 'magnetorquer.max_dipole: the rods need a field'),
    ({'environment.magnetic_field': 'none', 'magnetorquer.max_dipole': [0.0, 0.0, 0.0],
      'magnetometer.enabled': True}, 'magnetometer.enabled: a magnetometer needs a field'),
    ({'integrator': 'exact'}, 'integrator: exact does not integrate magnetorquer.max_dipole'),
    ({'environment.magnetic_field': 'earth'}, 'environment.magnetic_field'),
])
def test_bad_magnetic_scenes_are_refused_naming_the_key(overrides, message):
    with pytest.raises(ValueError, match=message):
        EngineConfig.from_parameters(scene(**overrides))


def test_methods_without_the_term_refuse_the_rods():
    o = kepler()
    env = o.elements()
    magnetic_field.FieldAlongOrbit('dipole', o, EPOCH).fill(env)
    with pytest.raises(ValueError, match='exact does not integrate the environment\'s torques '
                       r'\(magnetorquer.max_dipole\)'):
        create('exact', Dynamics(np.array([0.03, 0.025, 0.01]), environment=env))


def _readings(**overrides):
    p = scene(**{'magnetometer.enabled': True, 'magnetometer.rate': 4.0, 'duration': 50.0,
                 **overrides})
    engine = Engine(EngineConfig.from_parameters(p))
    engine.apply_dipole_command([0.1, -0.2, 0.05])
    blocks = list(engine.run())
    t = np.concatenate([b.magnetometer.t_ns for b in blocks if b.magnetometer is not None])
    field = np.concatenate([b.magnetometer.field for b in blocks if b.magnetometer is not None])
    return engine, SampleBlock.concatenate(blocks), t, field


def test_the_magnetometer_reads_the_field_its_bias_noise_and_the_rods():
    """Readings every 0.25 s in the body frame: the truth (the field turned by the attitude
    at that instant) + bias + coupling × the rods' dipole (NOS3 #145), + white noise of
    the set σ, the same for the same seed and another for another."""
    bias, coupling = [2e-7, -1e-7, 3e-7], 4e-6
    clean, block, t, field = _readings(**{'magnetometer.bias': bias,
                                          'magnetometer.torquer_coupling': coupling})
    np.testing.assert_array_equal(t, np.arange(201) * 250_000_000)
    o = clean.config.environment.magnetic.field
    samples = {int(ns): q for ns, q in zip(block.t_ns, block.attitude)}  # 1 Hz samples
    checked = 0
    for ns, reading in zip(t, field):
        if int(ns) in samples:
            truth = Rotation.from_quat(samples[int(ns)]).inv().apply(o.at(ns * 1e-9))
            expected = truth + bias + coupling * np.array([0.1, -0.2, 0.05])
            np.testing.assert_allclose(reading, expected, rtol=0, atol=1e-15)
            checked += 1
    assert checked == 51
    sigma = 5e-8
    _, _, _, noisy = _readings(**{'magnetometer.bias': bias, 'magnetometer.noise': sigma,
                                  'magnetometer.torquer_coupling': coupling, 'seed': 3})
    _, _, _, again = _readings(**{'magnetometer.bias': bias, 'magnetometer.noise': sigma,
                                  'magnetometer.torquer_coupling': coupling, 'seed': 3})
    _, _, _, other = _readings(**{'magnetometer.bias': bias, 'magnetometer.noise': sigma,
                                  'magnetometer.torquer_coupling': coupling, 'seed': 4})
    np.testing.assert_array_equal(noisy, again)
    error = noisy - field
    assert 0.8 * sigma < error.std() < 1.2 * sigma and abs(error.mean()) < 0.3 * sigma
    assert not np.array_equal(noisy, other)
