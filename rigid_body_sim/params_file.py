"""ROS 2 params files read as rcl reads them, without ROS (for offline runs and the nodes).

``rcl_yaml_param_parser`` (rcl 9.2, Jazzy) and rclpy (7.1) decide two things that plain
``yaml.safe_load`` gets wrong:

* **Which node a section is for.** Node keys may be nested as namespaces (``ns: {node:
  {ros__parameters: …}}`` is ``ns/node``). A key without a leading ``/`` gets one; ``/*``
  stands for one name token and ``/**`` for any number, and the key must match the node's
  fully qualified name as a whole (rclpy: ``"/*" → "(/\\w+)"``, ``std::regex_match``).
  Sections apply in file order; a later one overrides an earlier one key by key.
* **What type a value has.** A scalar tagged ``!!str`` or quoted is a string; otherwise
  ``y/yes/true/on`` and ``n/no/false/off`` (three capitalisations) are bools, then what
  ``strtoll(…, 0)`` reads whole is an integer (``0x10`` too), then what ``strtod`` reads
  whole is a double (``1e-06``, ``inf``; ``.inf``/``.nan`` as YAML spells them), else a
  string. A sequence must hold one type (``[1.0, 2]`` is an error, as in rcl). PyYAML
  instead reads ``1e-06`` as a string and ``0x10`` as 16 — so we parse YAML events.

:func:`node_parameters` returns a node's flattened parameters (``a: {b: 1}`` → ``a.b``),
with the section each came from, so an error can name the file, the section and the key.
"""
import copy
import math
import re
from dataclasses import dataclass
from typing import Any, Dict, List, Tuple

import yaml

PARAMS_KEY = 'ros__parameters'
_TRUE = {'Y', 'y', 'yes', 'Yes', 'YES', 'true', 'True', 'TRUE', 'on', 'On', 'ON'}
_FALSE = {'N', 'n', 'no', 'No', 'NO', 'false', 'False', 'FALSE', 'off', 'Off', 'OFF'}
_SPECIAL = {'.nan': math.nan, '.NaN': math.nan, '.NAN': math.nan}
_SPECIAL.update({sign + inf: (-math.inf if sign == '-' else math.inf)
                 for sign in ('', '+', '-') for inf in ('.inf', '.Inf', '.INF')})
# strtod's accepted forms (C locale): decimal, hex float, inf/infinity, nan(…); optional
# leading whitespace and sign. Python's float() reads the decimal/inf/nan ones alike.
_STRTOD = re.compile(r'\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf(?:inity)?'
                     r'|nan(?:\([0-9A-Za-z_]*\))?|0[xX](?:[0-9a-fA-F]+\.?[0-9a-fA-F]*'
                     r'|\.[0-9a-fA-F]+)(?:[pP][+-]?\d+)?)', re.IGNORECASE)
_STRTOLL = re.compile(r'\s*[+-]?(?:0[xX][0-9a-fA-F]+|0[0-7]*|[1-9]\d*)')
STR_TAG = 'tag:yaml.org,2002:str'


class ParamsFileError(ValueError):
    """A params file rcl would refuse, or that we cannot read; names the file and why."""


@dataclass(frozen=True)
class Value:
    """A parameter value as rcl types it, and the node key (section) it came from."""
    value: Any
    section: str


def scalar(text: str, style, tag) -> Any:
    """One YAML scalar typed as rcl's ``get_value`` types it (see the module docstring)."""
    if tag == STR_TAG or style in ("'", '"'):
        return text
    if text == '':
        return None  # rcl: "no value"
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    if _STRTOLL.fullmatch(text):
        value = int(text.strip(), 0) if not re.fullmatch(r'\s*[+-]?0[0-7]+', text) \
            else int(text.strip(), 8)
        if -2 ** 63 <= value < 2 ** 63:  # strtoll sets ERANGE beyond int64: then a double
            return value
    if text in _SPECIAL:
        return _SPECIAL[text]
    if _STRTOD.fullmatch(text):
        t = text.strip()
        if re.match(r'[+-]?0[xX]', t):
            sign = -1.0 if t.startswith('-') else 1.0
            return sign * float.fromhex(t.lstrip('+-'))
        return float(re.sub(r'\(.*\)$', '', t))
    return text


# Documents already parsed, by (path, text): a scene's loading reads its file ~6 times
# (each node's section, the overrides) and a demo ~30, at ~4 ms of pure-Python YAML each
# (issue 32). Keyed on the text, so an edited file is parsed again; each caller gets its
# own copy to change.
_PARSED: Dict[Tuple[str, str], Any] = {}
_PARSED_MAX = 64


