"""Parameters of the momentum-exchange actuators (``actuators.*``), merged into the
simulator's specs. A scene without wheels and CMGs leaves them at their defaults and the
engine runs the plain rigid body (nothing of this is built).

Arrays are flat, as rcl wants them: 3N values for N axes. Axes are checked by
``actuators.ActuatorConfig`` (``finite=False`` here), so that a bad one is named by its
wheel or gimbal rather than by its index in the flat array. Per-actuator limits take one
value (shared) or one per actuator. Frames: axes in the body frame (child_frame_id).
"""
import math

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
