"""The orbit as a function of time: Kepler, J2's secular drift, SGP4; bad orbits refused."""
import math
from datetime import timedelta

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from rigid_body_sim.engine.config import EngineConfig
from rigid_body_sim.physics import orbit
from rigid_body_sim.physics.orbit import J2Orbit, KeplerOrbit, osculating_elements
from rigid_body_sim.physics.orbit import kernel

pytestmark = pytest.mark.fast  # make check

# the ISS, as in the sgp4 package's README
ISS = ['1 25544U 98067A   19343.69339541  .00001764  00000-0  38792-4 0  9991',
       '2 25544  51.6439 211.2001 0007417  17.6667  85.6398 15.50103472202482']


def _eccentric():
    return KeplerOrbit(8.0e6, 0.3, 0.9, 0.4, 1.3, 2.0)


@pytest.mark.parametrize('periods', [1, 10, 1000])
def test_kepler_position_after_whole_periods_returns_to_round_off(periods):
    o = _eccentric()
    r0, v0 = o.state(0.0)
    r, v = o.state(periods * o.period())
    # M = M0 + n·kT is reduced mod 2π: the error is the rounding of kT (k·eps·2π rad)
    assert np.linalg.norm(r - r0) / np.linalg.norm(r0) < 4e-16 * 2 * math.pi * periods + 1e-15
    assert np.linalg.norm(v - v0) / np.linalg.norm(v0) < 4e-16 * 2 * math.pi * periods + 1e-15
    # and half a period away it is elsewhere (the check could fail)
    assert np.linalg.norm(o.state(o.period() / 2)[0] - r0) > 1e6


def test_kepler_matches_the_integrated_two_body_problem():
    o = _eccentric()
    mu = orbit.MU
    r0, v0 = o.state(0.0)

    def rhs(_, y):
        r = y[:3]
        return np.concatenate((y[3:], -mu * r / np.linalg.norm(r) ** 3))
    times = np.linspace(0.0, o.period(), 7)[1:]
    sol = solve_ivp(rhs, (0, times[-1]), np.concatenate((r0, v0)), method='DOP853',
                    rtol=1e-13, atol=1e-6, t_eval=times)
    for k, t in enumerate(times):
        r, v = o.state(t)
        assert np.linalg.norm(r - sol.y[:3, k]) / np.linalg.norm(r) < 1e-9
        assert np.linalg.norm(v - sol.y[3:, k]) / np.linalg.norm(v) < 1e-9
    # the elements come back from the state (radius at t = 0 from the true anomaly)
    p = o.a * (1 - o.e ** 2)
    assert np.linalg.norm(r0) == pytest.approx(p / (1 + o.e * math.cos(o.nu0)), rel=1e-14)


def test_kepler_equation_is_solved_to_round_off():
    for e in (0.0, 0.1, 0.5, 0.9, 0.99):
        for m in np.linspace(-3.1, 3.1, 13):
            big_e = kernel.eccentric_anomaly(m, e)
            assert abs(big_e - e * math.sin(big_e) - m) < 4e-15


def _node(o, t):
    r, v = o.state(t)
    h = np.cross(r, v)
    return math.atan2(h[0], -h[1])


def test_j2_node_drift_against_its_secular_rate():
    a, e, i = 7.078e6, 0.01, math.radians(98.19)  # ~700 km, near sun-synchronous
    o = J2Orbit(a, e, i, 0.3, 0.5, 0.0)
    n = math.sqrt(orbit.MU / a ** 3)
    p = a * (1 - e * e)
    rate = -1.5 * n * orbit.J2 * (orbit.RADIUS / p) ** 2 * math.cos(i)
    days = 30
    t = days * 86400.0
    measured = math.remainder(_node(o, t) - _node(o, 0.0), 2 * math.pi)
    assert measured == pytest.approx(rate * t, rel=1e-9)
    # sun-synchronous: the node follows the Sun, 0.9856°/day (Vallado §9)
    assert math.degrees(measured) / days == pytest.approx(0.9856, rel=0.01)
    # Kepler alone leaves the node where it was
    k = KeplerOrbit(a, e, i, 0.3, 0.5, 0.0)
    assert abs(math.remainder(_node(k, t) - _node(k, 0.0), 2 * math.pi)) < 1e-12


def test_osculating_elements_reproduce_the_state():
    o = _eccentric()
    t = 1234.5
    r, v = o.state(t)
    env = osculating_elements(r, v, orbit.MU, t)
    out = np.zeros(6)
    for dt in (0.0, 10.0, 1000.0):
        kernel.state_at(env, t + dt, out)
        r_ref, _ = o.state(t + dt)
        assert np.linalg.norm(out[:3] - r_ref) / np.linalg.norm(r_ref) < 1e-12


