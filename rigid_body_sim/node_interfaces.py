"""What each node publishes, subscribes to and serves, and the recorder's parameters: data,
free of ROS.

The documentation's reference pages are generated from this table and from the parameter
specs (``engine/specs.py``, ``viewer/specs.py``); ``test/test_node_interfaces.py`` starts
the real nodes and checks that their graph is exactly this table, so it cannot go stale.
Topic names are relative to the node's namespace unless they start with ``/``.

``when`` names the condition under which an entry exists (empty: always). The test turns
the conditions on or off per run, so keep them to this small vocabulary.
"""
from typing import NamedTuple, Tuple

from .param_spec import ParamSpec

# conditions (``when``)
CLOCK = 'publish_clock: true'
WHEELS = 'actuators.wheels'
CMGS = 'actuators.cmgs'
ACTUATORS = 'actuators (wheels or CMGs)'
GYRO = 'sensors.gyro'
STAR_TRACKER = 'sensors.star_tracker'
SIM_INTERFACES = 'simulation_interfaces installed'
FEEDBACK_TRUTH = 'feedback: truth, lockstep: false'
LOCKSTEP = 'lockstep: true'
FEEDBACK_SENSORS = 'feedback: sensors'
ORBIT = 'orbit.model'
GRAVITY_GRADIENT = 'environment.gravity_gradient'
ENVIRONMENT_TORQUE = ('environment.gravity_gradient, magnetorquer.max_dipole, '
                      'solar_radiation_pressure or drag')
MAGNETORQUERS = 'magnetorquer.max_dipole'
MAGNETOMETER = 'magnetometer.enabled'
BDOT = 'mode: bdot'
SUN_SENSOR = 'sun_sensor'


class Topic(NamedTuple):
    direction: str  # 'pub' | 'sub'
    name: str
    type: str       # pkg/msg/Type
    description: str
    when: str = ''


class Service(NamedTuple):
    name: str
    type: str       # pkg/srv/Type, or pkg/action/Type for an action server
    description: str
    when: str = ''


class NodeInterfaces(NamedTuple):
    name: str
    executable: str
    summary: str
    topics: Tuple[Topic, ...]
    services: Tuple[Service, ...] = ()


_SIM = 'simulation_interfaces/srv/'

