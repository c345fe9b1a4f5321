"""The sun sensor (sun_direction) through the engine's output: silent in the Earth's shadow
exactly between the eclipse's entry and exit of the cylinder's closed form, the Sun's
direction in the body frame when lit, its noise seeded like the gyro's."""
import math

import numpy as np
import pytest

from rigid_body_sim.engine import EngineConfig, SampleBlock
from rigid_body_sim.engine.core import Engine
from rigid_body_sim.physics import orbit, rotation
from rigid_body_sim.physics.environment import sunlight as sl

pytestmark = pytest.mark.fast  # make check

EPOCH = '2026-03-20T12:00:00Z'
A, INC, RAAN = 6.778e6, 0.5, 0.3
N = math.sqrt(orbit.MU / A ** 3)


def params(**overrides):
    p = {'inertia': [3.0, 4.0, 2.0], 'orbit.model': 'kepler', 'orbit.semi_major_axis': A,
         'orbit.inclination': INC, 'orbit.raan': RAAN, 'epoch': EPOCH,
         'environment.shadow': 'cylindrical', 'sun_sensor.enabled': True,
         'sun_sensor.rate': 1.0, 'initial_angular_velocity': [0.01, -0.02, 0.005],
         'publish_rate': 1.0, 'duration': 2 * math.pi / N + 10.0, 'integrator': 'splitting4',
         'step': 0.5}
    p.update(overrides)
    return p


def run(p):
    engine = Engine(EngineConfig.from_parameters(p))
    blocks = list(engine.run())
    readings = [b.sensors for b in blocks if b.sensors is not None]
    t = np.concatenate([r.sun_t_ns for r in readings]) / 1e9
    u = np.concatenate([r.sun for r in readings])
    return engine, SampleBlock.concatenate(blocks), t, u


def shadow_boundaries():
    """(entry, exit) times (s) of the first eclipse, closed form: on the circle
    r = a(cos u P + sin u Q), u = n t, the cylinder holds r·ŝ < −√(a² − R_E²), i.e.
    cos(u − φ) < −√(1 − R_E²/a²)/ρ with ŝ = ρ(cos φ P + sin φ Q) + (normal part); ŝ taken
    at the boundary's own instant (a fixed point: the Sun moves 1e-3 rad per orbit)."""
    P = np.array([math.cos(RAAN), math.sin(RAAN), 0.0])
    Q = np.array([-math.sin(RAAN) * math.cos(INC), math.cos(RAAN) * math.cos(INC),
                  math.sin(INC)])
    out = []
    for sign in (-1.0, 1.0):
        t = math.pi / N
        for _ in range(6):
            s = sl.sun_direction(EPOCH, t)
            sp, sq = float(s @ P), float(s @ Q)
            rho, phi = math.hypot(sp, sq), math.atan2(sq, sp)
            alpha = math.acos(math.sqrt(1.0 - (sl.EARTH_RADIUS / A) ** 2) / rho)
            u = (phi + math.pi + sign * alpha) % (2 * math.pi)
            t = u / N
        out.append(t)
    return tuple(out)


def test_no_reading_in_the_shadow_between_the_closed_forms_entry_and_exit():
    engine, _, t, _ = run(params())
    entry, exit_ = shadow_boundaries()
    assert 0.0 < entry < exit_ < t[-1]
    gaps = np.flatnonzero(np.diff(t) > 1.5)
    assert len(gaps) == 1, t[gaps]                     # one eclipse in the orbit
    last_lit, first_lit = t[gaps[0]], t[gaps[0] + 1]
    assert last_lit < entry <= last_lit + 1.0          # the shadow starts before the next reading
    assert first_lit - 1.0 < exit_ <= first_lit        # and ends after the one before
    # the readings missed are the ones the engine counted
    assert engine._sensors.eclipse_skips == round(first_lit - last_lit) - 1
    assert 30 * 60 < exit_ - entry < 40 * 60           # ~35 min at 400 km near the equinox


def test_lit_readings_are_the_suns_direction_in_the_body_frame():
    _, block, t, u = run(params(duration=600.0))
    assert np.allclose(np.linalg.norm(u, axis=1), 1.0, atol=1e-14)
    o = orbit.KeplerOrbit(A, 0.0, INC, RAAN, 0.0, 0.0)
    samples = {int(ts): q for ts, q in zip(block.t_ns, block.q)}
    checked = 0
    for ti, ui in zip(t[::50], u[::50]):
        q = samples[int(round(ti * 1e9))]
        r, _ = o.state(ti)
        to_sun = sl.sun_vector(EPOCH, ti) - r
        expected = rotation.rotate(rotation.conjugate(q), to_sun / np.linalg.norm(to_sun))
        np.testing.assert_allclose(ui, expected, atol=1e-12)
        checked += 1
    assert checked >= 10


def test_noise_is_seeded_and_of_its_size():
    sigma = 1e-3
    runs = [run(params(duration=300.0, **{'sun_sensor.noise': [sigma], 'seed': s}))[3]
            for s in (5, 5, 6)]
    np.testing.assert_array_equal(runs[0], runs[1])
    assert np.abs(runs[0] - runs[2]).max() > 0.0
    truth = run(params(duration=300.0))[3]
    angle = np.arccos(np.clip(np.sum(runs[0] * truth, axis=1), -1.0, 1.0))
    # a rotation with σ per axis moves a unit vector by σ·√2 rms (two axes across it)
    assert math.sqrt(np.mean(angle ** 2)) == pytest.approx(sigma * math.sqrt(2), rel=0.15)


@pytest.mark.parametrize('overrides,match', [
    ({'orbit.model': 'none'}, 'sun_sensor.enabled: needs an orbit'),
    ({'epoch': ''}, 'sun_sensor.enabled: needs an epoch'),
])
def test_a_sun_sensor_without_orbit_or_epoch_is_refused_by_name(overrides, match):
    with pytest.raises(ValueError, match=match):
        EngineConfig.from_parameters(params(**overrides))


def test_with_sgp4_the_tles_epoch_is_the_suns_epoch():
    """orbit.model sgp4 with no epoch: sim time 0 is the TLE's epoch (2019 day 343.69339541),
    and the sun sensor reads the Sun of that instant."""
    from datetime import datetime, timedelta, timezone
    from test_orbit import ISS
    p = params(**{'orbit.model': 'sgp4', 'orbit.tle': ISS, 'epoch': '', 'duration': 60.0})
    config = EngineConfig.from_parameters(p)
    expected = datetime(2019, 1, 1, tzinfo=timezone.utc) + timedelta(days=342.69339541)
    assert abs((config.environment.epoch - expected).total_seconds()) < 1e-3
    engine, block, t, u = run(p)
    r, _ = config.environment.orbit.state(0.0)
    lit = sl.shadow(r, sl.sun_vector(expected, 0.0), 'cylindrical')
    assert (len(t) == 61) == (lit == 1.0) and (len(t) > 0) == (lit == 1.0)
    if len(t):
        to_sun = sl.sun_vector(expected, 0.0) - r
        np.testing.assert_allclose(u[0], rotation.rotate(rotation.conjugate(block.q[0]),
                                                         to_sun / np.linalg.norm(to_sun)),
                                   atol=1e-9)

