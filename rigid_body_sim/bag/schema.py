"""Message definitions, type hashes and QoS strings exactly as rosbag2 (Jazzy) stores them.

rosbag2's MCAP plugin embeds each type's ``.msg`` text with its dependencies appended
(``LocalMessageDefinitionSource::get_full_text``) and stores the publishers' QoS as a
version-9 YAML string. Readers (Foxglove, rosbags, mcap-ros2-support) rely on both.
"""
from __future__ import annotations

import functools
import json
import os
import re
from typing import Any, Iterable

import rigid_body_sim  # noqa: F401  (puts the venv prefix on AMENT_PREFIX_PATH)

DELIMITER = '=' * 80

# Types rosbag2 does not treat as dependencies (rosidl primitive names plus ROS 1 time).
_PRIMITIVES = frozenset({
    'bool', 'byte', 'char', 'float32', 'float64', 'int8', 'uint8', 'int16', 'uint16',
    'int32', 'uint32', 'int64', 'uint64', 'string', 'wstring', 'time', 'duration',
})
# "<type>[<bounds>] <name>" at the start of a line; constants and comments never match a
# non-primitive type, so they fall out when primitives are skipped.
_FIELD = re.compile(r'^\s*([A-Za-z0-9_/]+)(?:<=\d+)?(?:\[[^\]]*\])?\s+[A-Za-z_]\w*')

# rosbag2 fills these in for a publisher with default (infinite) durations.
_INFINITE = {'sec': 9223372036, 'nsec': 854775807}


class TypeNotFound(LookupError):
    """The interface files of a message type are not installed."""


def split_type(type_name: str) -> tuple[str, str]:
    """``pkg/msg/Type`` or ``pkg/Type`` -> ``(pkg, Type)``."""
    parts = type_name.split('/')
    if len(parts) == 3 and parts[1] == 'msg':
        return parts[0], parts[2]
    if len(parts) == 2:
        return parts[0], parts[1]
    raise TypeNotFound(f'not a message type name: {type_name!r}')


def _share_file(package: str, type_: str, ext: str) -> str:
    from ament_index_python.packages import PackageNotFoundError, get_package_share_directory
    try:
        share = get_package_share_directory(package)
    except (PackageNotFoundError, LookupError, ValueError) as exc:
        raise TypeNotFound(f'message package {package!r} is not installed') from exc
    path = os.path.join(share, 'msg', f'{type_}.{ext}')
    if not os.path.isfile(path):
        raise TypeNotFound(f'message type {package}/msg/{type_} is not installed')
    return path


def _dependencies(text: str, package: str) -> set[str]:
    deps = set()
    for line in text.splitlines():
        match = _FIELD.match(line.split('#', 1)[0])
        if not match or match.group(1) in _PRIMITIVES:
            continue
        name = match.group(1)
        deps.add(name if '/' in name else f'{package}/{name}')
    return deps


@functools.lru_cache(maxsize=None)
def _msg_text(type_name: str) -> str:
    package, type_ = split_type(type_name)
    with open(_share_file(package, type_, 'msg'), encoding='utf-8') as f:
        return f.read()


@functools.lru_cache(maxsize=None)
def message_definition(type_name: str) -> str:
    """The ``ros2msg`` schema text of ``type_name`` (``pkg/msg/Type``), as rosbag2 builds it.

    Root text, then each dependency once, depth-first in sorted order, each introduced by
    a line of 80 ``=`` and ``MSG: pkg/Type`` (the short name Foxglove's parser requires).
    """
    seen: set[str] = set()

    def walk(name: str) -> str:
        text = _msg_text(name)
        package = split_type(name)[0]
        for dep in sorted(_dependencies(text, package)):
            if dep in seen:
                continue
            seen.add(dep)
            text += f'\n{DELIMITER}\nMSG: {dep}\n' + walk(dep)
        return text

    return walk(type_name)


@functools.lru_cache(maxsize=None)
def type_hash(type_name: str) -> str:
    """The RIHS01 hash rosidl installed in ``share/<pkg>/msg/<Type>.json``, or ``''``."""
    package, type_ = split_type(type_name)
    try:
        with open(_share_file(package, type_, 'json'), encoding='utf-8') as f:
            hashes = json.load(f).get('type_hashes', [])
    except (TypeNotFound, OSError, ValueError):
        return ''
    full = f'{package}/msg/{type_}'
    return next((h['hash_string'] for h in hashes if h.get('type_name') == full), '')


def message_class(type_name: str) -> Any:
    """The generated Python class of ``type_name``; raises :class:`TypeNotFound`."""
    import importlib
    package, type_ = split_type(type_name)
    try:
        return getattr(importlib.import_module(f'{package}.msg'), type_)
    except (ImportError, AttributeError) as exc:
        raise TypeNotFound(f'message type {package}/msg/{type_} is not installed') from exc


