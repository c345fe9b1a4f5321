"""Shared helpers for the package's ROS 2 node shells: parameters, QoS, diagnostics.

The parameter specs themselves are ROS-free (``rigid_body_sim.engine.specs``); here they
become ROS parameter descriptors and validators. Also: QoS profiles, diagnostics
messages and time stamps.

Parameters
----------
::

    values = declare_parameters(node, specs.SIMULATOR)  # {name: coerced}; ValueError if bad
    def on_set(params):                                 # add_on_set_parameters_callback
        return validate_update(specs.SIMULATOR, values, params, check)

Numeric parameters are declared with ``dynamic_typing`` so that a params file may write
``1`` where ``1.0`` is meant (a classic ROS 2 trap); :meth:`ParamSpec.coerce` then accepts
integers and doubles, rejects everything else, and checks the range with a readable reason.
"""
from typing import Any, Dict, Iterable, List, Mapping, Sequence

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor,
                                ParameterType, SetParametersResult)
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy,
                       qos_profile_sensor_data)

from .. import params_file
from ..engine import specs as engine_specs
from ..param_spec import ParamSpec
from ..engine.specs import QOS_CHOICES, frame_id_problem  # noqa: F401 (re-exported)
from .usage import ros_arguments, ros_sources, scene_hint

# declared by rclpy on every node, or scene metadata the nodes read from '/**'
AUTOMATIC = {'use_sim_time', 'start_type_description_service', 'scene.name',
             'scene.description'}
# what a wildcard section of a scene may hold: any of the package's node parameters
SHARED = {s.name for s in engine_specs.SIMULATOR + engine_specs.CONTROLLER} | AUTOMATIC

# --- QoS ---------------------------------------------------------------------------------
# QOS_CHOICES (imported above): names accepted by :func:`qos_profile` (the ``qos`` parameter).


def qos_profile(name: str = 'reliable', depth: int = 10) -> QoSProfile:
    """QoS for state topics.

    ``reliable``: reliable, keep-last ``depth``, volatile — what default subscribers,
    ``ros2 topic echo`` and rosbag2 expect. ``sensor_data``: best effort, keep-last 5
    (ROS' sensor-data profile) for high-rate consumers that prefer fresh over complete.
    """
    if name == 'reliable':
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                          reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
    if name == 'sensor_data':
        return qos_profile_sensor_data
    raise ValueError(f'unknown qos {name!r}; choose one of {", ".join(QOS_CHOICES)}')


# --- parameters --------------------------------------------------------------------------

def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """The ROS parameter descriptor of a spec (shown by ``ros2 param describe``)."""
    text = spec.description + (f' [{spec.unit}]' if spec.unit else '')
    d = ParameterDescriptor(name=spec.name, description=text, read_only=spec.read_only,
                            additional_constraints=spec.constraints())
    if spec.kind in ('float', 'float_array'):
        d.dynamic_typing = True  # accept 1 for 1.0 from params files; coerce() checks the type
        if spec.kind == 'float' and spec.low is not None and spec.high is not None:
            d.floating_point_range = [FloatingPointRange(
                from_value=float(spec.low), to_value=float(spec.high), step=0.0)]
    elif spec.kind == 'int':
        d.type = ParameterType.PARAMETER_INTEGER
        if spec.low is not None and spec.high is not None:
            d.integer_range = [IntegerRange(from_value=int(spec.low), to_value=int(spec.high),
                                            step=1)]
    elif spec.kind == 'bool':
        d.type = ParameterType.PARAMETER_BOOL
    elif spec.kind == 'string_array':
        d.type = ParameterType.PARAMETER_STRING_ARRAY
    elif spec.false_is is not None:
        d.dynamic_typing = True  # YAML's unquoted `off` arrives as false; coerce() maps it
    else:
        d.type = ParameterType.PARAMETER_STRING
    return d


def _value(parameter: Parameter):
    v = parameter.value
    return list(v) if parameter.type_ in (Parameter.Type.DOUBLE_ARRAY,
                                          Parameter.Type.INTEGER_ARRAY) else v


def _same(a, b) -> bool:
    """Equal in value and in rcl type (10 is not 10.0 for rcl)."""
    return params_file.rcl_type(a) == params_file.rcl_type(b) and a == b


def overridden_warnings(node, argv=None) -> List[str]:
    """One line per parameter whose last value on the command line is not the one the node
    got (rcl's precedence, or a type that differs from an earlier value's): the key, the
    value that won and where each came from. Files that cannot be read are left to
    :func:`check_overrides`."""
    fqn = node.get_fully_qualified_name()
    try:
        given, kept = params_file.given_values(ros_sources(argv), fqn)
    except params_file.ParamsFileError:
        return []
    actual = getattr(node, '_parameter_overrides', {})
    lines = []
    for name, values in given.items():
        last, won = values[-1], kept.get(name)
        if name in actual:  # rclpy's own answer is the truth; ours names the origin
            value = _value(actual[name])
            if won is None or not _same(won.value, value):
                won = params_file.Value(value, 'an unknown source')
        if won is None or (won.section == last.section and _same(won.value, last.value)):
            continue
        if params_file.rcl_type(won.value) != params_file.rcl_type(last.value):
            why = (f'its type ({params_file.rcl_type(last.value)}) differs from '
                   f'{params_file.rcl_type(won.value)}: rcl keeps both and rclpy takes the '
                   f'{params_file.rcl_type(won.value)}; write it as the other values are written')
        else:
            why = ('rcl applies the node sections in the order they first appear, later ones '
                   "winning, and -p values go to '/**'; give it in a section that comes later, "
                   'or set it at run time (ros2 param set)')
        lines.append(f'parameter {name}: {last.value!r} from {last.section} is overridden: '
                     f'{won.value!r} from {won.section} is in effect ({why})')
    return lines


