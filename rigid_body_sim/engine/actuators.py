"""Momentum-exchange actuators: reaction wheels and single-gimbal CMGs (no ROS).

:class:`ActuatorConfig` is built from the ``actuators.*`` parameters (validated, with
notes such as a normalised axis); :class:`Actuators` holds their state and commands and
advances body + actuators by the compiled gyrostat kernel
(``physics.integrators.gyrostat_kernel``) for the registered method that carries them
(``physics.integrators.gyrostat.GyrostatStrang``). Frames: axes and torques in the body
frame at this interface; the kernel works in the principal frame.

Body torque → actuators (``actuators.command`` = torque): CMGs if the scene has any
(singularity-robust inverse at the current gimbal angles), else wheels (pseudo-inverse of
the axis matrix). Forward commands (= forward): wheel motor torques (N·m) then gimbal
rates (rad/s), held until the next valid one.
"""
from dataclasses import dataclass
import math
from typing import Optional, Tuple

import numpy as np

from ..physics.integrators import gyrostat_kernel as gk
from .actuator_specs import PYRAMID_SKEW

SPAN_TOL = 1e-6  # smallest singular value of the gimbal-axis matrix that counts as spanning


def pyramid(skew: float = PYRAMID_SKEW) -> Tuple[np.ndarray, np.ndarray]:
    """(gimbal axes, spin axes at δ = 0), body frame, of the classic four-CMG pyramid:
    gimbal axes tilted ``skew`` (rad) from +z toward ±x, ±y; zero momentum at δ = 0."""
    sb, cb = math.sin(skew), math.cos(skew)
    g = np.array([[sb, 0, cb], [0, sb, cb], [-sb, 0, cb], [0, -sb, cb]], float)
    s0 = np.array([[0, 1, 0], [-1, 0, 0], [0, -1, 0], [1, 0, 0]], float)
    return g, s0


def _per(values, n, name):
    v = np.asarray(values, float)
    if v.size == 1:
        return np.full(n, float(v[0]))
    if v.size != n:
        raise ValueError(f'{name} needs 1 or {n} values (one per actuator), got {v.size}')
    return v.copy()


def _axes(flat, name, labels, notes):
    v = np.asarray(flat, float)
    if v.size % 3:
        raise ValueError(f'{name} needs 3 values per axis, got {v.size}')
    a = v.reshape(-1, 3).copy()
    for i, row in enumerate(a):
        n = float(np.linalg.norm(row))
        if not (np.all(np.isfinite(row)) and n > 0.0):
            raise ValueError(f'{name}: axis of {labels[i]} is zero or not finite: '
                             f'{row.tolist()}')
        if abs(n - 1.0) > 1e-12:
            notes.append(f'{name}: axis of {labels[i]} {row.tolist()} normalised '
                         f'(norm {n:.6g})')
            a[i] = row / n
    return a


def _names(text, count, prefix, name):
    if not text.strip():
        return tuple(f'{prefix}_{i + 1}' for i in range(count))
    names = tuple(s.strip() for s in text.split(','))
    if len(names) != count or not all(names) or len(set(names)) != count:
        raise ValueError(f'{name} needs {count} distinct non-empty names, got {text!r}')
    return names


