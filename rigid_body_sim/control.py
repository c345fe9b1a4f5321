"""Attitude control law: detumble and quaternion-feedback slew (numpy only, no ROS).

Shared by the ``attitude_controller`` node and by offline closed-loop runs. Conventions
are the physics core's: quaternions (x, y, z, w), attitude q rotates body-frame vectors
into the inertial frame, ω is in the body frame, torques are in the body frame.

Laws (principal frame, per principal axis i with moment I_i)
-------------------------------------------------------------
Error quaternion (body frame)::

    q_e = q_target* ⊗ q,   sign chosen so that q_e.w ≥ 0 (shortest path, no unwinding)

``detumble`` — rate damping::

    τ = −K_ω ω                        (default K_ω,i = k_d,i = 2 ζ ω_n I_i)

``slew`` — PD on the vector part e = vec(q_e), written as a rate loop::

    ω_cmd = −sat_ωmax(g ⊙ e),   g_i = k_p,i / k_d,i
    τ     = −k_d ⊙ (ω − ω_cmd)  [+ ω × Iω]
    ⇔ τ = −k_p ⊙ e − k_d ⊙ ω  [+ ω × Iω]   while |g ⊙ e| ≤ ω_max (always, without a limit)

Gain derivation. About a principal axis, e ≈ θ/2 and ė ≈ ω/2, so the linearised loop is
I_i θ̈ = −(k_p,i/2) θ − k_d,i θ̇. Matching θ̈ + 2ζω_n θ̇ + ω_n² θ = 0 gives

    k_p,i = 2 I_i ω_n²,      k_d,i = 2 ζ ω_n I_i.

(The factor 2 in k_p is the "half angle" of the quaternion vector part.) With ζ = 1 the
linear error from rest decays as θ(t)/θ(0) = (1 + ω_n t) e^(−ω_n t), no overshoot.

With the same ω_n and ζ on all axes, K_p = 2ω_n² I and K_d = 2ζω_n I, and with gyroscopic
compensation the closed loop is ω̇ = −2ω_n² e − 2ζω_n ω exactly: a rest-to-rest slew is an
eigenaxis rotation, and V = |ω|²/(4ω_n²) + 2(1 − |q_e.w|) proves almost-global convergence
(V̇ = −ζ|ω|²/ω_n). At large angles e = sin(θ/2) n is smaller than θ/2, so the loop is
slightly softer than linear there (no overshoot added).

Saturation (``max_torque`` > 0): the torque vector is scaled down as a whole to
|τ| ≤ max_torque (direction kept — never per-axis clipping, which would bend the eigenaxis
and can limit-cycle), and the commanded rate is bounded by

    ω_max(n̂) = max_torque / |I ⊙ g ⊙ n̂|,   n̂ = ω_cmd / |ω_cmd|  (principal frame)

(max_torque / (I_i ω_n / ζ) about principal axis i with bandwidth gains; ``max_rate`` if
smaller). Far from the target the body then cruises at |ω| ≤ ω_max and the braking needed
once ω_cmd leaves its bound, ≈ |I ⊙ g ⊙ ω| / 2, is within half the available torque, so the
loop re-enters its linear region without overshoot. There is no integrator, hence nothing to
wind up.

Detumble decay prediction. With K_ω = c I (the default, c = 2ζω_n when ω_n is one
number) the inertial angular momentum obeys dL/dt = −c L exactly: |L(t)| = |L₀| e^(−ct), and
the motion is the torque-free motion with time slowed down (T and |L|² both decay as
e^(−2ct), so the polhode does not change). The linear prediction |ω(t)| = |ω₀| e^(−ct) is
therefore exact up to |ω| wandering on the polhode, and |ω(t)| ≤ |L₀| e^(−ct) / I_min gives
the guaranteed bound :func:`detumble_time` returns with ``bound=True``.
"""
from dataclasses import dataclass, field
import math
from typing import Optional

import numpy as np

from .control_params import CONFIG_PARAMETERS, MODES, PARAMETER_DEFAULTS
from .physics import rotation
from .physics.body import RigidBody

# A target quaternion whose norm is further than this from 1 is rejected, not normalised:
# it is most likely not a rotation at all (a typo, a field order mix-up, Euler angles).
UNIT_TOLERANCE = 1e-3


def validated_target(target) -> np.ndarray:
    """The target quaternion (x, y, z, w) as a unit float array, or ValueError with the reason.

    NaN/Inf, zero norm and a norm off 1 by more than ``UNIT_TOLERANCE`` are rejected.
    """
    q = np.asarray(target, dtype=float)
    if q.shape != (4,):
        raise ValueError(f'target must have 4 components (x, y, z, w), got shape {q.shape}')
    if not np.all(np.isfinite(q)):
        raise ValueError(f'target is not finite: {q.tolist()}')
    norm = float(np.linalg.norm(q))
    if norm < 1e-6:
        raise ValueError('target has zero norm; a rotation needs a unit quaternion (x, y, z, w)')
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise ValueError(f'target is not a unit quaternion (norm {norm:.6g}, '
                         f'tolerance {UNIT_TOLERANCE:g}); '
                         'send (x, y, z, w) normalised')
    return q / norm


