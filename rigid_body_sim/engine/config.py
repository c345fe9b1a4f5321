"""Typed, validated engine configuration built from parameter values (no ROS).

:func:`EngineConfig.from_parameters` turns the simulator's (and optionally the
controller's) coerced parameter values into frozen, typed settings; the engine never
reads a dict. Times on the engine's axis are integers in nanoseconds.
"""
from dataclasses import dataclass, field, replace
import math
from typing import Mapping, Optional

import numpy as np

from .. import bdot, control
from ..physics import Dissipation, RigidBody, rotation
from ..sensors.specs import SensorSettings, check_feedback
from . import specs
from .actuator_specs import ActuatorConfig
from .environment_specs import (EnvironmentSettings, environment_from_parameters,
                                initial_state_in_world)
from ..param_spec import coerce_all

NS = 1_000_000_000


def seconds_to_ns(seconds: float, name: str) -> int:
    """Whole nanoseconds of a positive finite duration; ValueError naming ``name``."""
    if not (math.isfinite(seconds) and seconds > 0.0):
        raise ValueError(f'{name} must be finite and > 0 s, got {seconds}')
    return max(1, int(round(seconds * NS)))


@dataclass(frozen=True)
class ControlSettings:
    """The in-process control law (offline runs, campaigns): the controller node's parameters."""
    config: control.ControlConfig
    mode: str
    target: np.ndarray
    period_ns: int
    free_time: float = 0.0
    detumble_exit_rate: float = 0.0
    feedback: str = 'truth'             # or 'sensors' (the estimator's output)
    estimator_bandwidth: float = 0.5    # rad/s
    bdot_gain: float = 0.0              # kg·m²/s, mode bdot (``bdot``)

    def bandwidth(self) -> float:
        """The law's rate scale (1/s): its fastest gain over the principal moments."""
        cfg = self.config
        i = cfg.body.principal_moments
        if self.mode == 'bdot':  # the rods' law: ω decays at k/I at most (bdot.py)
            return self.bdot_gain / float(i.min())
        # plain floats, the same correctly rounded operations as numpy's (the law's gains
        # are finite and > 0: control._vector): asked at each choice of auto under the law,
        # where three numpy reductions took ~9 µs of slew's ~110 µs selection
        (p0, p1, p2), (d0, d1, d2), (w0, w1, w2), (i0, i1, i2) = (
            cfg.kp_principal.tolist(), cfg.kd_principal.tolist(),
            cfg.rate_gain_principal.tolist(), i.tolist())
        return max(math.sqrt(p0 / i0), math.sqrt(p1 / i1), math.sqrt(p2 / i2),
                   d0 / i0, d1 / i1, d2 / i2, w0 / i0, w1 / i1, w2 / i2)

    @classmethod
    def from_parameters(cls, values: Mapping) -> 'ControlSettings':
        p = coerce_all(specs.CONTROLLER, values)
        try:
            target = control.validated_target(p['target_attitude'])
        except ValueError as exc:
            raise ValueError(f'target_attitude: {exc}') from None
        control.Mission(p['mission.free_time'], p['mission.detumble_exit_rate'])  # validates
        config = control.config_from_parameters(p)
        gain = bdot.gain_from_parameters(p, float(config.body.principal_moments.min())) \
            if p['mode'] == 'bdot' else 0.0
        return cls(config, p['mode'], target,
                   seconds_to_ns(1.0 / p['control_rate'], 'control period'),
                   p['mission.free_time'], p['mission.detumble_exit_rate'],
                   p['feedback'], p['estimator.bandwidth'], gain)


