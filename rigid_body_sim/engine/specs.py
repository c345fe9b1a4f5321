"""The parameters of the simulator and the controller: one spec list each, free of ROS.

Scene files, the offline run and the nodes all read these. A new parameter is one line
here; the node declares it from this line and the engine reads it from the typed config.
"""
from typing import Optional

# numba-free modules only (test_imports): scene files, --help and the nodes' parameter
# checks read these specs, and must not wait for the compiled kernels' imports
from .. import control_params as control
from ..physics.choices import BODY_ONLY, DISSIPATION_MODELS
from .actuator_specs import ACTUATORS
from .environment_specs import ENVIRONMENT
from ..sensors import specs as sensor_specs
from ..param_spec import ParamSpec

AUTO = 'auto'
QOS_CHOICES = ('reliable', 'sensor_data')

SIMULATOR = (
    ParamSpec('inertia', [1.0, 2.0, 3.0],
              'inertia: 3 principal moments or 9 values row-major (body frame)',
              kind='float_array', unit='kg*m^2', sizes=(3, 9),
              note='positive definite, symmetric, triangle inequalities; takes effect on ~/reset'),
    ParamSpec('initial_attitude', [0.0, 0.0, 0.0, 1.0],
              'initial attitude quaternion (x, y, z, w), rotation child_frame_id -> frame_id',
              kind='float_array', sizes=(4,),
              note='non-zero, normalised on use; takes effect on ~/reset'),
    ParamSpec('initial_angular_velocity', [0.05, 1.0, 0.0], 'initial angular velocity, body frame',
              kind='float_array', unit='rad/s', sizes=(3,), note='takes effect on ~/reset'),
    ParamSpec('dissipation.model', 'none', 'internal/external dissipation model', kind='string',
              choices=DISSIPATION_MODELS, note='applies at once, state continuous'),
    ParamSpec('dissipation.coefficient', 0.0,
              'dissipation coefficient: double_bracket alpha [s/(kg*m^2)], viscous c [N*m*s]',
              kind='float', low=0.0, note='applies at once, state continuous'),
    ParamSpec('integrator', AUTO,
              'integration method, or auto (chosen from the scene and accuracy)',
              kind='string', choices=(AUTO,) + BODY_ONLY,
              note='may change while running; with wheels or CMGs the method that '
              'carries them (gyrostat_strang), always'),
    ParamSpec('step', 0.001, 'physics step of a fixed integrator (each interval between events '
              'is split into equal steps no longer than this); auto picks its own, up to '
              'the sample and control period',
              kind='float', unit='s', low=1e-9, high=1e7),
    ParamSpec('accuracy', 1e-6, 'attitude-error budget used by integrator auto', kind='float',
              unit='rad', low=1e-15, high=1.0),
    ParamSpec('publish_rate', 100.0, 'state sample rate in simulated time (period rounded to '
              'whole nanoseconds)', kind='float', unit='Hz', low=1e-9, high=10000.0),
    ParamSpec('real_time_factor', 1.0, 'simulated seconds per wall second; 0 = as fast as '
              'possible', kind='float', low=0.0, high=1e9),
    ParamSpec('publish_clock', False, 'publish /clock (sim time) and stamp messages with it',
              kind='bool'),
    ParamSpec('duration', 0.0, 'simulated time to run from start (or last ~/reset), then exit; '
              '0 = until stopped', kind='float', unit='s', low=0.0, high=1e12),
    ParamSpec('frame_id', 'world', 'inertial frame (REP-105)', kind='string'),
    ParamSpec('child_frame_id', 'base_link', 'body frame (REP-103); commands must use it or '
              'empty', kind='string'),
    ParamSpec('max_torque', 1.0, 'per-axis saturation of commanded torque', kind='float',
              unit='N*m', low=0.0, high=1e9),
    ParamSpec('command_timeout', 0.5, 'a command held longer than this (sim time) drops to '
              'zero torque', kind='float', unit='s', low=1e-6, high=1e6, low_open=True),
    ParamSpec('command_stamp_tolerance', 0.5,
              'commands stamped further than this in the future (vs. the stamps this node '
              'publishes) are rejected; a zero stamp is accepted', kind='float', unit='s',
              low=0.0, high=1e6),
    ParamSpec('deadline_tolerance', 0.05,
              'a sample published later than this (wall time) after it was due counts as a '
              'missed deadline in diagnostics (real-time modes only)', kind='float', unit='s',
              low=0.0, high=1e6),
    ParamSpec('qos', 'reliable', 'QoS of state topics and command subscriptions',
              kind='string', choices=QOS_CHOICES, read_only=True),
    ParamSpec('wait_for_subscribers', 0, 'before t = 0, wait until every state topic has at '
              'least this many matched subscriptions (1 for a recorder), and every one '
              'discovered is matched, so that they get every sample from the first; 0 = '
              'start at once (live node only)', kind='int',
              low=0, high=1000, read_only=True),
    ParamSpec('wait_for_controller', False, 'before t = 0, also wait for a controller: a '
              'matched publisher on a command topic whose node\'s state subscriptions are '
              'discovered and matched, so that its first state is that of t = 0 (its mission '
              'clock starts there); lockstep implies it (live node only)', kind='bool',
              read_only=True),
    ParamSpec('wait_for_subscribers_timeout', 10.0, 'longest wait for those subscribers (wall '
              'time); then the run starts anyway, with a warning naming the topics without '
              'them', kind='float', unit='s', low=0.0, high=1e6, read_only=True),
    ParamSpec('lockstep', False, 'hold every control instant until the command stamped with '
              'that instant\'s state stamp arrives (engine/lockstep.py; needs publish_clock)',
              kind='bool', read_only=True),
    ParamSpec('control_rate', 50.0, 'with lockstep: the controller\'s control_rate; its '
              'instants are the multiples of its period in sim time', kind='float', unit='Hz',
              low=0.0, high=10000.0, low_open=True, read_only=True,
              note='the publish rate must be a whole multiple of it'),
    ParamSpec('lockstep_timeout', 1.0, 'with lockstep: wall time without the held instant\'s '
              'command after which the simulator reports that it is paused (it keeps '
              'waiting, never guesses)', kind='float', unit='s', low=0.0, high=1e6,
              low_open=True),
    ParamSpec('cpu_affinity', -1, 'pin every thread of the simulator\'s process (its own and '
              'the middleware\'s) to this CPU core (Linux); -1 = off, the OS places them '
              '(live node only; nodes/process.py: pin_process)', kind='int', low=-1, high=65535,
              read_only=True, note='in lockstep, the controller on the same core lowers the '
              'simulator\'s CPU per exchange; a core kept for them (docs/live-nodes.md)'),
    # [''], not []: rclpy types an empty list as a byte array, and then refuses a list of names
    ParamSpec('spacecraft', [''], 'names of the spacecraft this simulator runs, each with its '
              'topics under <name>/ and its own values under <name>.<key> (engine/fleet.py); '
              'none (empty names are ignored) = one unnamed spacecraft in the node\'s '
              'namespace', kind='string_array', read_only=True),
) + ACTUATORS + sensor_specs.SIMULATOR + ENVIRONMENT  # wheels and CMGs (actuator_specs); seed,
# sensors.*; the orbit and the environment's torques (environment_specs)