@dataclass(frozen=True, eq=False)
class ActuatorConfig:
    """Validated actuators. Wheels: axes (N, 3) unit, body frame; inertia (kg·m²), limits
    max_torque (N·m), max_speed (rad/s), friction (N·m·s), initial_speed (rad/s, relative).
    CMGs: gimbal (K, 3) and spin0 (K, 3) unit and perpendicular, body frame; momentum h0
    (N·m·s), max_rate (rad/s), angle_limit (rad, 0 none), initial_angles (rad)."""
    command: str
    wheel_names: tuple
    axes: np.ndarray
    inertia: np.ndarray
    max_torque: np.ndarray
    max_speed: np.ndarray
    friction: np.ndarray
    initial_speed: np.ndarray
    cmg_names: tuple
    gimbal: np.ndarray
    spin0: np.ndarray
    momentum: np.ndarray
    max_rate: np.ndarray
    angle_limit: np.ndarray
    initial_angles: np.ndarray
    sr_gain: float = 0.01
    sr_scale: float = 10.0
    notes: tuple = ()

    @property
    def wheels(self) -> int:
        return len(self.axes)

    @property
    def cmgs(self) -> int:
        return len(self.gimbal)

    @property
    def joint_names(self) -> tuple:
        return self.wheel_names + self.cmg_names

    @classmethod
    def from_parameters(cls, p) -> Optional['ActuatorConfig']:
        """From coerced simulator parameters; None when the scene has no actuators.
        ValueError naming the parameter and the wheel or gimbal."""
        notes = []
        flat = p['actuators.wheels.axes']
        nw = len(flat) // 3
        wnames = _names(p['actuators.wheels.names'], nw, 'wheel', 'actuators.wheels.names')
        axes = _axes(flat, 'actuators.wheels.axes', wnames, notes) if flat else np.zeros((0, 3))
        w = {k: _per(p[f'actuators.wheels.{k}'], nw, f'actuators.wheels.{k}')
             for k in ('inertia', 'max_torque', 'max_speed', 'friction', 'initial_speed')}
        cluster = p['actuators.cmgs.cluster']
        if cluster == 'pyramid':
            g, s0 = pyramid(p['actuators.cmgs.skew'])
        elif cluster == 'custom':
            gf, sf = p['actuators.cmgs.gimbal_axes'], p['actuators.cmgs.spin_axes']
            if not gf or len(gf) != len(sf):
                raise ValueError('actuators.cmgs: a custom cluster needs gimbal_axes and '
                                 f'spin_axes of equal length (3 per CMG), got {len(gf)} and '
                                 f'{len(sf)} values')
            labels = _names(p['actuators.cmgs.names'], len(gf) // 3, 'gimbal',
                            'actuators.cmgs.names') if len(gf) % 3 == 0 else ()
            g = _axes(gf, 'actuators.cmgs.gimbal_axes', labels, notes)
            s0 = _axes(sf, 'actuators.cmgs.spin_axes', labels, notes)
            for j in range(len(g)):
                s = s0[j] - np.dot(s0[j], g[j]) * g[j]
                n = float(np.linalg.norm(s))
                if n < 1e-6:
                    raise ValueError(f'actuators.cmgs.spin_axes: spin axis of {labels[j]} is '
                                     'parallel to its gimbal axis')
                if abs(n - 1.0) > 1e-12:
                    notes.append(f'actuators.cmgs.spin_axes: spin axis of {labels[j]} made '
                                 'perpendicular to its gimbal axis')
                s0[j] = s / n
        else:
            g = s0 = np.zeros((0, 3))
        k = len(g)
        if k and (k < 3 or np.linalg.svd(g, compute_uv=False)[-1] < SPAN_TOL):
            raise ValueError(f'actuators.cmgs: the {k} gimbal axes do not span 3-D, so the '
                             'cluster cannot give torque about every axis')
        cnames = _names(p['actuators.cmgs.names'], k, 'gimbal', 'actuators.cmgs.names')
        c = {key: _per(p[f'actuators.cmgs.{key}'], k, f'actuators.cmgs.{key}')
             for key in ('momentum', 'max_rate', 'angle_limit', 'initial_angles')}
        for j in range(k):
            lim, d0 = c['angle_limit'][j], c['initial_angles'][j]
            if lim > 0 and abs(d0) > lim:
                raise ValueError(f'actuators.cmgs.initial_angles: {cnames[j]} starts at '
                                 f'{d0:g} rad, beyond its angle limit {lim:g} rad')
        if nw == 0 and k == 0:
            return None
        return cls(p['actuators.command'], wnames, axes, w['inertia'], w['max_torque'],
                   w['max_speed'], w['friction'], w['initial_speed'], cnames, g, s0,
                   c['momentum'], c['max_rate'], c['angle_limit'], c['initial_angles'],
                   p['actuators.cmgs.sr_gain'], p['actuators.cmgs.sr_scale'], tuple(notes))


