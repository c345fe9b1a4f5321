"""What each node executable answers to ``-h``/``--help``, and the checks of its ROS
arguments that need no ROS.

``nodes.entry`` calls :func:`answer` before it imports the node's module: help never
starts ROS, never writes a file, and costs only the parameter specs' import. The
parameter list comes from the very specs the node declares (``engine.specs``,
``viewer.specs``, ``node_interfaces``); the example is spelled for the setup it runs in
(``rigid_body_sim.command``: the venv's script or ``ros2 run``).
"""
import os
import sys
import textwrap
from dataclasses import dataclass
from typing import Callable, List, Optional, Tuple

from .. import command

HELP = ('-h', '--help')


@dataclass(frozen=True)
class Executable:
    node: str                # the node's default name
    purpose: str
    specs: Callable[[], tuple]  # the parameter specs the node declares (imported on demand)
    topics: Tuple[str, ...]
    services: Tuple[str, ...]
    example: str             # arguments after the executable's name; {scene} = a scene file
    extra: str = ''


def _simulator_specs():
    from ..engine import specs
    return specs.SIMULATOR_DECLARED


def _controller_specs():
    from ..engine import specs
    return specs.CONTROLLER


def _viewer_specs():
    from ..viewer.specs import VIEWER
    return VIEWER


def _recorder_specs():
    from ..node_interfaces import RECORDER_PARAMETERS as RECORDER
    return RECORDER


SCENES = ('Scenes: a node takes a scene as a params file, '
          '--ros-args --params-file {config}/<scene>.yaml ({cli} scenes lists them).')

EXECUTABLES = {
    'simulator': Executable(
        'attitude_simulator',
        'Live rigid-body attitude simulation on standard ROS 2 topics, paced against the '
        'wall clock (or as fast as possible).',
        _simulator_specs,
        ('pub attitude (geometry_msgs/QuaternionStamped, base_link -> world)',
         'pub pose, transform (PoseStamped, TransformStamped); /tf (tf2_msgs/TFMessage)',
         'pub odometry (nav_msgs/Odometry); imu (sensor_msgs/Imu)',
         'pub angular_velocity, angular_momentum_body (Vector3Stamped, body frame), '
         'angular_momentum (world)',
         'pub kinetic_energy (std_msgs/Float64); /diagnostics (DiagnosticArray, 1 Hz)',
         'pub /clock (rosgraph_msgs/Clock) with publish_clock: true',
         'pub gyro (Imu), star_tracker (QuaternionStamped) with sensors.*.enabled',
         'pub wheel_states, gimbal_states (sensor_msgs/JointState) with actuators',
         'pub magnetic_field (sensor_msgs/MagneticField) with magnetometer.enabled',
         'sub torque_command (geometry_msgs/Vector3Stamped, body frame, N*m), '
         'wrench_command (WrenchStamped)',
         'sub actuator_command (std_msgs/Float64MultiArray) with actuators',
         'sub dipole_command (Vector3Stamped, body frame, A*m^2) with magnetorquers'),
        ('~/reset (std_srvs/Trigger): back to the initial state',
         '~/get_simulator_features, ~/get_simulation_state, ~/set_simulation_state, '
         '~/step_simulation, ~/simulate_steps (action), ~/reset_simulation, '
         '~/get_entities, ~/get_entities_states, ~/get_entity_info, ~/get_entity_state, '
         '~/set_entity_state, ~/get_available_worlds, ~/load_world, ~/get_current_world '
         '(simulation_interfaces, where installed)'),
        '--ros-args --params-file {scene}'),
    'controller': Executable(
        'attitude_controller',
        'Detumble and slew the simulated (or a real) spacecraft: torque_command at '
        'control_rate from the attitude state.',
        _controller_specs,
        ('sub attitude (QuaternionStamped), angular_velocity (Vector3Stamped); with '
         'feedback: sensors, gyro (Imu) and star_tracker (QuaternionStamped) instead',
         'sub attitude_target (QuaternionStamped): replaces target_attitude',
         'pub torque_command (geometry_msgs/Vector3Stamped, body frame, N*m); /diagnostics',
         'mode bdot: sub magnetic_field (MagneticField), pub dipole_command (A*m^2)'),
        (),
        '--ros-args --params-file {config}/slew.yaml'),
    'recorder': Executable(
        'mcap_recorder',
        'Record topics into a rosbag2-compatible MCAP bag (rigid-body-sim bag info reads '
        'it); Ctrl-C finishes the bag.',
        _recorder_specs,
        ('sub the parameter topics (default: what the simulator and controller publish), '
         'each once a publisher is seen',),
        (),
        '--ros-args -p output:=out/my_run'),
    'viewer': Executable(
        'attitude_viewer',
        'The live simulation in Foxglove, served over a WebSocket from this process '
        '(default ws://127.0.0.1:8765).',
        _viewer_specs,
        ('sub imu (sensor_msgs/Imu), attitude_target (QuaternionStamped), /diagnostics',
         'pub /diagnostics (this node\'s status)'),
        (),
        '--ros-args -p port:=8766'),
}


