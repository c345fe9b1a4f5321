"""The orbit as a function of time: the attitude does not change it (the torques that act
on the attitude are far too small to move the centre of mass), so it is evaluated at the
instants a method needs, never integrated with the attitude.

* :class:`KeplerOrbit`: two-body, Kepler's equation solved by Newton's method at each
  instant; the position after whole periods returns to round-off.
* :class:`J2Orbit`: the same conic with J2's secular drift of the node, the argument of
  periapsis and the mean anomaly (Vallado, *Fundamentals of Astrodynamics*, §9).
* :class:`Sgp4Orbit` (``sgp4_orbit``): SGP4 from a two-line element set.

Frames: the inertial frame is the one the attitude is given in (``world``); positions in
m, velocities in m/s, times in s of sim time (t = 0 at the scene's start).
"""
import math

import numpy as np

from . import constants, kernel


class OrbitError(RuntimeError):
    """The orbit cannot be evaluated at an instant (SGP4's error codes: decay, eccentricity
    out of range, …); names the time and the reason."""

    def __init__(self, t: float, reason: str):
        self.t, self.reason = t, reason
        super().__init__(f'orbit failed at t = {t:.9g} s: {reason}')


class Orbit:
    """Base: ``state(t)`` → (r, v); ``environment(t)`` the kernels' element array near t.

    ``anchored``: the kernels' array is exact only near the instant it was built for
    (SGP4's osculating conic): the engine rebuilds it at each interval between events.
    """
    name = ''
    anchored = False

    def state(self, t: float):
        raise NotImplementedError

    def elements(self, t: float = 0.0) -> np.ndarray:
        """The element array (``kernel`` layout, ON = 0) whose conic matches the orbit at t."""
        raise NotImplementedError

    @property
    def mean_motion(self) -> float:
        """n (rad/s): the rate at which the radial direction turns on average."""
        raise NotImplementedError

    def period(self) -> float:
        return 2.0 * math.pi / self.mean_motion


def eccentric_from_true(nu: float, e: float) -> float:
    """E from the true anomaly ν (same revolution)."""
    return 2.0 * math.atan2(math.sqrt(1.0 - e) * math.sin(0.5 * nu),
                            math.sqrt(1.0 + e) * math.cos(0.5 * nu))


class KeplerOrbit(Orbit):
    """Two-body motion from classical elements at t = 0 (a in m, angles in rad, 0 ≤ e < 1)."""
    name = 'kepler'

    def __init__(self, semi_major_axis, eccentricity, inclination, raan,
                 argument_of_periapsis, true_anomaly, mu=constants.MU):
        a, e = float(semi_major_axis), float(eccentricity)
        if not (a > 0.0 and math.isfinite(a)):
            raise ValueError(f'semi-major axis must be finite and > 0 m, got {a}')
        if not 0.0 <= e < 1.0:
            raise ValueError(f'eccentricity must be in [0, 1) (a closed orbit), got {e}')
        self.a, self.e, self.mu = a, e, float(mu)
        self.inclination, self.raan = float(inclination), float(raan)
        self.argp, self.nu0 = float(argument_of_periapsis), float(true_anomaly)
        big_e = eccentric_from_true(self.nu0, e)
        self.m0 = big_e - e * math.sin(big_e)
        self._env = self._elements()
        self._out = np.zeros(6)

    @property
    def mean_motion(self) -> float:
        return math.sqrt(self.mu / self.a ** 3)

    def rates(self):
        """(dΩ/dt, dω/dt, dM/dt), rad/s."""
        return 0.0, 0.0, self.mean_motion

    def _elements(self) -> np.ndarray:
        env = kernel.off()
        raan_rate, argp_rate, m_rate = self.rates()
        env[kernel.MU], env[kernel.A], env[kernel.E], env[kernel.INC] = \
            self.mu, self.a, self.e, self.inclination
        env[kernel.RAAN], env[kernel.ARGP], env[kernel.M0], env[kernel.T0] = \
            self.raan, self.argp, self.m0, 0.0
        env[kernel.RAAN_RATE], env[kernel.ARGP_RATE], env[kernel.M_RATE] = \
            raan_rate, argp_rate, m_rate
        return env

    def elements(self, t: float = 0.0) -> np.ndarray:
        return self._env.copy()

    def state(self, t: float):
        kernel.state_at(self._env, float(t), self._out)
        return self._out[:3].copy(), self._out[3:].copy()

    @property
    def perigee_radius(self) -> float:
        return self.a * (1.0 - self.e)

    @property
    def eccentricity(self) -> float:
        return self.e