def error_quaternion(attitude, target) -> np.ndarray:
    """q_e = target* ⊗ attitude with q_e.w ≥ 0 (shortest path). Shapes (..., 4)."""
    q_e = rotation.multiply(rotation.conjugate(target), attitude)
    return np.where(q_e[..., 3:4] < 0.0, -q_e, q_e)


def error_angle(attitude, target):
    """Rotation angle (rad, in [0, π]) between attitude and target."""
    return rotation.angle_between(target, attitude)


def bandwidth_gains(moments, natural_frequency, damping_ratio=1.0):
    """(k_p, k_d) per principal axis for the quaternion PD: k_p = 2 I ω_n², k_d = 2 ζ ω_n I."""
    moments = np.asarray(moments, float)
    wn = np.broadcast_to(np.asarray(natural_frequency, float), moments.shape)
    zeta = np.broadcast_to(np.asarray(damping_ratio, float), moments.shape)
    return 2.0 * moments * wn ** 2, 2.0 * zeta * wn * moments


def critical_settling_time(natural_frequency, tolerance=0.02) -> float:
    """Time t at which (1 + ω_n t) e^(−ω_n t) = tolerance: the linear, critically damped
    settling time (ω_n t ≈ 5.834 for 2 %)."""
    if not 0.0 < tolerance < 1.0:
        raise ValueError('tolerance must be in (0, 1)')
    x = -np.log(tolerance)
    for _ in range(60):  # Newton on f(x) = ln(1 + x) − x − ln(tol)
        x -= (np.log1p(x) - x - np.log(tolerance)) / (1.0 / (1.0 + x) - 1.0)
    return float(x / float(natural_frequency))


def detumble_time(angular_velocity, decay_rate, threshold=1e-3, moments=None,
                  bound=False) -> float:
    """Time for |ω| to fall below ``threshold`` under τ = −c I ω (``decay_rate`` = c, 1/s).

    Linear prediction ln(|ω₀| / threshold) / c. With ``bound=True`` (needs ``moments``): the
    guaranteed upper bound ln(|L₀| / (I_min threshold)) / c from |L| = |L₀| e^(−ct).
    Principal-frame ω and moments.
    """
    w = np.asarray(angular_velocity, float)
    if bound:
        moments = np.asarray(moments, float)
        start = np.linalg.norm(moments * w) / moments.min()
    else:
        start = np.linalg.norm(w)
    return float(max(0.0, np.log(start / threshold)) / decay_rate)


def _vector(value, name, allow_zero=False):
    """3 finite values (a scalar broadcasts), all > 0 (or ≥ 0)."""
    v = np.asarray(value, float).ravel()
    if v.size == 1:
        v = np.repeat(v, 3)
    if v.size != 3:
        raise ValueError(f'{name} needs 1 or 3 values, got {v.size}')
    if not np.all(np.isfinite(v)):
        raise ValueError(f'{name} is not finite: {v.tolist()}')
    if np.any(v < 0.0) or (not allow_zero and np.any(v == 0.0)):
        raise ValueError(f'{name} must be {">= 0" if allow_zero else "> 0"}, got {v.tolist()}')
    return v


def _unset(value) -> bool:
    """An optional vector parameter is unset when None, empty or all zeros."""
    if value is None:
        return True
    v = np.asarray(value, float).ravel()
    return v.size == 0 or (np.all(v == 0.0))


