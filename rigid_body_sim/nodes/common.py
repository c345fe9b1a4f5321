"""Shared helpers for the package's ROS 2 node shells (simulator, controller, ...).

Nothing here knows about a particular node: it turns declarative parameter specs into
ROS parameter descriptors and validators, parses physics inputs given as parameters,
builds the standard QoS profiles and diagnostics messages, and converts time stamps.

Parameters
----------
Declare a node's parameters from a tuple of :class:`ParamSpec`::

    SPECS = (
        ParamSpec('step', 0.001, 'physics step', kind='float', unit='s', low=0.0, low_open=True),
        ParamSpec('integrator', 'auto', 'method name', kind='string', choices=('auto', 'rk4')),
    )
    values = declare_parameters(node, SPECS)          # {name: coerced value}; ValueError on bad input
    ...
    def on_set(params):                               # add_on_set_parameters_callback
        try:
            new = coerce_parameters(SPECS, params)    # {name: coerced value} or ValueError(reason)
        except ValueError as exc:
            return SetParametersResult(successful=False, reason=str(exc))

Numeric parameters are declared with ``dynamic_typing`` so that a params file may write
``1`` where ``1.0`` is meant (a classic ROS 2 trap); :meth:`ParamSpec.coerce` then accepts
integers and doubles, rejects everything else, and checks the range with a readable reason.
"""
from dataclasses import dataclass
import math
from typing import Any, Dict, Iterable, Mapping, Optional, Sequence, Tuple

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rcl_interfaces.msg import (FloatingPointRange, IntegerRange, ParameterDescriptor, ParameterType,
                                 SetParametersResult)
from rclpy.parameter import Parameter
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy,
                       qos_profile_sensor_data)

# --- QoS ---------------------------------------------------------------------------------

#: Names accepted by :func:`qos_profile` (the ``qos`` parameter of the nodes).
QOS_CHOICES = ('reliable', 'sensor_data')


def qos_profile(name: str = 'reliable', depth: int = 10) -> QoSProfile:
    """QoS for state topics.

    ``reliable``: reliable, keep-last ``depth``, volatile — what default subscribers,
    ``ros2 topic echo`` and rosbag2 expect. ``sensor_data``: best effort, keep-last 5
    (ROS' sensor-data profile) for high-rate consumers that prefer fresh over complete.
    """
    if name == 'reliable':
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=depth,
                          reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
    if name == 'sensor_data':
        return qos_profile_sensor_data
    raise ValueError(f'unknown qos {name!r}; choose one of {", ".join(QOS_CHOICES)}')


# --- parameters --------------------------------------------------------------------------

_KINDS = ('float', 'int', 'bool', 'string', 'float_array')
_NUMERIC_TYPES = (ParameterType.PARAMETER_DOUBLE, ParameterType.PARAMETER_INTEGER)
_ARRAY_TYPES = (ParameterType.PARAMETER_DOUBLE_ARRAY, ParameterType.PARAMETER_INTEGER_ARRAY)


@dataclass(frozen=True)
class ParamSpec:
    """One ROS parameter: default, description, unit, type and valid range.

    kind: ``float`` | ``int`` | ``bool`` | ``string`` | ``float_array``.
    low/high: bounds (``None`` = unbounded); ``low_open``/``high_open`` make them strict.
    sizes: allowed lengths of a ``float_array``; choices: allowed strings.
    read_only: can only be given at start-up (params file / ``-p``).
    note: extra constraint text shown by ``ros2 param describe`` (e.g. when a change applies).
    """
    name: str
    default: Any
    description: str
    kind: str = 'float'
    unit: str = ''
    low: Optional[float] = None
    high: Optional[float] = None
    low_open: bool = False
    high_open: bool = False
    sizes: Tuple[int, ...] = ()
    choices: Tuple[str, ...] = ()
    finite: bool = True
    read_only: bool = False
    note: str = ''

    def __post_init__(self):
        if self.kind not in _KINDS:
            raise ValueError(f'unknown parameter kind {self.kind!r}')

    # ROS descriptor ------------------------------------------------------------------
    def constraints(self) -> str:
        """Human-readable constraints (also used in rejection reasons)."""
        parts = []
        if self.kind in ('float', 'int', 'float_array'):
            lo = None if self.low is None else ('> ' if self.low_open else '>= ') + f'{self.low:g}'
            hi = None if self.high is None else ('< ' if self.high_open else '<= ') + f'{self.high:g}'
            rng = ' and '.join(p for p in (lo, hi) if p)
            if rng:
                parts.append(('each value ' if self.kind == 'float_array' else '') + rng)
        if self.sizes:
            parts.append(' or '.join(str(s) for s in self.sizes) + ' values')
        if self.choices:
            parts.append('one of: ' + ', '.join(self.choices))
        if self.note:
            parts.append(self.note)
        return '; '.join(parts)

    def descriptor(self) -> ParameterDescriptor:
        text = self.description + (f' [{self.unit}]' if self.unit else '')
        d = ParameterDescriptor(name=self.name, description=text, read_only=self.read_only,
                                additional_constraints=self.constraints())
        if self.kind in ('float', 'float_array'):
            d.dynamic_typing = True  # accept 1 for 1.0 from params files; coerce() checks the type
            if self.kind == 'float' and self.low is not None and self.high is not None:
                d.floating_point_range = [FloatingPointRange(from_value=float(self.low),
                                                             to_value=float(self.high), step=0.0)]
        elif self.kind == 'int':
            d.type = ParameterType.PARAMETER_INTEGER
            if self.low is not None and self.high is not None:
                d.integer_range = [IntegerRange(from_value=int(self.low), to_value=int(self.high), step=1)]
        elif self.kind == 'bool':
            d.type = ParameterType.PARAMETER_BOOL
        else:
            d.type = ParameterType.PARAMETER_STRING
        return d

    # validation ----------------------------------------------------------------------
    def _check_number(self, x: float, what: str) -> None:
        if self.finite and not math.isfinite(x):
            raise ValueError(f'{what} must be finite, got {x}')
        if self.low is not None and (x < self.low or (self.low_open and x == self.low)):
            raise ValueError(f'{what} = {x:g} out of range: must be {self.constraints()}')
        if self.high is not None and (x > self.high or (self.high_open and x == self.high)):
            raise ValueError(f'{what} = {x:g} out of range: must be {self.constraints()}')

    def coerce(self, parameter: Parameter):
        """The parameter's value as a Python value of this kind; ValueError(reason) if invalid."""
        t = parameter.type_.value
        v = parameter.value
        if self.kind == 'float':
            if t not in _NUMERIC_TYPES:
                raise ValueError(f'{self.name} must be a number [{self.unit or "-"}], got {v!r}')
            x = float(v)
            self._check_number(x, self.name)
            return x
        if self.kind == 'int':
            if t != ParameterType.PARAMETER_INTEGER:
                raise ValueError(f'{self.name} must be an integer, got {v!r}')
            self._check_number(int(v), self.name)
            return int(v)
        if self.kind == 'bool':
            if t != ParameterType.PARAMETER_BOOL:
                raise ValueError(f'{self.name} must be true or false, got {v!r}')
            return bool(v)
        if self.kind == 'string':
            if t != ParameterType.PARAMETER_STRING:
                raise ValueError(f'{self.name} must be a string, got {v!r}')
            if self.choices and v not in self.choices:
                raise ValueError(f'{self.name} = {v!r} is not one of: {", ".join(self.choices)}')
            return str(v)
        # float_array
        if t not in _ARRAY_TYPES:
            raise ValueError(f'{self.name} must be a list of numbers [{self.unit or "-"}], got {v!r}')
        values = [float(x) for x in v]
        if self.sizes and len(values) not in self.sizes:
            raise ValueError(f'{self.name} needs {" or ".join(map(str, self.sizes))} values, got {len(values)}')
        for i, x in enumerate(values):
            self._check_number(x, f'{self.name}[{i}]')
        return values


