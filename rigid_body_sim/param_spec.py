"""Parameter specs: name, type, unit, range and description, free of ROS.

A :class:`ParamSpec` checks a plain Python value (what a params file or ``-p`` gives) and
returns it coerced to its kind, or raises ValueError naming the parameter and the reason.
Scene files are validated with these specs without importing rclpy; the nodes derive
their ``ParameterDescriptor`` from the same specs (``nodes/common.py``).

Numbers given as integers where a double is meant are accepted (``1`` for ``1.0``, a
classic ROS 2 params-file trap); booleans are never numbers.
"""
from dataclasses import dataclass
import math
from numbers import Integral, Real
from typing import Any, Dict, Iterable, Mapping, Optional, Tuple

KINDS = ('float', 'int', 'bool', 'string', 'float_array', 'string_array')


def _is_number(v) -> bool:
    # float and int first: the ABC check costs ~1 µs, ~90 times in building a run's config
    t = type(v)
    return t is float or t is int or isinstance(v, Real) and not isinstance(v, bool)


@dataclass(frozen=True)
class ParamSpec:
    """One parameter: default, description, unit, type and valid range.

    kind: ``float`` | ``int`` | ``bool`` | ``string`` | ``float_array`` | ``string_array``.
    low/high: bounds (``None`` = unbounded); ``low_open``/``high_open`` make them strict.
    sizes: allowed lengths of a ``float_array``; choices: allowed strings.
    scalar_ok: a ``float_array`` that also takes one number (``natural_frequency:=1.0``).
    false_is: a ``string`` that takes YAML's ``false`` as this value (an unquoted ``off``).
    path: a ``string`` naming a file or directory to write; one starting with ``-`` is
    refused (a mistyped option would otherwise become a file named like it).
    read_only: can only be given at start-up (params file / ``-p``).
    note: extra constraint text (e.g. when a change applies).
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
    scalar_ok: bool = False
    false_is: Optional[str] = None
    path: bool = False
    note: str = ''

    def __post_init__(self):
        if self.kind not in KINDS:
            raise ValueError(f'unknown parameter kind {self.kind!r}')

    def constraints(self) -> str:
        """Human-readable constraints (also used in rejection reasons)."""
        parts = []
        if self.kind in ('float', 'int', 'float_array'):
            lo = None if self.low is None else ('> ' if self.low_open else '>= ') + f'{self.low:g}'
            hi = None if self.high is None else \
                ('< ' if self.high_open else '<= ') + f'{self.high:g}'
            rng = ' and '.join(p for p in (lo, hi) if p)
            if rng:
                parts.append(('each value ' if self.kind == 'float_array' else '') + rng)
        if self.sizes:
            parts.append(' or '.join(str(s) for s in self.sizes) + ' values')
        if self.choices:
            parts.append('one of: ' + ', '.join(self.choices))
        if self.path:
            parts.append('must not start with "-"')
        if self.note:
            parts.append(self.note)
        return '; '.join(parts)

    def _check_number(self, x: float, what: str) -> None:
        if self.finite and not math.isfinite(x):
            raise ValueError(f'{what} must be finite, got {x}')
        if self.low is not None and (x < self.low or (self.low_open and x == self.low)):
            raise ValueError(f'{what} = {x:g} out of range: must be {self.constraints()}')
        if self.high is not None and (x > self.high or (self.high_open and x == self.high)):
            raise ValueError(f'{what} = {x:g} out of range: must be {self.constraints()}')

    def coerce(self, v):
        """``v`` as a Python value of this kind; ValueError(reason) if invalid."""
        if self.kind == 'float':
            if not _is_number(v):
                raise ValueError(f'{self.name} must be a number [{self.unit or "-"}], got '
                                 f'{v!r}')
            x = float(v)
            self._check_number(x, self.name)
            return x
        if self.kind == 'int':
            if not isinstance(v, Integral) or isinstance(v, bool):
                raise ValueError(f'{self.name} must be an integer, got {v!r}')
            self._check_number(int(v), self.name)
            return int(v)
        if self.kind == 'bool':
            if not isinstance(v, bool):
                raise ValueError(f'{self.name} must be true or false, got {v!r}')
            return v
        if self.kind == 'string':
            if v is False and self.false_is is not None:
                v = self.false_is
            if not isinstance(v, str):
                raise ValueError(f'{self.name} must be a string, got {v!r}')
            if self.choices and v not in self.choices:
                raise ValueError(f'{self.name} = {v!r} is not one of: {", ".join(self.choices)}')
            if self.path:
                check_output_path(v, self.name)
            return v
        if self.kind == 'string_array':
            if isinstance(v, (str, bytes)) or not hasattr(v, '__iter__') or \
                    not all(isinstance(x, str) for x in v):
                raise ValueError(f'{self.name} must be a list of strings, got {v!r}')
            return list(v)
        # float_array
        if self.scalar_ok and _is_number(v):
            v = [v]
        if isinstance(v, (str, bytes)) or not hasattr(v, '__iter__') or \
                not all(_is_number(x) for x in v):
            raise ValueError(f'{self.name} must be a list of numbers [{self.unit or "-"}], '
                             f'got {v!r}')
        values = [float(x) for x in v]
        if self.sizes and len(values) not in self.sizes:
            raise ValueError(f'{self.name} needs {" or ".join(map(str, self.sizes))} values, '
                             f'got {len(values)}')
        for i, x in enumerate(values):
            self._check_number(x, f'{self.name}[{i}]')
        return values


def check_output_path(path: str, what: str = 'output') -> str:
    """``path``, or ValueError if it starts with ``-``: such a path is almost always an
    option given where a path was expected (``--help``), and writing it would leave a
    file named like an option."""
    if str(path).startswith('-'):
        raise ValueError(f'{what} {str(path)!r} starts with "-" (an option where a path was '
                         f'expected?); write ./{path} if that is the name you mean')
    return path


def defaults(specs: Iterable[ParamSpec]) -> Dict[str, Any]:
    """{name: default} of ``specs``."""
    return {s.name: s.default for s in specs}


def coerce_all(specs: Iterable[ParamSpec], values: Mapping[str, Any],
               where: str = '') -> Dict[str, Any]:
    """Defaults overlaid with ``values`` coerced by their specs.

    An unknown key or an invalid value raises ValueError naming ``where``, the key and
    the reason (with the closest known key for a typo).
    """
    import difflib
    by_name = {s.name: s for s in specs}
    out = defaults(by_name.values())
    prefix = f'{where}: ' if where else ''
    for key, value in values.items():
        spec = by_name.get(key)
        if spec is None:
            close = difflib.get_close_matches(key, list(by_name), n=1)
            hint = f'; did you mean {close[0]!r}?' if close else \
                f'; known: {", ".join(sorted(by_name))}'
            raise ValueError(f'{prefix}{key}: unknown parameter{hint}')
        if value is spec.default and not (spec.scalar_ok and _is_number(value)):
            # the default object itself: what coerce_all put for a key not given (a scene
            # file's dict coerced again to build a run: 80 of its 90 keys, ~45 µs); out
            # holds it already, as for a key missing here (but a scalar_ok default that
            # is a number, which coerce makes a list)
            continue
        try:
            out[key] = spec.coerce(value)
        except (ValueError, TypeError) as exc:
            raise ValueError(f'{prefix}{exc}') from None
    return out