@dataclass(frozen=True, eq=False)
class ControlConfig:
    """Validated gains and limits. Constructing it raises ValueError naming the problem.

    Args:
        inertia: 3 principal moments, 9 tensor values or a 3×3 tensor (kg·m², body frame).
        natural_frequency: ω_n, rad/s, 1 or 3 values (per principal axis).
        damping_ratio: ζ, 1 or 3 values; 1 = critical damping.
        kp, kd: direct gains per principal axis (N·m per unit quaternion, N·m·s). When set
            (3 values each, not all zero) they win over ω_n / ζ; give both or neither.
        rate_gain: detumble K_ω, N·m·s. None/empty/zeros → k_d (∝ inertia, decay rate
            2ζω_n); 1 value → isotropic τ = −k ω; 3 values → per principal axis.
        gyroscopic_compensation: add ω × Iω in ``slew`` mode.
        max_torque: bound on |τ| (N·m, Euclidean norm); 0 or inf = unlimited.
        max_rate: bound on the commanded slew rate (rad/s); 0 or inf = derived from
            ``max_torque`` only (see :meth:`rate_limit_along`).

    Principal axes are those of :class:`RigidBody` (the body axes, in the given order, when
    the inertia is diagonal; otherwise eigenvectors in ascending moment order).
    """
    inertia: object = (1.0, 2.0, 3.0)
    natural_frequency: object = 0.5
    damping_ratio: object = 1.0
    kp: object = None
    kd: object = None
    rate_gain: object = None
    gyroscopic_compensation: bool = True
    max_torque: float = 0.0
    max_rate: float = 0.0
    # derived
    body: RigidBody = field(init=False)
    kp_principal: np.ndarray = field(init=False)
    kd_principal: np.ndarray = field(init=False)
    rate_gain_principal: np.ndarray = field(init=False)
    rate_limit: float = field(init=False)
    torque_limit: float = field(init=False)

    def __post_init__(self):
        body = RigidBody.from_inertia(self.inertia)
        moments = body.principal_moments
        wn = _vector(self.natural_frequency, 'natural_frequency')
        zeta = _vector(self.damping_ratio, 'damping_ratio')
        if _unset(self.kp) and _unset(self.kd):
            kp, kd = bandwidth_gains(moments, wn, zeta)
        elif _unset(self.kp) or _unset(self.kd):
            raise ValueError('set both kp and kd (3 values each), '
                             'or neither to use natural_frequency/damping_ratio')
        else:
            kp, kd = _vector(self.kp, 'kp'), _vector(self.kd, 'kd')
        if _unset(self.rate_gain):
            kw = kd.copy()
        else:
            kw = _vector(self.rate_gain, 'rate_gain')
        tau_max = float(self.max_torque)
        rate_max = float(self.max_rate)
        for name, value in (('max_torque', tau_max), ('max_rate', rate_max)):
            if np.isnan(value) or value < 0.0:
                raise ValueError(f'{name} must be >= 0 (0 = unlimited), got {value}')
        tau_max = np.inf if tau_max == 0.0 else tau_max
        limit = np.inf if rate_max == 0.0 else rate_max
        for name, value in (('body', body), ('kp_principal', kp), ('kd_principal', kd),
                            ('rate_gain_principal', kw), ('rate_limit', float(limit)),
                            ('torque_limit', float(tau_max)),
                            ('gyroscopic_compensation', bool(self.gyroscopic_compensation))):
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    def rate_limit_along(self, direction) -> float:
        """Bound on the commanded slew rate along a principal-frame ``direction`` (rad/s):
        min(max_rate, max_torque / |I ⊙ g ⊙ n̂|), g = k_p / k_d."""
        if not np.isfinite(self.torque_limit):
            return self.rate_limit
        n = np.asarray(direction, float)
        n = n / np.linalg.norm(n)
        demand = np.linalg.norm(
            self.body.principal_moments * self.kp_principal / self.kd_principal * n)
        return float(min(self.rate_limit, self.torque_limit / demand))

    @property
    def kp_body(self) -> np.ndarray:
        """K_p as a 3×3 matrix in the body frame."""
        return self.body.principal_axes @ np.diag(self.kp_principal) @ self.body.principal_axes.T

    @property
    def kd_body(self) -> np.ndarray:
        """K_d as a 3×3 matrix in the body frame."""
        return self.body.principal_axes @ np.diag(self.kd_principal) @ self.body.principal_axes.T


@dataclass(frozen=True)
class ControlOutput:
    """One evaluation of the law.

    torque: body-frame torque to apply, N·m (after saturation).
    unsaturated_torque: before scaling to ``max_torque``.
    saturated: the torque was scaled down (|unsaturated| > max_torque).
    rate_limited: the slew's commanded rate hit its bound.
    error_angle: rad, angle to the target (nan in ``detumble``/``off`` without a target).
    rate_norm: |ω|, rad/s.
    """
    torque: np.ndarray
    unsaturated_torque: np.ndarray
    saturated: bool
    rate_limited: bool
    error_angle: float
    rate_norm: float
    mode: str


