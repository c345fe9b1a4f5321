"""Solar radiation pressure and aerodynamic drag on a box-and-panels facet model, against
closed forms: a flat plate at a known angle (force and torque), sums over facets, the
shadow, the density table, and the compiled loops' Sun against the almanac's."""
import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from rigid_body_sim.engine import EngineConfig, SampleBlock
from rigid_body_sim.engine.core import Engine
from rigid_body_sim.physics.environment import facets as fm, facets_kernel as fk, sunlight as sl
from rigid_body_sim.physics.orbit import kernel as ok

pytestmark = pytest.mark.fast  # make check

EPOCH = '2026-03-20T12:00:00Z'
A = 6.778e6          # 400 km up
OMEGA_E = 7.2921158553e-5


def params(**overrides):
    p = {'inertia': [3.0, 4.0, 2.0], 'orbit.model': 'kepler', 'orbit.semi_major_axis': A,
         'orbit.inclination': 0.5, 'orbit.raan': 0.3, 'epoch': EPOCH,
         'facets.areas': [2.0], 'facets.normals': [1.0, 0.0, 0.0],
         'facets.centres': [0.0, 0.5, 0.2], 'environment.shadow': 'cylindrical'}
    p.update(overrides)
    return p


def dynamics(**overrides):
    config = EngineConfig.from_parameters(params(**overrides))
    return config, Engine(config).dynamics


def facing(direction_inertial, body_direction):
    """An attitude (body → inertial) that turns ``body_direction`` onto the inertial one."""
    return Rotation.align_vectors([direction_inertial], [body_direction])[0].as_quat()


def lit_time(config, lit=True):
    """A time (s) of the first orbit in sunlight (lit) or in the cylindrical shadow."""
    for t in np.linspace(0.0, 5600.0, 561):
        r, _ = config.environment.orbit.state(t)
        if (sl.shadow(r, sl.sun_vector(EPOCH, t), 'cylindrical') == 1.0) == lit:
            return float(t)
    raise AssertionError('no such time')


@pytest.mark.parametrize('theta,specular,diffuse', [(0.0, 0.0, 0.0), (0.6, 0.0, 0.0),
                                                    (0.6, 1.0, 0.0), (1.1, 0.3, 0.4)])
def test_flat_plate_srp_torque_is_the_closed_form(theta, specular, diffuse):
    config, dyn = dynamics(**{'environment.solar_radiation_pressure': True,
                              'facets.specular': [specular], 'facets.diffuse': [diffuse]})
    t = lit_time(config)
    r, _ = config.environment.orbit.state(t)
    to_sun = sl.sun_vector(EPOCH, t) - r
    s_body = np.array([math.cos(theta), math.sin(theta), 0.0])   # angle theta to the normal
    q = facing(to_sun, s_body)
    pressure = 4.56e-6 * (sl.AU / np.linalg.norm(to_sun)) ** 2
    n = np.array([1.0, 0.0, 0.0])
    c = math.cos(theta)
    force = -pressure * 2.0 * c * ((1 - specular) * s_body
                                   + (2 * specular * c + diffuse * 2 / 3) * n)
    if specular == 1.0:  # a mirror: along the normal, 2 P A cos²θ
        assert np.allclose(force, -2 * pressure * 2.0 * c * c * n, rtol=1e-14, atol=0)
    if specular == 0.0 and diffuse == 0.0:  # a black plate: along the Sun line, P A cosθ
        assert np.allclose(force, -pressure * 2.0 * c * s_body, rtol=1e-14, atol=0)
    expected = np.cross([0.0, 0.5, 0.2], force)
    got = dyn.environment_torque(q, t)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-9 * np.abs(expected).max())
    # the numpy reference gives the same
    _, tau = config.environment.sunlight.facets.srp(s_body, pressure)
    np.testing.assert_allclose(tau, expected, rtol=1e-12, atol=1e-25)
    # turned away from the Sun the plate feels nothing
    assert np.all(dyn.environment_torque(facing(to_sun, -s_body), t) == 0.0)


def test_srp_is_zero_in_the_shadow_and_drag_is_not():
    config, dyn = dynamics(**{'environment.solar_radiation_pressure': True})
    t = lit_time(config, lit=False)
    r, _ = config.environment.orbit.state(t)
    q = facing(sl.sun_vector(EPOCH, t) - r, [1.0, 0.0, 0.0])
    assert np.all(dyn.environment_torque(q, t) == 0.0)
    config, dyn = dynamics(**{'environment.solar_radiation_pressure': True,
                              'environment.drag': 'exponential'})
    r, v = config.environment.orbit.state(t)
    assert np.abs(dyn.environment_torque(facing(v, [1.0, 0.0, 0.0]), t)).max() > 1e-9