def _value(v) -> str:
    if isinstance(v, bool):
        return 'true' if v else 'false'
    if isinstance(v, str):
        return repr(v)
    if isinstance(v, (list, tuple)):
        return '[' + ', '.join(_value(x) for x in v) + ']'
    return repr(v)  # 1.0, not 1: a params file needs the type the node declares


KIND_TEXT = {'float': 'number', 'int': 'integer', 'bool': 'true|false', 'string': 'text',
             'float_array': 'numbers', 'string_array': 'texts'}


def parameters_text(specs) -> str:
    """One entry per spec: name, kind, unit, default; then description and constraints."""
    lines = []
    for s in specs:
        unit = f', {s.unit}' if s.unit else ''
        lines.append(f'  {s.name} ({KIND_TEXT[s.kind]}{unit}), default {_value(s.default)}')
        more = '; '.join(p for p in (s.constraints(), 'start-up only' if s.read_only else '')
                         if p)
        body = s.description + (f' [{more}]' if more else '')
        lines += textwrap.wrap(body, 88, initial_indent=' ' * 6, subsequent_indent=' ' * 6)
    return '\n'.join(lines)


def _display(path: str) -> str:
    rel = os.path.relpath(path)
    return path if rel.startswith(os.pardir) else rel


def config_dir() -> str:
    """The scenes' folder as a user would type it here: ``config`` in the checkout (as the
    README spells it), else the installed one (relative when under the cwd)."""
    if os.path.isfile(os.path.join('config', 'tennis_racket.yaml')):
        return 'config'
    from ..scene import config_dir as scenes
    return _display(scenes())


def _items(items) -> List[str]:
    return [line for item in items for line in textwrap.wrap(
        item, 88, initial_indent='  ', subsequent_indent='      ')]


def node_help(name: str) -> str:
    """The text of ``NAME --help`` for a node executable."""
    e = EXECUTABLES[name]
    exe, config = command(name), config_dir()
    scene = os.path.join(config, 'tennis_racket.yaml')
    parts = [f'usage: {exe} [-h] [--ros-args [--params-file FILE] [-p NAME:=VALUE] '
             f'[-r __ns:=/NS] ...]',
             '', textwrap.fill(f'{e.purpose} Node name: {e.node}.', 88), '',
             'Parameters (-p NAME:=VALUE, or a params file):',
             parameters_text(e.specs()), '',
             'Topics (relative names, remappable):', *_items(e.topics)]
    if e.services:
        parts += ['Services and actions:', *_items(e.services)]
    if name in ('simulator', 'controller'):
        parts += ['', textwrap.fill(SCENES.format(config=config, cli=command('rigid-body-sim')),
                                    88)]
    parts += ['', 'Example:', f'  {exe} {e.example.format(scene=scene, config=config)}']
    return '\n'.join(parts) + '\n'


def wants_help(argv: List[str]) -> bool:
    """-h/--help among the arguments before ``--ros-args``."""
    for arg in argv:
        if arg == '--ros-args':
            return False
        if arg in HELP:
            return True
    return False


def ros_sources(argv=None) -> List[Tuple[str, str]]:
    """('file', path) and ('param', 'name:=value') of the process's --ros-args, in order."""
    argv = sys.argv if argv is None else argv
    out, ros = [], False
    args = iter(argv)
    for a in args:
        if a == '--ros-args':
            ros = True
        elif a == '--':
            ros = False
        elif ros and a == '--params-file':
            out.append(('file', next(args, '')))
        elif ros and a in ('-p', '--param'):
            out.append(('param', next(args, '')))
    return out


def ros_arguments(argv=None) -> Tuple[List[str], dict]:
    """(params files, {name: 'name:=value'} of -p overrides) in the process's --ros-args."""
    sources = ros_sources(argv)
    return ([value for kind, value in sources if kind == 'file'],
            {value.split(':=', 1)[0]: value for kind, value in sources if kind == 'param'})


def ros_arguments_problem(argv) -> Optional[str]:
    """Why the ``--ros-args`` cannot start a node, where rcl's own answer would be a raw
    error with C source paths (a params file that does not exist); None if fine."""
    for path in ros_arguments(argv)[0]:
        if not path:
            return '--params-file needs a file'
        if not os.path.isfile(path):
            return f'--params-file {path}: no such file'
    return None


def scene_hint() -> str:
    """How a node takes a scene (for ``-p scene:=...`` on a node that has no such
    parameter)."""
    return ('; a node takes a scene as a params file: --ros-args --params-file '
            f'{os.path.join(config_dir(), "<scene>.yaml")}')


def answer(name: str, argv: List[str]) -> Optional[int]:
    """Help or an argument error for executable ``name`` before its node is imported:
    the exit code, or None to go on and start the node."""
    if name in EXECUTABLES and wants_help(argv[1:]):
        sys.stdout.write(node_help(name))
        return 0
    if name == 'replay' and wants_help(argv[1:]):
        from .replay_args import parser
        parser().print_help()
        return 0
    problem = ros_arguments_problem(argv)
    if problem:
        node = EXECUTABLES[name].node if name in EXECUTABLES else f'mcap_{name}'
        print(f'[FATAL] [{node}]: {problem}', file=sys.stderr)
        return 2
    return None