def _origin(node, name: str, files) -> str:
    """Where an override of ``name`` came from: 'FILE: SECTION: ' or '-p ' or ''."""
    fqn = node.get_fully_qualified_name()
    where = ''
    for path in files:  # the last file that sets it wins, as in rcl
        try:
            found = params_file.node_parameters(path, fqn).get(name)
        except params_file.ParamsFileError:
            continue
        if found is not None:
            where = f'{path}: {found.section}: '
    return where


def check_overrides(node, specs: Sequence[ParamSpec], argv=None) -> None:
    """Refuse overrides ``node`` does not declare (rclpy would ignore them silently): a
    key in a params-file section naming this node or given with -p must be one of its
    parameters; a wildcard section may hold any of the package's nodes' parameters.
    ValueError listing each problem with the file, the section, the key and the closest
    valid key."""
    own = {s.name for s in specs} | AUTOMATIC
    fqn = node.get_fully_qualified_name()
    files, cli = ros_arguments(argv)
    problems, seen = [], set(cli)
    for path in files:
        try:
            problems += params_file.unknown_keys(path, fqn, own, SHARED | own)
            seen.update(params_file.node_parameters(path, fqn))
        except params_file.ParamsFileError as exc:
            problems.append(str(exc))
    problems += [f'-p {text}: {name}: unknown parameter of {fqn}'
                 f'{scene_hint() if name == "scene" else params_file.closest(name, own)}'
                 for name, text in cli.items() if name not in own]
    # anything else rcl handed over (e.g. from files given some other way)
    for name in getattr(node, '_parameter_overrides', {}):
        if name not in own | SHARED and name not in seen:
            problems.append(f'{name}: unknown parameter of {fqn}'
                            f'{params_file.closest(name, own)}')
    if problems:
        raise ValueError('; '.join(problems))


def declare_parameters(node, specs: Sequence[ParamSpec], argv=None,
                       check: bool = True) -> Dict[str, Any]:
    """Declare ``specs`` on ``node`` (overrides from params files apply) and return coerced values.

    Raises ValueError with a readable reason if an override is not a parameter of the
    node, or has the wrong type or range (naming the params file and section it came
    from). Call before registering on-set callbacks, or they see the declarations too.
    ``check``: False when the caller declares in parts and has run :func:`check_overrides`
    on them all (the simulator's spacecraft keys).
    """
    if check:
        check_overrides(node, specs, argv)
        for line in overridden_warnings(node, argv):
            node.get_logger().warning(line)
    files = ros_arguments(argv)[0]
    values = {}
    for spec in specs:
        try:
            param = node.declare_parameter(spec.name, spec.default, descriptor(spec))
            values[spec.name] = spec.coerce(_value(param))
        except Exception as exc:  # rclpy raises InvalidParameterValueException / TypeError
            raise ValueError(f'{_origin(node, spec.name, files)}parameter {spec.name}: '
                             f'{exc}') from None
    return values


def coerce_parameters(specs: Iterable[ParamSpec],
                      parameters: Iterable[Parameter]) -> Dict[str, Any]:
    """{name: value} for the given parameters that appear in ``specs``; ValueError(reason) if
    invalid.

    Parameters not in ``specs`` are ignored (e.g. ``use_sim_time``).
    """
    by_name = {s.name: s for s in specs}
    out = {}
    for p in parameters:
        spec = by_name.get(p.name)
        if spec is not None:
            out[p.name] = spec.coerce(_value(p))
    return out


def validate_update(specs: Sequence[ParamSpec], current: Mapping[str, Any],
                    parameters: Iterable[Parameter], check) -> SetParametersResult:
    """The on-set-parameters answer: coerce, merge into ``current``, cross-check with
    ``check(merged)``.

    Any ValueError becomes ``successful=False`` with its message as the reason.
    """
    parameters = list(parameters)
    names = {s.name for s in specs}
    for p in parameters:  # rclpy's own refusal names no parameter: say which and why
        if p.name not in names | AUTOMATIC:
            return SetParametersResult(
                successful=False, reason=f'{p.name}: not a parameter of this node'
                f'{params_file.closest(p.name, names)}')
    try:
        check(dict(current, **coerce_parameters(specs, parameters)))
    except ValueError as exc:
        return SetParametersResult(successful=False, reason=str(exc))
    return SetParametersResult(successful=True)


def changed_values(specs: Sequence[ParamSpec], current: Mapping[str, Any],
                   parameters: Iterable[Parameter]) -> Dict[str, Any]:
    """{name: new value} for the parameters whose coerced value differs from ``current``."""
    return {k: v for k, v in coerce_parameters(specs, parameters).items() if current.get(k) != v}


# --- time ------------------------------------------------------------------------------

def stamp_to_seconds(stamp: Time) -> float:
    return stamp.sec + 1e-9 * stamp.nanosec


# --- diagnostics -----------------------------------------------------------------------

LEVELS = {'OK': DiagnosticStatus.OK, 'WARN': DiagnosticStatus.WARN,
          'ERROR': DiagnosticStatus.ERROR, 'STALE': DiagnosticStatus.STALE}


def format_value(value) -> str:
    """Diagnostic value text: floats with 9 significant digits, bools lower-case."""
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return f'{value:.9g}'
    return str(value)


def diagnostic_status(name: str, hardware_id: str, level: str, message: str,
                      values: Mapping[str, Any]) -> DiagnosticStatus:
    """A DiagnosticStatus with ``level`` 'OK' | 'WARN' | 'ERROR' | 'STALE' and key-values."""
    return DiagnosticStatus(level=LEVELS[level], name=name, hardware_id=hardware_id,
                            message=message,
                            values=[KeyValue(key=k, value=format_value(v))
                                    for k, v in values.items()])
