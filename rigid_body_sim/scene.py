"""Scenes are data: ROS 2 params files in config/ that the nodes and offline runs load alike.

The built-in scenes use up to three sections, each ``{ros__parameters: {...}}``:

* ``/**``                    — shared keys (``inertia``) and ``scene.name`` / ``scene.description``
* ``/**/attitude_simulator`` — the simulator's parameters
* ``/**/attitude_controller`` — the controller's (only scenes that control the body)

Any form ``--params-file`` accepts works the same (``attitude_simulator:``, a namespace,
rcl's wildcards): files are read as rcl reads them (:mod:`.params_file`), so a file that
loads here starts the nodes and vice versa. Every key is validated against the very
parameter specs the nodes declare, and a bad file fails with the file, the section, the
key and the reason.
"""
import os
from dataclasses import dataclass, field
from typing import Any, Dict, List, Tuple

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
    # several spacecraft (engine/fleet.py): {name: its own values (<name>.<key>, prefix off)}
    spacecraft: Dict[str, Dict[str, Any]] = field(default_factory=dict)

    @property
    def controlled(self) -> bool:
        return bool(self.controller)


def content_sha256(paths) -> str:
    """SHA-256 (hex) of the files' bytes in order: the scene's content in a run record
    (one file: that file's hash, whether an offline run or a node read it)."""
    import hashlib
    digest = hashlib.sha256()
    for path in paths:
        with open(path, 'rb') as f:
            digest.update(f.read())
    return digest.hexdigest()


def params_files_record(paths) -> Dict[str, str]:
    """The simulator node's ``scene.name`` and ``scene.sha256`` (``engine.specs.SCENE_RECORD``)
    as its ``--params-file`` s give them, where the node is not given them: the first file's
    name without its extension (a built-in scene is config/<name>.yaml; a file's own
    ``scene.name`` reaches the node through rcl and wins) and the files' content hash.
    Empty without files; SceneError if a file cannot be read."""
    if not paths:
        return {}
    try:
        digest = content_sha256(paths)
    except OSError as exc:
        raise SceneError(f'{exc.filename}: cannot read the params file: {exc.strerror}') from None
    return {'scene.name': os.path.splitext(os.path.basename(paths[0]))[0],
            'scene.sha256': digest}


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
        from .params_file import closest
        names = [n for n, _, _ in list_scenes()]
        raise SceneError(f'unknown scene {scene!r}{closest(scene, names)}; built-in scenes: '
                         f'{", ".join(names)} (or give a path to a params file)')
    return path


def list_scenes() -> List[Tuple[str, str, str]]:
    """(name, one-line description, path) of every built-in scene."""
    from . import params_file
    out = []
    directory = config_dir()
    for fname in sorted(os.listdir(directory)):
        if not fname.endswith('.yaml'):
            continue
        path = os.path.join(directory, fname)
        try:
            meta = params_file.node_parameters(path, SIMULATOR_NODE)
        except params_file.ParamsFileError:
            continue
        if 'scene.name' in meta:
            description = meta.get('scene.description')
            out.append((str(meta['scene.name'].value),
                        str(description.value) if description else '', path))
    return out


SIMULATOR_NODE = '/attitude_simulator'
CONTROLLER_NODE = '/attitude_controller'
META_KEYS = SCENE_KEYS + ('use_sim_time',)  # declared by every node (rclpy) or metadata


