"""B-dot magnetic detumbling: the controller's ``bdot`` mode (no ROS).

The law commands the magnetorquers' dipole m = −k·Ḃ/|B|² (body frame, A·m²), with Ḃ the
finite difference of consecutive magnetometer readings (body frame, T). For a tumbling
body Ḃ ≈ B × ω, so m ≈ −(k/|B|)·b̂ × ω: the law of Avanzini & Giulietti, "Magnetic
detumbling of a rigid spacecraft", JGCD 35(4), 2012, whose gain rule is

    k* = 2 n (1 + sin ξ_m) I_min

(n the orbit's mean motion, ξ_m the inclination of the orbit to the geomagnetic equator,
I_min the smallest principal moment); the 1/|B|² makes k a gain in kg·m²/s, as theirs.
The torque m × B = −(k/|B|²)·(B × ω) × B is −k(ω − (b̂·ω)b̂): it damps the rate across the
field, and since the field turns along the orbit, every axis in turn. Each rod is clipped
to its largest dipole (``saturated`` counts the clipped commands).

Sampling: Ḃ from readings Δt apart aliases when |ω|Δt nears π (proves-core-reference
PR #79); the residual rate is about 2n about the orbit normal (the field turns at 2n in a
polar orbit), so "detumbled" means |ω| of that order.
"""
import math
from typing import Optional

import numpy as np


def avanzini_giulietti_gain(orbit_rate: float, magnetic_inclination: float,
                            i_min: float) -> float:
    """k* = 2n(1 + sin ξ_m)·I_min (kg·m²/s)."""
    return 2.0 * orbit_rate * (1.0 + math.sin(magnetic_inclination)) * i_min


def gain_from_parameters(p, i_min: float) -> float:
    """The controller's B-dot gain: ``bdot.gain`` if set, else k* from ``bdot.orbit_rate``
    and ``bdot.magnetic_inclination``. ValueError naming the key if neither is given."""
    if p['bdot.gain'] > 0.0:
        return float(p['bdot.gain'])
    if p['bdot.orbit_rate'] > 0.0:
        return avanzini_giulietti_gain(p['bdot.orbit_rate'], p['bdot.magnetic_inclination'],
                                       i_min)
    raise ValueError('bdot.gain: mode bdot needs a gain, or bdot.orbit_rate (and '
                     'bdot.magnetic_inclination) for the Avanzini-Giulietti gain')


def averaged_decay_rate(gain: float, moments) -> float:
    """The rate (1/s) at which B-dot slows the slowest principal rate, by the averaged
    closed loop (Avanzini & Giulietti 2012, §III): with Ḃ ≈ B × ω the torque is
    −k(ω − (b̂·ω)b̂), and over a tumble the field's direction in body axes averages to
    ⟨b̂b̂ᵀ⟩ = 1/3, so each principal rate decays as e^{−(2/3)(k/I_i)t}; the major axis's is
    the slowest: (2/3)k/I_max. Saturation of the rods only slows the start."""
    return 2.0 / 3.0 * float(gain) / float(np.max(moments))


def predicted_time(rate_start: float, rate_end: float, gain: float, moments) -> float:
    """Seconds from |ω| = rate_start to rate_end (rad/s) at :func:`averaged_decay_rate`."""
    return math.log(rate_start / rate_end) / averaged_decay_rate(gain, moments)


class Bdot:
    """m = −k·Ḃ/|B|² from consecutive readings, clipped per rod to ``max_dipole``."""

    def __init__(self, gain: float, max_dipole):
        if not (math.isfinite(gain) and gain > 0.0):
            raise ValueError(f'bdot.gain must be finite and > 0 kg*m^2/s, got {gain}')
        self.gain = float(gain)
        self.max_dipole = np.asarray(max_dipole, float)
        self.saturated = 0
        self.reset()

    def reset(self):
        self._last = None

    def update(self, t: float, field) -> Optional[np.ndarray]:
        """The dipole (body frame, A·m²) from the reading ``field`` (T, body frame) at time
        t (s); None for the first reading (no difference yet) or a repeated instant."""
        b = np.asarray(field, float).reshape(3)
        last, self._last = self._last, (float(t), b)
        if last is None or not t > last[0]:
            return None
        rate = (b - last[1]) / (t - last[0])
        m = -self.gain * rate / float(b @ b)
        if np.any(np.abs(m) > self.max_dipole):
            np.clip(m, -self.max_dipole, self.max_dipole, out=m)
            self.saturated += 1
        return m