@pytest.mark.parametrize('theta', [0.0, 0.7])
def test_flat_plate_drag_torque_offset_from_the_centre_of_mass(theta):
    config, dyn = dynamics(**{'environment.drag': 'exponential',
                              'facets.drag_coefficient': [2.2]})
    t = 1234.0
    r, v = config.environment.orbit.state(t)
    v_rel = v - np.cross([0.0, 0.0, OMEGA_E], r)      # the atmosphere turns with the Earth
    speed = np.linalg.norm(v_rel)
    u_body = np.array([math.cos(theta), math.sin(theta), 0.0])
    q = facing(v_rel, u_body)
    rho = fm.exponential_density(fm.height(r))
    force = -0.5 * rho * 2.2 * 2.0 * math.cos(theta) * speed ** 2 * u_body
    expected = np.cross([0.0, 0.5, 0.2], force)
    np.testing.assert_allclose(dyn.environment_torque(q, t), expected, rtol=1e-9,
                               atol=1e-9 * np.abs(expected).max())
    # a plate through the centre of mass, face on, feels no torque
    _, dyn0 = dynamics(**{'environment.drag': 'exponential', 'facets.centres': [0, 0, 0]})
    assert np.all(dyn0.environment_torque(q, t) == 0.0)


def test_exponential_table_at_its_nodes_and_between():
    assert fm.exponential_density(400e3) == pytest.approx(3.725e-12, rel=1e-12)
    assert fm.exponential_density(0.0) == pytest.approx(1.225, rel=1e-12)
    # between nodes: the lower layer's scale height
    assert fm.exponential_density(425e3) == pytest.approx(3.725e-12 * math.exp(-25 / 58.515),
                                                          rel=1e-12)
    # the compiled twin at the same points (height above the ellipsoid, equator and pole)
    env = np.zeros(ok.SIZE)
    env[ok.DENSITY] = 1.0
    for r in ([fm.EARTH_RADIUS + 425e3, 0.0, 0.0], [0.0, 0.0, 6.8e6], [4.0e6, 3.0e6, 3.5e6]):
        assert fk.density(env, *r) == pytest.approx(fm.exponential_density(fm.height(r)),
                                                    rel=1e-13)
    polar = fm.height([0.0, 0.0, 6.8e6])   # the ellipsoid's polar radius is 6,356.75 km
    assert polar == pytest.approx(6.8e6 - 6356752.3, abs=1.0)


def test_torques_sum_over_facets():
    normals = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, -0.6, 0.0, 0.8]
    centres = [0.3, 0.1, 0.0, 0.0, -0.4, 0.2, 0.1, 0.1, -0.5]
    keys = {'environment.solar_radiation_pressure': True, 'environment.drag': 'exponential',
            'facets.specular': [0.2], 'facets.diffuse': [0.1, 0.3, 0.0]}
    config, dyn = dynamics(**keys, **{'facets.areas': [1.0, 0.5, 2.0], 'facets.normals': normals,
                                      'facets.centres': centres})
    t = lit_time(config)
    q = Rotation.from_rotvec([0.3, -1.2, 0.8]).as_quat()
    total = dyn.environment_torque(q, t)
    parts = sum(dynamics(**dict(keys, **{
        'facets.areas': [a], 'facets.normals': normals[3 * i:3 * i + 3],
        'facets.centres': centres[3 * i:3 * i + 3], 'facets.diffuse': [[0.1, 0.3, 0.0][i]]}))[1]
        .environment_torque(q, t) for i, a in enumerate([1.0, 0.5, 2.0]))
    np.testing.assert_allclose(total, parts, rtol=1e-12, atol=1e-20)
    assert np.abs(total).max() > 0.0


