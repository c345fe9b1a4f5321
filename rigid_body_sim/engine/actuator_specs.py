"""Parameters of the momentum-exchange actuators (``actuators.*``), merged into the
simulator's specs. A scene without wheels and CMGs leaves them at their defaults and the
engine runs the plain rigid body (nothing of this is built).

Arrays are flat, as rcl wants them: 3N values for N axes. Axes are checked by
``ActuatorConfig`` below (``finite=False`` in the specs), so that a bad one is named by its
wheel or gimbal rather than by its index in the flat array. Per-actuator limits take one
value (shared) or one per actuator. Frames: axes in the body frame (child_frame_id).
"""
from dataclasses import dataclass
import math
from typing import Optional, Tuple

import numpy as np

from ..param_spec import ParamSpec

COMMAND_MODES = ('torque', 'forward')
CLUSTERS = ('none', 'pyramid', 'custom')
PYRAMID_SKEW = math.acos(1.0 / math.sqrt(3.0))  # 54.7356°: the isotropic pyramid

ACTUATORS = (
    ParamSpec('actuators.command', 'torque', 'torque: the body torque (torque_command or the '
              'in-process law) is allocated to the actuators; forward: actuator_command '
              '(Float64MultiArray: wheel torques [N*m] then gimbal rates [rad/s]) drives them',
              kind='string', choices=COMMAND_MODES, read_only=True),
    ParamSpec('actuators.wheels.names', '', 'joint names of the wheels, comma-separated '
              '(empty: wheel_1 ... wheel_N)', kind='string', read_only=True),
    ParamSpec('actuators.wheels.axes', [], 'reaction-wheel spin axes, body frame, 3 values per '
              'wheel (flat); empty = no wheels', kind='float_array', read_only=True, finite=False,
              note='non-zero; normalised'),
    ParamSpec('actuators.wheels.inertia', [0.01], 'rotor spin-axis inertia, one value or one '
              'per wheel', kind='float_array', unit='kg*m^2', low=0.0, low_open=True,
              scalar_ok=True, read_only=True),
    ParamSpec('actuators.wheels.max_torque', [0.1], 'motor torque limit, one value or one per '
              'wheel', kind='float_array', unit='N*m', low=0.0, scalar_ok=True, read_only=True),
    ParamSpec('actuators.wheels.max_speed', [600.0], 'wheel speed limit (relative to the body); '
              'the motor cannot drive past it', kind='float_array', unit='rad/s', low=0.0,
              low_open=True, scalar_ok=True, read_only=True),
    ParamSpec('actuators.wheels.friction', [0.0], 'viscous bearing friction on the relative '
              'wheel speed, one value or one per wheel', kind='float_array', unit='N*m*s',
              low=0.0, scalar_ok=True, read_only=True),
    ParamSpec('actuators.wheels.initial_speed', [0.0], 'initial wheel speeds relative to the '
              'body, one value or one per wheel', kind='float_array', unit='rad/s',
              scalar_ok=True, read_only=True, note='takes effect on ~/reset'),
    ParamSpec('actuators.cmgs.cluster', 'none', 'single-gimbal CMGs: none, the built-in '
              'four-CMG pyramid, or custom gimbal_axes/spin_axes', kind='string',
              choices=CLUSTERS, read_only=True),
    ParamSpec('actuators.cmgs.skew', PYRAMID_SKEW, 'pyramid skew angle (gimbal axes from the '
              'body z axis)', kind='float', unit='rad', low=0.0, high=math.pi / 2,
              low_open=True, high_open=True, read_only=True),
    ParamSpec('actuators.cmgs.names', '', 'joint names of the gimbals, comma-separated '
              '(empty: gimbal_1 ... gimbal_K)', kind='string', read_only=True),
    ParamSpec('actuators.cmgs.gimbal_axes', [], 'custom cluster: gimbal axes, body frame, 3 '
              'values per CMG (flat)', kind='float_array', read_only=True, finite=False,
              note='non-zero; normalised; must span 3-D'),
    ParamSpec('actuators.cmgs.spin_axes', [], 'custom cluster: rotor spin axes at zero gimbal '
              'angle, body frame, 3 values per CMG', kind='float_array', read_only=True,
              finite=False,
              note='not parallel to the gimbal axis; made perpendicular to it and normalised'),
    ParamSpec('actuators.cmgs.momentum', [10.0], 'rotor angular momentum h0, one value or one '
              'per CMG', kind='float_array', unit='N*m*s', low=0.0, low_open=True,
              scalar_ok=True, read_only=True),
    ParamSpec('actuators.cmgs.max_rate', [1.0], 'gimbal rate limit (the rate vector is scaled '
              'to respect it)', kind='float_array', unit='rad/s', low=0.0, low_open=True,
              scalar_ok=True, read_only=True),
    ParamSpec('actuators.cmgs.angle_limit', [0.0], 'gimbal angle limit |delta|; 0 = none',
              kind='float_array', unit='rad', low=0.0, scalar_ok=True, read_only=True),
    ParamSpec('actuators.cmgs.initial_angles', [0.0], 'initial gimbal angles, one value or one '
              'per CMG', kind='float_array', unit='rad', scalar_ok=True, read_only=True,
              note='takes effect on ~/reset'),
    ParamSpec('actuators.cmgs.sr_gain', 0.01, 'singularity-robust inverse: lambda = sr_gain * '
              'h0^2 * exp(-sr_scale * det(A A^T))', kind='float', low=0.0, high=1e6,
              read_only=True),
    ParamSpec('actuators.cmgs.sr_scale', 10.0, 'singularity-robust inverse: decay of lambda '
              'with the singularity measure', kind='float', low=0.0, high=1e6, read_only=True),
)


SPAN_TOL = 1e-6  # smallest singular value of the gimbal-axis matrix that counts as spanning


def pyramid(skew: float = PYRAMID_SKEW) -> Tuple[np.ndarray, np.ndarray]:
    """(gimbal axes, spin axes at δ = 0), body frame, of the classic four-CMG pyramid:
    gimbal axes tilted ``skew`` (rad) from +z toward ±x, ±y; zero momentum at δ = 0."""
    sb, cb = math.sin(skew), math.cos(skew)
    g = np.array([[sb, 0, cb], [0, sb, cb], [-sb, 0, cb], [0, -sb, cb]], float)
    s0 = np.array([[0, 1, 0], [-1, 0, 0], [0, -1, 0], [1, 0, 0]], float)
    return g, s0


def _per(values, n, name):
    if n == 0 and type(values) is list and len(values) <= 1:
        return np.zeros(0)  # no such actuator (most scenes): nothing to convert
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