def _tree(path: str, text: str = None):
    """The YAML document (file ``path``, or ``text``) as nested dicts/lists with typed
    scalars (from parser events, so that quoting and explicit tags are seen as rcl sees
    them)."""
    try:
        if text is None:
            with open(path, encoding='utf-8') as f:
                text = f.read()
        key = (path, text)
        if key in _PARSED:
            return copy.deepcopy(_PARSED[key])
        events = list(yaml.parse(text))
    except OSError as exc:
        raise ParamsFileError(f'{path}: {exc.strerror}') from None
    except UnicodeDecodeError as exc:
        raise ParamsFileError(f'{path}: not UTF-8 text ({exc.reason} at byte '
                              f'{exc.start})') from None
    except yaml.YAMLError as exc:
        raise ParamsFileError(f'{path}: not valid YAML: {str(exc).splitlines()[0]}') from None
    root = _build(path, events)
    if len(_PARSED) >= _PARSED_MAX:
        _PARSED.clear()
    _PARSED[key] = root
    return copy.deepcopy(root)


def _build(path: str, events):
    """The tree of parser ``events`` (see _tree)."""
    stack: List[Any] = []
    keys: List[Any] = []
    root = None

    def put(value):
        nonlocal root
        if not stack:
            root = value
        elif isinstance(stack[-1], list):
            stack[-1].append(value)
        elif keys[-1] is None:
            keys[-1] = value
        else:
            stack[-1][keys[-1]] = value
            keys[-1] = None

    for ev in events:
        if isinstance(ev, yaml.ScalarEvent):
            put(scalar(ev.value, ev.style, ev.tag) if not (stack and isinstance(
                stack[-1], dict) and keys[-1] is None) else ev.value)
        elif isinstance(ev, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
            container = {} if isinstance(ev, yaml.MappingStartEvent) else []
            put(container)
            stack.append(container)
            keys.append(None)
        elif isinstance(ev, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
            stack.pop()
            keys.pop()
        elif isinstance(ev, yaml.AliasEvent):
            raise ParamsFileError(f'{path}: YAML aliases are not supported in params files')
    return root


def _flatten(d: dict, path: str, section: str, prefix: str = '') -> Dict[str, Any]:
    out = {}
    for key, value in d.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(_flatten(value, path, section, name + '.'))
        elif isinstance(value, list):
            kinds = {bool if isinstance(v, bool) else type(v) for v in value}
            if any(isinstance(v, (dict, list)) for v in value) or len(kinds) > 1:
                raise ParamsFileError(
                    f'{path}: {section}: {name}: a sequence must hold values of one type '
                    '(all doubles, all integers, all bools or all strings), as rcl requires; '
                    f'got {value!r}')
            out[name] = list(value)
        elif value is None:
            raise ParamsFileError(f'{path}: {section}: {name}: no value (rcl refuses it)')
        else:
            out[name] = value
    return out


def sections(path: str) -> List[Tuple[str, Dict[str, Any]]]:
    """[(node key with a leading '/', {parameter: value})] in file order."""
    root = _tree(path)
    if root is None:
        return []
    if not isinstance(root, dict):
        raise ParamsFileError(f'{path}: a params file maps node names to '
                              f'{{{PARAMS_KEY}: ...}}')
    out = []

    def walk(d, names):
        for key, value in d.items():
            key = str(key)
            if key == PARAMS_KEY:
                if not names:
                    raise ParamsFileError(f'{path}: {PARAMS_KEY} needs a node name above it')
                node = '/'.join(names)
                node = node if node.startswith('/') else '/' + node
                if not isinstance(value, dict):
                    raise ParamsFileError(f'{path}: {node}: {PARAMS_KEY} must be a mapping')
                out.append((node, _flatten(value, path, node)))
            elif isinstance(value, dict):
                walk(value, names + [key.strip('/')] if names else [key.rstrip('/')])
            else:
                where = '/'.join(names + [key]) or key
                raise ParamsFileError(f'{path}: {where}: expected a node name holding '
                                      f'{PARAMS_KEY}, got a value')
    walk(root, [])
    return out


def matches(node_key: str, node_fqn: str) -> bool:
    """rclpy's rule: '/*' → one name token, '/**' → any number, whole-name match."""
    pattern = re.escape(node_key).replace(r'/\*', r'(/\w+)').replace(r'\*', '*')
    return re.fullmatch(pattern, node_fqn) is not None


def node_parameters(path: str, node_fqn: str) -> Dict[str, Value]:
    """{name: Value} that the node ``node_fqn`` (e.g. ``/attitude_simulator``,
    ``/sat1/attitude_simulator``) takes from the file, later sections winning."""
    out: Dict[str, Value] = {}
    for key, params in sections(path):
        if matches(key, node_fqn):
            out.update({name: Value(value, key) for name, value in params.items()})
    return out


def parse_override(text: str) -> Tuple[str, Any]:
    """``KEY=VALUE`` (a --set option) → (key, value typed as rcl types that value in a
    params file: ``1e-06`` a double, ``[1.0, 2.0]`` a double array, ``off`` a bool)."""
    key, sep, value = text.partition('=')
    key = key.strip()
    if not sep or not key:
        raise ParamsFileError(f'--set {text}: expected KEY=VALUE, e.g. --set accuracy=1e-9')
    tree = _tree(f'--set {key}', f'x: {value}' if value.strip() else 'x: ""')
    flat = _flatten(tree, f'--set {key}', '--set')
    return key, flat['x']


def fully_qualified(name: str, namespace: str = '/') -> str:
    namespace = '/' + namespace.strip('/') if namespace.strip('/') else ''
    return f'{namespace}/{name}'


def closest(name: str, candidates) -> str:
    """' (did you mean X?)' for the nearest candidate name, or ''."""
    import difflib
    near = difflib.get_close_matches(name, sorted(candidates), n=1, cutoff=0.6)
    return f' (did you mean {near[0]}?)' if near else ''


def unknown_keys(path: str, node_fqn: str, own: set, shared: set) -> List[str]:
    """Problems with the keys the file gives ``node_fqn``: a key from a section naming this
    node must be one of ``own``; a key from a wildcard section that matches other nodes
    too may be any of ``shared`` (the package's nodes' parameters). One line each, naming
    the file, the section and the key, with the closest valid key."""
    problems = []
    for section, params in sections(path):
        if not matches(section, node_fqn):
            continue
        allowed = shared if '*' in section else own
        for key in params:
            if key not in allowed:
                problems.append(f'{path}: {section}: {key}: unknown parameter of '
                                f'{node_fqn}{closest(key, allowed)}')
    return problems


# --- what a node gets from several params files and -p, as rcl and rclpy decide ----------
# rcl parses every --params-file and -p, in command-line order, into one table of node
# keys (first appearance order; -p goes to '/**'). A key set again in the same node key
# overwrites the value of the same type, but one of another type is kept beside it (a
# variant holds one slot per type), and rclpy then takes the first slot in this order:
RCL_TYPE_ORDER = ('bool', 'integer', 'double', 'string', 'bool_array', 'integer_array',
                  'double_array', 'string_array', 'empty_array')
# rclpy applies the node keys that match the node in table order, later ones winning.


def rcl_type(value) -> str:
    """The rcl variant slot a typed value (from :func:`scalar`) lands in."""
    if isinstance(value, list):
        return rcl_type(value[0]) + '_array' if value else 'empty_array'
    if isinstance(value, bool):
        return 'bool'
    return {int: 'integer', float: 'double'}.get(type(value), 'string')


def parse_param_rule(text: str) -> Tuple[str, str, Any]:
    """``-p [node:]name:=value`` → (node key, name, value typed as rcl types it)."""
    name, sep, value = text.partition(':=')
    node, colon, param = name.partition(':')
    node, name = (node, param) if colon else ('/**', name)
    if not sep or not name:
        raise ParamsFileError(f'-p {text}: expected NAME:=VALUE')
    if not value.strip():
        raise ParamsFileError(f'-p {text}: no value (rcl refuses it)')
    flat = _flatten(_tree(f'-p {text}', f'x: {value}'), f'-p {text}', '-p')
    return node if node.startswith('/') else '/' + node, name, flat['x']


def given_values(sources, node_fqn: str) -> Tuple[Dict[str, List[Value]], Dict[str, Value]]:
    """What the command line gives the node ``node_fqn``, and what it ends up with.

    ``sources``: ``('file', path)`` and ``('param', 'name:=value')`` in command-line order.
    Returns ({name: [every Value given, in command-line order]}, {name: the Value rcl and
    rclpy keep}); a Value's ``section`` says where it came from (``FILE: SECTION`` or
    ``-p TEXT``). ParamsFileError for a file or rule rcl would refuse."""
    table: Dict[str, Dict[str, Dict[str, Value]]] = {}
    given: Dict[str, List[Value]] = {}
    for kind, arg in sources:
        if kind == 'file':
            items = [(section, name, value, f'{arg}: {section}')
                     for section, params in sections(arg) for name, value in params.items()]
        else:
            node, name, value = parse_param_rule(arg)
            items = [(node, name, value, f'-p {arg}')]
        for node, name, value, origin in items:
            entry = table.setdefault(node, {}).setdefault(name, {})
            entry[rcl_type(value)] = Value(value, origin)
            if matches(node, node_fqn):
                given.setdefault(name, []).append(Value(value, origin))
    kept: Dict[str, Value] = {}
    for node, params in table.items():
        if matches(node, node_fqn):
            for name, slots in params.items():
                kept[name] = slots[min(slots, key=RCL_TYPE_ORDER.index)]
    return given, kept