SIMULATOR = NodeInterfaces('attitude_simulator', 'simulator', (
    'Integrates the rigid body against the wall clock (or as fast as possible) and publishes '
    'its state; every message of one sample carries the same sim-time stamp. With '
    'spacecraft, each one\'s topics are these under <name>/ (/tf, /clock and /diagnostics '
    'stay shared; torque_command and wrench_command here route by frame_id).'), (
    Topic('pub', 'attitude', 'geometry_msgs/msg/QuaternionStamped',
          'rotation child_frame_id -> frame_id (x, y, z, w)'),
    Topic('pub', 'pose', 'geometry_msgs/msg/PoseStamped',
          'the attitude, for Foxglove\'s 3D panel'),
    Topic('pub', 'transform', 'geometry_msgs/msg/TransformStamped', 'the attitude as a transform'),
    Topic('pub', '/tf', 'tf2_msgs/msg/TFMessage', 'frame_id -> child_frame_id, every sample; '
          'with an orbit also frame_id -> orbit.frame_id (LVLH, rotation only)'),
    Topic('pub', 'orbit', 'nav_msgs/msg/Odometry', 'position [m] and LVLH orientation in '
          'frame_id; inertial velocity [m/s] and LVLH rate [rad/s] resolved in '
          'orbit.frame_id (child_frame_id)', ORBIT),
    Topic('pub', 'environment_torque', 'geometry_msgs/msg/WrenchStamped',
          'the environment\'s torque (the sum of the terms the scene names: gravity '
          'gradient, the magnetorquers\' m x B, solar radiation pressure, drag), body frame '
          '[N*m]', ENVIRONMENT_TORQUE),
    Topic('pub', 'odometry', 'nav_msgs/msg/Odometry',
          'pose in frame_id, angular velocity in child_frame_id'),
    Topic('pub', 'angular_velocity', 'geometry_msgs/msg/Vector3Stamped', 'body frame [rad/s]'),
    Topic('pub', 'angular_momentum', 'geometry_msgs/msg/Vector3Stamped',
          'inertial frame (constant while torque-free) [kg*m^2/s]'),
    Topic('pub', 'angular_momentum_body', 'geometry_msgs/msg/Vector3Stamped',
          'body frame [kg*m^2/s]'),
    Topic('pub', 'kinetic_energy', 'std_msgs/msg/Float64', 'rotational kinetic energy [J]'),
    Topic('pub', 'imu', 'sensor_msgs/msg/Imu', 'orientation and body rate of an ideal IMU '
          '(truth: variance 1e-18; no acceleration)'),
    Topic('pub', 'wheel_states', 'sensor_msgs/msg/JointState',
          'one joint per wheel: speed relative to the body [rad/s]', WHEELS),
    Topic('pub', 'gimbal_states', 'sensor_msgs/msg/JointState',
          'one joint per CMG gimbal: angle [rad] and rate [rad/s]', CMGS),
    Topic('pub', 'gyro', 'sensor_msgs/msg/Imu', 'noisy, biased body rate (no orientation)', GYRO),
    Topic('pub', 'star_tracker', 'geometry_msgs/msg/QuaternionStamped',
          'noisy attitude fixes, none during outages', STAR_TRACKER),
    Topic('pub', 'magnetic_field', 'sensor_msgs/msg/MagneticField', 'magnetometer: the '
          'field in the body frame [T] with its bias, noise and the rods\' coupling',
          MAGNETOMETER),
    Topic('pub', 'sun_direction', 'geometry_msgs/msg/Vector3Stamped', 'unit vector to the '
          'Sun, body frame (noisy); none in the Earth\'s shadow', SUN_SENSOR),
    Topic('pub', '/clock', 'rosgraph_msgs/msg/Clock', 'sim time', CLOCK),
    Topic('pub', '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
          '1 Hz: integrator and why, real-time factor, drifts, rejected commands, deadlines'),
    Topic('sub', 'torque_command', 'geometry_msgs/msg/Vector3Stamped',
          'body-frame torque [N*m], held for command_timeout'),
    Topic('sub', 'wrench_command', 'geometry_msgs/msg/WrenchStamped', 'its torque part'),
    Topic('sub', 'dipole_command', 'geometry_msgs/msg/Vector3Stamped', 'the magnetorquers\' '
          'dipole, body frame [A*m^2], clipped per rod, held for command_timeout',
          MAGNETORQUERS),
    Topic('sub', 'actuator_command', 'std_msgs/msg/Float64MultiArray',
          'N wheel torques then K gimbal rates (actuators.command: forward)', ACTUATORS),
    Topic('sub', 'robot_joint_commands', 'sensor_msgs/msg/JointState',
          'ros2_control joint_state_topic_hardware_interface: wheel effort [N*m], gimbal '
          'velocity [rad/s] (actuators.command: forward)', ACTUATORS),
), (
    Service('~/reset', 'std_srvs/srv/Trigger', 'back to the initial state; sim time goes on'),
    Service('~/get_simulator_features', _SIM + 'GetSimulatorFeatures', 'what is supported',
            SIM_INTERFACES),
    Service('~/get_simulation_state', _SIM + 'GetSimulationState', 'PLAYING, PAUSED, ...',
            SIM_INTERFACES),
    Service('~/set_simulation_state', _SIM + 'SetSimulationState',
            'PLAYING, PAUSED, STOPPED (reset and paused), QUITTING', SIM_INTERFACES),
    Service('~/step_simulation', _SIM + 'StepSimulation',
            'while paused: n sample periods, each published', SIM_INTERFACES),
    Service('~/reset_simulation', _SIM + 'ResetSimulation', 'as ~/reset', SIM_INTERFACES),
    Service('~/simulate_steps', 'simulation_interfaces/action/SimulateSteps',
            'action: as step_simulation, with feedback per step and cancellation',
            SIM_INTERFACES),
    Service('~/get_entities', _SIM + 'GetEntities',
            'the spacecraft (child_frame_id), its wheels and CMGs (<child_frame_id>/<joint>)',
            SIM_INTERFACES),
    Service('~/get_entities_states', _SIM + 'GetEntitiesStates',
            'their states (filters: regex, category, tags)', SIM_INTERFACES),
    Service('~/get_entity_info', _SIM + 'GetEntityInfo', 'category, description, tags',
            SIM_INTERFACES),
    Service('~/get_entity_state', _SIM + 'GetEntityState',
            'pose and twist of the body, or of a wheel or CMG in the body frame',
            SIM_INTERFACES),
    Service('~/set_entity_state', _SIM + 'SetEntityState', 'set attitude and rate',
            SIM_INTERFACES),
    Service('~/get_available_worlds', _SIM + 'GetAvailableWorlds', 'the scenes (config/)',
            SIM_INTERFACES),
    Service('~/load_world', _SIM + 'LoadWorld',
            'switch scenes live (refused if start-up-only parameters differ)', SIM_INTERFACES),
    Service('~/get_current_world', _SIM + 'GetCurrentWorld', 'the scene loaded last',
            SIM_INTERFACES),
    Service('~/spawn_entity', _SIM + 'SpawnEntity', 'a spacecraft at run time (name, '
            'attitude from initial_pose, body from a scene uri or resource_string)',
            SIM_INTERFACES),
    Service('~/delete_entity', _SIM + 'DeleteEntity', 'a spacecraft, with its wheels and CMGs',
            SIM_INTERFACES),
))