def test_loops_sun_is_the_almanacs_and_their_shadow_is_the_models():
    config, dyn = dynamics(**{'environment.solar_radiation_pressure': True})
    env = dyn.environment
    for t in (0.0, 3600.0, 86400.0, 30 * 86400.0):
        x, y, z, d = fk.sun(env, t)
        s = sl.sun_vector(EPOCH, t)
        # the obliquity is held at the epoch's value: 6e-9 rad a day
        error = np.linalg.norm(np.array([x, y, z]) - s / np.linalg.norm(s))
        assert error < 1e-9 + 1e-8 * t / 86400
        assert d == pytest.approx(np.linalg.norm(s), rel=1e-12)
    rng = np.random.default_rng(7)
    s = sl.sun_vector(EPOCH, 0.0)
    u = s / np.linalg.norm(s)
    base = -u * 6.9e6
    for _ in range(200):
        r = base + rng.normal(scale=7e6, size=3) * [1, 1, 1] * rng.uniform(0, 1)
        if np.linalg.norm(r) < 6.5e6:
            continue
        for code, model in enumerate(('cylindrical', 'conical')):
            assert fk.shadow(*r, *u, np.linalg.norm(s), float(code)) == \
                pytest.approx(float(sl.shadow(r, s, model)), abs=1e-12)


def test_terms_off_build_nothing_and_on_name_themselves():
    config = EngineConfig.from_parameters(params())
    assert config.environment.terms == () and Engine(config).dynamics.environment is None
    config = EngineConfig.from_parameters(params(**{
        'environment.solar_radiation_pressure': True, 'environment.drag': 'exponential',
        'integrator': 'rk4', 'duration': 10.0}))
    engine = Engine(config)
    assert 'solar radiation pressure' in engine.reason and 'drag (exponential)' in engine.reason
    assert engine.dynamics.environment[ok.ON] == 0.0   # no gravity gradient: its slot is off


@pytest.mark.parametrize('overrides,match', [
    ({'orbit.model': 'none', 'environment.solar_radiation_pressure': True},
     'environment.solar_radiation_pressure: needs an orbit'),
    ({'epoch': '', 'environment.solar_radiation_pressure': True},
     'environment.solar_radiation_pressure: needs an epoch'),
    ({'environment.drag': 'exponential', 'facets.areas': []}, 'environment.drag: needs a facet'),
    ({'environment.drag': 'exponential', 'facets.normals': [1.0, 0.0]}, 'facets.normals: needs 3'),
    ({'environment.drag': 'exponential', 'facets.normals': [0.0, 0.0, 0.0]},
     'facets.normals: facet 0 has a zero normal'),
    ({'environment.solar_radiation_pressure': True, 'facets.specular': [0.7],
      'facets.diffuse': [0.5]}, r'facets.specular \+ facets.diffuse'),
    ({'environment.drag': 'exponential', 'integrator': 'implicit_midpoint'},
     'integrator: implicit_midpoint does not integrate environment.drag'),
])
def test_bad_facet_scenes_are_refused_by_name(overrides, match):
    with pytest.raises(ValueError, match=match):
        EngineConfig.from_parameters(params(**overrides))


_SCRIPT = '''
import json, sys
import numpy as np
sys.path.insert(0, %r)
from test_facets import params
from rigid_body_sim.engine import EngineConfig, SampleBlock
from rigid_body_sim.engine.core import Engine
from rigid_body_sim.physics import rotation
from rigid_body_sim.physics.jit import COMPILED
out = {'compiled': COMPILED}
for method, step in (('splitting4', 2.0), ('rk4', 1.0), ('dop853', 20.0)):
    p = params(**{'environment.solar_radiation_pressure': True, 'environment.drag': 'exponential',
                  'facets.areas': [0.01], 'facets.centres': [0.0, 1.0, 0.5],
                  'initial_angular_velocity': [0.001, -0.002, 0.0015], 'integrator': method,
                  'step': step, 'duration': 3000.0, 'publish_rate': 0.01,
                  'orbit.true_anomaly': 2.0})
    engine = Engine(EngineConfig.from_parameters(p))
    block = SampleBlock.concatenate(list(engine.run()))
    # the inertial angular momentum (the torque changes it) and the attitude
    out[method] = rotation.rotate(block.q[-1], block.m[-1]).tolist() + block.q[-1].tolist()
print(json.dumps(out))
'''


@pytest.mark.slow
def test_every_kind_of_method_integrates_the_terms_compiled_and_plain():
    """Through an eclipse (t = 0 … 3000 s from ν = 2 rad), with a panel whose torque
    changes the rate: splitting4 (a kick), rk4 and dop853 (a right-hand-side term) agree
    with each other to their accuracy and the two modes to round-off."""
    import os
    from jit_modes import run_both
    compiled, plain = run_both(_SCRIPT % os.path.dirname(os.path.abspath(__file__)))
    assert compiled.pop('compiled') is True and plain.pop('compiled') is False
    free = np.array([0.003, -0.008, 0.003])   # L = I ω0 at rest attitude, kept if torque-free
    ref = np.array(compiled['dop853'])
    assert np.abs(ref[:3] - free).max() > 1e-5
    for method in compiled:
        np.testing.assert_allclose(plain[method], compiled[method], atol=1e-11, err_msg=method)
        np.testing.assert_allclose(compiled[method][:3], ref[:3], atol=1e-9, err_msg=method)
        np.testing.assert_allclose(compiled[method][3:], ref[3:], atol=1e-6, err_msg=method)