class J2Orbit(KeplerOrbit):
    """Mean elements drifting at J2's secular rates, p = a(1 − e²):
    dΩ/dt = −(3/2) n J2 (R/p)² cos i, dω/dt = (3/4) n J2 (R/p)² (5 cos² i − 1),
    dM/dt = n [1 + (3/4) J2 (R/p)² √(1 − e²)(3 cos² i − 1)]."""
    name = 'j2'

    def __init__(self, *args, j2=constants.J2, radius=constants.RADIUS, **kwargs):
        self.j2, self.radius = float(j2), float(radius)
        super().__init__(*args, **kwargs)

    def rates(self):
        n = math.sqrt(self.mu / self.a ** 3)
        p = self.a * (1.0 - self.e * self.e)
        k = self.j2 * (self.radius / p) ** 2
        c = math.cos(self.inclination)
        return (-1.5 * n * k * c, 0.75 * n * k * (5.0 * c * c - 1.0),
                n * (1.0 + 0.75 * k * math.sqrt(1.0 - self.e * self.e) * (3.0 * c * c - 1.0)))

    @property
    def mean_motion(self) -> float:
        return self.rates()[2] + self.rates()[1]  # the argument of latitude's mean rate


def osculating_elements(r, v, mu: float, t: float) -> np.ndarray:
    """The element array (ON = 0) of the two-body conic through (r, v) at time t (Vallado
    algorithm 9, singularities handled by the vector forms: the argument of periapsis and
    the anomaly enter only as their sum where e or i vanish)."""
    r, v = np.asarray(r, float), np.asarray(v, float)
    rn = float(np.linalg.norm(r))
    h = np.cross(r, v)
    hn = float(np.linalg.norm(h))
    ecc_vec = np.cross(v, h) / mu - r / rn
    e = float(np.linalg.norm(ecc_vec))
    a = 1.0 / (2.0 / rn - float(v @ v) / mu)
    if not (a > 0.0 and e < 1.0):
        raise ValueError(f'the state is not on a closed orbit (a = {a:g} m, e = {e:g})')
    inc = math.acos(max(-1.0, min(1.0, h[2] / hn)))
    node = np.array([-h[1], h[0], 0.0])
    nn = float(np.linalg.norm(node))
    raan = math.atan2(node[1], node[0]) if nn > 1e-12 * hn else 0.0
    n_hat = node / nn if nn > 1e-12 * hn else np.array([1.0, 0.0, 0.0])
    m_hat = np.cross(h / hn, n_hat)  # in the plane, 90° ahead of the node
    u = math.atan2(float(r @ m_hat), float(r @ n_hat))  # argument of latitude
    if e > 1e-12:
        argp = math.atan2(float(ecc_vec @ m_hat), float(ecc_vec @ n_hat))
    else:
        argp = 0.0
    nu = u - argp
    big_e = eccentric_from_true(nu, e)
    env = kernel.off()
    env[kernel.MU], env[kernel.A], env[kernel.E], env[kernel.INC] = mu, a, e, inc
    env[kernel.RAAN], env[kernel.ARGP] = raan, argp
    env[kernel.M0], env[kernel.T0] = big_e - e * math.sin(big_e), t
    env[kernel.M_RATE] = math.sqrt(mu / a ** 3)
    return env
