"""Several spacecraft in one simulator: the scene's keys and each spacecraft's values.

A scene names its spacecraft in ``spacecraft`` (a list) and gives each one's own values
under its name, which rcl reads as prefixed keys::

    spacecraft: [chaser, target]
    inertia: [1.0, 2.0, 3.0]          # node level: every spacecraft that gives none
    chaser:
      inertia: [10.0, 12.0, 14.0]     # rcl: chaser.inertia
      initial_angular_velocity: [0.0, 0.0, 0.1]

Only the body's own keys (``BODY_KEYS``: inertia, state, dissipation, torque limits,
actuators, sensors, and ``lockstep``: false leaves it out of the lockstep loop) may be
given per spacecraft; a key a spacecraft leaves out takes the
node-level value. The numerics, pacing, frames and QoS are the simulator's, shared.

Without ``spacecraft`` the simulator runs one unnamed spacecraft exactly as before: its
topics in the node's namespace, its body frame ``child_frame_id``. A named spacecraft
publishes the same topics under ``<name>/`` and its body frame is
``<name>/<child_frame_id>``.
"""
import re
from dataclasses import replace
from typing import Dict, Iterable, List, Mapping, Optional

from . import specs

BODY_KEYS = ('inertia', 'initial_attitude', 'initial_angular_velocity', 'dissipation.model',
             'dissipation.coefficient', 'max_torque', 'command_timeout', 'seed',
             'lockstep') + tuple(
    s.name for s in specs.SIMULATOR if s.name.startswith(('actuators.', 'sensors.')))
_BY_NAME = {s.name: s for s in specs.SIMULATOR}
SPEC = _BY_NAME['spacecraft']
# first components of node-level keys: a spacecraft so named would read as one of them
RESERVED = {s.name.split('.')[0] for s in specs.SIMULATOR} | {'scene', 'use_sim_time'}
_NAME = re.compile(r'[A-Za-z][A-Za-z0-9_]*\Z')


def name_problem(name: str, taken: Iterable[str] = ()) -> Optional[str]:
    """Why ``name`` cannot name a spacecraft (None if it can): it becomes a ROS namespace
    and a parameter prefix, so a letter then letters, digits and single underscores."""
    if not isinstance(name, str) or not _NAME.match(name) or '__' in name:
        return (f'spacecraft name {name!r} is invalid: it names a namespace and a parameter '
                'prefix, so it must start with a letter and hold only letters, digits and '
                'single underscores')
    if name in RESERVED:
        return f'spacecraft name {name!r} is a simulator parameter\'s name; choose another'
    if name in taken:
        return f'spacecraft name {name!r} is already in use'
    return None


def check_names(names: List[str]) -> List[str]:
    """The scene's ``spacecraft`` list, checked; ValueError naming the bad name."""
    for i, name in enumerate(names):
        problem = name_problem(name, names[:i])
        if problem:
            raise ValueError(f'spacecraft: {problem}')
    return list(names)


def craft_specs(names: Iterable[str], base: Optional[Mapping] = None) -> List:
    """The per-spacecraft parameter specs ``<name>.<key>``; their defaults are the node-level
    values ``base`` (when given) so that a key left out inherits."""
    out = []
    for name in names:
        for key in BODY_KEYS:
            spec = _BY_NAME[key]
            default = spec.default if base is None else base[key]
            out.append(replace(spec, name=f'{name}.{key}', default=default,
                               description=f'spacecraft {name}: {spec.description}'))
    return out


def craft_values(p: Mapping, name: str) -> Dict:
    """The simulator values of spacecraft ``name`` ('' = the unnamed one): the node-level
    values with its own ``<name>.<key>`` over them and its body frame
    ``<name>/<child_frame_id>``."""
    out = node_values(p)
    if not name:
        return out
    for key in BODY_KEYS:
        if f'{name}.{key}' in p:
            out[key] = p[f'{name}.{key}']
    out['child_frame_id'] = f'{name}/{p["child_frame_id"]}'
    return out


def _craft_names(p: Mapping) -> set:
    return {k.split('.')[0] for k in p if '.' in k and k.split('.')[0] not in RESERVED}


def node_values(p: Mapping) -> Dict:
    """``p`` without the per-spacecraft keys: what the engine's config reads."""
    names = _craft_names(p)
    return {k: v for k, v in p.items() if '.' not in k or k.split('.')[0] not in names}