@dataclass(frozen=True, eq=False)
class EngineConfig:
    """Everything the engine needs, validated.

    body: mass properties (user's body frame ↔ principal frame).
    attitude: initial quaternion (x, y, z, w), body → inertial; angular_velocity: initial ω,
        body frame, rad/s.
    integrator: a registered method or ``auto``; integrator_options: for a fixed method
        (e.g. dop853 rtol); step: the largest physics step, s.
    accuracy: auto's attitude-error budget over ``duration`` (rad).
    sample_period_ns: sample instants are its multiples (from t = 0).
    duration_ns: the run ends there (0 = open-ended).
    max_torque: per-axis clip of commanded torque (N·m); command_timeout_ns: hold time.
    control: the in-process control law, or None (commands come from outside).
    law_bandwidth: with commands from outside, the rate scale of the controller's law when
        its gains are known (a lockstep controller's scene), so that ``auto`` expects the
        torque the offline run's in-process law gives and chooses as it does; 0 = unknown.
    actuators: reaction wheels / CMGs (``actuators``), or None: the plain rigid body.
    sensors: the simulated gyro / star tracker (``sensors.specs``), or None.
    environment: the orbit and the environment's torques (``environment_specs``), or None:
        the free body, nothing evaluated.
    """
    body: RigidBody
    dissipation: Dissipation
    attitude: np.ndarray
    angular_velocity: np.ndarray
    integrator: str = specs.AUTO
    step: float = 0.001
    accuracy: float = 1e-6
    sample_period_ns: int = 10_000_000
    duration_ns: int = 0
    max_torque: float = 1.0
    command_timeout_ns: int = 500_000_000
    control: Optional[ControlSettings] = None
    integrator_options: Mapping = field(default_factory=dict)
    actuators: Optional[ActuatorConfig] = None
    sensors: Optional[SensorSettings] = None  # None: no sensor simulated (nothing built)
    law_bandwidth: float = 0.0  # 1/s: an outside controller's, when its gains are known
    environment: Optional[EnvironmentSettings] = None

    @property
    def duration(self) -> float:
        return self.duration_ns / NS

    @property
    def sample_period(self) -> float:
        return self.sample_period_ns / NS

    def event_spacing(self) -> float:
        """The longest step the engine may take (s): the sample and control period, and a
        fixed method's ``step`` too. ``auto`` is not capped by ``step``: it picks its own,
        dividing the spacing."""
        h = self.sample_period if self.integrator == specs.AUTO else \
            min(self.step, self.sample_period)
        if self.control is not None:
            h = min(h, self.control.period_ns / NS)
        return h

    def torque_rate(self, commanded: bool = True) -> float:
        """Rate scale (1/s) of the torque ``auto`` must expect: with commands
        (``commanded``), the control law's bandwidth (in process, or ``law_bandwidth`` of an
        outside one whose gains are known), else that of the largest command,
        √(√3·max_torque/I_min); with the gravity gradient at least its own,
        √(3μ/r_p³ · (I_max − I_min)/I_min), and the rods', SRP's and drag's their own
        (``MagneticSettings.torque_rate``, ``Sunlight.torque_rate``). Before any command
        (``commanded`` False) only the environment's: the engine chooses again at the
        first command, so a scene's max_torque must not set the step of a run that has
        none."""
        rate = 0.0
        if commanded and self.control is not None:
            rate = self.control.bandwidth()
        elif commanded and self.law_bandwidth > 0.0:
            rate = self.law_bandwidth
        elif commanded:
            rate = math.sqrt(math.sqrt(3.0) * self.max_torque / self.body.principal_moments.min())
        env = self.environment
        if env is not None and env.gravity_gradient:
            rate = max(rate, env.gravity_gradient_rate(self.body.principal_moments))
        if env is not None and env.magnetorquers:
            rate = max(rate, env.magnetic.torque_rate(self.body.principal_moments))
        if env is not None and env.sunlight is not None:  # SRP and drag on the facets
            rate = max(rate, env.sunlight.torque_rate(self.body.principal_moments, env.orbit))
        return rate

    def replace(self, **changes) -> 'EngineConfig':
        return replace(self, **changes)

    @classmethod
    def from_parameters(cls, simulator: Mapping, controller: Optional[Mapping] = None,
                        **overrides) -> 'EngineConfig':
        """From the simulator's parameter values (missing ones take their defaults) and,
        for an in-process control law, the controller's. ValueError naming the parameter."""
        p = coerce_all(specs.SIMULATOR, simulator)
        specs.check_frames(p)
        try:
            body = RigidBody.from_inertia(p['inertia'])
        except ValueError as exc:
            raise ValueError(f'inertia: {exc}') from None
        q = rotation.validated(list(p['initial_attitude']), 'initial_attitude')
        w = np.asarray(p['initial_angular_velocity'], float)
        dissipation = Dissipation(p['dissipation.model'], p['dissipation.coefficient'])
        ctl = None if controller is None else ControlSettings.from_parameters(controller)
        actuators = ActuatorConfig.from_parameters(p)
        if actuators is not None and dissipation.active:
            raise ValueError('dissipation.model: the gyrostat (wheels/CMGs) integrator has no '
                             'dissipation; set it to none with actuators')
        sensors = SensorSettings.from_parameters(p)
        environment = environment_from_parameters(p)
        q, w = initial_state_in_world(environment, p['initial_attitude_frame'], q, w)
        if environment is not None and environment.terms:
            # the registry loads every method's kernels (numba): only for this question
            from ..physics.integrators import get_integrator
            if p['integrator'] != specs.AUTO and \
                    not get_integrator(p['integrator']).environment:
                keys = ' and '.join(k for k, on in (
                    ('environment.gravity_gradient', environment.gravity_gradient),
                    ('magnetorquer.max_dipole', environment.magnetorquers),
                    ('environment.solar_radiation_pressure',
                     p['environment.solar_radiation_pressure']),
                    ('environment.drag', p['environment.drag'] != 'none')) if on)
                raise ValueError(f'integrator: {p["integrator"]} does not integrate '
                                 f'{keys}; use auto, a splitting, rk4, euler or dop853')
        if ctl is not None:
            check_feedback(sensors, ctl.feedback, ctl.estimator_bandwidth)
        config = cls(body, dissipation, q, w, integrator=p['integrator'], step=p['step'],
                     accuracy=p['accuracy'],
                     sample_period_ns=seconds_to_ns(1.0 / p['publish_rate'], 'sample period'),
                     duration_ns=int(round(p['duration'] * NS)), max_torque=p['max_torque'],
                     command_timeout_ns=seconds_to_ns(p['command_timeout'], 'command_timeout'),
                     control=ctl, actuators=actuators, sensors=sensors,
                     environment=environment)
        return config.replace(**overrides) if overrides else config
