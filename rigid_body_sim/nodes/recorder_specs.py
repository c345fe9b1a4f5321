"""The recorder node's parameters (``mcap_recorder``): one spec list, free of ROS.

The node declares these (``nodes/recorder.py``) and ``recorder --help`` prints them
(``nodes/usage.py``), so the two cannot drift apart.
"""
from ..param_spec import ParamSpec

# What the simulator and controller publish (relative names resolve in our namespace).
# /clock is left out: replay --clock regenerates it from the log time. /tf appears only
# where tf2_msgs is installed.
DEFAULT_TOPICS = [
    'attitude', 'pose', 'transform', 'odometry', 'angular_velocity', 'angular_momentum',
    'angular_momentum_body', 'kinetic_energy', 'imu', 'torque_command', 'wrench_command',
    'attitude_target', '/diagnostics', '/tf', 'gyro', 'star_tracker',
    'wheel_states', 'gimbal_states', 'actuator_command',  # scenes with wheels / CMGs
]
# where a bag goes without -p output: under out/ (ignored by git), named by the start time
DEFAULT_OUTPUT_DIR = 'out'

RECORDER = (
    ParamSpec('topics', DEFAULT_TOPICS, 'topics to record (relative names resolve in the '
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
    ParamSpec('scene', '', 'scene name stored in the run configuration', kind='string'),
)