def load(scene: str, overrides=(), namespace: str = '/') -> SceneFile:
    """Load and validate a built-in scene (by name) or a params file (by path).

    ``namespace``: the nodes' namespace, for files whose sections name it
    (``/sat1/attitude_simulator``), as ``-r __ns:=/sat1`` would run them.

    ``overrides``: ``KEY=VALUE`` texts (``--set``) applied after the file, to each node of
    the scene that declares KEY; an unknown KEY fails with the closest valid one.

    The file is read as rcl reads it (``params_file``): the simulator takes what a node
    ``/attitude_simulator`` would take from ``--params-file``, the controller what
    ``/attitude_controller`` would. Values are checked with the nodes' parameter specs
    (``engine.specs``) without importing ROS; an unknown key, a section that names neither
    node, or a bad value fails with the file, the section, the key and the reason."""
    from .engine import EngineConfig, fleet, specs
    from .param_spec import coerce_all
    from . import params_file
    path = resolve(scene)
    sim_node = params_file.fully_qualified('attitude_simulator', namespace)
    ctl_node = params_file.fully_qualified('attitude_controller', namespace)
    sim_names = {s.name for s in specs.SIMULATOR} | set(META_KEYS)
    ctl_names = {s.name for s in specs.CONTROLLER} | set(META_KEYS)
    try:
        # the spacecraft's own keys (<name>.<key>) are the simulator's too
        crafts = params_file.node_parameters(path, sim_node).get('spacecraft')
        try:
            names = [] if crafts is None else fleet.check_names(
                [n for n in fleet.SPEC.coerce(crafts.value) if n])
        except ValueError as exc:
            raise SceneError(f'{path}: {crafts.section}: {exc}') from None
        craft_specs = fleet.craft_specs(names)
        sim_names |= {s.name for s in craft_specs}
        file_sections = params_file.sections(path)
        for section, _ in file_sections:
            if not (params_file.matches(section, sim_node)
                    or params_file.matches(section, ctl_node)):
                raise SceneError(f'{path}: {section}: this section applies to neither '
                                 f'{sim_node} nor {ctl_node} (node keys are '
                                 'matched as rcl matches them: attitude_simulator, '
                                 '/**/attitude_simulator, /**, ...)')
        problems = (params_file.unknown_keys(path, sim_node, sim_names,
                                             sim_names | ctl_names)
                    + params_file.unknown_keys(path, ctl_node, ctl_names,
                                               sim_names | ctl_names))
        if problems:
            raise SceneError(problems[0])
        sim_raw = params_file.node_parameters(path, sim_node)
        ctl_raw = params_file.node_parameters(path, ctl_node)
    except params_file.ParamsFileError as exc:
        raise SceneError(str(exc)) from None
    # controlled: some section is for the controller and not for the simulator
    controlled = any(params_file.matches(k, ctl_node)
                     and not params_file.matches(k, sim_node) for k, _ in file_sections)
    try:
        for text in overrides:
            key, value = params_file.parse_override(text)
            targets = [raw for raw, names in ((sim_raw, sim_names), (ctl_raw, ctl_names))
                       if key in names and (raw is sim_raw or controlled)]
            if not targets or key in META_KEYS:
                known = sim_names | (ctl_names if controlled else set())
                raise SceneError(f'--set {text}: {key}: not a parameter of this scene\'s '
                                 f'nodes{params_file.closest(key, known - set(META_KEYS))}')
            for raw in targets:
                raw[key] = params_file.Value(value, '--set')
    except params_file.ParamsFileError as exc:
        raise SceneError(str(exc)) from None
    meta = {**{k: v.value for k, v in ctl_raw.items()}, **{k: v.value for k, v in
                                                           sim_raw.items()}}
    name = str(meta.get('scene.name') or os.path.splitext(os.path.basename(path))[0])
    description = str(meta.get('scene.description', ''))

    def values(raw, names, node_specs, node):
        own = {k: v.value for k, v in raw.items() if k in names and k not in META_KEYS}
        for key, value in own.items():  # one by one, to name the section of a bad value
            try:
                coerce_all(node_specs, {key: value})
            except ValueError as exc:
                where = '--set' if raw[key].section == '--set' else \
                    f'{path}: {raw[key].section}'
                raise SceneError(f'{where}: {exc}') from None
        return coerce_all(node_specs, own, node)

    sim = values(sim_raw, sim_names, specs.SIMULATOR + tuple(craft_specs), sim_node)
    ctl = values(ctl_raw, ctl_names, specs.CONTROLLER, ctl_node) if controlled else {}
    try:
        # a key a spacecraft leaves out is the node-level value (not the default)
        own = {n: {k: sim[f'{n}.{k}'] for k in fleet.BODY_KEYS if f'{n}.{k}' in sim_raw}
               for n in names}
        sim = fleet.node_values(sim)
        for craft in names:  # each spacecraft's engine, as the simulator node builds it
            try:
                EngineConfig.from_parameters({**sim, **own[craft]})
            except ValueError as exc:
                raise ValueError(f'spacecraft {craft}: {exc}') from None
        EngineConfig.from_parameters(sim, ctl or None)
    except ValueError as exc:
        raise SceneError(f'{path}: {exc}') from None
    return SceneFile(name, description, path, sim, ctl, own)


def add_arguments(parser):
    parser.add_argument('--paths', action='store_true', help='also print each file path')


def run(args) -> int:
    for name, description, path in list_scenes():
        print(f'{name:15s} {description}' + (f'  [{path}]' if args.paths else ''))
    return 0


def spacecraft_scene(scene: SceneFile, name: str, controller=None) -> SceneFile:
    """Spacecraft ``name`` of a formation scene as a scene of its own: what the simulator
    runs for it (the node-level values, its own over them, its body frame
    ``<name>/<child_frame_id>``) and the controller that answers it in its namespace (the
    scene's values, with ``controller``: {key: value} its own params give it). Each
    spacecraft's engine runs apart from the others', so an offline run of this scene gives
    that spacecraft's messages of a lockstep run of the formation. SceneError for a name
    that is not one of the scene's spacecraft or a bad controller value."""
    from .engine import specs
    from .param_spec import coerce_all
    if name not in scene.spacecraft:
        raise SceneError(f'{scene.path}: no spacecraft {name!r} (it has: '
                         f'{", ".join(scene.spacecraft) or "none"})')
    sim = {**scene.simulator, **scene.spacecraft[name], 'spacecraft': ['']}
    sim['child_frame_id'] = f'{name}/{scene.simulator["child_frame_id"]}'
    try:
        ctl = coerce_all(specs.CONTROLLER, {**scene.controller, **(controller or {})}) \
            if scene.controller or controller else {}
    except ValueError as exc:
        raise SceneError(f'{scene.path}: spacecraft {name}\'s controller: {exc}') from None
    return SceneFile(f'{scene.name}/{name}', scene.description, scene.path, sim, ctl)