def test_nrlmsis_reads_no_file_from_the_network_and_its_local_fit_holds(monkeypatch):
    """pymsis downloads its space-weather file unless F10.7 and Ap are given: we give them,
    so a run with no network works (CI has none). The interval's local exponential fit
    follows NRLMSIS's own density 5 km away to its curvature (< 1%)."""
    import socket
    import urllib.request
    from rigid_body_sim.engine.sunlight_specs import FIT_STEP, msis_density

    def no_network(*args, **kwargs):
        raise AssertionError('pymsis reached for the network')
    monkeypatch.setattr(urllib.request, 'urlopen', no_network)
    monkeypatch.setattr(socket.socket, 'connect', no_network)
    config, dyn = dynamics(**{'environment.drag': 'nrlmsis', 'environment.f107': 150.0})
    engine = Engine(config)
    assert engine.orbit_anchored and 'drag (nrlmsis)' in engine.reason
    env = dyn.environment
    r, _ = config.environment.orbit.state(0.0)
    rho = msis_density(EPOCH, 0.0, r, 0.0, 150.0, 4.0)
    assert 1e-13 < rho < 1e-10   # 400 km at moderate solar activity
    assert env[ok.RHO_REF] == rho and env[ok.SCALE_HEIGHT] > 30e3
    up = r * (1.0 + 5e3 / np.linalg.norm(r))
    assert fk.density(env, *up) == pytest.approx(msis_density(EPOCH, 0.0, r, 5e3, 150.0, 4.0),
                                                 rel=1e-2)
    assert fk.density(env, *(r * (1.0 + FIT_STEP / np.linalg.norm(r)))) == pytest.approx(
        msis_density(EPOCH, 0.0, r, FIT_STEP, 150.0, 4.0), rel=1e-6)
    # more solar flux, a hotter and denser thermosphere
    assert msis_density(EPOCH, 0.0, r, 0.0, 250.0, 4.0) > 1.5 * rho
    # and a run re-fits at each interval
    block = SampleBlock.concatenate(list(Engine(EngineConfig.from_parameters(params(**{
        'environment.drag': 'nrlmsis', 'duration': 20.0, 'publish_rate': 1.0,
        'integrator': 'rk4', 'step': 0.5}))).run()))
    assert len(block) == 21 and np.all(np.isfinite(block.m))


# slow: compiles the gyrostat's loop with the facets' terms, 5 CPU-s
@pytest.mark.slow
def test_the_gyrostat_integrates_the_facets_torque_too():
    """Four reaction wheels (wheel_slew's body, no law): the drag on a large offset panel is
    the only external torque, so the total momentum H = Iω + h_wheels (inertial) changes
    by ∫ R(q) τ dt, τ from the closed-form model along the run (trapezoid over 0.1 s
    samples), and stays fixed without it."""
    from rigid_body_sim import scene as S
    from rigid_body_sim.physics import rotation
    sim = dict(S.load('wheel_slew').simulator)
    sim.update(params(**{'environment.drag': 'exponential', 'facets.areas': [20.0],
                         'facets.centres': [0.0, 2.0, 1.0], 'duration': 60.0,
                         'publish_rate': 10.0}))
    sim['inertia'] = [4.0, 5.0, 3.0]
    for drag in ('exponential', 'none'):
        sim['environment.drag'] = drag
        engine = Engine(EngineConfig.from_parameters(sim))
        assert engine.actuators is not None
        H = [engine.angular_momentum.copy()]
        times, torques = [], []
        for block in engine.run():
            for t_ns, q in zip(block.t_ns, block.q):
                times.append(t_ns / 1e9)
                torques.append(rotation.rotate(q, engine.dynamics.environment_torque(
                    q, t_ns / 1e9)) if drag != 'none' else np.zeros(3))
        H.append(engine.angular_momentum.copy())
        change = H[1] - H[0]
        if drag == 'none':
            assert np.abs(change).max() < 1e-12
            continue
        impulse = np.trapezoid(np.array(torques), np.array(times), axis=0)
        assert np.linalg.norm(impulse) > 1e-4
        np.testing.assert_allclose(change, impulse, rtol=0, atol=1e-3 * np.linalg.norm(impulse))