# --- QoS -----------------------------------------------------------------------------

def _duration(ns: int) -> dict[str, int]:
    if ns <= 0 or ns >= 9223372036854775807:
        return dict(_INFINITE)
    return {'sec': ns // 1_000_000_000, 'nsec': ns % 1_000_000_000}


def qos_to_dict(qos: Any) -> dict[str, Any]:
    """An rclpy ``QoSProfile`` as one entry of rosbag2's v9 QoS list."""
    return {
        'history': qos.history.name.lower(),
        'depth': int(qos.depth),
        'reliability': qos.reliability.name.lower(),
        'durability': qos.durability.name.lower(),
        'deadline': _duration(qos.deadline.nanoseconds),
        'lifespan': _duration(qos.lifespan.nanoseconds),
        'liveliness': qos.liveliness.name.lower(),
        'liveliness_lease_duration': _duration(qos.liveliness_lease_duration.nanoseconds),
        'avoid_ros_namespace_conventions': bool(qos.avoid_ros_namespace_conventions),
    }


def qos_yaml(profiles: Iterable[dict[str, Any]]) -> str:
    """rosbag2's ``serialize_rclcpp_qos_vector`` output (v9: policies as strings)."""
    lines = []
    for p in profiles:
        entry = []
        for key, value in p.items():
            if isinstance(value, dict):
                value = '{sec: %d, nsec: %d}' % (value['sec'], value['nsec'])
            elif isinstance(value, bool):
                value = 'true' if value else 'false'
            entry.append(f'{key}: {value}')
        lines.append('- ' + '\n  '.join(entry))
    return '\n'.join(lines) + ('\n' if lines else '')


DEFAULT_QOS = {
    'history': 'keep_last', 'depth': 10, 'reliability': 'reliable', 'durability': 'volatile',
    'deadline': dict(_INFINITE), 'lifespan': dict(_INFINITE), 'liveliness': 'automatic',
    'liveliness_lease_duration': dict(_INFINITE), 'avoid_ros_namespace_conventions': False,
}
DEFAULT_QOS_YAML = qos_yaml([DEFAULT_QOS])

# rosbag2 metadata v8 and older stored the policies as rmw enum integers.
_V8_ENUMS = {
    'history': {0: 'system_default', 1: 'keep_last', 2: 'keep_all'},
    'reliability': {0: 'system_default', 1: 'reliable', 2: 'best_effort'},
    'durability': {0: 'system_default', 1: 'transient_local', 2: 'volatile'},
    'liveliness': {0: 'system_default', 1: 'automatic', 3: 'manual_by_topic'},
}


def parse_qos_yaml(text: str) -> list[dict[str, Any]]:
    """Inverse of :func:`qos_yaml`; ``''`` means no profiles. Accepts v8 integer enums."""
    import yaml
    data = yaml.safe_load(text) if text and text.strip() else []
    profiles = data if isinstance(data, list) else []
    for p in profiles:
        for key, names in _V8_ENUMS.items():
            if isinstance(p.get(key), int):
                p[key] = names.get(p[key], 'system_default')
    return [p for p in profiles if isinstance(p, dict)]


def qos_from_dict(entry: dict[str, Any]) -> Any:
    """An rclpy ``QoSProfile`` for a publisher offering ``entry`` (infinite durations dropped)."""
    from rclpy.duration import Duration
    from rclpy.qos import (DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile,
                           ReliabilityPolicy)

    def policy(enum: Any, key: str, default: Any) -> Any:
        # DDS discovery reports history as "unknown" (depth 0); unknown -> the default.
        name = str(entry.get(key, '')).upper()
        return default if name in ('', 'UNKNOWN', 'SYSTEM_DEFAULT') else \
            enum.__members__.get(name, default)

    qos = QoSProfile(
        history=policy(HistoryPolicy, 'history', HistoryPolicy.KEEP_LAST),
        depth=max(1, int(entry.get('depth') or 10)),
        reliability=policy(ReliabilityPolicy, 'reliability', ReliabilityPolicy.RELIABLE),
        durability=policy(DurabilityPolicy, 'durability', DurabilityPolicy.VOLATILE),
        liveliness=policy(LivelinessPolicy, 'liveliness', LivelinessPolicy.AUTOMATIC),
    )
    for key in ('deadline', 'lifespan', 'liveliness_lease_duration'):
        value = entry.get(key)
        finite = isinstance(value, dict) and value != _INFINITE
        if finite and (value.get('sec') or value.get('nsec')):
            setattr(qos, key, Duration(seconds=int(value.get('sec', 0)),
                                       nanoseconds=int(value.get('nsec', 0))))
    return qos
