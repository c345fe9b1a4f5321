"""auto's test of the gravity gradient's LVLH equilibrium a body starts near
(physics.auto.libration): its stability against the linearised roll–yaw equations, and
auto promising nothing about an unstable one (it erred 700× its budget there)."""
import math

import numpy as np
import pytest

from rigid_body_sim.offline import simulate
from rigid_body_sim.physics import rotation
from rigid_body_sim.physics.auto import libration
from rigid_body_sim.physics.orbit import KeplerOrbit, frames
from rigid_body_sim.scene import load

SHORT = ('duration=2000.0',)


def _roots_stable(ix, iy, iz):
    """Roll–yaw stable iff s⁴ + (1 + 3k_R + k_R k_Y)s² + 4k_R k_Y = 0 (s in units of n)
    has only imaginary roots (ω = −i s real): checked by numpy's roots, not the closed
    form."""
    k_r, k_y = (iy - iz) / ix, (iy - ix) / iz
    roots = np.roots([1.0, 0.0, 1.0 + 3.0 * k_r + k_r * k_y, 0.0, 4.0 * k_r * k_y])
    return bool(np.all(np.abs(roots.real) < 1e-6))


def test_stability_matches_the_linearised_equations():
    rng = np.random.default_rng(3)
    seen = set()
    for _ in range(2000):
        while True:
            m = rng.uniform(0.2, 3.0, 3)
            if 2.0 * m.max() <= m.sum():
                break
        pitch, roll_yaw = libration.stability(*m)
        assert pitch == (m[0] > m[2])
        if min(abs(m[1] - m[0]), abs(m[1] - m[2])) > 1e-3:  # off the marginal cases
            assert roll_yaw == _roots_stable(*m), m
        seen.add((pitch, roll_yaw))
    assert seen == {(True, True), (True, False), (False, True), (False, False)}
    assert libration.stability(3.0, 4.0, 2.0) == (True, True)   # Lagrange region
    assert libration.stability(2.0, 2.0, 2.0) == (False, False)  # marginal: unknown


def _near(moments, q_lvlh, w_rel):
    orbit = KeplerOrbit(7.0e6, 0.0, 0.9, 0.0, 0.0, 0.0)
    r, v = orbit.state(0.0)
    q = rotation.multiply(frames.lvlh_attitude(r, v), q_lvlh)
    w = np.asarray(w_rel) + rotation.rotate(rotation.conjugate(q), frames.lvlh_rate(r, v))
    return libration.nearest(np.asarray(moments, float), q, w, r, v)


def test_the_nearest_equilibrium_assigns_the_moments_to_lvlh_axes():
    n = math.sqrt(3.986004418e14 / 7.0e6 ** 3)
    q = rotation.exp([0.02, 0.05, 0.0])
    near = _near((3.0, 4.0, 2.0), q, (0.0, 0.0, 0.0))
    assert near.moments == (3.0, 4.0, 2.0) and near.stable
    assert near.angle == pytest.approx(math.hypot(0.02, 0.05), rel=1e-6)
    # a quarter turn about z (nadir) swaps the axes along x and y: I_x = 4, I_y = 3
    turned = rotation.multiply(rotation.exp([0.0, 0.0, math.pi / 2]), q)
    swapped = _near((3.0, 4.0, 2.0), turned, (0.0, 0.0, 0.0))
    assert swapped.moments == (4.0, 3.0, 2.0) and swapped.angle < 0.06
    assert not swapped.roll_yaw_stable  # k_R k_Y < 0 there
    assert _near((3.0, 4.0, 2.0), rotation.exp([0.0, 0.7, 0.0]), (0, 0, 0)) is None
    assert _near((3.0, 4.0, 2.0), q, (0.0, 0.0, n)) is None  # a tumble, no libration


def test_auto_keeps_its_promise_about_a_stable_equilibrium():
    """config/gravity_gradient: the Lagrange region; auto's a-priori choice stands."""
    r = simulate(load('gravity_gradient', SHORT), keep='none')
    assert 'leaves it exponentially' not in r.reason and math.isfinite(
        r.selection.predicted_error), r.reason


def test_auto_promises_nothing_about_an_unstable_equilibrium():
    """The same scene with I_x < I_z (pitch unstable): no promise, the most accurate."""
    r = simulate(load('gravity_gradient', SHORT + ('inertia=[2.0, 4.0, 3.0]',)),
                 keep='none')
    assert 'unstable in pitch' in r.reason and 'leaves it exponentially' in r.reason
    assert math.isinf(r.selection.predicted_error)
    assert r.integrator == 'dop853' and 'rtol 1e-13' in r.reason