class Actuators:
    """State, commands and stepping of a body's wheels and CMGs (see the module docstring).

    ``body``: the RigidBody (its principal frame is the kernel's frame)."""

    def __init__(self, config: ActuatorConfig, body):
        self.config, self.body = config, body
        c = config
        # outer, middle, inner axis of the Strang composition, as the body's splittings
        # order them (integrators/splitting.py _ORDER: smallest, largest, intermediate)
        self.split_axes = np.argsort(body.principal_moments, kind='stable')[[0, 2, 1]]
        to_p = body.to_principal
        self.wa = np.ascontiguousarray(to_p(c.axes)) if c.wheels else np.zeros((0, 3))
        self.g = np.ascontiguousarray(to_p(c.gimbal)) if c.cmgs else np.zeros((0, 3))
        self.s0 = np.ascontiguousarray(to_p(c.spin0)) if c.cmgs else np.zeros((0, 3))
        self.pinv = np.linalg.pinv(self.wa.T) if c.wheels else np.zeros((0, 3))
        self.u_cmd = np.zeros(c.wheels)
        self.rate_cmd = np.zeros(c.cmgs)
        self.u = np.zeros(c.wheels)       # applied (after allocation, before limits)
        self.rate = np.zeros(c.cmgs)
        self.tau_des = np.zeros(3)       # principal frame
        self.allocate = c.command == 'torque'
        self.status = np.zeros(gk.ST_SIZE)
        self.accepted = self.rejected = 0
        self.last_rejection = ''
        self.reset(np.zeros(3))

    def reset(self, angular_velocity_principal):
        """Initial wheel speeds and gimbal angles (the scene's); commands cleared."""
        c = self.config
        self.hw = c.inertia * (c.initial_speed + self.wa @ angular_velocity_principal)
        self.delta = c.initial_angles.copy()
        self.u_cmd[:] = 0.0
        self.rate_cmd[:] = 0.0
        self.u[:] = 0.0
        self.rate[:] = 0.0
        self.tau_des[:] = 0.0
        self.status[:] = 0.0
        self.status[gk.ST_SINGULARITY] = self.singularity()

    # ------------------------------------------------------------------ commands
    def set_body_torque(self, tau_principal) -> None:
        """The body torque to allocate (principal frame, N·m), None = zero."""
        self.tau_des = np.zeros(3) if tau_principal is None else \
            np.array(tau_principal, float).reshape(3)

    def command(self, values) -> None:
        """A forward command: N wheel torques (N·m) then K gimbal rates (rad/s). ValueError
        (counted; the last valid command stays) if the length is wrong, a value is not
        finite, or the scene allocates body torque instead."""
        c = self.config
        try:
            v = np.asarray(list(values), float)
            if self.allocate:
                raise ValueError('actuators.command is torque: the body torque is allocated '
                                 '(set actuators.command: forward to drive them directly)')
            if v.shape != (c.wheels + c.cmgs,):
                raise ValueError(f'actuator command needs {c.wheels + c.cmgs} values '
                                 f'({c.wheels} wheel torques, {c.cmgs} gimbal rates), got '
                                 f'{v.size}')
            if not np.all(np.isfinite(v)):
                raise ValueError(f'actuator command is not finite: {v.tolist()}')
        except (TypeError, ValueError) as exc:
            self.rejected += 1
            self.last_rejection = str(exc)
            raise ValueError(str(exc)) from None
        self.accepted += 1
        self.u_cmd[:] = v[:c.wheels]
        self.rate_cmd[:] = v[c.wheels:]

    # ------------------------------------------------------------------ stepping
    def run(self, q, m, h, n, moments, split_axes, tau_ext_p, t0=0.0, env=None):
        """n steps of size h on (q, m) in place with the actuators; first non-finite step
        or -1. ``tau_ext_p``: external torque, principal frame, or None; ``env``: the
        orbit's element array (the gravity gradient from t0 on), or None."""
        c = self.config
        ext = np.zeros(3) if tau_ext_p is None else np.asarray(tau_ext_p, float)
        inertia = _NO_INERTIA if env is None else self._mass_inertia(moments)
        return gk.gyrostat_run(
            q, m, self.hw, self.delta, h, n, moments, split_axes, ext, tau_ext_p is not None,
            self.wa, c.inertia, c.max_torque, c.max_speed, c.friction, self.u_cmd,
            self.g, self.s0, c.momentum, c.max_rate, c.angle_limit, self.rate_cmd,
            self.allocate, self.tau_des, self.pinv, c.sr_gain, c.sr_scale, self.u, self.rate,
            self.status, t0, env, inertia)

    def _mass_inertia(self, moments):
        """``mass_inertia`` of this body and its wheels (principal frame), built once."""
        if getattr(self, '_inertia', None) is None:
            self._inertia = mass_inertia(self.config, self.body)
        return self._inertia

    # ------------------------------------------------------------------ observables
    def momentum_principal(self) -> np.ndarray:
        """h_A = Σ h_i a_i + Σ h0_j s_j(δ_j), principal frame, kg·m²/s."""
        out = np.zeros(3)
        gk.actuator_momentum(self.hw, self.delta, self.wa, self.g, self.s0,
                             self.config.momentum, np.empty((max(self.config.cmgs, 1), 3)), out)
        return out

    def wheel_speeds(self, m, moments) -> np.ndarray:
        """Wheel speeds relative to the body, rad/s (m: body momentum, principal frame)."""
        return self.hw / self.config.inertia - self.wa @ (m / moments)

    def energy(self) -> float:
        """Kinetic energy of the wheels' spin, Σ h_i²/(2 J_i), J (the CMG rotors' is
        constant and left out)."""
        return float(np.sum(self.hw ** 2 / (2.0 * self.config.inertia)))

    def singularity(self) -> float:
        """det(A Aᵀ) of the unit CMG torque directions now (1 without CMGs... 0 if K < 3)."""
        if not self.config.cmgs:
            return float('nan')
        t = np.empty((self.config.cmgs, 3))
        gk.cmg_jacobian(self.g, self.s0, self.delta, t)
        return float(np.linalg.det(t.T @ t))

    def row(self, m, moments) -> np.ndarray:
        """One sample: wheel speeds (N, rad/s), wheel momenta (N, N·m·s), gimbal angles
        (K, rad), gimbal rates (K, rad/s), singularity measure, |h_A| (N·m·s)."""
        return np.concatenate((self.wheel_speeds(m, moments), self.hw, self.delta, self.rate,
                               [self.singularity(), np.linalg.norm(self.momentum_principal())]))

    @property
    def width(self) -> int:
        return 2 * (self.config.wheels + self.config.cmgs) + 2

    def diagnostics(self, m, moments) -> dict:
        """Saturation counters, the wheels at their speed limit now, the singularity
        measure (with CMGs), command counters (m: body momentum, principal frame)."""
        s, c = self.status, self.config
        out = {'wheel_torque_saturated_kicks': int(s[gk.ST_WHEEL_TORQUE_SAT]),
               'wheel_speed_limited_kicks': int(s[gk.ST_WHEEL_SPEED_SAT]),
               'actuator_commands_accepted': self.accepted,
               'actuator_commands_rejected': self.rejected,
               'actuator_last_rejection': self.last_rejection}
        if c.wheels:
            speeds = np.abs(self.wheel_speeds(m, moments))
            out['wheels_at_speed_limit'] = ', '.join(
                n for n, v, lim in zip(c.wheel_names, speeds, c.max_speed) if v >= lim)
        if c.cmgs:
            out.update({'gimbal_rate_saturated_steps': int(s[gk.ST_GIMBAL_RATE_SAT]),
                        'gimbal_angle_limited_kicks': int(s[gk.ST_GIMBAL_ANGLE_SAT]),
                        'cmg_singularity_measure': self.singularity()})
        return out


def mass_inertia(config: ActuatorConfig, body) -> np.ndarray:
    """The whole mass distribution's inertia (3, 3, principal frame), for the gravity
    gradient: the body's (which excludes the rotors' spin-axis inertia, Hughes' form) plus
    each wheel rotor's J a aᵀ (CMG rotors: their momentum only, no inertia modelled)."""
    full = np.diag(np.asarray(body.principal_moments, float))
    if config is not None and config.wheels:
        wa = body.to_principal(config.axes)
        full = full + (wa.T * config.inertia) @ wa
    return full


_NO_INERTIA = np.eye(3)  # passed when no orbit acts (the loop never reads it then)
