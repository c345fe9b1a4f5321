"""Basilisk's magnetorquer harness (bench/basilisk_mtb.py; basilisk_mtb_sweep.py compares it
with ours): its field and torque are the closed forms ours has, to 1e-12 relative."""
import math

import numpy as np
import pytest

from rigid_body_sim.bench import basilisk_gg as bg, basilisk_mtb as bm
from rigid_body_sim.physics import rotation

MU0_OVER_4PI = 1e-7
# IGRF-14's degree 1 at 2025.0 (nT), as the harness takes them (T)
G10, G11, H11 = -29350.0e-9, -1410.3e-9, 4545.5e-9


@pytest.fixture(scope='module')
def mtb():
    base = bg.Setup.of(bg.SCENES[1].scene_file())
    return bm.MtbSetup(base, (G10, G11, H11), (0.3, -0.2, 0.5), theta0=1.1)


def dipole_field(r, m):
    """μ0/(4π r³)[3(m·r̂)r̂ − m]: the notes' centred dipole, one frame for r, m and B."""
    rn = np.linalg.norm(r)
    u = r / rn
    return MU0_OVER_4PI / rn ** 3 * (3.0 * (m @ u) * u - m)


def test_field_and_torque_are_the_dipole_and_m_cross_b(mtb):
    moment_ecef = bm.IGRF_RADIUS ** 3 / MU0_OVER_4PI * np.array([G11, H11, G10])
    q = np.array([0.3, -0.5, 0.2, 0.787])
    q /= np.linalg.norm(q)
    for t in (0.0, 1000.0, 15_000.0):
        r, _ = mtb.base.orbit.state(t)
        turn = mtb.earth_to_inertial(t)
        expected = turn @ dipole_field(turn.T @ r, moment_ecef)
        b, torque = bm.field_and_torque(mtb, q, r, t)
        assert 1e-6 < np.linalg.norm(expected) < 1e-4  # tens of µT in low orbit
        assert np.linalg.norm(b - expected) <= 1e-12 * np.linalg.norm(expected), t
        b_body = rotation.rotate(rotation.conjugate(q), b)
        tau = np.cross(mtb.dipole, b_body)
        assert np.linalg.norm(torque - tau) <= 1e-12 * np.linalg.norm(tau), t


def test_the_field_turns_with_the_earth(mtb):
    """A quarter turn of the Earth later the same inertial point sees a different field:
    the planet-state message is read (a fixed dipole would give the same)."""
    r, _ = mtb.base.orbit.state(0.0)
    quarter = 0.5 * math.pi / mtb.earth_rate
    b0, _ = bm.field_and_torque(mtb, mtb.base.attitude, r, 0.0)
    b1, _ = bm.field_and_torque(mtb, mtb.base.attitude, r, quarter)
    assert np.linalg.norm(b1 - b0) > 0.05 * np.linalg.norm(b0)


def test_rods_saturate_each_at_its_limit(mtb):
    from dataclasses import replace
    r, _ = mtb.base.orbit.state(0.0)
    capped = replace(mtb, max_dipole=0.25)
    b, torque = bm.field_and_torque(capped, mtb.base.attitude, r, 0.0)
    b_body = rotation.rotate(rotation.conjugate(mtb.base.attitude), b)
    held = np.clip(mtb.dipole, -0.25, 0.25)
    assert np.allclose(torque, np.cross(held, b_body), rtol=1e-12, atol=0.0)


def test_a_run_holds_the_command_and_samples_at_the_scene_rate(mtb):
    """A short run: samples at the scene's rate; the held dipole turns the body away from
    the run without rods (same start, same orbit)."""
    from dataclasses import replace
    short = replace(mtb, base=bg.Setup(**{**mtb.base.__dict__, 'duration': 200.0}),
                    field_period=1.0)
    _, t, q, _ = bm.run(short, 'rk4', 1.0)
    assert np.array_equal(t, np.arange(0.0, 201.0, short.base.sample_period))
    _, _, q_off, _ = bm.run(replace(short, dipole=(0.0, 0.0, 0.0)), 'rk4', 1.0)
    apart = rotation.angle_between(q, q_off)
    assert apart[0] < 1e-15 and apart[-1] > 1e-6