# What the simulator node declares besides SIMULATOR: the scene it runs, for a recording's
# run record (nodes/recorder.py stores them, with the keys of the offline run's record).
# Not physics: scene files and offline runs never set them, the engine never reads them.
SCENE_RECORD = (
    ParamSpec('scene.name', '', 'name of the scene run: the params file\'s scene.name, else '
              'the first params file\'s name without .yaml; empty without a params file',
              kind='string', read_only=True),
    ParamSpec('scene.sha256', '', 'SHA-256 (hex) of the bytes of the --params-file(s), in '
              'order (one file: that file\'s hash, as rigid-body-sim run records it); empty '
              'without a params file', kind='string', read_only=True),
)
SIMULATOR_DECLARED = SIMULATOR + SCENE_RECORD  # every parameter the simulator node declares

D = control.PARAMETER_DEFAULTS
CONTROLLER = (
    ParamSpec('mode', D['mode'], 'detumble: tau = -K_w w; slew: go to the target and hold; '
              'off: zero torque; bdot: the magnetorquers\' dipole m = -k dB/dt / |B|^2 from '
              'magnetic_field, on dipole_command (bdot.*)', kind='string',
              choices=control.MODES, false_is='off',
              note='switchable at runtime'),
    ParamSpec('inertia', D['inertia'], 'inertia of the controlled body: 3 principal moments or '
              '9 values row-major, body frame (same format as the simulator\'s)',
              kind='float_array', unit='kg*m^2', sizes=(3, 9),
              note='positive definite, symmetric, triangle inequalities'),
    ParamSpec('control_rate', D['control_rate'], 'rate of torque_command (node clock)',
              kind='float', unit='Hz', low=0.0, high=10000.0, low_open=True),
    ParamSpec('natural_frequency', D['natural_frequency'], 'slew natural frequency w_n, one '
              'value or one per principal axis: kp = 2 I w_n^2, kd = 2 zeta w_n I',
              kind='float_array', unit='rad/s', sizes=(1, 3), low=0.0, low_open=True,
              scalar_ok=True, note='ignored when kp and kd are set'),
    ParamSpec('damping_ratio', D['damping_ratio'], 'slew damping ratio zeta (1 = critical), '
              'one value or one per principal axis', kind='float_array', sizes=(1, 3), low=0.0,
              low_open=True, scalar_ok=True),
    ParamSpec('kp', D['kp'], 'direct proportional gains per principal axis on the error '
              'quaternion vector part; all zero = from natural_frequency/damping_ratio',
              kind='float_array', unit='N*m', sizes=(3,), low=0.0,
              note='set both kp and kd (they then win), or neither'),
    ParamSpec('kd', D['kd'], 'direct rate gains per principal axis; all zero = from '
              'natural_frequency/damping_ratio', kind='float_array', unit='N*m*s', sizes=(3,),
              low=0.0),
    ParamSpec('rate_gain', D['rate_gain'], 'detumble gain K_w: 0 = kd (proportional to '
              'inertia, |L| decays as exp(-2 zeta w_n t)); one value = isotropic; three = per '
              'principal axis', kind='float_array', unit='N*m*s', sizes=(1, 3), low=0.0,
              scalar_ok=True),
    ParamSpec('gyroscopic_compensation', D['gyroscopic_compensation'],
              'add w x Iw to the slew torque', kind='bool'),
    ParamSpec('max_torque', D['max_torque'], 'bound on the Euclidean norm of the commanded '
              'torque (vector scaled, direction kept; the slew rate is limited to match); '
              '0 = unlimited', kind='float', unit='N*m', low=0.0, high=1e9),
    ParamSpec('max_rate', D['max_rate'], 'bound on the commanded slew rate; 0 = from '
              'max_torque only', kind='float', unit='rad/s', low=0.0, high=1e9),
    ParamSpec('state_timeout', 0.5, 'state older than this (node clock vs. message stamps) '
              'gives zero torque', kind='float', unit='s', low=0.0, high=1e6, low_open=True),
    ParamSpec('target_attitude', D['target_attitude'], 'slew target (x, y, z, w) in the '
              'attitude\'s frame_id; attitude_target messages replace it until this is set '
              'again', kind='float_array', sizes=(4,),
              note='unit quaternion (|norm - 1| <= 1e-3)'),
    ParamSpec('mission.free_time', D['mission.free_time'], 'free phase: no torque for this '
              'long after the first state received (state time)', kind='float', unit='s',
              low=0.0, high=1e9),
    ParamSpec('mission.detumble_exit_rate', D['mission.detumble_exit_rate'], 'in detumble '
              '(or bdot), switch to slew once |w| falls below this; 0 = never', kind='float',
              unit='rad/s', low=0.0, high=1e6),
    ParamSpec('bdot.gain', 0.0, 'B-dot gain k (m = -k dB/dt / |B|^2); 0 = Avanzini-Giulietti '
              '2n(1 + sin xi_m) I_min from bdot.orbit_rate and bdot.magnetic_inclination',
              kind='float', unit='kg*m^2/s', low=0.0, high=1e9),
    ParamSpec('bdot.orbit_rate', 0.0, 'orbit mean motion n for the B-dot gain rule',
              kind='float', unit='rad/s', low=0.0, high=1.0),
    ParamSpec('bdot.magnetic_inclination', 1.5707963267948966, 'inclination xi_m of the orbit '
              'to the geomagnetic equator, for the B-dot gain rule', kind='float', unit='rad',
              low=0.0, high=3.141592653589793),
    ParamSpec('bdot.max_dipole', [0.0, 0.0, 0.0], 'the rods\' largest dipoles the B-dot '
              'command is clipped to (the simulator clips to its own too); all zero = no clip',
              kind='float_array', unit='A*m^2', sizes=(3,), low=0.0, high=1e6),
    ParamSpec('child_frame_id', 'base_link', 'body frame: frame_id of torque_command',
              kind='string'),
    ParamSpec('qos', 'reliable', 'QoS of state subscriptions and torque_command',
              kind='string', choices=QOS_CHOICES, read_only=True),
    ParamSpec('lockstep', False, 'answer each state at a control instant (stamp a multiple of '
              'the control period) at once, with a command stamped with that state\'s stamp, '
              'instead of on a timer (the simulator\'s lockstep)', kind='bool', read_only=True,
              note='needs feedback truth and the simulator\'s publish_clock'),
) + sensor_specs.CONTROLLER  # feedback, estimator.*


def frame_id_problem(frame: str) -> Optional[str]:
    """Why ``frame`` is not a usable tf2 frame id (None if fine): empty, leading '/', spaces."""
    if not frame:
        return 'must not be empty'
    if frame.startswith('/'):
        return 'must not start with "/" (tf2 frame ids are relative)'
    if any(c.isspace() for c in frame):
        return 'must not contain whitespace'
    return None


def check_frames(p, keys=('frame_id', 'child_frame_id')):
    """ValueError(reason) if a frame id in ``p`` is unusable or the two coincide."""
    for name in keys:
        if name in p:
            problem = frame_id_problem(p[name])
            if problem:
                raise ValueError(f'{name} {p[name]!r} {problem}')
    if 'frame_id' in p and p.get('frame_id') == p.get('child_frame_id'):
        raise ValueError(f'frame_id and child_frame_id must differ (both {p["frame_id"]!r})')