def declare_parameters(node, specs: Sequence[ParamSpec]) -> Dict[str, Any]:
    """Declare ``specs`` on ``node`` (overrides from params files apply) and return coerced values.

    Raises ValueError with a readable reason if an override has the wrong type or range.
    Call before registering on-set callbacks, or they see the declarations too.
    """
    values = {}
    for spec in specs:
        try:
            param = node.declare_parameter(spec.name, spec.default, spec.descriptor())
        except Exception as exc:  # rclpy raises InvalidParameterValueException / TypeError
            raise ValueError(f'parameter {spec.name}: {exc}') from None
        values[spec.name] = spec.coerce(param)
    return values


def coerce_parameters(specs: Iterable[ParamSpec], parameters: Iterable[Parameter]) -> Dict[str, Any]:
    """{name: value} for the given parameters that appear in ``specs``; ValueError(reason) if invalid.

    Parameters not in ``specs`` are ignored (e.g. ``use_sim_time``).
    """
    by_name = {s.name: s for s in specs}
    out = {}
    for p in parameters:
        spec = by_name.get(p.name)
        if spec is not None:
            out[p.name] = spec.coerce(p)
    return out


def validate_update(specs: Sequence[ParamSpec], current: Mapping[str, Any], parameters: Iterable[Parameter],
                    check) -> SetParametersResult:
    """The on-set-parameters answer: coerce, merge into ``current``, cross-check with ``check(merged)``.

    Any ValueError becomes ``successful=False`` with its message as the reason.
    """
    try:
        check(dict(current, **coerce_parameters(specs, parameters)))
    except ValueError as exc:
        return SetParametersResult(successful=False, reason=str(exc))
    return SetParametersResult(successful=True)


def changed_values(specs: Sequence[ParamSpec], current: Mapping[str, Any],
                   parameters: Iterable[Parameter]) -> Dict[str, Any]:
    """{name: new value} for the parameters whose coerced value differs from ``current``."""
    return {k: v for k, v in coerce_parameters(specs, parameters).items() if current.get(k) != v}


# --- physics inputs given as parameters -------------------------------------------------

def rigid_body_from_parameter(values):
    """RigidBody from 3 principal moments or 9 row-major values (kg·m²); ValueError(reason)."""
    from ..physics import RigidBody
    return RigidBody.from_inertia(values)


def quaternion_from_parameter(values, name: str = 'quaternion'):
    """Unit quaternion (x, y, z, w) as a numpy array, normalised; ValueError(reason)."""
    from ..physics import rotation
    return rotation.validated(list(values), name)


def frame_id_problem(frame: str) -> Optional[str]:
    """Why ``frame`` is not a usable tf2 frame id (None if fine): empty, leading '/', spaces."""
    if not frame:
        return 'must not be empty'
    if frame.startswith('/'):
        return 'must not start with "/" (tf2 frame ids are relative)'
    if any(c.isspace() for c in frame):
        return 'must not contain whitespace'
    return None


# --- time ------------------------------------------------------------------------------

def set_stamp(stamp: Time, seconds: float) -> Time:
    """Write ``seconds`` (>= 0) into a builtin_interfaces/Time in place (nanosecond rounding)."""
    ns = int(round(seconds * 1e9))
    stamp.sec, stamp.nanosec = divmod(ns, 1_000_000_000)
    return stamp


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
    return DiagnosticStatus(level=LEVELS[level], name=name, hardware_id=hardware_id, message=message,
                            values=[KeyValue(key=k, value=format_value(v)) for k, v in values.items()])
