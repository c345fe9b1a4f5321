"""Scenes are data: ROS 2 params files in config/ that the nodes and offline runs load alike.

A scene file has up to three sections, each ``{ros__parameters: {...}}``:

* ``/**``                    — shared keys (``inertia``) and ``scene.name`` / ``scene.description``
* ``/**/attitude_simulator`` — the simulator's parameters
* ``/**/attitude_controller`` — the controller's (only scenes that control the body)

The ``/**/`` wildcard makes a section apply to the node under any namespace. Every key is
validated against the very parameter specs the nodes declare, so a file that loads here
also starts the nodes, and a bad file fails with the file, the key and the reason.
"""
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Tuple

import yaml

SIMULATOR_SECTION = '/**/attitude_simulator'
CONTROLLER_SECTION = '/**/attitude_controller'
SHARED_SECTION = '/**'
SCENE_KEYS = ('scene.name', 'scene.description')


class SceneError(ValueError):
    """A scene that cannot be loaded; the message names the file, the key and the reason."""


@dataclass
class SceneFile:
    """A validated scene: coerced parameter values per node."""
    name: str
    description: str
    path: str
    simulator: Dict[str, Any] = field(default_factory=dict)
    controller: Dict[str, Any] = field(default_factory=dict)

    @property
    def controlled(self) -> bool:
        return bool(self.controller)


def config_dir() -> str:
    """The installed share/rigid_body_sim/config, or the source tree's config/."""
    try:
        from ament_index_python.packages import get_package_share_directory
        path = os.path.join(get_package_share_directory('rigid_body_sim'), 'config')
        if os.path.isdir(path):
            return path
    except (LookupError, OSError, ImportError):
        pass
    return os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), 'config')


def resolve(scene: str) -> str:
    """Path of a built-in scene name or of a params file."""
    if os.path.sep in scene or scene.endswith(('.yaml', '.yml')):
        if not os.path.isfile(scene):
            raise SceneError(f'{scene}: no such scene file')
        return scene
    path = os.path.join(config_dir(), scene + '.yaml')
    if not os.path.isfile(path):
        names = ', '.join(n for n, _, _ in list_scenes())
        raise SceneError(f'unknown scene {scene!r}; built-in scenes: {names} '
                         '(or give a path to a params file)')
    return path


def list_scenes() -> List[Tuple[str, str, str]]:
    """(name, one-line description, path) of every built-in scene."""
    out = []
    directory = config_dir()
    for fname in sorted(os.listdir(directory)):
        if not fname.endswith('.yaml'):
            continue
        path = os.path.join(directory, fname)
        try:
            with open(path) as f:
                data = yaml.safe_load(f) or {}
            shared = (data.get(SHARED_SECTION) or {}).get('ros__parameters', {})
            scene = shared.get('scene') or {}
        except (OSError, yaml.YAMLError, AttributeError):
            continue
        if scene.get('name'):
            out.append((scene['name'], scene.get('description', ''), path))
    return out


def _flatten(d, prefix=''):
    """ROS params-file nesting {a: {b: 1}} → {'a.b': 1}."""
    out = {}
    for key, value in d.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            out.update(_flatten(value, name + '.'))
        else:
            out[name] = value
    return out


def load(scene: str) -> SceneFile:
    """Load and validate a built-in scene (by name) or a params file (by path).

    Uses the nodes' parameter specs (``engine.specs``) without importing ROS."""
    from .engine import EngineConfig, specs
    from .engine.params import coerce_all
    path = resolve(scene)
    try:
        with open(path) as f:
            data = yaml.safe_load(f)
    except yaml.YAMLError as exc:
        raise SceneError(f'{path}: not valid YAML: {str(exc).splitlines()[0]}') from None
    except OSError as exc:
        raise SceneError(f'{path}: {exc.strerror}') from None
    if not isinstance(data, dict):
        raise SceneError(f'{path}: a params file maps node names to {{ros__parameters: ...}}')
    sections = {}
    for key, body in data.items():
        if key not in (SHARED_SECTION, SIMULATOR_SECTION, CONTROLLER_SECTION):
            raise SceneError(f'{path}: {key}: unknown section; use {SHARED_SECTION}, '
                             f'{SIMULATOR_SECTION} or {CONTROLLER_SECTION}')
        if not isinstance(body, dict) or set(body) != {'ros__parameters'} or \
                not isinstance(body['ros__parameters'], dict):
            raise SceneError(f'{path}: {key}: must hold exactly one mapping ros__parameters')
        sections[key] = _flatten(body['ros__parameters'])
    shared = sections.get(SHARED_SECTION, {})
    name = str(shared.get('scene.name') or os.path.splitext(os.path.basename(path))[0])
    description = str(shared.get('scene.description', ''))
    shared_params = {k: v for k, v in shared.items() if k not in SCENE_KEYS + ('use_sim_time',)}
    # Shared keys must be known to at least one node; each node takes those it declares.
    sim_names = {s.name for s in specs.SIMULATOR}
    ctl_names = {s.name for s in specs.CONTROLLER}
    for key in shared_params:
        if key not in sim_names | ctl_names:
            raise SceneError(f'{path}: {SHARED_SECTION}: {key}: unknown parameter for both nodes')

    def section(which, names, node_specs):
        own = {k: v for k, v in sections.get(which, {}).items() if k != 'use_sim_time'}
        values = {**{k: v for k, v in shared_params.items() if k in names}, **own}
        try:
            return coerce_all(node_specs, values, which)
        except ValueError as exc:
            raise SceneError(f'{path}: {exc}') from None

    sim = section(SIMULATOR_SECTION, sim_names, specs.SIMULATOR)
    ctl = section(CONTROLLER_SECTION, ctl_names, specs.CONTROLLER) \
        if CONTROLLER_SECTION in sections else {}
    try:
        EngineConfig.from_parameters(sim, ctl or None)
    except ValueError as exc:
        raise SceneError(f'{path}: {exc}') from None
    return SceneFile(name, description, path, sim, ctl)


def add_arguments(parser):
    parser.add_argument('--paths', action='store_true', help='also print each file path')


def run(args) -> int:
    for name, description, path in list_scenes():
        print(f'{name:15s} {description}' + (f'  [{path}]' if args.paths else ''))
    return 0