def test_sgp4_against_the_sgp4_package():
    from sgp4.api import Satrec
    sat = Satrec.twoline2rv(*ISS)
    o = orbit.from_tle(ISS)
    for minutes in (0.0, 1.5, 45.0, 1440.0):
        code, r, v = sat.sgp4_tsince(minutes)
        assert code == 0
        r_ours, v_ours = o.state(minutes * 60.0)
        # the same routine; only the time arithmetic differs (Julian date vs minutes)
        assert np.linalg.norm(r_ours - np.array(r) * 1e3) < 1e-4  # m
        assert np.linalg.norm(v_ours - np.array(v) * 1e3) < 1e-7  # m/s
    # an epoch one hour after the TLE's: sim time 0 is that hour
    from rigid_body_sim.physics.orbit.sgp4_orbit import julian_date  # noqa: F401
    from datetime import datetime, timezone
    tle_epoch = datetime(2019, 1, 1, tzinfo=timezone.utc) + timedelta(days=343.69339541 - 1)
    later = orbit.from_tle(ISS, tle_epoch + timedelta(hours=1))
    _, r, _ = sat.sgp4_tsince(60.0)
    assert np.linalg.norm(later.state(0.0)[0] - np.array(r) * 1e3) < 1e-3
    # the osculating conic through SGP4's state follows it closely over a second
    env = o.elements(100.0)
    out = np.zeros(6)
    kernel.state_at(env, 101.0, out)
    assert np.linalg.norm(out[:3] - o.state(101.0)[0]) < 0.05  # m, of 6.8e6


def test_sgp4_failure_names_the_time_and_code():
    # a decaying orbit: SGP4 reports error 6 (decay) long before a year has passed
    o = orbit.from_tle(ISS)
    with pytest.raises(orbit.OrbitError, match=r'SGP4 error \d'):
        for days in range(0, 200000, 500):
            o.state(days * 86400.0)


def _config(**values):
    return EngineConfig.from_parameters(values)


def test_free_body_builds_no_environment():
    assert _config().environment is None


def test_orbit_scene_keys_build_the_orbit():
    c = _config(**{'orbit.model': 'j2', 'orbit.semi_major_axis': 7.1e6,
                   'orbit.eccentricity': 0.01, 'orbit.inclination': 1.0,
                   'environment.gravity_gradient': True, 'epoch': '2026-03-20T12:00:00Z'})
    env = c.environment
    assert isinstance(env.orbit, J2Orbit) and env.gravity_gradient
    assert env.orbit.a == 7.1e6 and env.epoch.year == 2026 and env.terms == ('gravity gradient',)
    c = _config(**{'orbit.model': 'sgp4', 'orbit.tle': ISS})
    assert c.environment.orbit.name == 'sgp4' and not c.environment.gravity_gradient


@pytest.mark.parametrize('values,message', [
    ({'orbit.model': 'kepler', 'orbit.semi_major_axis': 6.3e6},
     r'orbit\.semi_major_axis: the perigee .* below the Earth\'s surface'),
    ({'orbit.model': 'kepler', 'orbit.semi_major_axis': 1.0e7, 'orbit.eccentricity': 0.4},
     r'orbit\.semi_major_axis: the perigee a\(1 - e\) = 6000 km is below'),
    ({'orbit.model': 'kepler', 'orbit.eccentricity': 1.0}, r'orbit\.eccentricity .*< 1'),
    ({'orbit.model': 'kepler', 'orbit.eccentricity': 1.5}, r'orbit\.eccentricity .*< 1'),
    ({'orbit.model': 'sgp4'}, r'orbit\.tle: .*needs the two lines'),
    ({'orbit.model': 'sgp4', 'orbit.tle': [ISS[0]]}, r'orbit\.tle: needs exactly two lines'),
    ({'orbit.model': 'sgp4', 'orbit.tle': [ISS[0][:-1] + '0', ISS[1]]},
     r'orbit\.tle: line 1 checksum'),
    ({'orbit.model': 'sgp4', 'orbit.tle': [ISS[0], ISS[1][:60]]},
     r'orbit\.tle: line 2 has 60 characters'),
    ({'orbit.model': 'sgp4', 'orbit.tle': [ISS[1], ISS[0]]},
     r'orbit\.tle: line 1 must start with "1 "'),
    ({'orbit.model': 'orbit'}, r'orbit\.model .*not one of'),
    ({'environment.gravity_gradient': True}, r'environment\.gravity_gradient: needs an orbit'),
    ({'orbit.model': 'kepler', 'epoch': 'yesterday'}, r'epoch .*not an ISO 8601'),
])
def test_bad_orbit_is_refused_at_load_naming_the_key(values, message):
    with pytest.raises(ValueError, match=message):
        _config(**values)
