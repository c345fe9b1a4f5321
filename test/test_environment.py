"""The orbit environment's models against closed forms, published values and the field
model's own package (physics/environment: Earth rotation, magnetic field, Sun, shadow)."""
import math

import numpy as np
import pytest

from rigid_body_sim.physics.environment import earth, magnetic_field as mf, sunlight as sl

pytestmark = pytest.mark.fast
RNG = np.random.default_rng(20261126)


def test_gmst_matches_vallados_example():
    # Vallado, Fundamentals of Astrodynamics, example 3-5: 1992-08-20 12:14 UT1
    assert math.degrees(earth.gmst('1992-08-20T12:14:00Z')) == pytest.approx(152.578787886,
                                                                            abs=1e-6)
    # one sidereal day later the angle is back (to the IAU-1982 series' T² terms)
    day = 2 * math.pi / earth.EARTH_ROTATION_RATE
    assert float(earth.gmst('2026-01-01T00:00:00Z', day)) == pytest.approx(
        float(earth.gmst('2026-01-01T00:00:00Z')), abs=1e-8)


def test_frames_round_trip_and_turn_about_the_spin_axis():
    v = RNG.normal(size=(5, 3))
    angle = 1.234
    ecef = earth.eci_to_ecef(v, angle)
    assert np.allclose(earth.ecef_to_eci(ecef, angle), v, rtol=0, atol=1e-15)
    assert np.allclose(ecef[:, 2], v[:, 2]) and np.allclose(np.linalg.norm(ecef, axis=1),
                                                            np.linalg.norm(v, axis=1))
    # the Greenwich meridian (ECEF x) points at RA = GMST in the inertial frame
    x = earth.ecef_to_eci(np.array([1.0, 0.0, 0.0]), angle)
    assert math.atan2(x[1], x[0]) == pytest.approx(angle)


@pytest.mark.parametrize('when,declination', [
    ('2026-03-20T14:46:00Z', 0.0),          # March equinox
    ('2026-06-21T08:24:00Z', 23.4362),      # June solstice: the obliquity of date
    ('2026-12-21T20:50:00Z', -23.4362),     # December solstice
])
def test_sun_declination_at_equinox_and_solstices(when, declination):
    s = sl.sun_direction(when)
    assert np.linalg.norm(s) == pytest.approx(1.0, abs=1e-15)
    assert math.degrees(math.asin(s[2])) == pytest.approx(declination, abs=0.01)


def test_sun_distance_at_perihelion_and_aphelion():
    assert np.linalg.norm(sl.sun_vector('2026-01-03T17:00:00Z')) / sl.AU == pytest.approx(
        0.98330, abs=2e-5)
    assert np.linalg.norm(sl.sun_vector('2026-07-06T17:00:00Z')) / sl.AU == pytest.approx(
        1.01670, abs=2e-5)


def test_dipole_field_is_minus_the_gradient_of_its_potential():
    m = mf.dipole_moment('2026-01-01T00:00:00Z')
    assert np.linalg.norm(m) == pytest.approx(7.7e22, rel=0.02)
    for r in RNG.normal(size=(4, 3)) * 7e6:
        def potential(x):  # B = −∇V, V = μ0/(4π)·(m·x)/|x|³
            return mf.MU0_OVER_4PI * (m @ x) / np.linalg.norm(x) ** 3
        h = 1.0  # m
        grad = np.array([(potential(r + h * e) - potential(r - h * e)) / (2 * h)
                         for e in np.eye(3)])
        assert np.allclose(mf.dipole_field(r, m), -grad, rtol=1e-7, atol=0)
    # on the dipole's equator μ0 m/(4π r³); on its axis twice that
    axis = m / np.linalg.norm(m)
    r = 7e6
    equator = np.cross(axis, [1.0, 0.0, 0.0])
    equator /= np.linalg.norm(equator)
    b0 = mf.MU0_OVER_4PI * np.linalg.norm(m) / r ** 3
    assert np.linalg.norm(mf.dipole_field(r * equator, m)) == pytest.approx(b0, rel=1e-12)
    assert np.linalg.norm(mf.dipole_field(r * axis, m)) == pytest.approx(2 * b0, rel=1e-12)


def test_igrf_to_degree_one_is_our_dipole_at_any_point_and_epoch():
    """ppigrf's synthesis cut at degree 1 (geocentric r, θ, φ components) equals the
    closed-form dipole of our moment: the moment, the component frames and the
    interpolation in time all agree."""
    for epoch in ('1965-07-01T00:00:00Z', '2026-11-26T06:00:00Z', '2029-06-30T12:00:00Z'):
        m = mf.dipole_moment(epoch)
        points = RNG.normal(size=(6, 3))
        points *= (mf.IGRF_RADIUS + RNG.uniform(2e5, 3e7, size=6))[:, None] \
            / np.linalg.norm(points, axis=1)[:, None]
        ours = mf.dipole_field(points, m)
        theirs = mf.igrf_field_ecef(points, epoch, max_degree=1)
        assert np.allclose(theirs, ours, rtol=1e-10, atol=0), epoch