class AttitudeController:
    """The law with its mode and target. Stateless between calls apart from those two.

    Example::

        ctl = AttitudeController(ControlConfig(inertia=[1, 2, 3], natural_frequency=1.0),
                                 mode='slew', target=rotation.axis_rotation(2, np.pi / 2))
        tau = ctl.torque(attitude, angular_velocity)   # body frame, N·m

    In closed loop it runs inside the simulation engine as a torque source
    (``engine.sources.ControlLaw``), in the controller node and offline alike.
    """

    def __init__(self, config: Optional[ControlConfig] = None, mode: str = 'detumble',
                 target=(0.0, 0.0, 0.0, 1.0), compiled: bool = True):
        self.config = config if config is not None else ControlConfig()
        # compiled=False: the same law interpreted (control_law.py), for a front end that
        # evaluates it once per control period and should not load numba for that (the node)
        self.compiled = compiled
        self.set_mode(mode)
        self.target = validated_target(target)

    def set_mode(self, mode: str):
        if mode not in MODES:
            raise ValueError(f'unknown mode {mode!r}; choose one of {", ".join(MODES)}')
        self.mode = mode

    def set_target(self, target):
        """Validate and set the target (x, y, z, w). On ValueError the previous target is kept."""
        self.target = validated_target(target)

    def set_config(self, config: ControlConfig):
        self.config = config

    def compute(self, attitude, angular_velocity) -> ControlOutput:
        """The body-frame torque for the state (attitude q body→inertial, ω body frame)."""
        cfg, body = self.config, self.config.body
        w = np.asarray(angular_velocity, dtype=float).reshape(3)
        q = np.asarray(attitude, dtype=float).reshape(4)
        tau, unsaturated = np.empty(3), np.empty(3)
        # The law itself is one function (control_law.py), the same in every front end,
        # compiled (control_kernel.py) unless ``compiled`` is off; imported here, on the
        # first use: a scene's checks build a ControlConfig without it.
        if self.compiled:
            from .control_kernel import MODE_CODES, control_torque
        else:
            from .control_law import MODE_CODES, control_torque
        saturated, rate_limited, angle, rate_norm = control_torque(
            MODE_CODES[self.mode], q, w, self.target, body.principal_axes,
            body.principal_moments, cfg.kp_principal, cfg.kd_principal,
            cfg.rate_gain_principal, cfg.rate_limit, cfg.torque_limit,
            cfg.gyroscopic_compensation, body.inertia, tau, unsaturated)
        return ControlOutput(tau, unsaturated, bool(saturated), bool(rate_limited), float(angle),
                             float(rate_norm), self.mode)

    def torque(self, attitude, angular_velocity) -> np.ndarray:
        """Shortcut for ``compute(...).torque``."""
        return self.compute(attitude, angular_velocity).torque


def config_from_parameters(params) -> ControlConfig:
    """ControlConfig from controller-node parameter values (missing ones take the defaults)."""
    p = dict(PARAMETER_DEFAULTS, **{k: v for k, v in params.items() if k in PARAMETER_DEFAULTS})
    return ControlConfig(**{k: p[k] for k in CONFIG_PARAMETERS})


class Mission:
    """A scene's schedule for the controller, as data (same live and offline).

    free_time: s of state time (from the first state seen) with no torque: the free phase.
    detumble_exit_rate: rad/s; in ``detumble`` (or ``bdot``: the rods' detumbling), once
        |ω| falls below it the controller switches itself to ``slew`` (go to the target
        and hold). 0 = never.
    """

    def __init__(self, free_time: float = 0.0, detumble_exit_rate: float = 0.0):
        for name, value in (('mission.free_time', free_time),
                            ('mission.detumble_exit_rate', detumble_exit_rate)):
            if not (math.isfinite(value) and value >= 0.0):
                raise ValueError(f'{name} must be finite and >= 0, got {value}')
        self.free_time, self.detumble_exit_rate = float(free_time), float(detumble_exit_rate)
        self.start = None

    @property
    def active(self) -> bool:
        return self.free_time > 0.0 or self.detumble_exit_rate > 0.0

    def update(self, controller: 'AttitudeController', t: float, angular_velocity):
        """(free, switched_to) at state time ``t``: free → command zero torque; switched_to is
        the new mode when the schedule changed it now, else None."""
        if self.start is None:
            self.start = t
        if t - self.start < self.free_time:
            return True, None
        if (controller.mode in ('detumble', 'bdot') and self.detumble_exit_rate > 0.0
                and float(np.linalg.norm(angular_velocity)) < self.detumble_exit_rate):
            controller.set_mode('slew')
            return False, 'slew'
        return False, None


def slew_begins(s, free_end, controller) -> float:
    """When the slew began (s; inf if not): at the end of the free phase in slew mode,
    else at the first sample after it with |ω| below mission.detumble_exit_rate (the
    figure marks it, the demo's summary prints it)."""
    t = np.asarray(s['t'])
    w = np.linalg.norm(s['angular_velocity'], axis=1)
    active = t >= (free_end if np.isfinite(free_end) else t[0])
    exit_rate = controller.get('mission.detumble_exit_rate', 0.0)
    if controller['mode'] == 'slew' and np.any(active):
        return float(t[np.argmax(active)])
    if exit_rate > 0 and np.any(active & (w < exit_rate)):
        return float(t[np.argmax(active & (w < exit_rate))])
    return np.inf