CONTROLLER = NodeInterfaces('attitude_controller', 'controller', (
    'Detumbles and slews the body with a quaternion PD law; runs on the true state or on '
    'the sensors through an estimator.'), (
    Topic('pub', 'torque_command', 'geometry_msgs/msg/Vector3Stamped',
          'body-frame torque [N*m] at control_rate'),
    Topic('pub', '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', 'mode, errors, status'),
    Topic('sub', 'attitude', 'geometry_msgs/msg/QuaternionStamped', 'the true attitude',
          FEEDBACK_TRUTH),
    Topic('sub', 'angular_velocity', 'geometry_msgs/msg/Vector3Stamped', 'the true body rate',
          FEEDBACK_TRUTH),
    Topic('sub', 'odometry', 'nav_msgs/msg/Odometry', 'lockstep: the true attitude and body '
          'rate in one message, instead of attitude and angular_velocity', LOCKSTEP),
    Topic('sub', 'gyro', 'sensor_msgs/msg/Imu', 'measured body rate', FEEDBACK_SENSORS),
    Topic('sub', 'star_tracker', 'geometry_msgs/msg/QuaternionStamped', 'attitude fixes',
          FEEDBACK_SENSORS),
    Topic('sub', 'attitude_target', 'geometry_msgs/msg/QuaternionStamped',
          'new slew target (NaN, zero or non-unit rejected)'),
    Topic('pub', 'dipole_command', 'geometry_msgs/msg/Vector3Stamped', 'B-dot: the '
          'magnetorquers\' dipole, body frame [A*m^2], at control_rate', BDOT),
    Topic('sub', 'magnetic_field', 'sensor_msgs/msg/MagneticField', 'B-dot: magnetometer '
          'readings', BDOT),
))

VIEWER = NodeInterfaces('attitude_viewer', 'viewer', (
    'Serves the running simulation to Foxglove over its WebSocket protocol; only '
    'subscribes, so it never disturbs the simulation.'), (
    Topic('pub', '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
          'subscriptions, samples served, rejected client messages'),
    Topic('sub', 'imu', 'sensor_msgs/msg/Imu', 'attitude and rate of each sample (a '
          'formation\'s: <name>/imu, each spacecraft the simulator lists)'),
    Topic('sub', 'orbit', 'nav_msgs/msg/Odometry', 'the orbit\'s state, for the Earth, the '
          'orbit, LVLH, the Sun and the field (<name>/orbit in a formation)'),
    Topic('sub', 'attitude_target', 'geometry_msgs/msg/QuaternionStamped', 'the slew target'),
    Topic('sub', '/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray',
          'served to Foxglove; the simulator\'s reset count, spacecraft and sim time'),
))

