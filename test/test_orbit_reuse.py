"""The loops evaluate the orbit once per instant (physics/orbit/kernel.py ``frame``,
``radial_framed``, ``gravity_gradient_at``; rk4's stages 2 and 3 share t + h/2, a
splitting's stage-end torque is the next stage's start torque): the same numbers, bit for
bit, as evaluating the whole torque at every kick and stage, which the references below
do step by step from Python through the compiled pieces. Kepler's iteration stops when
Newton's error bound says the next step would be below round-off: checked against a
60-digit solution."""
import math

import mpmath
import numpy as np
import pytest

from rigid_body_sim.physics import dynamics_kernel
from rigid_body_sim.physics.integrators import explicit_kernel, splitting_kernel
from rigid_body_sim.physics.orbit import orbit
from rigid_body_sim.physics.orbit import kernel as orbit_kernel

MOMENTS = np.array([10.0, 12.0, 8.0])
Q0 = np.array([0.1, -0.3, 0.2, 0.9]) / np.linalg.norm([0.1, -0.3, 0.2, 0.9])
M0 = MOMENTS * np.array([0.002, -0.001, 0.003])
ORBITS = {'kepler': orbit.KeplerOrbit(9.0e6, 0.25, 0.6, 0.3, 0.5, 2.0),
          'j2': orbit.J2Orbit(7.078e6, 0.01, math.radians(98.19), 0.3, 0.5, 0.0)}


def _env(name):
    env = ORBITS[name].elements(0.0)
    env[orbit_kernel.ON] = 1.0
    return env


@pytest.mark.parametrize('name', sorted(ORBITS))
def test_framed_orbit_and_torque_are_the_plain_ones(name):
    env = _env(name)
    fr = orbit_kernel.frame(env, 3.0)
    assert (fr[6] == 1.0) == (name == 'kepler')          # J2's node and periapsis move
    for t in np.linspace(0.0, 2.0e4, 37):
        rad = orbit_kernel.radial_framed(env, t, fr)
        assert rad == orbit_kernel.radial(env, t)
        assert orbit_kernel.gravity_gradient_at(Q0, *rad, env, MOMENTS) == \
            orbit_kernel.gravity_gradient_torque(Q0, t, env, MOMENTS)


def _kick(q, m, t, env, s):
    g = orbit_kernel.gravity_gradient_torque(q, t, env, MOMENTS)
    for i in range(3):
        m[i] = m[i] + s * g[i]


def _splitting_reference(q, m, h, n, weights, axes, t0, env):
    """splitting_run's composition with the torque evaluated afresh at every kick."""
    for k in range(n):
        t = t0 + k * h
        for w in weights:
            hw = w * h
            _kick(q, m, t, env, 0.5 * hw)
            for axis, f in zip((axes[0], axes[1], axes[2], axes[1], axes[0]),
                               (0.5, 0.5, 1.0, 0.5, 0.5)):
                dynamics_kernel._axis_flow(q, m, axis, f * hw, MOMENTS)
            t += hw
            _kick(q, m, t, env, 0.5 * hw)


@pytest.mark.parametrize('name', sorted(ORBITS))
def test_splitting_reuses_the_stage_end_torque_bit_for_bit(name):
    env = _env(name)
    y4 = 1.0 / (2.0 - 2.0 ** (1.0 / 3.0))
    weights, axes = np.array([y4, 1.0 - 2.0 * y4, y4]), np.array([0, 2, 1])
    q, m = Q0.copy(), M0.copy()
    failed, _ = splitting_kernel.splitting_run(q, m, 10.0, 30, weights, axes, MOMENTS,
                                               np.zeros(3), False, 0, 0.0, False, 5.0, env)
    qr, mr = Q0.copy(), M0.copy()
    _splitting_reference(qr, mr, 10.0, 30, weights, axes, 5.0, env)
    assert failed == -1
    assert np.array_equal(q, qr) and np.array_equal(m, mr)


def _rk4_reference(q, m, h, n, t0, env):
    """rk4_steps with the environment evaluated at each stage's own instant."""
    zero = np.zeros(3)
    kq, km = np.zeros((4, 4)), np.zeros((4, 3))
    qs, ms = np.empty(4), np.empty(3)
    for k in range(n):
        t = t0 + k * h
        dynamics_kernel._rates(q, m, MOMENTS, zero, 0, 0.0, kq[0], km[0])
        dynamics_kernel._environment(q, t, env, MOMENTS, km[0])
        for s, (f, ts) in enumerate(((0.5 * h, t + 0.5 * h), (0.5 * h, t + 0.5 * h),
                                     (h, t + h)), start=1):
            for i in range(4):
                qs[i] = q[i] + f * kq[s - 1, i]
            for i in range(3):
                ms[i] = m[i] + f * km[s - 1, i]
            dynamics_kernel._rates(qs, ms, MOMENTS, zero, 0, 0.0, kq[s], km[s])
            dynamics_kernel._environment(qs, ts, env, MOMENTS, km[s])
        for i in range(4):
            q[i] += (h / 6.0) * (kq[0, i] + 2.0 * kq[1, i] + 2.0 * kq[2, i] + kq[3, i])
        for i in range(3):
            m[i] += (h / 6.0) * (km[0, i] + 2.0 * km[1, i] + 2.0 * km[2, i] + km[3, i])
        dynamics_kernel._normalise(q)


@pytest.mark.parametrize('name', sorted(ORBITS))
def test_rk4_shares_the_half_step_orbit_bit_for_bit(name):
    env = _env(name)
    q, m = Q0.copy(), M0.copy()
    assert explicit_kernel.rk4_steps(q, m, 10.0, 30, MOMENTS, np.zeros(3), 0, 0.0,
                                     np.zeros((10, 4)), 5.0, env) == -1
    qr, mr = Q0.copy(), M0.copy()
    _rk4_reference(qr, mr, 10.0, 30, 5.0, env)
    assert np.array_equal(q, qr) and np.array_equal(m, mr)


def test_kepler_stops_within_an_ulp_of_the_60_digit_solution():
    """Newton's early stop (its error bound below KEPLER_TOL/2) leaves E within 2 ulp of
    the true root, eccentricities up to 0.99."""
    mpmath.mp.dps = 60
    for e in (0.0, 0.01, 0.25, 0.5, 0.9, 0.99):
        for m in np.linspace(-3.1, 3.1, 41):
            big_e = orbit_kernel.eccentric_anomaly(m, e)
            ref = mpmath.findroot(lambda x: x - e * mpmath.sin(x) - m, mpmath.mpf(big_e))
            assert abs(big_e - float(ref)) <= 2 * math.ulp(max(abs(float(ref)), 1.0)), (e, m)