def test_full_igrf_is_earths_field_near_the_surface_and_the_dipole_far_away():
    epoch = '2026-11-26T00:00:00Z'
    lat, lon = np.meshgrid(np.radians(np.arange(-80, 81, 20)), np.radians(np.arange(0, 360, 30)))
    surface = mf.IGRF_RADIUS * np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon),
                                         np.sin(lat)], axis=-1).reshape(-1, 3)
    b = np.linalg.norm(mf.igrf_field_ecef(surface, epoch), axis=1)
    assert 20e-6 < b.min() and b.max() < 68e-6  # the field's known range at the surface
    # degree n falls off as (a/r)^(n+2): the rest shrinks against the dipole as a/r
    scale = mf.MU0_OVER_4PI * 7.7e22
    for factor, bound in ((10, 0.06), (40, 0.015)):
        far = surface * factor
        gap = np.linalg.norm(mf.igrf_field_ecef(far, epoch)
                             - mf.dipole_field(far, mf.dipole_moment(epoch)), axis=1)
        assert np.max(gap) < bound * scale / (factor * mf.IGRF_RADIUS) ** 3, factor


def test_field_in_the_inertial_frame_turns_with_the_earth():
    epoch = '2026-11-26T00:00:00Z'
    r = np.array([7e6, 1e6, 2e6])
    for model in mf.MODELS:
        b = mf.field(model, r, epoch, t=3600.0)
        angle = earth.gmst(epoch, 3600.0)
        ecef = earth.eci_to_ecef(r, angle)
        direct = mf.dipole_field(ecef, mf.dipole_moment('2026-11-26T01:00:00Z')) \
            if model == 'dipole' else mf.igrf_field_ecef(ecef, '2026-11-26T01:00:00Z')
        assert np.allclose(earth.eci_to_ecef(b, angle), direct, rtol=1e-12, atol=0)


@pytest.mark.parametrize('epoch,why', [('1899-12-31T00:00:00Z', 'outside the IGRF-14'),
                                        ('2031-01-01T00:00:00Z', 'outside the IGRF-14'),
                                        ('26 Nov 2026', 'not an ISO 8601')])
def test_epochs_the_model_does_not_cover_are_refused_by_name(epoch, why):
    with pytest.raises(ValueError, match=f'epoch.*{why}'):
        mf.field('igrf', np.array([7e6, 0.0, 0.0]), epoch)
    with pytest.raises(ValueError, match='magnetic_field'):
        mf.field('wmm', np.array([7e6, 0.0, 0.0]), '2026-01-01T00:00:00Z')


def test_eclipse_entry_and_exit_on_a_circular_orbit_match_the_geometry():
    """A circular orbit of radius R in the plane holding the Sun's direction: the
    cylindrical shadow spans 2·asin(R_E/R)/n centred on the anti-Sun point; the conical
    umbra lies inside it and the penumbra around it, symmetric about the same centre."""
    R = 7.0e6
    n = math.sqrt(3.986004418e14 / R ** 3)
    sun = np.array([sl.AU, 0.0, 0.0])

    def position(t):
        u = n * np.asarray(t)
        return R * np.stack([np.cos(u), np.sin(u), np.zeros_like(u)], axis=-1)

    def crossing(model, level, lo, hi):  # the time (s) fraction passes ``level``, by bisection
        f_lo = sl.shadow(position(lo), sun, model) - level
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            if (sl.shadow(position(mid), sun, model) - level) * f_lo > 0:
                lo = mid
            else:
                hi = mid
        return 0.5 * (lo + hi)
    half = math.asin(sl.EARTH_RADIUS / R) / n
    centre = math.pi / n
    entry = crossing('cylindrical', 0.5, centre - 2 * half, centre)
    exit_ = crossing('cylindrical', 0.5, centre, centre + 2 * half)
    assert entry == pytest.approx(centre - half, abs=1e-6)
    assert exit_ == pytest.approx(centre + half, abs=1e-6)
    # conical: penumbra from f < 1, umbra at f = 0; within seconds of the cylinder in LEO
    pen_in = crossing('conical', 1.0 - 1e-12, centre - 2 * half, centre)
    umb_in = crossing('conical', 1e-12, centre - 2 * half, centre)
    umb_out = crossing('conical', 1e-12, centre, centre + 2 * half)
    pen_out = crossing('conical', 1.0 - 1e-12, centre, centre + 2 * half)
    assert pen_in < entry < umb_in < centre < umb_out < exit_ < pen_out
    assert 0.5 * (umb_in + umb_out) == pytest.approx(centre, abs=1e-6)
    assert 0.5 * (pen_in + pen_out) == pytest.approx(centre, abs=1e-6)
    assert 1.0 < umb_in - pen_in < 30.0  # the penumbra lasts seconds in LEO
    assert sl.shadow(position(0.0), sun, 'conical') == 1.0
    assert sl.shadow(position(centre), sun, 'conical') == 0.0