RECORDER = NodeInterfaces('mcap_recorder', 'recorder', (
    'Records topics into a rosbag2-compatible MCAP bag; subscribes to the default topics at '
    'its start (so a simulator waiting for subscribers starts at t = 0 with it), and to '
    'others once a publisher appears, with a QoS compatible with its publishers.'), (
    Topic('sub', '(each recorded topic)', '(its publishers\' type)',
          'the default list, or every topic with all: true'),
    Topic('pub', '~/matched_publishers', 'std_msgs/msg/String', 'JSON: what it records and '
          'the publishers each subscription has matched, at each change (transient local; '
          'a simulator in lockstep waits for it)'),
))

NODES = (SIMULATOR, CONTROLLER, VIEWER, RECORDER)

# What the simulator and controller publish (relative names resolve in the recorder's
# namespace). /clock is left out: replay --clock regenerates it from the log time. /tf
# appears only where tf2_msgs is installed.
RECORDED_BY_DEFAULT = [
    'attitude', 'pose', 'transform', 'odometry', 'angular_velocity', 'angular_momentum',
    'angular_momentum_body', 'kinetic_energy', 'imu', 'torque_command', 'wrench_command',
    'attitude_target', '/diagnostics', '/tf', 'gyro', 'star_tracker',
    'wheel_states', 'gimbal_states', 'actuator_command',  # scenes with wheels / CMGs
    'orbit', 'environment_torque',  # scenes with an orbit (as offline bags carry them)
    'magnetic_field', 'dipole_command',  # scenes with a magnetometer, magnetorquers
    'sun_direction',  # the sun sensor
]

# Their types, the nodes' own: the recorder subscribes to them before their publishers exist.
RECORDED_TYPES = {t.name: t.type for node in (SIMULATOR, CONTROLLER) for t in node.topics
                  if t.name in RECORDED_BY_DEFAULT}
assert set(RECORDED_TYPES) == set(RECORDED_BY_DEFAULT), 'a default topic with no type'

# where a bag goes without -p output: under out/ (ignored by git), named by the start time
DEFAULT_OUTPUT_DIR = 'out'

# The recorder declares these (nodes/recorder.py) and `recorder --help` prints them
# (nodes/usage.py), so the node, its help and the docs' reference cannot drift apart.
RECORDER_PARAMETERS = (
    ParamSpec('topics', RECORDED_BY_DEFAULT, 'topics to record (relative names resolve in the '
              'node\'s namespace); default: what the simulator and controller publish',
              kind='string_array'),
    ParamSpec('all', False, 'record every topic (hidden ones excepted)', kind='bool'),
    ParamSpec('exclude', [''], 'topics never recorded', kind='string_array'),
    ParamSpec('output', '', 'bag directory; empty = out/rigid_body_sim_<date-time>',
              kind='string', path=True),
    ParamSpec('name', '', 'file name stem inside the bag (<name>_0.mcap); empty = the '
              'directory\'s name', kind='string'),
    ParamSpec('max_bag_duration', 0.0, 'start a new file after this much log time; 0 = one '
              'file', kind='float', unit='s', low=0.0),
    ParamSpec('max_bag_size', 0, 'start a new file past this size; 0 = no limit', kind='int',
              unit='bytes', low=0),
    ParamSpec('flush_period', 1.0, 'chunks reach the disk at least this often (what a crash '
              'can lose)', kind='float', unit='s', low=0.0, low_open=True),
    ParamSpec('compression', 'zstd', 'chunk compression', kind='string',
              choices=('zstd', 'lz4', 'none')),
    ParamSpec('qos_depth', 1000, 'history depth of the subscriptions (at least the '
              'publishers\')', kind='int', low=1),
    ParamSpec('discovery_period', 0.2, 'how often new publishers are looked for', kind='float',
              unit='s', low=0.0, low_open=True),
    ParamSpec('simulator_node', 'attitude_simulator', 'node whose parameters go into the '
              'bag\'s run configuration', kind='string'),
    ParamSpec('config_timeout', 10.0, 'how long to wait for them', kind='float', unit='s',
              low=0.0),
    ParamSpec('scene', '', 'scene name stored in the run configuration; empty = the '
              'simulator\'s scene.name', kind='string'),
)
