"""Momentum-exchange actuators: reaction wheels and single-gimbal CMGs (no ROS).

:class:`ActuatorConfig` (``actuator_specs``) is built from the ``actuators.*`` parameters
(validated, with notes such as a normalised axis); :class:`Actuators` holds their state and
commands and advances body + actuators by the compiled gyrostat kernel
(``physics.integrators.gyrostat_kernel``) for the registered method that carries them
(``physics.integrators.gyrostat.GyrostatStrang``). Frames: axes and torques in the body
frame at this interface; the kernel works in the principal frame.

Body torque → actuators (``actuators.command`` = torque): CMGs if the scene has any
(singularity-robust inverse at the current gimbal angles), else wheels (pseudo-inverse of
the axis matrix). Forward commands (= forward): wheel motor torques (N·m) then gimbal
rates (rad/s), held until the next valid one.
"""
import numpy as np

from ..physics.integrators import gyrostat_kernel as gk
# the configuration lives beside its parameters, free of numba (a scene's checks build it)
from .actuator_specs import ActuatorConfig, pyramid  # noqa: F401 (engine.actuators.pyramid)


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
