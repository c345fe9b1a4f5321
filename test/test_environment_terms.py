"""Every environment torque together (branches mag and sun merged): the gravity gradient,
the magnetorquers' m × B, solar radiation pressure and drag on the facets. Their sum is
each term's own (compiled), the environment_torque message carries the sum, and every
method that integrates the environment integrates each term (against an independent
scipy integration; dropping any one term moves the answer far more than the methods'
disagreement)."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rigid_body_sim.engine import Engine, EngineConfig
from rigid_body_sim.engine.magnetic import STREAM_MAGNETOMETER
from rigid_body_sim.physics import Dynamics, create, rotation
from rigid_body_sim.physics.environment import sunlight as sl
from rigid_body_sim.physics.orbit import kernel as k
from rigid_body_sim.sensors import noise

pytestmark = pytest.mark.fast  # make check

EPOCH = '2026-03-20T12:00:00Z'
FACETS = {'facets.areas': [4.0, 0.3], 'facets.normals': [1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
          'facets.centres': [0.3, 0.4, 0.0, 0.0, 0.08, -0.04], 'facets.specular': [0.3],
          'facets.diffuse': [0.2]}
ALL = dict(FACETS, **{'environment.gravity_gradient': True,
                      'environment.solar_radiation_pressure': True,
                      'environment.drag': 'exponential', 'environment.shadow': 'cylindrical'})
DIPOLE = np.array([0.15, -0.1, 0.18])  # A·m², body frame
# each term's switch in the loops' array, and the value that turns it off
TERMS = {'gravity gradient': ((k.ON,), 0.0), 'rods': ((k.MAG_MODEL,), 0.0),
         'srp': ((k.SRP_ON,), 0.0), 'drag': ((k.DRAG_ON,), 0.0)}


def params(**overrides):
    p = {'inertia': [3.0, 4.0, 2.0], 'orbit.model': 'kepler',
         'orbit.semi_major_axis': 6.778e6, 'orbit.inclination': 0.9, 'orbit.raan': 0.3,
         'epoch': EPOCH, 'environment.magnetic_field': 'dipole',
         'magnetorquer.max_dipole': [0.2, 0.2, 0.2], 'command_timeout': 1e4,
         'initial_angular_velocity': [0.05, -0.03, 0.04], 'duration': 60.0,
         'publish_rate': 1.0, 'integrator': 'rk4', 'step': 0.05}
    p.update(ALL)
    p.update(overrides)
    return p


def lit_time(config):
    for t in np.linspace(0.0, 5600.0, 561):
        r, _ = config.environment.orbit.state(t)
        if sl.shadow(r, sl.sun_vector(EPOCH, t), 'cylindrical') == 1.0 and \
                sl.shadow(*(config.environment.orbit.state(t + 400.0)[:1]),
                          sl.sun_vector(EPOCH, t + 400.0), 'cylindrical') == 1.0:
            return float(t)
    raise AssertionError('no lit stretch')


def arrays(config):
    """The loops' array with every term on (the rods' DIPOLE held), and one per term with
    only that term on."""
    body = config.body
    env = config.environment.elements(0.0, body.to_principal)
    env[k.MAG_DIPOLE:k.MAG_DIPOLE + 3] = body.to_principal(DIPOLE)
    alone = {}
    for name in TERMS:
        e = env.copy()
        for other, (slots, off) in TERMS.items():
            if other != name:
                for s in slots:
                    e[s] = off
        alone[name] = e
    return env, alone


def test_the_sum_is_each_terms_own_and_none_is_negligible():
    config = EngineConfig.from_parameters(params())
    assert config.environment.terms == ('gravity gradient', 'magnetorquers',
                                        'solar radiation pressure', 'drag (exponential)')
    moments = config.body.principal_moments
    env, alone = arrays(config)
    t = lit_time(config)
    q1 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    for generic, q in ((True, q1), (False, np.array([0.0, 0.0, 0.0, 1.0]))):
        total = Dynamics(moments, environment=env).environment_torque(q, t)
        parts = {n: Dynamics(moments, environment=e).environment_torque(q, t)
                 for n, e in alone.items()}
        np.testing.assert_allclose(total, sum(parts.values()), rtol=1e-12,
                                   atol=1e-15 * np.linalg.norm(total))
        for name, part in parts.items():
            assert not generic or np.linalg.norm(part) > 1e-2 * np.linalg.norm(total), name


def rhs(dynamics):
    def f(t, y):
        q, m = y[:4], y[4:]
        tau = dynamics.environment_torque(q / np.linalg.norm(q), t)
        w = m / dynamics.moments
        return np.concatenate([0.5 * rotation.multiply(q, np.append(w, 0.0)),
                               dynamics.momentum_rate(m, tau)])
    return f


def reference(dynamics, q0, m0, t0, span):
    sol = solve_ivp(rhs(dynamics), (t0, t0 + span), np.concatenate([q0, m0]),
                    method='DOP853', rtol=1e-12, atol=1e-15)
    q = sol.y[:4, -1]
    return q / np.linalg.norm(q), sol.y[4:, -1]


@pytest.mark.parametrize('method,h,tol', [
    ('splitting2', 0.01, 2e-7), ('splitting4', 0.05, 5e-8), ('splitting6', 0.1, 5e-8),
    ('splitting2_lstable', 0.01, 2e-7), ('rk4', 0.02, 1e-8),
    pytest.param('euler', 1e-4, 5e-6, marks=pytest.mark.slow),  # 1.2e6 steps: make test
    ('dop853', 1.0, 1e-7)])
def test_every_method_integrates_every_term(method, h, tol):
    """120 s in sunlight at 400 km: the final momentum within tol (relative) of scipy's
    DOP853 on the same right-hand side, where leaving out any one term is off by far
    more."""
    config = EngineConfig.from_parameters(params())
    moments = config.body.principal_moments
    env, alone = arrays(config)
    t0, span = lit_time(config), 120.0
    q0 = np.array([0.1, -0.2, 0.3, 0.9]) / np.linalg.norm([0.1, -0.2, 0.3, 0.9])
    m0 = moments * np.array([0.05, -0.03, 0.04])
    q_ref, m_ref = reference(Dynamics(moments, environment=env), q0, m0, t0, span)
    scale = np.linalg.norm(m_ref)
    n = round(span / h)
    q, m = create(method, Dynamics(moments, environment=env.copy())).run(
        q0.copy(), m0.copy(), h, n, None, t0)
    assert np.linalg.norm(m - m_ref) < tol * scale, np.linalg.norm(m - m_ref) / scale
    assert min(np.linalg.norm(q - q_ref), np.linalg.norm(q + q_ref)) < 100 * tol
    for name in TERMS:  # without the term: a different answer, by far more than tol
        without = env.copy()
        for s in TERMS[name][0]:
            without[s] = 0.0
        _, m_without = reference(Dynamics(moments, environment=without), q0, m0, t0, span)
        assert np.linalg.norm(m_without - m_ref) > 10 * tol * scale, name


def test_the_environment_torque_message_is_the_sum_of_all_four_terms():
    """An engine run with a held dipole command: each sample's environment_torque (as
    live and in bags) against the compiled sum at that state, all four terms on."""
    from rigid_body_sim.nodes.orbit_messages import OrbitMessages
    config = EngineConfig.from_parameters(params(duration=20.0))
    engine = Engine(config)
    engine.apply_dipole_command(DIPOLE)
    block = next(iter(engine.run()))
    assert block.dipole is not None and np.allclose(block.dipole[1:], DIPOLE)
    msgs = OrbitMessages(config, 'world', 'base_link', 'lvlh')
    env, _ = arrays(config)
    body = config.body
    for i in range(1, len(block)):
        msgs.fill(block, i, int(block.t_ns[i]))
        w = msgs.torque.wrench.torque
        env[k.MAG_DIPOLE:k.MAG_DIPOLE + 3] = body.to_principal(block.dipole[i])
        tau = body.to_body(Dynamics(body.principal_moments, environment=env)
                           .environment_torque(block.q[i], block.t_ns[i] * 1e-9))
        np.testing.assert_allclose([w.x, w.y, w.z], tau, rtol=1e-9,
                                   atol=1e-12 * np.linalg.norm(tau))


def test_the_sensors_noise_streams_are_distinct():
    """The magnetometer's and the sun sensor's noise draw from streams of their own."""
    used = [noise.STREAM_ARW, noise.STREAM_GM, noise.STREAM_RRW, noise.STREAM_STAR,
            noise.STREAM_SUN, STREAM_MAGNETOMETER]
    assert len(set(used)) == len(used)
